r"""Cycles of a run logged by a phase-machine controller, cut at the approach times.

Cycle k spans the rows from :math:`\tau_0^k` of the first declared contact to
:math:`\tau_0^{k+1}` (exclusive; the end of the log for the last cycle). It holds the
transition :math:`I_k`, the constrained phase, the takeoff and the free phase that leads to the
next approach. The log must hold the fields ``events`` and ``contact_phase`` of
:class:`ucontrol.control.BrogliatoController`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ucontrol.control.phase import Event
from ucontrol.exceptions import InvalidParameterError
from ucontrol.log import Log

#: Log fields a phase-machine controller writes and the cycle analyses read.
CYCLE_FIELDS = frozenset({"events", "contact_phase", "phase", "V"})


@dataclass(frozen=True)
class CycleEvents:
    r"""Rows and event times of one cycle.

    Times are NaN for events that did not happen in the cycle. Each list has one entry per
    declared contact, in the controller's order.

    Attributes:
        index: Cycle number k, from 0.
        start: Row of :math:`\tau_0^k` of the first declared contact.
        stop: Row of the next cycle's start, or the number of rows.
        tau0: Start of each approach :math:`\tau_0` in [s].
        first_impact: First impact :math:`t_0` in [s].
        accumulation_end: End of the accumulation of impacts :math:`t_f` in [s].
        takeoff: Takeoff :math:`t_d` in [s].
    """

    index: int
    start: int
    stop: int
    tau0: list[float]
    first_impact: list[float]
    accumulation_end: list[float]
    takeoff: list[float]

    @property
    def complete(self) -> bool:
        """Every contact settled on its surface (:math:`t_f`) and took off (:math:`t_d`)."""
        return all(
            math.isfinite(t_f) and math.isfinite(t_d)
            for t_f, t_d in zip(self.accumulation_end, self.takeoff, strict=True)
        )


def cycle_events(log: Log) -> list[CycleEvents]:
    """The cycles of ``log``, each with its rows and event times (see the module docstring)."""
    events = log.events  # (N, contacts) flags, zero in most rows
    rows, contacts = np.nonzero(events)  # the few flagged cells, rows ascending
    flags = events[rows, contacts]
    starts = rows[(contacts == 0) & ((flags & Event.TAU0) != 0)]
    bounds = [*starts.tolist(), len(log)]
    cycles = []
    for k in range(len(starts)):
        within = (rows >= bounds[k]) & (rows < bounds[k + 1])

        def times(flag: Event, within: NDArray[np.bool_] = within) -> list[float]:
            marked = within & ((flags & flag) != 0)
            found = [rows[marked & (contacts == i)] for i in range(events.shape[1])]
            return [float(log.t[f[0]]) if f.size else math.nan for f in found]

        cycles.append(
            CycleEvents(
                index=k,
                start=bounds[k],
                stop=bounds[k + 1],
                tau0=times(Event.TAU0),
                first_impact=times(Event.FIRST_IMPACT),
                accumulation_end=times(Event.ACCUMULATION_END),
                takeoff=times(Event.TAKEOFF),
            )
        )
    return cycles


def cycles_of(log: Log, cycles: list[CycleEvents] | None) -> list[CycleEvents]:
    """The cycles of ``log``: ``cycles`` when a caller found them already, else found.

    Args:
        log: The run's log.
        cycles: ``cycle_events(log)``, or None.

    Raises:
        InvalidParameterError: ``cycles`` are not cycle records ending at the last row of
            ``log`` (those of another log).
    """
    if cycles is None:
        return cycle_events(log)
    if not all(isinstance(cycle, CycleEvents) for cycle in cycles) or (
        cycles and cycles[-1].stop != len(log)
    ):
        raise InvalidParameterError(
            "cycles", cycles, f"cycle_events(log) of this log (the last ending at row {len(log)})"
        )
    return cycles


def finite_or_none(value: float) -> float | None:
    """``value`` for JSON: None when it is NaN or infinite."""
    return float(value) if math.isfinite(value) else None
