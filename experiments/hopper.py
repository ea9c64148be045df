r"""The hopper under Raibert's laws: apexes over many hops and the apex return map.

``robots/hopper.toml`` (Moreau–Jean, ``--dt``) and its event-driven closed loop
(:class:`~ucontrol.analysis.hop_flow.HopFlow`):

- ``hops``: ``--hops`` hops in place from the commanded apex 0.8 m: the largest relative error
  of the apexes, and the same from starts at 0.7 m and 0.95 m;
- ``gait``: :func:`~ucontrol.analysis.gait.find_gait` with ``section="apex"`` on the chart
  (z, pitch, hip, l, ẋ, pitch rate, hip rate, l̇) at the apex: the fixed point, the period
  and the multipliers;
- ``return map``: the next apex against the apex from starts at heights in [0.65, 1.0] m,
  event-driven and Moreau–Jean (the first hop of each run);
- the figure ``hopper_apex.png``: the apexes per hop, and the return map.

Run: ``python experiments/hopper.py`` (about 1 min; ``--hops 5 --starts 3`` for a smoke run);
writes ``hopper_apex.png`` and ``hopper.md`` to ``--out`` (default docs/figures/legged).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ucontrol.analysis.gait import Gait, find_gait
from ucontrol.analysis.hop_flow import HopFlow, logged_apexes
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures" / "legged"
#: The scene's commanded apex [m].
COMMAND = 0.8
#: Duration of one hop in place [s] (the gait's period is 0.688 s).
HOP = 0.69


def to_state(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The apex state (q, v) of chart coordinates (z, pitch, hip, l, ẋ, pitch', hip', l')."""
    return np.concatenate(([0.0], z[:4])), np.concatenate((z[4:5], [0.0], z[5:]))


def from_state(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The chart coordinates of an apex state (x and ż left out)."""
    return np.concatenate((q[1:], v[:1], v[2:]))


def run_apexes(scene: Scene, height: float, hops: int, dt: float) -> np.ndarray:
    """Apexes [m] of a Moreau–Jean run released at rest with the hip at ``height``."""
    q0 = np.array(scene.q0, dtype=float)
    q0[1] = height
    started = dataclasses.replace(scene, q0=q0)
    log = simulate(started, duration=HOP * (hops + 0.5), dt=dt, progress=False).log
    q, v = np.asarray(log.q), np.asarray(log.v)
    return logged_apexes(q[:, 1], v[:, 1])[0]


def gait_at_apex(flow: HopFlow, scene: Scene) -> Gait:
    """The period-one hop by Newton on the apex map."""
    z0 = from_state(np.asarray(scene.q0, dtype=float), np.zeros(5))
    return find_gait(flow, to_state, from_state, z0, section="apex")


def figure(
    sequences: dict[float, np.ndarray],
    starts: np.ndarray,
    event_driven: np.ndarray,
    time_stepped: np.ndarray,
    path: Path,
) -> None:
    """Apexes per hop (left) and the return map (right)."""
    fig = Figure(figsize=(10, 4))
    left, right = fig.subplots(1, 2)
    for start, apexes in sequences.items():
        left.plot(np.arange(apexes.size), apexes, "o-", ms=3, label=f"released at {start} m")
    left.axhspan(COMMAND * 0.99, COMMAND * 1.01, color="0.85", label="command ± 1 %")
    left.set_xlabel("hop")
    left.set_ylabel("apex of the hip [m]")
    left.legend()
    right.plot(starts, starts, color="0.6", lw=1, label="identity")
    right.plot(starts, event_driven, "-", label="event-driven (HopFlow)")
    right.plot(starts, time_stepped, "x", label="Moreau–Jean, first hop")
    right.set_xlabel("apex $h_k$ [m]")
    right.set_ylabel("next apex $h_{k+1}$ [m]")
    right.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: Sequence[str] | None = None) -> dict[str, object]:
    """Run the studies; returns the measured figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--hops", type=int, default=50, help="hops of the runs in place")
    parser.add_argument("--starts", type=int, default=8, help="starts of the return map")
    parser.add_argument("--dt", type=float, default=1e-3, help="Moreau–Jean step [s]")
    parser.add_argument("--out", type=Path, default=FIGURES, help="folder of the outputs")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    scene = load_scene("hopper")
    flow = HopFlow(scene.constraints, scene.build_controller())

    sequences = {h: run_apexes(scene, h, args.hops, args.dt) for h in (COMMAND, 0.7, 0.95)}
    errors = {h: float(np.max(np.abs(a - COMMAND)) / COMMAND) for h, a in sequences.items()}
    settled = {h: float(np.max(np.abs(a[1:] - COMMAND)) / COMMAND) for h, a in sequences.items()}
    gait = gait_at_apex(flow, scene)

    starts = np.linspace(0.65, 1.0, args.starts)
    event_driven = np.array([flow.apex(*to_state(_at(gait.z, h))).q[1] for h in starts])
    time_stepped = np.array([run_apexes(scene, h, 1, args.dt)[0] for h in starts])
    figure(sequences, starts, event_driven, time_stepped, args.out / "hopper_apex.png")

    lines = [
        f"Moreau–Jean, dt = {args.dt:g} s, {args.hops} hops:",
        *(
            f"- released at {h} m: {a.size} apexes, largest error {errors[h]:.2e} "
            f"(after the first hop {settled[h]:.2e}) of the command {COMMAND} m"
            for h, a in sequences.items()
        ),
        f"Apex gait (event-driven): z* = {np.array2string(gait.z, precision=9)}, "
        f"period {gait.period:.9f} s, residual {gait.residual:.1e}",
        "multipliers: " + ", ".join(f"{m:.6g}" for m in gait.multipliers),
        "|multipliers|: " + ", ".join(f"{abs(m):.6g}" for m in gait.multipliers),
        "return map (h_k -> h_k+1) event-driven | Moreau–Jean:",
        *(
            f"- {h:.3f} -> {e:.6f} | {s:.6f}"
            for h, e, s in zip(starts, event_driven, time_stepped, strict=True)
        ),
    ]
    text = "\n".join(lines)
    print(text)
    (args.out / "hopper.md").write_text(text + "\n")
    return {"errors": errors, "gait": gait, "event_driven": event_driven}


def _at(z: np.ndarray, height: float) -> np.ndarray:
    """The gait's apex state with the hip at ``height``."""
    changed = z.copy()
    changed[0] = height
    return changed


if __name__ == "__main__":
    main()
