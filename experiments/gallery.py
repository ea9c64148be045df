"""Figures of the environment scenes in robots/ for docs/gallery.md.

Each scene is run as declared (its integrator and step) and drawn in one figure
``docs/figures/gallery_<scene>.png``: the generalized coordinates against time above, the gap
of every constraint (the smallest of a pair's rows) and the normal impulse per step below.

Usage::

    python experiments/gallery.py                    # every scene, full duration
    python experiments/gallery.py --duration 0.05 --out /tmp/gallery   # a quick check
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: The scenes of the gallery, in the order of docs/gallery.md.
SCENES = (
    "box_drop_collision",
    "capsule_arm_box",
    "ball_mesh_wedge",
    "ball_vibrating_box",
    "ball_vibrating_table",
    "four_bar",
    "four_bar_stop",
    "block_incline",
    "block_incline_welded",
    "slider_crank",
)


def draw(name: str, out: Path, duration: float | None) -> Path:
    """Run scene ``name`` of robots/ and write its figure; returns the PNG's path.

    Args:
        name: Scene file name without ``.toml``.
        out: Folder of the figure.
        duration: Simulated time in [s], or None for the scene's own.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ucontrol.analysis.coordinates import coordinate_names, coordinate_units
    from ucontrol.scene import Scene
    from ucontrol.simulate import simulate

    scene = Scene.from_toml(ROOT / "robots" / f"{name}.toml")
    log = simulate(scene, duration=duration, out=None, progress=False).log
    t = np.asarray(log.t)
    q = np.asarray(log.q)
    gap = np.asarray(log.gap)
    impulse = np.asarray(log.impulse)
    names = list(log.constraint_names)
    pairs = sorted({label.split("#")[0] for label in names})
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 5.0), sharex=True)
    shown = min(q.shape[1], 7)
    q_names, _ = coordinate_names(scene.robot.model, q.shape[1], np.asarray(log.v).shape[1])
    q_units, _ = coordinate_units(scene.robot.model, q.shape[1], np.asarray(log.v).shape[1])
    units = list(dict.fromkeys(q_units[:shown]))  # one axis per unit: the first two
    axes = [top] + ([top.twinx()] if len(units) > 1 else [])
    for axis, unit in zip(axes, units, strict=False):
        for k in (k for k in range(shown) if q_units[k] == unit):
            axis.plot(t, q[:, k], label=q_names[k], ls="-" if axis is top else "--")
        axis.set_ylabel(f"q [{unit}]")
        axis.legend(loc="upper left" if axis is top else "upper right", fontsize=7, ncol=2)
    top.set_title(f"{name} ({scene.integrator.name}, h = {scene.integrator.dt:g} s)")
    bilateral = scene.constraints.bilateral
    if not names and bilateral is not None:  # a closed chain: its closure residual
        residual = [np.max(np.abs(bilateral.residuals(row))) for row in q[:, : scene.robot.nq]]
        bottom.semilogy(t, np.maximum(residual, 1e-17), label="max |h(q)|")
        bottom.set_ylabel("closure residual [m]")
        bottom.set_xlabel("t [s]")
        bottom.legend(loc="upper left", fontsize=7)
        return _save(figure, out / f"gallery_{name}.png")
    for pair in pairs:
        rows = [i for i, label in enumerate(names) if label.split("#")[0] == pair]
        bottom.plot(t, gap[:, rows].min(axis=1), label=f"gap {pair}")
    bottom.set_ylabel("gap [m] (stops: [rad] or [m])")
    bottom.set_xlabel("t [s]")
    if gap.size:
        low, high = float(gap.min()), float(np.percentile(gap.min(axis=1), 95))
        bottom.set_ylim(min(low, 0.0) - 0.01, max(high, 0.02) + 0.01)
    right = bottom.twinx()
    right.plot(t, impulse.sum(axis=1), color="0.6", lw=0.8, label="Σ impulse")
    right.set_ylabel("normal impulse per step [N s]")
    bottom.legend(loc="upper left", fontsize=7)
    right.legend(loc="upper right", fontsize=7)
    return _save(figure, out / f"gallery_{name}.png")


def _save(figure: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path


def main(argv: list[str] | None = None) -> None:
    """Draw the gallery's figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=None, help="simulated time [s]")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    parser.add_argument("--scenes", nargs="*", default=list(SCENES), help="scene names")
    args = parser.parse_args(argv)
    for name in args.scenes:
        print(draw(name, args.out, args.duration))


if __name__ == "__main__":
    main()
