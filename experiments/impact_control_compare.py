r"""Impact-aware laws compared on one task each: Brogliato, reference spreading, impact-invariant.

Two tasks, each run under five controllers on the same Moreau–Jean plant:

- ``panda``: the Panda's tool centre point lands on a table at 0.3 m/s (e = 0) and slides with
  10 N (``robots/panda_landing_rs.toml``);
- ``two_link``: the planar two-link arm lands on the ground (e = 0.7) and slides with 5 N
  (``robots/two_link_one_constraint_rs.toml``, the task of
  ``robots/two_link_one_constraint.toml``).

The scene's ``[controller]`` table is reference spreading; the others are built from it on the
same path and contact phase: ``impedance`` (its impedance keys), ``impact-invariant`` (the same
with ``impact_invariant = true``), ``RS + invariant`` (reference spreading with it) and
``Brogliato`` (the phase machine with the gains of the task's Brogliato scene,
:data:`BROGLIATO`).

Figures per landing k (nominal impact :math:`t_i = s + kP`; first plant impact :math:`t_1` of
the contact in the cycle), from the log, every law measured alike:

- *velocity-error peak*: :math:`\max \|J\dot q - \dot x_r\|` over the rows of
  :math:`[t_1, t_1 + T_w]` (``ucontrol.analysis.impact_metrics.WINDOW``), :math:`\dot x_r`
  the reference velocity the law feeds back at that row (Brogliato: its target's, mapped to
  the world);
- *torque jump*: the largest :math:`\|u_{k} - u_{k-1}\|` over the same rows, in [N m];
- *force overshoot*: the largest :math:`\lambda - \lambda_d` over the rows of
  :math:`[t_1, t_1 + 0.5]` s without impact (λ = impulse / dt), in [N];
- *impacts*: the plant's impacts of the contact over the cycle.

Prints a Markdown table (peaks: max over landings; impacts: mean) and writes it into
``--out`` (``impact_control_compare.md``).

Run: ``python experiments/impact_control_compare.py --landings 2``.
"""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol.analysis.impact_metrics import (
    FORCE_WINDOW,
    Landing,
    frame_velocities,
    landing,
    landing_window,
)
from ucontrol.control.controller import ContactState, Vector
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = ROOT / "robots"
#: The tasks: label -> scene of robots/ (reference spreading).
TASKS = {"panda": "panda_landing_rs", "two_link": "two_link_one_constraint_rs"}
#: Keys of the reference-spreading table that the impedance law does not take.
SPREADING_KEYS = ("restitution", "blend_time", "interim_time", "impact_speed", "contact_gap")
#: Brogliato gains per task (those of robots/panda_table.toml and
#: robots/two_link_one_constraint.toml), with approach times that fit the cycle.
BROGLIATO: dict[str, dict[str, Any]] = {
    "panda": {
        "tangents": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        "gamma1": 50.0,
        "gamma2": 10.0,
        "force_gain": 0.5,
        "posture_gain": 2.0,
        "null_space_gain": 10.0,
        "approach_time": 0.5,
        "depth_min": 0.01,
    },
    "two_link": {
        "tangents": [[1.0, 0.0, 0.0]],
        "gamma1": 8.0,
        "gamma2": 7.0,
        "force_gain": 0.5,
    },
}
#: Laws compared, in table order.
LAWS = ("Brogliato", "impedance", "impact-invariant", "reference spreading", "RS + invariant")


class _TargetVelocity:
    """A Brogliato controller that also logs its target's velocity in the world frame."""

    def __init__(self, controller: Any) -> None:
        self.inner = controller
        self._A_T = controller.task.A.T  # world directions of the task coordinates (3, m)

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        return np.asarray(self.inner(t, q, v, contacts))

    def prepare_log(self, log: Log) -> None:
        self.inner.prepare_log(log)
        log.add_field("task_velocity_desired", (3,))

    def record(self, log: Log) -> None:
        self.inner.record(log)
        velocity = self._A_T @ self.inner.desired.target[1]  # [m/s]
        log.extra_fields(["task_velocity_desired"])[0][len(log)] = velocity


def controller_table(task: str, law: str, table: dict[str, Any]) -> dict[str, Any]:
    """The ``[controller]`` table of ``law`` on the task of the scene's table (RS)."""
    if law == "reference spreading":
        return dict(table)
    if law == "RS + invariant":
        return {**table, "impact_invariant": True}
    shared = {key: value for key, value in table.items() if key not in SPREADING_KEYS}
    if law == "impedance":
        return {**shared, "type": "impedance"}
    if law == "impact-invariant":
        return {**shared, "type": "impedance", "impact_invariant": True}
    return {
        "type": "brogliato",
        "frame": table["frame"],
        "path": table["path"],
        "contact_phases": table["contact_phases"],
        **BROGLIATO[task],
    }


def run(task: str, law: str, landings: int, dt: float | None = None) -> list[Landing]:
    """Run ``law`` on ``task`` over ``landings`` cycles; the figures of each landing."""
    name = TASKS[task]
    spec = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
    spec["controller"] = controller_table(task, law, spec["controller"])
    scene = Scene.from_dict(spec, base_dir=ROBOTS, default_name=name)
    controller = scene.build_controller()
    if law == "Brogliato":
        controller = _TargetVelocity(controller)
    phase = spec["controller"]["contact_phases"][0]
    period = float(spec["controller"]["path"]["period"])
    duration = phase["start"] + (landings - 1) * period + FORCE_WINDOW + 0.05  # [s]
    log = simulate(scene, controller, duration=duration, dt=dt, progress=False).log
    velocities = frame_velocities(log, scene.robot.model, str(spec["controller"]["frame"]))
    window = [landing_window(phase["start"], phase["end"], period, k) for k in range(landings)]
    references = log.task_velocity_desired
    return [landing(log, velocities, references, str(phase["contact"]), w) for w in window]


def table(results: dict[tuple[str, str], list[Landing]]) -> str:
    """Markdown table of the figures (max over landings; impacts: mean)."""
    lines = [
        "| task | law | velocity-error peak [m/s] | torque jump [N m] | force overshoot [N] "
        "| impacts per landing |",
        "|---|---|---|---|---|---|",
    ]
    for (task, law), landings in results.items():
        lines.append(
            f"| {task} | {law} | {max(x.velocity_error for x in landings):.3g} "
            f"| {max(x.torque_jump for x in landings):.3g} "
            f"| {max(x.force_overshoot for x in landings):.3g} "
            f"| {np.mean([x.impacts for x in landings]):.3g} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Run the comparison and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--landings", type=int, default=2, help="landings per run")
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=list(TASKS))
    parser.add_argument("--dt", type=float, default=None, help="time step [s] (scene's)")
    parser.add_argument("--out", type=Path, default=None, help="directory of the table")
    args = parser.parse_args(argv)
    results = {
        (task, law): run(task, law, args.landings, args.dt) for task in args.tasks for law in LAWS
    }
    text = table(results)
    print(text)
    for task in args.tasks:
        ratio = max(x.velocity_error for x in results[(task, "Brogliato")]) / max(
            x.velocity_error for x in results[(task, "reference spreading")]
        )
        print(f"{task}: Brogliato / reference spreading velocity-error peak = {ratio:.3g}")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "impact_control_compare.md").write_text(text + "\n")


if __name__ == "__main__":
    main()
