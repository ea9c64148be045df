r"""Impact-aware laws over Monte Carlo campaigns: Brogliato, spreading, invariant, impedance.

The comparison of ``experiments/impact_control_compare.py`` (the same two tasks, the same
controller tables, the same figures of :mod:`ucontrol.analysis.impact_metrics`), run as one
campaign per task and law on Dask (:mod:`ucontrol.campaign`) over randomized plants:

- restitution of the landing contact, ``contacts.0.restitution`` ~ U[0.2, 0.9] (the laws keep
  their declared restitution);
- surface height ~ U[-5, 5] mm about the nominal one, which the controller does not know (its
  model keeps the nominal surface, ``controller.model.surfaces``);
- the controller's masses, ``controller.model.mass_scale`` ~ U[0.9, 1.1] (±10 % on every
  body of the controller's model; the plant keeps the nominal one);

and every run has noisy sensors (its own noise: ``sensors.seed`` drawn among
:data:`NOISE_SEEDS`) and the measurement-only momentum observer (:data:`SENSORS`):
joint-position noise σ = 1e-5 rad, the velocity from the measured positions (100 Hz
low-pass, re-initialised at the impacts the observer flags), and the contact
information the controller sees estimated from the measured positions and the torque sent:
gaps on the surface the controller believes in (the nominal one), contact forces by the
observer for the constraints within ``contact_gap`` = 6 mm of it (the surface's uncertainty).

Per run, from the first landing (figures of :mod:`ucontrol.analysis.impact_metrics`,
:math:`t_1` the plant's first impact of the contact): ``velocity_error_peak`` [m/s],
``torque_jump`` [N m], ``force_overshoot`` [N], ``impacts``, and for the success criterion
``contact_held`` and ``settled_error`` [m/s]. **A run succeeds** when it completes without
error, the contact is reached (at least one impact in the landing window), it is closed on
every step of :math:`[t_1 + T_s, t_1 + T_s + T_h]` (:data:`SETTLE`, :data:`HOLD`) and the
95th percentile of the velocity error over that interval is below :data:`SETTLED_ERROR`.

Prints the campaign table (medians and 90th percentiles of the figures over the runs that
landed, success with its 95 % Wilson interval) and writes it to ``OUT/impact_campaign.md``;
each campaign's runs are in ``OUT/<task>_<law>/`` (resumable: the same command skips the runs
already done).

Run: ``python experiments/impact_campaign.py --runs 200 --workers 2 --out runs/impact_campaign``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tomllib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

EXPERIMENTS = Path(__file__).resolve().parent
ROBOTS = EXPERIMENTS.parent / "robots"
#: Laws compared, in table order (those of impact_control_compare.py without RS + invariant).
LAWS = ("Brogliato", "reference spreading", "impact-invariant", "impedance")
#: Per task: scene of robots/, landing surface, index of its height coordinate.
TASKS: dict[str, tuple[str, str, int]] = {
    "panda": ("panda_landing_rs", "table", 2),
    "two_link": ("two_link_one_constraint_rs", "ground", 1),
}
#: The sensors of every run: noisy positions, velocity from them, the momentum observer.
SENSORS: dict[str, Any] = {
    "position_noise": 1e-5,  # [rad]
    "velocity": "observer",  # difference of the measured positions, re-initialised at impacts
    "velocity_cutoff": 100.0,  # [Hz]
    "observer": "momentum",
    # [m] the observer's contact candidates: within the ±5 mm the believed surface may be off
    "contact_gap": 6e-3,
}
#: Time in [s] after the first impact from which the contact must be held ...
SETTLE = 0.5
#: ... for this long, in [s] ...
HOLD = 0.2
#: ... with the velocity error below this, in [m/s].
SETTLED_ERROR = 0.05
#: Metrics collected: column -> function of this module.
METRICS = (
    "velocity_error_peak",
    "torque_jump",
    "force_overshoot",
    "impacts",
    "contact_held",
    "settled_error",
)
SUCCESS = f"impacts >= 1 and contact_held and settled_error < {SETTLED_ERROR!r}"
#: Each run draws the seed of its sensor noise among this many (a choice: the campaign check
#: builds the scene once per value).
NOISE_SEEDS = 16
#: Seed of the campaigns' draws.
SEED = 2026


def _controller_table(task: str, law: str, table: dict[str, Any]) -> dict[str, Any]:
    import sys

    if str(EXPERIMENTS) not in sys.path:
        sys.path.append(str(EXPERIMENTS))
    from impact_control_compare import controller_table

    return controller_table(task, law, table)


def scene_table(task: str, law: str) -> dict[str, Any]:
    """The base scene of ``law`` on ``task``: the task's scene, the law's controller, sensors."""
    name, surface, _ = TASKS[task]
    table = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
    controller = _controller_table(task, law, table["controller"])
    nominal = list(table["surfaces"][surface]["point"])
    controller["model"] = {"surfaces": {surface: {"point": nominal}}}
    table["controller"] = controller
    table["sensors"] = dict(SENSORS)
    phase = controller["contact_phases"][0]
    table["duration"] = float(phase["start"]) + 0.1 + SETTLE + HOLD + 0.05  # [s]
    return table


def campaign(task: str, law: str, runs: int, seed: int = SEED) -> Any:
    """The checked campaign of ``law`` on ``task`` (:class:`ucontrol.campaign.spec.Campaign`)."""
    from ucontrol.campaign.spec import check_campaign, parse_campaign

    name, surface, axis = TASKS[task]
    base = scene_table(task, law)
    height = float(base["surfaces"][surface]["point"][axis])
    spec = {
        "campaign": {
            "name": f"{task}_{_slug(law)}",
            "scene": f"../robots/{name}.toml",
            "seed": seed,
            "runs": runs,
            "metrics": list(METRICS),
            "success": SUCCESS,
            "worst": "velocity_error_peak",
        },
        "metrics": {metric: f"impact_campaign:{metric}" for metric in METRICS},
        "distributions": {
            "contacts.0.restitution": {"type": "uniform", "low": 0.2, "high": 0.9},
            f"surfaces.{surface}.point.{axis}": {
                "type": "uniform",
                "low": height - 5e-3,
                "high": height + 5e-3,
            },
            "controller.model.mass_scale": {"type": "uniform", "low": 0.9, "high": 1.1},
            "sensors.seed": {"type": "choice", "values": list(range(NOISE_SEEDS))},
        },
    }
    parsed = parse_campaign(spec, EXPERIMENTS / "impact_campaign.toml")
    parsed = dataclasses.replace(parsed, scene_table=base)
    check_campaign(parsed)
    return parsed


def _slug(law: str) -> str:
    return law.replace(" ", "_").replace("-", "_").lower()


# --- metrics (module:function, called on the workers with the run's SimulationResult) ---

_cache: dict[str, Any] = {}


def _task_of(log: Any) -> str:
    scenes = {scene: task for task, (scene, _, _) in TASKS.items()}
    return scenes[str(log.metadata["scene"])]


def _nominal(task: str) -> tuple[Any, dict[str, Any]]:
    """The task's nominal scene (kinematics) and its controller table (RS), cached."""
    if task not in _cache:
        from ucontrol.scene import Scene

        name = TASKS[task][0]
        table = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
        scene = Scene.from_dict(table, base_dir=ROBOTS, default_name=name)
        _cache[task] = (scene, table["controller"])
    return _cache[task]  # type: ignore[no-any-return]


