"""Figures of merit of a run, as written to ``summary.json``."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.analysis.cycles import CYCLE_FIELDS, cycle_events
from ucontrol.analysis.energy_balance import work_of
from ucontrol.analysis.impacts import impact_cells, impacts_of
from ucontrol.log import SOLVED, UNSOLVED, Log

#: Energy changes below this, relative to 1 + the largest absolute energy in [J], are rounding.
ENERGY_ROUNDING = 1e-9


def summarize(
    log: Log,
    *,
    wall_time_s: float,
    cpu_time_s: float | None = None,
    theta: float = 0.5,
    impacts: NDArray[np.bool_] | None = None,
    work: NDArray[np.float64] | None = None,
) -> dict[str, Any]:
    """Summary of a run (keys documented in docs/outputs.md).

    What the caller derived from ``log`` already is passed on, not computed again (the run's
    own summary shares it with its physics checks); what it leaves out is computed here.

    Args:
        log: The run's log.
        wall_time_s: Wall-clock duration of the run in [s].
        cpu_time_s: The process's CPU time over the run in [s] (``time.process_time``: what a
            loaded machine's other work does not add), or None (not measured).
        theta: θ of the position update, used for the actuator work over a step.
        impacts: ``impact_mask(log)``, shape (N, n), or None to compute it.
        work: ``step_work(log, theta)`` in [J], shape (N - 1,), or None to compute it (read
            only when the run has impacts).

    Raises:
        ShapeError: ``impacts``, or ``work`` where it is read, does not have the shape of
            ``log``'s.
    """
    t = log.t
    steps = max(len(log) - 1, 0)
    gap = log.gap
    impacts = impacts_of(log, impacts)
    step_impacts = impacts[:steps]
    impact_rows, impact_columns = impact_cells(step_impacts)
    impact_steps = np.unique(impact_rows)
    energy_jump, worst_step = 0.0, None
    if impact_steps.size:
        k = impact_steps
        jumps = log.energy[k + 1] - log.energy[k] - work_of(log, theta, work)[k]  # [J]
        energy_jump, worst_step = float(np.max(jumps)), int(k[np.argmax(jumps)])
    summary = {
        "scene": log.metadata.get("scene", ""),
        "integrator": log.metadata.get("integrator", ""),
        "dt": log.metadata.get("dt"),
        "steps": steps,
        "final_time": float(t[-1]) if len(log) else 0.0,
        "wall_time_s": float(wall_time_s),
        "us_per_step": 1e6 * wall_time_s / steps if steps else None,
        "cpu_time_s": None if cpu_time_s is None else float(cpu_time_s),
        "constraints": log.constraint_names,
        "max_penetration": float(max(0.0, -gap.min())) if gap.size else 0.0,
        "n_impacts": int(impact_rows.size),
        "n_impacts_per_constraint": np.bincount(
            impact_columns, minlength=step_impacts.shape[1]
        ).tolist(),
        "energy_increase_at_impacts": max(0.0, energy_jump),
        "initial_energy": float(log.energy[0]) if len(log) else None,
        "final_energy": float(log.energy[-1]) if len(log) else None,
        "max_complementarity_residual": float(log.complementarity_residual.max(initial=0.0)),
        "max_solver_iterations": int(log.solver_iterations.max(initial=0)),
        **_contact_solves(log),
    }
    rounding = ENERGY_ROUNDING * (1.0 + float(np.max(np.abs(log.energy), initial=0.0)))
    if worst_step is not None and energy_jump > rounding:  # where the impacts added energy
        summary["energy_increase_time"] = float(t[worst_step])
        summary["energy_increase_constraints"] = [
            name for name, hit in zip(log.constraint_names, step_impacts[worst_step]) if hit
        ]
    if CYCLE_FIELDS <= set(log.fields):  # a phase-machine controller ran: its cycles' figures
        from ucontrol.analysis.tracking import tracking
        from ucontrol.analysis.weak_stability import weak_stability

        cycles = cycle_events(log)
        summary["weak_stability"] = weak_stability(log, cycles=cycles, impacts=impacts).to_dict()
        summary["tracking"] = tracking(log, cycles=cycles).to_dict()
    return summary


def _contact_solves(log: Log) -> dict[str, Any]:
    """Count, timing and failures of the contact solves of a run.

    A solve whose logged time is 0 was not timed apart: Moreau–Jean's compiled free step
    solves a one-row problem in closed form inside its own call, whose time is the step's
    (part of ``wall_time_s``). Those solves are counted in ``untimed_contact_solves`` and left
    out of the timing figures, which are those of the timed solves only: the mean is never
    pulled towards 0 by them, and a run whose every solve is such a closed form reports a
    total of 0 s and no mean or maximum.
    """
    solved = log.solver_status == SOLVED
    unsolved = log.solver_status == UNSOLVED
    times = log.solver_time[solved | unsolved]  # [s]
    timed = times[times > 0.0]
    return {
        "contact_solves": int(times.size),
        "untimed_contact_solves": int(times.size - timed.size),
        "n_unsolved_contact_solves": int(unsolved.sum()),
        "contact_solve_time_s": float(timed.sum()),
        "mean_contact_solve_us": 1e6 * float(timed.mean()) if timed.size else None,
        "max_contact_solve_us": 1e6 * float(timed.max()) if timed.size else None,
        "max_solver_outer_iterations": int(log.solver_outer_iterations.max(initial=0)),
    }
