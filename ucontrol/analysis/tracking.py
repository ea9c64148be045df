"""Tracking and force errors per cycle of a phase-machine controller."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.analysis.cycles import CycleEvents, cycles_of, finite_or_none
from ucontrol.control.phase import Phase
from ucontrol.log import Log

#: Part of each constrained phase, centred on its middle, where the force error is measured.
MID_FRACTION = 1.0 / 3.0


@dataclass(frozen=True)
class CycleTracking:
    r"""Errors over one cycle (see :class:`ucontrol.analysis.cycles.CycleEvents`).

    Attributes:
        index: Cycle number k.
        free_error_max: Largest :math:`\|X - X_d\|` in [m] over the free motion of the cycle
            (takeoff and free phases, :math:`\Omega_{2k+2}`).
        free_error_rms: Its root mean square in [m].
        constrained_error_max: Largest :math:`\|X - X_d\|` in [m] over the constrained phases.
        force_error_mid: Per contact, relative error of the mean contact force over the middle
            third of its constrained phase, :math:`|\bar\lambda - \bar\lambda_d| /
            \bar\lambda_d` (NaN without a constrained phase). The mean of impulse/dt is the
            mean force even when the contact chatters or is hit by impacts.
        accumulation_time: Per contact, :math:`t_f - t_0` in [s] (NaN if unfinished).
    """

    index: int
    free_error_max: float
    free_error_rms: float
    constrained_error_max: float
    force_error_mid: list[float]
    accumulation_time: list[float]


@dataclass(frozen=True)
class TrackingReport:
    """Per-cycle tracking errors.

    Attributes:
        initial_free_error_max: Largest task error in [m] before the first approach (the
            transient from the initial state).
        cycles: One record per cycle.
    """

    initial_free_error_max: float
    cycles: list[CycleTracking]

    @property
    def free_error_max(self) -> float:
        """Largest free-motion error in [m] after the first contact cycle started."""
        return max((cycle.free_error_max for cycle in self.cycles), default=math.nan)

    @property
    def force_error_mid_max(self) -> float:
        """Largest mid-phase relative error of the mean force over every cycle and contact."""
        errors = [e for cycle in self.cycles for e in cycle.force_error_mid if math.isfinite(e)]
        return max(errors, default=math.nan)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (written under ``tracking`` in ``summary.json``)."""
        return {
            "initial_free_error_max": finite_or_none(self.initial_free_error_max),
            "free_error_max": finite_or_none(self.free_error_max),
            "force_error_mid_max": finite_or_none(self.force_error_mid_max),
            "cycles": [
                {
                    "index": c.index,
                    "free_error_max": finite_or_none(c.free_error_max),
                    "free_error_rms": finite_or_none(c.free_error_rms),
                    "constrained_error_max": finite_or_none(c.constrained_error_max),
                    "force_error_mid": [finite_or_none(e) for e in c.force_error_mid],
                    "accumulation_time": [finite_or_none(a) for a in c.accumulation_time],
                }
                for c in self.cycles
            ],
        }


def tracking(log: Log, *, cycles: list[CycleEvents] | None = None) -> TrackingReport:
    """Tracking and force errors of a run of :class:`ucontrol.control.BrogliatoController`.

    Args:
        log: The run's log.
        cycles: ``cycle_events(log)``, or None to compute them.

    Raises:
        InvalidParameterError: ``cycles`` are those of another log.
    """
    error = _row_norms(log.task_position - log.task_desired)  # [m]
    cycles = cycles_of(log, cycles)
    first = cycles[0].start if cycles else len(log)
    return TrackingReport(
        initial_free_error_max=float(error[:first].max(initial=0.0)),
        cycles=[_cycle(log, cycle, error) for cycle in cycles],
    )


def _row_norms(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Euclidean norm of each row of ``x``, shape (N, m) -> (N,).

    The squares are summed column after column, as whole columns (numpy reduces a short second
    axis row by row). Up to m = 7 these are the floats of ``np.linalg.norm(x, axis=1)``; numpy
    sums longer rows pairwise, and may round them differently in the last bit.
    """
    squares = x * x
    total = squares[:, 0].copy()
    for column in squares.T[1:]:
        total += column
    return np.sqrt(total)


def _cycle(log: Log, cycle: CycleEvents, error: np.ndarray) -> CycleTracking:
    rows = slice(cycle.start, cycle.stop)
    phase = log.phase[rows]
    free = error[rows][(phase == Phase.FREE) | (phase == Phase.TAKEOFF)]
    constrained = error[rows][phase == Phase.CONSTRAINED]
    return CycleTracking(
        index=cycle.index,
        free_error_max=float(free.max()) if free.size else math.nan,
        free_error_rms=float(np.sqrt(np.mean(free**2))) if free.size else math.nan,
        constrained_error_max=float(constrained.max()) if constrained.size else math.nan,
        force_error_mid=[_force_error(log, rows, i) for i in range(len(cycle.tau0))],
        accumulation_time=[
            t_f - t_0 for t_0, t_f in zip(cycle.first_impact, cycle.accumulation_end, strict=True)
        ],
    )


def _force_error(log: Log, rows: slice, i: int) -> float:
    held = np.flatnonzero(log.contact_phase[rows, i] == Phase.CONSTRAINED)
    if held.size == 0:
        return math.nan
    t = log.t[rows][held]
    middle, half = 0.5 * (t[0] + t[-1]), 0.5 * MID_FRACTION * (t[-1] - t[0])
    mid = held[np.abs(t - middle) <= half]
    lambda_d = float(np.mean(log.lambda_d[rows, i][mid]))
    return abs(float(np.mean(log.contact_force[rows, i][mid])) - lambda_d) / lambda_d
