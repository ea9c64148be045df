r"""The Cartesian impedance baseline against the Brogliato phase machine, same task, same plant.

Two tasks, each run with both controllers on the same Moreau–Jean plant:

- ``two_link_one_constraint``: the planar two-link arm lands on the ground (e = 0.7), slides
  with a desired force of 5 N and takes off, period 10 s
  (``robots/two_link_one_constraint.toml`` vs ``robots/two_link_one_constraint_impedance.toml``);
- ``panda_table``: the Panda's tool centre point lands on a table (e = 0.5), slides with 10 N,
  takes off, period 4 s (``robots/panda_table.toml`` vs ``robots/panda_table_impedance.toml``).

Figures per landing (contact phase [s, e] of cycle k, period P, approach time T_a of the
Brogliato cycle), from the log only, so that both controllers are measured alike:

- *landing window* :math:`[kP + s - T_a, kP + (s + e)/2]`: impacts (steps with a positive
  impulse while closing faster than 1e-6 m/s), the first-impact and largest impulse, the
  transition duration (last impact - first impact);
- *plateau* :math:`[kP + (s + e)/2, kP + e - T_f]` (T_f = 0.5 s, the fall of the desired
  force): relative error of the mean contact force, RMS force error, largest persistent
  contact force (impulse / dt on steps without impact), tangential error to the projected
  nominal path;
- *free window* :math:`[kP + e + 0.4, (k + 1)P + s - T_a]`: largest distance of the frame to
  the nominal path.

Prints a Markdown table (mean over cycles; peaks: max) and writes it with a figure
(``impedance_vs_brogliato.md``, ``impedance_vs_brogliato.png``) into ``--figures``.

Run: ``python experiments/impedance_vs_brogliato.py --cycles 3 --dt 1e-3``.
"""

from __future__ import annotations

import argparse
import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ucontrol.analysis.impacts import impact_mask
from ucontrol.control.desired_cycle import ContactPhase, NominalPath
from ucontrol.control.path_table import path_from_table
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.scene.impedance_table import impedance_from_table
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = ROOT / "robots"
#: The tasks compared: (label, Brogliato scene, impedance scene).
TASKS = (
    ("two-link, 1 constraint", "two_link_one_constraint", "two_link_one_constraint_impedance"),
    ("Panda, table", "panda_table", "panda_table_impedance"),
)
#: Approach time of the Brogliato cycle (its default) in [s]: the landing window opens then.
APPROACH_TIME = 0.8
#: Fall time of the desired force in [s]: the plateau window ends this long before takeoff.
FALL_TIME = 0.5
#: Takeoff blend in [s]: the free window opens this long after takeoff.
TAKEOFF_TIME = 0.4


@dataclass(frozen=True)
class Landing:
    """Figures of one landing (one cycle, one contact); see the module docstring."""

    impacts: int
    first_impulse: float  # [N s]
    peak_impulse: float  # [N s]
    transition: float  # [s]
    force_error_mean: float  # relative [-]
    force_error_rms: float  # [N]
    peak_force: float  # [N]
    sliding_error: float  # [m]
    free_error: float  # [m]


@dataclass(frozen=True)
class Run:
    """A run and what is needed to measure it."""

    task: str
    controller: str
    log: Log
    frame: str
    scene: Scene
    path: NominalPath
    phase: ContactPhase
    landings: list[Landing]


def load(name: str) -> tuple[Scene, dict]:
    """A scene of robots/ (with a zero controller) and its ``[controller]`` table.

    The controller is built apart, so that a controller type the scene format does not know yet
    (``impedance``) loads too.
    """
    table = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
    controller = table.pop("controller")
    table["controller"] = {"type": "zero"}
    return Scene.from_dict(table, base_dir=ROBOTS, default_name=name), controller


def run(task: str, name: str, cycles: int, dt: float) -> Run:
    """Run a scene for ``cycles`` periods (plus the last takeoff) and measure every landing."""
    scene, table = load(name)
    if table["type"] == "impedance":
        controller = impedance_from_table(scene, table)
    else:
        controller = Scene.from_toml(ROBOTS / f"{name}.toml").build_controller()
    path = path_from_table(table["path"])
    phase = ContactPhase(**table["contact_phases"][0])
    duration = cycles * path.period + 0.5  # [s]
    log = simulate(scene, controller, duration=duration, dt=dt, progress=False).log
    frame = str(table["frame"])
    positions = _frame_positions(log, scene, frame)
    nominal = np.array([path(float(time))[0] for time in log.t])
    landings = [
        _landing(log, scene, positions, nominal, path.period, phase, k, dt) for k in range(cycles)
    ]
    return Run(task, str(table["type"]), log, frame, scene, path, phase, landings)


def _frame_positions(log: Log, scene: Scene, frame: str) -> np.ndarray:
    """World position of ``frame`` at every row, (N, 3) in [m]."""
    model = scene.robot.model
    data = pin.Data(model)
    frame_id = model.getFrameId(frame)
    positions = np.empty((len(log), 3))
    for row, q in enumerate(log.q[:, : model.nq]):
        pin.framesForwardKinematics(model, data, q)
        positions[row] = data.oMf[frame_id].translation
    return positions


