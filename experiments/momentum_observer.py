r"""Brogliato's law on the two-link tasks: the plant's impulses against a momentum observer.

The same scene (``robots/two_link_one_constraint.toml``; with ``--scenes`` also its flexible
twin ``two_link_flexible_one_constraint.toml``, oracle and default momentum observer only) is
run with ``[sensors]`` tables that differ only in where the controller's contact information
comes from: ``observer = "oracle"`` (the plant's impulses) or ``"momentum"`` (measured q and
the torque applied, see docs/observers.md), with the observer's bandwidth and the velocity
estimate varied. Figures of the first cycle, from the log:

- first impact t0, accumulation end t_f and takeoff t_d as the controller declared them [s];
- largest task-space error in the free phase and in the constrained phase [m] (the
  ``tracking`` block of ``summary.json``);
- largest relative error of the contact force the controller read on the plateau
  (6.0 s to 9.5 s) against the plant's mean force over the same period;
- with the momentum observer: the delay of its impact flag after each plant impulse above
  ``--impulse`` [N s] (in samples; "missed" if none within two), and flags with no impulse in
  the two samples before them.

Prints a Markdown table. Run: ``python experiments/momentum_observer.py``.
"""

from __future__ import annotations

import argparse
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol.analysis.cycles import cycle_events
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
#: The runs compared: (label, [sensors] table).
CASES: tuple[tuple[str, dict[str, Any]], ...] = (
    ("oracle", {}),
    ("momentum, K_o = 50/s", {"observer": "momentum"}),
    ("momentum, K_o = 20/s", {"observer": "momentum", "observer_gain": 20.0}),
    ("momentum, K_o = 200/s", {"observer": "momentum", "observer_gain": 200.0}),
    ("oracle, v from q (100 Hz)", {"velocity": "difference", "velocity_cutoff": 100.0}),
    (
        "momentum, v from q (100 Hz)",
        {"observer": "momentum", "velocity": "difference", "velocity_cutoff": 100.0},
    ),
    ("oracle, v observer (100 Hz)", {"velocity": "observer", "velocity_cutoff": 100.0}),
    (
        "momentum, v observer (100 Hz)",
        {"observer": "momentum", "velocity": "observer", "velocity_cutoff": 100.0},
    ),
)
#: The scenes and the cases run on each (the flexible law is slower: two cases).
SCENES = {
    "two_link_one_constraint": CASES,
    "two_link_flexible_one_constraint": CASES[:2],
}
#: The plateau of the desired force in the first cycle [s].
PLATEAU = (6.0, 9.5)


def _scene(name: str, sensors: dict[str, Any]) -> Scene:
    table = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
    table.pop("reference", None)
    table["sensors"] = sensors
    return Scene.from_dict(table, base_dir=ROBOTS)


def _row(scene: str, label: str, sensors: dict[str, Any], duration: float, impulse: float) -> str:
    result = simulate(_scene(scene, sensors), duration=duration)
    log, dt = result.log, result.log.metadata["dt"]
    cycle = cycle_events(log)[0]
    tracking = result.summary["tracking"]["cycles"][0]
    rows = np.flatnonzero((log.t > PLATEAU[0]) & (log.t < PLATEAU[1]))
    if rows.size:
        seen, plant = log.contact_force[rows, 0], log.impulse[rows - 1, 0] / dt
        force = f"{np.abs(seen - plant).max() / plant.max():.2%}"
    else:
        force = "-"
    detection = "-"
    if "impact_detected" in log.fields:
        impacts = np.flatnonzero(log.impulse.sum(axis=1) > 0.0)
        flags = np.flatnonzero(log.impact_detected)
        delays = []
        for k in np.flatnonzero(log.impulse[:, 0] > impulse):
            after = flags[(flags > k) & (flags <= k + 2)]
            delays.append(str(int(after[0] - k)) if after.size else "missed")
        false = sum(not np.any((f - impacts >= 1) & (f - impacts <= 2)) for f in flags)
        detection = f"{' '.join(delays)}; {false} false"
    times = (cycle.first_impact[0], cycle.accumulation_end[0], cycle.takeoff[0])  # [s]
    errors = (tracking.get("free_error_max"), tracking.get("constrained_error_max"))  # [m]
    cells = [f"{t:.3f}" for t in times] + ["-" if e is None else f"{e:.3g}" for e in errors]
    return f"| {scene} | {label} | {' | '.join(cells)} | {force} | {detection} |"


def main(argv: Sequence[str] | None = None) -> list[str]:
    """Run every case and print the table; returns its rows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=11.0, help="run length [s]")
    parser.add_argument(
        "--impulse", type=float, default=0.03, help="smallest plant impulse checked [N s]"
    )
    parser.add_argument(
        "--scenes", nargs="+", choices=sorted(SCENES), default=list(SCENES), help="scenes run"
    )
    args = parser.parse_args(argv)
    print(
        "| scene | run | t0 [s] | t_f [s] | t_d [s] | free error [m] | constrained error [m] "
        "| force error (plateau) | flag delay per impulse [samples]; false flags |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    rows = [
        _row(scene, label, sensors, args.duration, args.impulse)
        for scene in args.scenes
        for label, sensors in SCENES[scene]
    ]
    for row in rows:
        print(row)
    return rows


if __name__ == "__main__":
    main()
