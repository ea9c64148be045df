"""A per-cycle table (Markdown) of events, Lyapunov values and errors of a phase-machine run."""

from __future__ import annotations

import math
from typing import Any

from ucontrol.analysis.cycles import cycle_events
from ucontrol.analysis.tracking import tracking
from ucontrol.analysis.weak_stability import weak_stability
from ucontrol.log import Log


def cycle_table(log: Log) -> str:
    """One row per cycle and contact: τ0, t0, t_f, t_d, V(τ0), free error, mid force error."""
    contacts = log.metadata.get("controller_contacts", [])
    cycles = cycle_events(log)
    stability = weak_stability(log, cycles=cycles).cycles
    errors = tracking(log, cycles=cycles).cycles
    lines = [
        "| cycle | contact | τ0 [s] | t0 [s] | t_f [s] | t_d [s] | V(τ0) [J] | "
        "rise of V over I_k [J] | free error max [m] | mean-force error mid [-] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for cycle, stable, error in zip(cycles, stability, errors, strict=True):
        for i, name in enumerate(contacts):
            lines.append(
                f"| {cycle.index} | {name} | {_f(cycle.tau0[i], '.3f')} | "
                f"{_f(cycle.first_impact[i], '.3f')} | {_f(cycle.accumulation_end[i], '.3f')} | "
                f"{_f(cycle.takeoff[i], '.3f')} | {_f(stable.V_tau0, '.3e')} | "
                f"{_f(stable.transition_rise, '.3e')} | {_f(error.free_error_max, '.2e')} | "
                f"{_f(error.force_error_mid[i], '.2e')} |"
            )
    return "\n".join(lines)


def summary_line(summary: dict[str, Any]) -> str:
    """One line of the run-level figures of a phase-machine run's ``summary.json``."""
    stability, tracking = summary["weak_stability"], summary["tracking"]
    V_tau0 = ", ".join(f"{value:.3e}" for value in stability["V_tau0"])
    return (
        f"complete cycles: {stability['n_complete_cycles']} of {stability['n_cycles']}; "
        f"free-motion error after the first approach: {_f(tracking['free_error_max'], '.3e')} m; "
        f"mid-phase mean-force error: {_f(tracking['force_error_mid_max'], '.2e')}; "
        f"V(τ0) per cycle: {V_tau0} J"
    )


def _f(value: float | None, spec: str) -> str:
    return "–" if value is None or not math.isfinite(value) else format(value, spec)