def _directions(task: str) -> Any:
    """World directions of the Brogliato law's task coordinates on ``task``, (m, 3)."""
    key = f"{task}/A"
    if key not in _cache:
        from ucontrol.scene import Scene

        table = scene_table(task, "Brogliato")
        table.pop("sensors")
        scene = Scene.from_dict(table, base_dir=ROBOTS, default_name=TASKS[task][0])
        _cache[key] = np.array(scene.build_controller().task.A)
    return _cache[key]


def figures(result: Any) -> dict[str, Any]:
    """The figures of the first landing of a run (one evaluation per run, cached)."""
    from ucontrol.analysis import impact_metrics as im

    log = result.log
    if _cache.get("log") is log:
        return _cache["figures"]  # type: ignore[no-any-return]
    task = _task_of(log)
    scene, controller = _nominal(task)
    phase = controller["contact_phases"][0]
    period = float(controller["path"]["period"])
    contact = str(phase["contact"])
    velocities = im.frame_velocities(log, scene.robot.model, str(controller["frame"]))
    if log.metadata.get("controller") == "brogliato":
        references = im.target_velocities(log, _directions(task))
    else:
        references = np.asarray(log.task_velocity_desired)
    window = im.landing_window(float(phase["start"]), float(phase["end"]), period, 0)
    landing = im.landing(log, velocities, references, contact, window)
    hold = (landing.t_1 + SETTLE, landing.t_1 + SETTLE + HOLD)
    landed = landing.impacts > 0
    out = {
        "velocity_error_peak": landing.velocity_error,
        "torque_jump": landing.torque_jump,
        "force_overshoot": landing.force_overshoot,
        "impacts": landing.impacts,
        "contact_held": landed and im.contact_held(log, contact, hold),
        "settled_error": im.settled_error(log, velocities, references, hold)
        if landed
        else float("nan"),
    }
    _cache["log"], _cache["figures"] = log, out
    return out


