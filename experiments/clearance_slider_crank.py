r"""The slider-crank with a clearance joint: slider acceleration spikes and convergence as c → 0.

``robots/slider_crank_clearance.toml`` (the crank–rod joint with radial clearance c, journal
radius 10 mm, e = 0.5, μ = 0.1 in the bearing) runs beside ``robots/slider_crank.toml`` (the
ideal joint) for ``--duration`` seconds at step ``--dt``. Three panels:

1. the slider's acceleration :math:`\ddot x_s` (central differences of its logged velocity)
   with the ideal joint and with c = 0.5 mm: every impact of the journal on its bearing is a
   spike;
2. the journal's centre inside the bearing, :math:`(x, y)` against the circle of radius c;
3. the largest error of the crank angle against the ideal joint's, for a frictionless bearing,
   against c (log-log): it falls at least linearly.

Writes ``clearance_slider_crank.png`` and ``clearance_slider_crank.md`` (the convergence
table) into ``--out`` (default docs/figures) and prints the table.
Run: ``python experiments/clearance_slider_crank.py`` (about 30 s).
"""

from __future__ import annotations

import argparse
import copy
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol.log import Log
from ucontrol.scene.scene import Scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = ROOT / "robots"
DOCS_FIGURES = ROOT / "docs" / "figures"
#: The clearances of the convergence study, in [m].
CLEARANCES = (1e-3, 5e-4, 2.5e-4, 1.25e-4)
#: Coordinates of the ideal mechanism inside the played one (crank, rod, slider x, y).
IDEAL_COORDINATES = [0, 3, 4, 5]


def scene(clearance: float | None, friction: float | None = None) -> Scene:
    """The clearance scene with another c and bearing μ, or (None) the ideal slider-crank."""
    with (ROBOTS / "slider_crank_clearance.toml").open("rb") as file:
        table: dict[str, Any] = copy.deepcopy(tomllib.load(file))
    if clearance is None:
        table.pop("clearance")
    else:
        table["clearance"][0]["clearance"] = clearance
        if friction is not None:
            table["clearance"][0]["friction"] = friction
    return Scene.from_dict(table, base_dir=ROBOTS)


def run(clearance: float | None, dt: float, duration: float, friction: float | None) -> Log:
    """The log of one run."""
    return simulate(scene(clearance, friction), duration=duration, dt=dt, progress=False).log


def convergence(dt: float, duration: float) -> list[tuple[float, float, int]]:
    """(c [m], largest crank-angle error [rad], impacts) of frictionless bearings."""
    ideal = np.asarray(run(None, dt, duration, None).q)
    rows = []
    for clearance in CLEARANCES:
        log = run(clearance, dt, duration, 0.0)
        error = np.max(np.abs(np.asarray(log.q)[:, 0] - ideal[:, 0]))
        rows.append((clearance, float(error), len(log.impacts)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dt", type=float, default=1e-4, help="step [s]")
    parser.add_argument("--duration", type=float, default=0.3, help="run length [s]")
    parser.add_argument("--out", type=Path, default=DOCS_FIGURES)
    args = parser.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ideal, played = run(None, args.dt, args.duration, None), run(5e-4, args.dt, args.duration, None)
    rows = convergence(args.dt, args.duration)
    errors = np.array([error for _, error, _ in rows])
    order = np.polyfit(np.log(CLEARANCES), np.log(errors), 1)[0]
    lines = [
        f"Frictionless bearing, e = 0.5, h = {args.dt:g} s, {args.duration:g} s "
        f"(fitted order {order:.2f} in c):",
        "",
        "| clearance c [m] | largest crank-angle error [rad] | impacts in the bearing |",
        "|---|---|---|",
        *(f"| {c:.3g} | {e:.3e} | {n} |" for c, e, n in rows),
    ]
    print("\n".join(lines))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "clearance_slider_crank.md").write_text("\n".join(lines) + "\n")

    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for log, label, q_index in ((ideal, "ideal joint", 2), (played, "c = 0.5 mm", 4)):
        t, v = np.asarray(log.t), np.asarray(log.v)[:, q_index]
        axes[0].plot(t[1:-1], (v[2:] - v[:-2]) / (t[2:] - t[:-2]), label=label, lw=0.8)
    axes[0].set_xlabel("t [s]")
    axes[0].set_ylabel("slider acceleration [m/s²]")
    axes[0].legend()
    axes[0].set_title("impacts in the bearing: acceleration spikes")
    offset = np.asarray(played.q)[:, 1:3] * 1e3
    angle = np.linspace(0.0, 2.0 * np.pi, 200)
    axes[1].plot(0.5 * np.cos(angle), 0.5 * np.sin(angle), "k", lw=0.8, label="|p| = c")
    axes[1].plot(offset[:, 0], offset[:, 1], lw=0.8, label="journal centre")
    axes[1].set_aspect("equal")
    axes[1].set_xlabel("x [mm]")
    axes[1].set_ylabel("y [mm]")
    axes[1].legend(loc="upper right", fontsize=8)
    axes[1].set_title("the journal inside its bearing")
    clearances = np.array(CLEARANCES) * 1e3
    axes[2].loglog(clearances, errors, "o-", label="crank-angle error")
    axes[2].loglog(clearances, errors[0] * clearances / clearances[0], "k--", label="slope 1")
    axes[2].set_xticks(clearances, [f"{c:g}" for c in clearances])
    axes[2].minorticks_off()
    axes[2].set_xlabel("clearance c [mm]")
    axes[2].set_ylabel("largest error [rad]")
    axes[2].legend()
    axes[2].set_title("convergence to the ideal joint (μ = 0)")
    fig.tight_layout()
    fig.savefig(args.out / "clearance_slider_crank.png", dpi=110)


if __name__ == "__main__":
    main()
