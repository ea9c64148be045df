r"""Weak-stability monitor of a cyclic task with impacts (Brogliato ch. 8).

The closed loop is weakly stable when, cycle after cycle,

1. V does not increase on the :math:`\Omega` phases (free, constrained, takeoff);
2. the increase of V over the transition :math:`I_k = [\tau_0^k, t_f^k]` is bounded by a
   function of :math:`V(\tau_0^k)` that vanishes with it;
3. :math:`V(\tau_0^{k+1}) \le V(\tau_0^k)`.

:func:`weak_stability` measures the three on a log. In discrete time, 1. holds up to the
discretisation of the zero-order hold (its violations shrink as :math:`h^2`), and 3. down to the
floor that error leaves once the cycle is periodic; with a smallest virtual depth
:math:`d_{min} > 0` the bound of 2. does not vanish with :math:`V(\tau_0)`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.analysis.cycles import CycleEvents, cycles_of, finite_or_none
from ucontrol.analysis.impacts import impact_cells, impacts_of
from ucontrol.control.phase import TRANSITION_PHASES, Phase
from ucontrol.log import Log


@dataclass(frozen=True)
class CycleStability:
    r"""The Lyapunov function over one cycle (energies in [J], times in [s]).

    Attributes:
        index: Cycle number k.
        tau0: :math:`\tau_0^k` of the first declared contact.
        complete: Every contact settled and took off in the cycle.
        V_tau0: :math:`V(\tau_0^k)`.
        V1_tau0: :math:`V_1(\tau_0^k)`, which sets the virtual depth.
        transition_rise: Sum of the increases of V from row to row over :math:`I_k`.
        impact_jumps: Sum of the jumps of V over the impact steps of :math:`I_k` (signed).
        omega_max_rise: Largest increase of V above its running minimum within one
            :math:`\Omega` phase of the cycle (0 when V never increases there).
        V_end: V at the last row of the cycle (just before :math:`\tau_0^{k+1}`).
        first_impact_velocity: Per declared contact, its normal velocity at the start of the
            step of its first impact in [m/s] (< 0; NaN without impact).
        contact_impact_jumps: Per declared contact, the sum of the jumps of V over the steps
            of its impacts before its :math:`t_f` (signed).
        accumulation_time: Per declared contact, from the start of the step of its first
            impact to the end of the step of its last impact before :math:`t_f`, in [s]
            (NaN without :math:`t_f`).
        min_constrained_force: Per declared contact, its smallest measured contact force over
            the rows of its constrained phase in [N] (NaN without one).
    """

    index: int
    tau0: float
    complete: bool
    V_tau0: float
    V1_tau0: float
    transition_rise: float
    impact_jumps: float
    omega_max_rise: float
    V_end: float
    first_impact_velocity: list[float]
    contact_impact_jumps: list[float]
    accumulation_time: list[float]
    min_constrained_force: list[float]


@dataclass(frozen=True)
class WeakStabilityReport:
    """Per-cycle measurements and the run-level verdicts.

    Attributes:
        cycles: One record per cycle.
    """

    cycles: list[CycleStability]

    @property
    def V_tau0(self) -> list[float]:
        r""":math:`V(\tau_0^k)` for every cycle, in [J]."""
        return [cycle.V_tau0 for cycle in self.cycles]

    def V_tau0_decreasing(self, floor: float = 0.0) -> bool:
        r"""Whether :math:`V(\tau_0^{k+1}) \le \max(V(\tau_0^k), \text{floor})` for every k.

        Args:
            floor: Level in [J] below which V is taken as the discretisation floor.
        """
        return all(b <= max(a, floor) for a, b in pairwise(self.V_tau0))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (written under ``weak_stability`` in ``summary.json``)."""
        return {
            "n_cycles": len(self.cycles),
            "n_complete_cycles": sum(cycle.complete for cycle in self.cycles),
            "V_tau0": self.V_tau0,
            "V_tau0_ratio": [b / a if a > 0.0 else None for a, b in pairwise(self.V_tau0)],
            "max_omega_rise": max((c.omega_max_rise for c in self.cycles), default=0.0),
            "cycles": [
                {key: _json(value) for key, value in vars(cycle).items()} for cycle in self.cycles
            ],
        }


