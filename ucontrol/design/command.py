"""``ucontrol design TASK.toml --out DIR``: design a cycle, write it, its report and figures.

:mod:`ucontrol.cli` adds the subcommand with :func:`add_design_parser`, which imports nothing
heavy; :func:`run_design` imports casadi when the command runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import InfeasibleDesignError
from ucontrol.output_files import check_output_dir

if TYPE_CHECKING:  # scipy loads with it, for this command only
    from ucontrol.design.open_loop_replay import ReplayResult


def add_design_parser(commands: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add the ``design`` subcommand to ``commands`` (the CLI's subparsers)."""
    design = commands.add_parser(
        "design", help="design a desired cycle by optimal control (casadi, IPOPT) from a task file"
    )
    design.add_argument("task", type=Path, help="task TOML file (see docs/design.md)")
    design.add_argument(
        "--out", type=Path, default=None, help="output directory (default: runs/design_<task>)"
    )
    design.add_argument(
        "--no-figures", dest="figures", action="store_false", help="skip the figures"
    )
    design.add_argument(
        "--no-replay",
        dest="replay",
        action="store_false",
        help="skip the open-loop replay of the torques in the event-driven plant",
    )
    return design


def run_design(args: argparse.Namespace) -> int:
    """Run ``ucontrol design``; returns the exit status (0 designed, 1 infeasible)."""
    # casadi loads with these, for this command only; matplotlib and scipy's integrators
    # only for the figures and the replay, when asked
    from ucontrol.design.cycle_transcription import design_cycle
    from ucontrol.design.design_task import DesignTask

    if _is_gait_task(args.task):
        from ucontrol.design.gait_command import run_gait_design

        return run_gait_design(args)
    task = DesignTask.from_toml(args.task)
    out = args.out if args.out is not None else Path("runs") / f"design_{Path(args.task).stem}"
    check_output_dir("--out", out)  # before the solve

    def progress(iteration: int, objective: float, inf_pr: float, inf_du: float) -> None:
        print(
            f"ipopt iteration {iteration:4d}: objective {objective:.6g}, "
            f"inf_pr {inf_pr:.2e}, inf_du {inf_du:.2e}",
            flush=True,
        )

    try:
        cycle, report = design_cycle(task, progress=progress)
    except InfeasibleDesignError as error:
        if error.best is not None:
            error.best.save(out / "best_iterate")
        if error.report is not None:
            error.report.save(out / "report.json")
            (out / "report.md").write_text(error.report.markdown())
        print(f"ucontrol design: {error}", file=sys.stderr)
        print(f"best iterate and report written to {out}", file=sys.stderr)
        return 1
    cycle.save(out / "cycle")
    table = report.to_dict()
    if args.replay and cycle.friction == 0.0:
        from ucontrol.design.open_loop_replay import replay_open_loop

        replay = replay_open_loop(task, cycle, restart=True)
        run = replay_open_loop(task, cycle)  # one open-loop run over the whole cycle
        table["replay"] = {
            "q_error_rad": replay.q_error,
            "v_error_rad_s": replay.v_error,
            "impact_time_errors_s": _timed(replay.impact_time_errors),
            "landing_speeds_m_s": replay.landing_speeds.tolist(),
            "cycle_q_error_rad": run.q_error,
            "cycle_impact_time_errors_s": _timed(run.impact_time_errors),
        }
    import json

    (out / "report.json").write_text(json.dumps(table, indent=2, default=float) + "\n")
    markdown = report.markdown()
    if "replay" in table:
        markdown += (
            "\n## Open-loop replay (event-driven plant, each interval from the design's state)"
            f"\n\n- max |q error|: {table['replay']['q_error_rad']:.3g} rad"
            f"\n- impact time errors: {_impact_time_errors(replay, task.zeno_velocity)}\n"
        )
    (out / "report.md").write_text(markdown)
    if args.figures:
        from ucontrol.design.design_figures import save_design_figures

        save_design_figures(cycle, task.torque_limit, task.scene.robot.joint_names, out)
    print(
        f"designed cycle: {report.status} after {report.iterations} iterations, cost "
        f"{report.cost:.6g}, period {cycle.period:.4g} s, landing at {cycle.landing_time:.4g} s; "
        f"written to {out}"
    )
    return 0


def _is_gait_task(path: Path) -> bool:
    """The task file says ``kind = "gait"`` (a walking step, :mod:`ucontrol.design.gait_task`).

    An unreadable file is not a gait task: the cycle task's reader then names the problem.
    """
    import tomllib

    try:
        return bool(tomllib.loads(Path(path).read_text()).get("kind") == "gait")
    except (OSError, tomllib.TOMLDecodeError):
        return False


def _timed(errors: NDArray[np.float64]) -> list[float | None]:
    """Impact time errors for JSON in [s]: None (null) for a soft landing, never timed."""
    return [float(error) if np.isfinite(error) else None for error in errors]


def _impact_time_errors(replay: ReplayResult, zeno_velocity: float) -> str:
    """The replay's impact time errors in words, a soft landing's said to be untimed.

    A landing slower than 100 ``zeno_velocity`` has no well-conditioned impact time
    (:func:`~ucontrol.design.open_loop_replay.replay_open_loop`), so no error is given for it.
    """
    words = [
        f"{error:.3g} s"
        if np.isfinite(error)
        else f"not timed (soft landing at {speed:.3g} m/s, below {100 * zeno_velocity:.3g} m/s)"
        for error, speed in zip(replay.impact_time_errors, replay.landing_speeds, strict=True)
    ]
    return "; ".join(words) if words else "no impact"