def _landing(
    log: Log,
    scene: Scene,
    positions: np.ndarray,
    nominal: np.ndarray,
    P: float,
    phase: ContactPhase,
    k: int,
    dt: float,
) -> Landing:
    """Figures of the landing of cycle ``k`` (frame and nominal positions per row, (N, 3))."""
    i = log.constraint_names.index(phase.contact)
    contact = scene.contacts[[c.name for c in scene.contacts].index(phase.contact)]
    n = contact.surface.normal
    t = log.t
    impacts = impact_mask(log)[:, i]
    middle = k * P + 0.5 * (phase.start + phase.end)
    landing = (t >= k * P + phase.start - APPROACH_TIME) & (t < middle)
    hits = np.flatnonzero(landing & impacts)
    plateau = (t >= middle) & (t <= k * P + phase.end - FALL_TIME)
    force = log.impulse[:, i] / dt  # [N]
    error = force[plateau] - log.lambda_d[plateau, 0]
    lambda_d = float(np.mean(log.lambda_d[plateau, 0]))
    gap = nominal @ n - (n @ contact.surface.point + contact.radius)
    projected = nominal - np.minimum(gap, 0.0)[:, None] * n  # on the surface where below
    tangential = positions - projected
    tangential -= (tangential @ n)[:, None] * n
    free = (t >= k * P + phase.end + TAKEOFF_TIME) & (
        t <= (k + 1) * P + phase.start - APPROACH_TIME
    )
    persistent = plateau & ~impacts
    return Landing(
        impacts=int(hits.size),
        first_impulse=float(log.impulse[hits[0], i]) if hits.size else math.nan,
        peak_impulse=float(log.impulse[hits, i].max()) if hits.size else math.nan,
        transition=float(t[hits[-1]] - t[hits[0]]) if hits.size else math.nan,
        force_error_mean=abs(float(np.mean(force[plateau])) - lambda_d) / lambda_d,
        force_error_rms=float(np.sqrt(np.mean(error**2))),
        peak_force=float(force[persistent].max(initial=0.0)),
        sliding_error=float(np.linalg.norm(tangential[plateau], axis=1).max()),
        free_error=float(np.linalg.norm(positions[free] - nominal[free], axis=1).max(initial=0.0))
        if free.any()
        else math.nan,
    )


def table(runs: Sequence[Run]) -> str:
    """Markdown table: one row per task and controller (means over cycles, peaks: max)."""
    lines = [
        "| task | controller | impacts per landing | first impulse [N s] | peak impulse [N s] | "
        "transition [s] | mean-force error [-] | RMS force error [N] | peak force [N] | "
        "sliding error [m] | free error [m] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        ls = r.landings

        def mean(name: str, landings: list[Landing] = ls) -> float:
            values = [getattr(x, name) for x in landings if math.isfinite(getattr(x, name))]
            return float(np.mean(values)) if values else math.nan

        def peak(name: str, landings: list[Landing] = ls) -> float:
            values = [getattr(x, name) for x in landings if math.isfinite(getattr(x, name))]
            return max(values) if values else math.nan

        lines.append(
            f"| {r.task} | {r.controller} | {mean('impacts'):.1f} | {mean('first_impulse'):.3f} | "
            f"{peak('peak_impulse'):.3f} | {mean('transition'):.3f} | "
            f"{mean('force_error_mean'):.2e} | {mean('force_error_rms'):.3f} | "
            f"{peak('peak_force'):.2f} | {peak('sliding_error'):.2e} | {peak('free_error'):.2e} |"
        )
    return "\n".join(lines)


def figure(runs: Sequence[Run], path: Path) -> Path:
    """Gap and contact force around the second landing of each task, both controllers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = list(dict.fromkeys(r.task for r in runs))
    fig, axes = plt.subplots(2, len(tasks), figsize=(6.0 * len(tasks), 6.0), squeeze=False)
    for column, task in enumerate(tasks):
        for r in (r for r in runs if r.task == task):
            P = r.path.period
            k = 1 if len(r.landings) > 1 else 0
            t0 = k * P + r.phase.start - APPROACH_TIME
            t1 = k * P + r.phase.end + TAKEOFF_TIME
            rows = (r.log.t >= t0) & (r.log.t <= t1)
            i = r.log.constraint_names.index(r.phase.contact)
            dt = float(np.median(np.diff(r.log.t)))
            axes[0, column].plot(r.log.t[rows], 1e3 * r.log.gap[rows, i], label=r.controller)
            force = np.clip(r.log.impulse[rows, i] / dt, 0.0, 4.0 * r.phase.force)
            axes[1, column].plot(r.log.t[rows], force, label=r.controller, lw=0.8)
        axes[0, column].set_title(task)
        axes[0, column].set_ylabel("gap [mm]")
        axes[1, column].set_ylabel("contact force impulse/dt [N] (clipped)")
        axes[1, column].set_xlabel("t [s]")
        for ax in axes[:, column]:
            ax.legend()
            ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: Sequence[str] | None = None) -> list[Run]:
    """Run both controllers on both tasks; print and write the table and the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3, help="number of cycles per run")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step in [s]")
    parser.add_argument(
        "--tasks", nargs="+", default=[name for _, name, _ in TASKS], help="scenes to compare"
    )
    parser.add_argument(
        "--figures",
        type=Path,
        default=ROOT / "docs" / "figures" / "impedance",
        help="folder of the table and figure",
    )
    parser.add_argument("--no-figures", action="store_true", help="write nothing")
    args = parser.parse_args(argv)
    runs = []
    for task, brogliato, impedance in TASKS:
        if brogliato not in args.tasks:
            continue
        for name in (brogliato, impedance):
            runs.append(run(task, name, args.cycles, args.dt))
    text = table(runs)
    print(text)
    if not args.no_figures:
        args.figures.mkdir(parents=True, exist_ok=True)
        (args.figures / "impedance_vs_brogliato.md").write_text(
            f"Command: `python experiments/impedance_vs_brogliato.py --cycles {args.cycles} "
            f"--dt {args.dt:g}`\n\n{text}\n"
        )
        print(f"wrote {figure(runs, args.figures / 'impedance_vs_brogliato.png')}")
    return runs


if __name__ == "__main__":
    main()
