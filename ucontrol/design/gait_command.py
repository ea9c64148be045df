"""``ucontrol design GAIT_TASK.toml --out DIR``: design a walking step, fit it, write a scene.

:func:`ucontrol.design.command.run_design` hands a task file with ``kind = "gait"`` to
:func:`run_gait_design`, which imports casadi when the command runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ucontrol.exceptions import InfeasibleDesignError
from ucontrol.output_files import check_output_dir


def run_gait_design(args: argparse.Namespace) -> int:
    """Design the step of ``args.task``; returns the exit status (0 designed, 1 infeasible).

    Writes ``gait.npz`` and ``gait.json`` (the step, the solver's figures and the residuals
    recomputed with Pinocchio), ``scene.toml`` (the HZD controller on the fitted virtual
    constraints, released at the step's start) and, unless ``--no-figures``, ``gait.png``.
    """
    from ucontrol.design.gait_task import GaitTask
    from ucontrol.design.gait_transcription import design_gait
    from ucontrol.design.hzd_fit import fit_bezier, write_hzd_scene

    task = GaitTask.from_toml(args.task)
    out = args.out if args.out is not None else Path("runs") / f"design_{Path(args.task).stem}"
    check_output_dir("--out", out)  # before the solve
    try:
        gait = design_gait(task)
    except InfeasibleDesignError as error:
        if error.best is not None:
            error.best.save(out / "best_iterate", task.friction)
        print(f"ucontrol design: {error}", file=sys.stderr)
        return 1
    gait.save(out, task.friction)
    fit = fit_bezier(gait, task.degree)
    write_hzd_scene(Path(out) / "scene.toml", task, gait, fit, name="walk_designed")
    if args.figures:
        from ucontrol.design.gait_figures import save_gait_figure

        save_gait_figure(gait, fit, Path(out) / "gait.png")
    print(
        f"designed step: {gait.status} after {gait.iterations} iterations "
        f"({gait.cpu_time:.3g} s CPU), cost {gait.cost:.6g} N² m² s/m, step length "
        f"{gait.step_length:.4g} m, step time {gait.step_time:.4g} s; Bézier fit degree "
        f"{fit.degree}, max error {fit.max_error:.2e} rad; written to {out} "
        f"(run it: ucontrol run {Path(out) / 'scene.toml'})"
    )
    return 0