def _metric(name: str, kind: type) -> Callable[[Any], Any]:
    """The campaign metric ``name``: that figure of :func:`figures`, as a ``kind``."""

    def metric(result: Any) -> Any:
        return kind(figures(result)[name])

    metric.__name__ = metric.__qualname__ = name
    metric.__doc__ = f"The run's ``{name}`` (:func:`figures`)."
    return metric


velocity_error_peak = _metric("velocity_error_peak", float)  # [m/s]
torque_jump = _metric("torque_jump", float)  # [N m]
force_overshoot = _metric("force_overshoot", float)  # [N]
impacts = _metric("impacts", int)
contact_held = _metric("contact_held", bool)
settled_error = _metric("settled_error", float)  # [m/s]


# --- the table ---

#: Columns of the table: metric, header, format.
COLUMNS = (
    ("velocity_error_peak", "velocity-error peak [m/s]", ".3g"),
    ("torque_jump", "torque jump [N m]", ".3g"),
    ("force_overshoot", "force overshoot [N]", ".3g"),
    ("impacts", "impacts per landing", ".3g"),
)


def row(task: str, law: str, frame: Any) -> str:
    """One Markdown row: medians [90th percentiles] of the figures, success and its interval."""
    from ucontrol.campaign.table import wilson_interval

    n = len(frame)
    successes = int(frame["success"].sum())
    low, high = wilson_interval(successes, n)
    landed = frame[frame["status"].eq("ok") & (frame["impacts"] > 0)]
    cells = []
    for metric, _, fmt in COLUMNS:
        values = landed[metric].astype(float).to_numpy()
        if values.size == 0:
            cells.append("–")
            continue
        median, p90 = np.percentile(values, [50, 90])
        cells.append(f"{median:{fmt}} [{p90:{fmt}}]")
    return (
        f"| {task} | {law} | {n} | {' | '.join(cells)} "
        f"| {successes}/{n} = {successes / n:.3f} | [{low:.3f}, {high:.3f}] |"
    )


def table(rows: Sequence[str]) -> str:
    """The Markdown table of the campaign rows."""
    header = " | ".join(name for _, name, _ in COLUMNS)
    return "\n".join(
        [
            f"| task | law | runs | {header} | success | 95 % Wilson interval |",
            "|---" * (7 + len(COLUMNS) - 2) + "|",
            *rows,
        ]
    )


def main(argv: Sequence[str] | None = None) -> str:
    """Run the campaigns (those not yet done in ``--out``) and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200, help="runs per task and law")
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=list(TASKS))
    parser.add_argument("--laws", nargs="+", default=list(LAWS), choices=list(LAWS))
    parser.add_argument("--workers", type=int, default=None, help="Dask workers (cores)")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--out", type=Path, default=Path("runs/impact_campaign"))
    args = parser.parse_args(argv)
    from ucontrol.campaign import load, run_campaign
    from ucontrol.exceptions import UControlError

    rows = []
    load_before = os.getloadavg()
    for task in args.tasks:
        for law in args.laws:
            directory = args.out / f"{task}_{_slug(law)}"
            try:
                checked = campaign(task, law, args.runs, args.seed)
                outcome = run_campaign(checked, directory, workers=args.workers)
            except UControlError as error:  # bad flags or output directory: one line, exit 2
                parser.error(str(error))
            if outcome.interrupted:  # Ctrl-C or SIGTERM: the same command resumes
                raise SystemExit(130 if outcome.signum is None else 128 + outcome.signum)
            rows.append(row(task, law, load(directory)))
    text = table(rows)
    load_after = os.getloadavg()
    note = (
        f"\n\n{args.runs} runs per task and law, seed {args.seed}; load average "
        f"(1, 5, 15 min) {load_before[0]:.1f}/{load_before[1]:.1f}/{load_before[2]:.1f} "
        f"before, {load_after[0]:.1f}/{load_after[1]:.1f}/{load_after[2]:.1f} after."
    )
    print(text + note)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "impact_campaign.md").write_text(text + note + "\n")
    return text


if __name__ == "__main__":
    main()
