r"""Cost of the friction solve of shipped scenes, ours against Pinocchio's ADMM and PGS.

A scene's run (its own controller) records every Coulomb problem its Moreau–Jean steps hand to
the friction solver, in order. The recorded sequence is then solved again, in the same process
and in turn, by :class:`~ucontrol.solvers.ProxsuiteCoulombSolver` (one solver object: its warm
starts carry from problem to problem as in the run) and by Pinocchio 4.1's
``ADMMConstraintSolver`` and ``PGSConstraintSolver`` through
:class:`~ucontrol.solvers.PinocchioContactSolver` (warm-started the same way, PGS swept until
our residual tolerance is met), and by ours without the compiled Newton step
(``compiled_newton=False``: the numpy polish alone). Reported per scene and solver: the CPU
time per solve (median of ``--rounds`` interleaved rounds), the largest natural-map residual in
[m/s], the solves left above the tolerance, and for ours the solves settled without a QP.

Run: ``python experiments/bench_friction.py`` (about 2 min);
``--scenes panda_table_friction --limit 200`` for a smoke run.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.solvers import CoulombProblem, PinocchioContactSolver, ProxsuiteCoulombSolver

SCENES = ("panda_table_friction", "block_incline_spatial", "block_incline", "painleve_rod")
#: Ours (compiled Newton from the warm start where the layout has one), ours with the numpy
#: polish alone (``compiled_newton=False``), Pinocchio's two.
SOLVERS = ("ucontrol", "ucontrol numpy", "pin ADMM", "pin PGS")
TOLERANCE = 1e-8  # [m/s], natural-map residual accepted as solved


def recorded_problems(scene_name: str, duration: float | None) -> list[CoulombProblem]:
    """The Coulomb problems of a run of ``scene_name``, in the order the steps solved them."""
    problems: list[CoulombProblem] = []
    original = ProxsuiteCoulombSolver.solve_coulomb

    def recording(self: ProxsuiteCoulombSolver, problem: CoulombProblem) -> Any:
        problems.append(
            CoulombProblem(
                problem.D.copy(),
                problem.b.copy(),
                problem.mu,
                problem.tangents,
                problem.equalities,
            )
        )
        return original(self, problem)

    ProxsuiteCoulombSolver.solve_coulomb = recording  # type: ignore[method-assign]
    try:
        simulate(load_scene(scene_name), duration=duration, progress=False)
    finally:
        ProxsuiteCoulombSolver.solve_coulomb = original  # type: ignore[method-assign]
    return problems


def _solver(name: str) -> Any:
    if name.startswith("ucontrol"):
        compiled = name == "ucontrol"
        return ProxsuiteCoulombSolver(residual_tolerance=TOLERANCE, compiled_newton=compiled)
    kind = "admm" if name == "pin ADMM" else "pgs"
    return PinocchioContactSolver(kind, residual_tolerance=TOLERANCE)


def solve_all(name: str, problems: Sequence[CoulombProblem]) -> dict[str, float]:
    """Solve the sequence with a fresh solver ``name``: CPU µs per solve and the residuals."""
    solver = _solver(name)
    start = time.process_time()
    solutions = [solver.solve_coulomb(problem) for problem in problems]
    cpu = time.process_time() - start
    return {
        "us": 1e6 * cpu / max(len(problems), 1),
        "residual": max((s.residual for s in solutions), default=0.0),
        "unsolved": sum(s.status != "solved" for s in solutions),
        "qp_free": sum(s.outer_iterations == 0 for s in solutions),
    }


def main(argv: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Record each scene's problems, time the three solvers, print a markdown table.

    Returns:
        Per scene: its name, the number of solves, and each solver's last round (µs per solve,
        largest residual, unsolved count, solves without a QP).
    """
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), help="scene names")
    parser.add_argument("--duration", type=float, default=None, help="simulated time [s]")
    parser.add_argument("--limit", type=int, default=0, help="first problems kept; 0: all [-]")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds [-]")
    args = parser.parse_args(argv)
    print(
        "| scene | rows | solves | "
        + " | ".join(f"{name} [µs/solve]" for name in SOLVERS)
        + " | "
        + " | ".join(f"{name} max residual [m/s]" for name in SOLVERS)
        + f" | unsolved ({', '.join(SOLVERS)}) | ours without a QP |"
    )
    print("|:---|---:|---:|" + "---:|" * (2 * len(SOLVERS) + 2))
    results = []
    for scene_name in args.scenes:
        problems = recorded_problems(scene_name, args.duration)
        if args.limit > 0:
            problems = problems[: args.limit]
        rounds: dict[str, list[dict[str, float]]] = {name: [] for name in SOLVERS}
        for _ in range(args.rounds):
            for name in SOLVERS:
                rounds[name].append(solve_all(name, problems))
        median = {name: float(np.median([r["us"] for r in rounds[name]])) for name in SOLVERS}
        last = {name: rounds[name][-1] for name in SOLVERS}
        rows = sorted({problem.size for problem in problems})
        print(
            f"| {scene_name} | {'/'.join(map(str, rows))} | {len(problems)} | "
            + " | ".join(f"{median[name]:.1f}" for name in SOLVERS)
            + " | "
            + " | ".join(f"{last[name]['residual']:.1e}" for name in SOLVERS)
            + " | "
            + ", ".join(str(int(last[name]["unsolved"])) for name in SOLVERS)
            + f" | {int(last['ucontrol']['qp_free'])} |"
        )
        results.append({"scene": scene_name, "solves": len(problems), **last})
    return results


if __name__ == "__main__":
    main()