def weak_stability(
    log: Log,
    *,
    cycles: list[CycleEvents] | None = None,
    impacts: NDArray[np.bool_] | None = None,
) -> WeakStabilityReport:
    """Measure the weak-stability conditions on a log of a phase-machine controller.

    Args:
        log: A run of :class:`ucontrol.control.BrogliatoController` (fields ``V``, ``V1``,
            ``phase``, ``contact_phase``, ``events``).
        cycles: ``cycle_events(log)``, or None to compute them.
        impacts: ``impact_mask(log)``, shape (N, n), or None to compute it.

    Raises:
        InvalidParameterError: ``cycles`` are those of another log.
        ShapeError: ``impacts`` does not have the shape of ``log``'s.
    """
    impacts = impacts_of(log, impacts)
    stepped = np.zeros(len(impacts), dtype=bool)  # rows whose step holds an impact
    stepped[impact_cells(impacts)[0]] = True
    return WeakStabilityReport(
        [_cycle(log, cycle, impacts, stepped) for cycle in cycles_of(log, cycles)]
    )


def _cycle(
    log: Log,
    cycle: CycleEvents,
    impacts: NDArray[np.bool_],
    stepped: NDArray[np.bool_],
) -> CycleStability:
    rows = slice(cycle.start, cycle.stop)
    V = log.V[rows]
    transiting = np.isin(log.phase[rows], [int(phase) for phase in TRANSITION_PHASES])
    rise = np.diff(V, append=V[-1])  # V[k+1] - V[k]: the change over the step from row k
    return CycleStability(
        index=cycle.index,
        tau0=float(log.t[cycle.start]),
        complete=cycle.complete,
        V_tau0=float(V[0]),
        V1_tau0=float(log.V1[cycle.start]),
        transition_rise=float(np.maximum(rise[transiting], 0.0).sum()),
        impact_jumps=float(rise[transiting & stepped[rows]].sum()),
        omega_max_rise=_max_rise(V, ~transiting),
        V_end=float(V[-1]),
        **_contact_measures(log, cycle, impacts),
    )


def _contact_measures(
    log: Log, cycle: CycleEvents, impacts: NDArray[np.bool_]
) -> dict[str, list[float]]:
    """First-impact velocity, jumps of V, accumulation time and constrained force per contact.

    Args:
        log: The run's log.
        cycle: The cycle measured.
        impacts: ``impact_mask(log)``, shape (N, n).
    """
    columns = [log.constraint_index(name) for name in log.metadata["controller_contacts"]]
    rows = slice(cycle.start, cycle.stop)
    velocity, jumps, accumulation, force = [], [], [], []
    last_row = len(log) - 1
    for i, column in enumerate(columns):
        t_0, t_f = cycle.first_impact[i], cycle.accumulation_end[i]
        end = t_f if math.isfinite(t_f) else math.inf  # [s]
        hits = cycle.start + np.flatnonzero(impacts[rows, column] & (log.t[rows] < end))
        velocity.append(float(log.normal_velocity[hits[0], column]) if hits.size else math.nan)
        steps = hits[hits < last_row]
        jumps.append(float((log.V[steps + 1] - log.V[steps]).sum()))
        if hits.size and math.isfinite(t_0) and math.isfinite(t_f):
            last = hits[-1]
            step = log.t[last + 1] - log.t[last] if last < last_row else 0.0  # [s]
            accumulation.append(float(log.t[last] + step - log.t[hits[0]]))
        else:
            accumulation.append(math.nan)
        held = log.contact_phase[rows, i] == int(Phase.CONSTRAINED)
        force.append(float(log.contact_force[rows, i][held].min()) if held.any() else math.nan)
    return {
        "first_impact_velocity": velocity,
        "contact_impact_jumps": jumps,
        "accumulation_time": accumulation,
        "min_constrained_force": force,
    }


def _json(value: Any) -> Any:
    """``value`` with non-finite floats as None, lists element-wise."""
    if isinstance(value, list):
        return [_json(item) for item in value]
    return finite_or_none(value) if isinstance(value, float) else value


def _max_rise(V: np.ndarray, mask: np.ndarray) -> float:
    """Largest ``V - running minimum`` over the contiguous runs of ``mask``."""
    worst = 0.0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    for begin, end in zip(edges[::2], edges[1::2], strict=True):
        segment = V[begin:end]
        worst = max(worst, float(np.max(segment - np.minimum.accumulate(segment))))
    return worst
