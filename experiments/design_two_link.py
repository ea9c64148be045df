"""Design the two-link one-constraint cycle, replay it in the plant, draw the figures.

Writes the designed cycle, its report and figures to ``--out`` (default
docs/figures/design/) and prints, for each number of RK4 substeps, the solve and the
open-loop replay in the event-driven plant: the largest joint error one control interval
after each design node, the impact-time error, the error of one open-loop run from
takeoff after ``--horizon`` seconds and over the whole cycle.

    python experiments/design_two_link.py [--scheme rk8] [--substeps 4 6 8] [--intervals N]
        [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from ucontrol.design import DesignTask, design_cycle
from ucontrol.design.design_figures import save_design_figures
from ucontrol.design.open_loop_replay import replay_open_loop

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> dict[int, dict[str, float]]:
    """Run the study; returns per number of substeps the measured figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--task", type=Path, default=ROOT / "robots/two_link_one_constraint_task.toml"
    )
    parser.add_argument("--substeps", type=int, nargs="+", default=[4, 6, 8])
    parser.add_argument("--scheme", choices=["rk4", "rk8"], default=None, help="default: task's")
    parser.add_argument(
        "--intervals", type=int, default=None, help="flight and contact intervals (task's)"
    )
    parser.add_argument("--horizon", type=float, default=1.0, help="open-loop horizon in [s]")
    parser.add_argument("--out", type=Path, default=ROOT / "docs/figures/design")
    args = parser.parse_args(argv)
    base = DesignTask.from_toml(args.task)
    rows: dict[int, dict[str, float]] = {}
    print(
        "| substeps | IPOPT status | iterations | cost | landing [s] | max q defect [rad] "
        "| impact time error [s] | open-loop q error at horizon [rad] | whole cycle [rad] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for substeps in args.substeps:
        grid = dataclasses.replace(base.grid, substeps=substeps)
        if args.intervals is not None:
            grid = dataclasses.replace(
                grid, flight_intervals=args.intervals, contact_intervals=args.intervals
            )
        if args.scheme is not None:
            grid = dataclasses.replace(grid, scheme=args.scheme)
        task = dataclasses.replace(base, grid=grid)
        cycle, report = design_cycle(task)
        restarted = replay_open_loop(task, cycle, restart=True)
        run = replay_open_loop(task, cycle)
        designed = np.vstack([cycle.phases[0].q] + [p.q[1:] for p in cycle.phases[1:]])
        within = run.t <= args.horizon + 1e-12
        horizon_error = float(np.max(np.abs(run.q[within] - designed[within])))
        print(
            f"| {substeps} | {report.status} | {report.iterations} | {report.cost:.6g} | "
            f"{cycle.landing_time:.6g} | {restarted.q_error:.2e} | "
            f"{np.max(restarted.impact_time_errors, initial=0.0):.2e} | {horizon_error:.2e} | "
            f"{run.q_error:.2e} |"
        )
        rows[substeps] = {
            "q_defect": restarted.q_error,
            "horizon_error": horizon_error,
            "cycle_error": run.q_error,
            "landing_time": cycle.landing_time,
            "success": float(report.success),
        }
        if substeps == base.grid.substeps:
            args.out.mkdir(parents=True, exist_ok=True)
            save_design_figures(cycle, task.torque_limit, task.scene.robot.joint_names, args.out)
            report.save(args.out / "report.json")
    return rows


if __name__ == "__main__":
    main()
