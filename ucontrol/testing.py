r"""Assertions on closed-loop runs, for users' own test suites (pytest or plain asserts).

Each ``assert_*`` takes a :class:`ucontrol.simulate.SimulationResult` or its
:class:`ucontrol.log.Log` and raises :class:`RunAssertionError` (an :class:`AssertionError`)
whose message names the cycle, the time and the value that failed; the measurements are those
of :mod:`ucontrol.analysis` (cycles, weak stability, tracking, energy balance)::

    from ucontrol.testing import assert_cycles_complete, assert_force_tracks

    def test_my_controller():
        result = simulate(Scene.from_toml("my_task.toml"), duration=21.0)
        assert_cycles_complete(result, min_cycles=2)
        assert_force_tracks(result, within=0.05)

:func:`campaign_cases` parametrises a test over the runs of a campaign file.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol._validation import as_int, as_non_negative
from ucontrol.analysis.cycles import CYCLE_FIELDS, cycle_events
from ucontrol.analysis.energy_balance import step_work
from ucontrol.analysis.impacts import impact_mask
from ucontrol.analysis.tracking import tracking
from ucontrol.analysis.weak_stability import weak_stability
from ucontrol.log import Log

__all__ = [
    "CampaignCase",
    "RunAssertionError",
    "assert_cycles_complete",
    "assert_force_tracks",
    "assert_lyapunov_decreases",
    "assert_no_energy_gain",
    "assert_penetration_below",
    "campaign_cases",
]


class RunAssertionError(AssertionError):
    """A closed-loop run misses a property.

    Attributes:
        check: The assertion, e.g. ``"assert_force_tracks"``.
        cycle: The cycle index k where it failed, or None.
        time: The time in [s] where it failed, or None.
        value: The offending value.
    """

    def __init__(
        self, check: str, message: str, *, cycle: int | None, time: float | None, value: Any
    ) -> None:
        self.check = check
        self.cycle = cycle
        self.time = time
        self.value = value
        super().__init__(f"{check}: {message}")


def assert_cycles_complete(run: Any, *, min_cycles: int = 1) -> None:
    r"""Every cycle settles (:math:`t_f`) and takes off (:math:`t_d`) for each contact.

    Every cycle that started (:math:`\tau_0`) must be complete: end the run after a takeoff.

    Args:
        run: A SimulationResult or Log of a phase-machine controller.
        min_cycles: Fewest cycles the run must hold.

    Raises:
        RunAssertionError: Naming the first incomplete cycle, its :math:`\tau_0`, the contact
            and the missing event; or the number of cycles found.
        InvalidParameterError: ``min_cycles`` is not a whole number >= 0.
    """
    min_cycles = as_int("min_cycles", min_cycles, low=0)
    log = _phase_log(run, "assert_cycles_complete")
    cycles = cycle_events(log)
    if len(cycles) < min_cycles:
        raise RunAssertionError(
            "assert_cycles_complete",
            f"{len(cycles)} cycle(s) started (tau0) before t = {float(log.t[-1]):.6g} s, "
            f"expected at least {min_cycles}",
            cycle=None,
            time=float(log.t[-1]),
            value=len(cycles),
        )
    contacts = log.metadata.get("controller_contacts", [])
    for cycle in cycles:
        for i, (t_f, t_d) in enumerate(zip(cycle.accumulation_end, cycle.takeoff, strict=True)):
            missing = "t_f (end of the impacts)" if not math.isfinite(t_f) else None
            if missing is None and not math.isfinite(t_d):
                missing = "t_d (takeoff)"
            if missing is not None:
                name = contacts[i] if i < len(contacts) else str(i)
                raise RunAssertionError(
                    "assert_cycles_complete",
                    f"cycle {cycle.index} (tau0 = {cycle.tau0[i]:.6g} s), contact {name!r}: "
                    f"no {missing} before t = {float(log.t[cycle.stop - 1]):.6g} s",
                    cycle=cycle.index,
                    time=float(cycle.tau0[i]),
                    value=missing,
                )


def assert_force_tracks(run: Any, *, within: float) -> None:
    r"""The mean contact force tracks the desired force within a relative error ``within``.

    The mean is taken over the middle third of each constrained phase; the error is
    :math:`|\bar\lambda - \bar\lambda_d| / \bar\lambda_d`
    (:func:`ucontrol.analysis.tracking.tracking`); cycles without a constrained phase are
    skipped.

    Args:
        run: A SimulationResult or Log of a phase-machine controller.
        within: Largest relative error accepted (0.05: 5 %).

    Raises:
        RunAssertionError: Naming the cycle, the contact, the middle of the window in [s] and
            the error.
        InvalidParameterError: ``within`` is not a finite number >= 0.
    """
    within = as_non_negative("within", within)
    log = _phase_log(run, "assert_force_tracks")
    contacts = log.metadata.get("controller_contacts", [])
    events = cycle_events(log)
    for cycle, errors in zip(events, tracking(log).cycles, strict=True):
        for i, error in enumerate(errors.force_error_mid):
            if math.isfinite(error) and error > within:
                time = _mid_constrained_time(log, cycle.start, cycle.stop, i)
                name = contacts[i] if i < len(contacts) else str(i)
                raise RunAssertionError(
                    "assert_force_tracks",
                    f"cycle {cycle.index}, contact {name!r}: mean force off by "
                    f"{error:.3g} (relative) around t = {time:.6g} s, allowed {within:g}",
                    cycle=cycle.index,
                    time=time,
                    value=error,
                )


def assert_no_energy_gain(run: Any, *, tolerance: float = 1e-6) -> None:
    r"""No impact adds energy.

    Over each impact step :math:`E_{k+1} - E_k - W_k \le` ``tolerance``, with :math:`W_k`
    the actuators' work
    (:func:`ucontrol.analysis.energy_balance.step_work`).

    Args:
        run: A SimulationResult or Log.
        tolerance: Largest gain accepted, in [J].

    Raises:
        RunAssertionError: Naming the time of the impact, the constraint, its cycle (phase
            machines) and the gain in [J].
        InvalidParameterError: ``tolerance`` is not a finite number >= 0.
    """
    tolerance = as_non_negative("tolerance", tolerance)
    log = _log(run)
    steps = max(len(log) - 1, 0)
    impacts = impact_mask(log)[:steps]
    rows = np.flatnonzero(impacts.any(axis=1))
    if rows.size == 0:
        return
    gain = log.energy[rows + 1] - log.energy[rows] - step_work(log)[rows]  # [J]
    worst = int(np.argmax(gain))  # the first NaN, if any: a NaN gain fails
    if not gain[worst] <= tolerance:
        k = int(rows[worst])
        constraint = log.constraint_names[int(np.flatnonzero(impacts[k])[0])]
        cycle = _cycle_of(log, k)
        where = "" if cycle is None else f"cycle {cycle}, "
        raise RunAssertionError(
            "assert_no_energy_gain",
            f"{where}impact on {constraint!r} at t = {float(log.t[k]):.6g} s adds "
            f"{gain[worst]:.3g} J (allowed {tolerance:g} J)",
            cycle=cycle,
            time=float(log.t[k]),
            value=float(gain[worst]),
        )


def assert_lyapunov_decreases(
    run: Any, *, floor: float = 0.0, omega_rise: float | None = None
) -> None:
    r"""V at the start of each approach decreases from cycle to cycle (weak stability).

    :math:`V(\tau_0^{k+1}) \le \max(V(\tau_0^k), \text{floor})` for every k, and optionally
    V does not rise by more than ``omega_rise`` within an :math:`\Omega` phase.

    Args:
        run: A SimulationResult or Log of a phase-machine controller.
        floor: Level in [J] below which V is the discretisation floor.
        omega_rise: Largest rise of V in [J] accepted within a free, constrained or takeoff
            phase (it shrinks as h²); None: not checked.

    Raises:
        RunAssertionError: Naming the cycle, :math:`\tau_0^{k+1}` and both values of V.
        InvalidParameterError: ``floor`` or ``omega_rise`` is not a finite number >= 0.
    """
    floor = as_non_negative("floor", floor)
    if omega_rise is not None:
        omega_rise = as_non_negative("omega_rise", omega_rise)
    log = _phase_log(run, "assert_lyapunov_decreases")
    cycles = weak_stability(log).cycles
    for before, after in itertools.pairwise(cycles):
        if after.V_tau0 > max(before.V_tau0, floor):
            raise RunAssertionError(
                "assert_lyapunov_decreases",
                f"cycle {after.index}: V(tau0) = {after.V_tau0:.6g} J at t = {after.tau0:.6g} s "
                f"exceeds V(tau0) = {before.V_tau0:.6g} J of cycle {before.index} "
                f"(t = {before.tau0:.6g} s)",
                cycle=after.index,
                time=after.tau0,
                value=after.V_tau0,
            )
    if omega_rise is None:
        return
    for cycle in cycles:
        if cycle.omega_max_rise > omega_rise:
            raise RunAssertionError(
                "assert_lyapunov_decreases",
                f"cycle {cycle.index} (tau0 = {cycle.tau0:.6g} s): V rises by "
                f"{cycle.omega_max_rise:.3g} J within an Omega phase, allowed {omega_rise:g} J",
                cycle=cycle.index,
                time=cycle.tau0,
                value=cycle.omega_max_rise,
            )


def assert_penetration_below(run: Any, limit: float) -> None:
    """Every gap stays above ``-limit`` (penetration below ``limit``, in [m] or [rad]).

    Args:
        run: A SimulationResult or Log.
        limit: Deepest penetration accepted, >= 0, in [m] (contacts) or [rad] (stops).

    Raises:
        RunAssertionError: Naming the constraint, the time, the cycle (phase machines) and
            the deepest penetration.
        InvalidParameterError: ``limit`` is not a finite number >= 0.
    """
    limit = as_non_negative("limit", limit)
    log = _log(run)
    gap = log.gap
    if gap.size == 0:
        return
    k, j = np.unravel_index(int(np.argmin(gap)), gap.shape)  # the first NaN, if any
    depth = float(-gap[k, j])
    if not depth < limit:
        cycle = _cycle_of(log, int(k))
        where = "" if cycle is None else f"cycle {cycle}, "
        raise RunAssertionError(
            "assert_penetration_below",
            f"{where}{log.constraint_names[j]!r} penetrates {depth:.3g} at "
            f"t = {float(log.t[k]):.6g} s, limit {limit:g}",
            cycle=cycle,
            time=float(log.t[k]),
            value=depth,
        )


@dataclass(frozen=True)
class CampaignCase:
    """One run of a campaign, for a parametrised test.

    Attributes:
        run_id: The run's id in the campaign (``run-00003``).
        parameters: Dotted scene key -> value.
        campaign: The campaign it belongs to (:class:`ucontrol.campaign.Campaign`).
    """

    run_id: str
    parameters: Mapping[str, Any]
    campaign: Any

    def scene(self) -> Any:
        """The base scene with this run's parameters (and the campaign's duration and dt)."""
        from ucontrol.campaign.overrides import apply_overrides
        from ucontrol.scene import Scene

        table = apply_overrides(self.campaign.scene_table, self.parameters)
        return Scene.from_dict(
            table,
            base_dir=self.campaign.scene_base_dir(),
            default_name=self.campaign.scene_name(),
        )

    def simulate(self) -> Any:
        """Run :meth:`scene` with :func:`ucontrol.simulate.simulate` (no progress bar)."""
        from ucontrol.simulate import simulate

        return simulate(self.scene(), progress=False)


def campaign_cases(path: str | Path, *, check: bool = False) -> list[Any]:
    """The runs of a campaign file, as ``pytest.param(case, id=run_id)``.

    Use with ``@pytest.mark.parametrize("case", campaign_cases("robust.toml"))``; each case is
    a :class:`CampaignCase` (without pytest installed, the cases themselves are returned).

    Args:
        path: The campaign TOML file.
        check: Also check keys and metrics against the scene (slower, at collection).
    """
    from ucontrol.campaign.spec import load_campaign

    campaign = load_campaign(path, check=check)
    cases = [CampaignCase(run.run_id, run.parameters, campaign) for run in campaign.plan()]
    try:
        import pytest
    except ImportError:  # pragma: no cover - pytest is a dev dependency
        return list(cases)
    return [pytest.param(case, id=case.run_id) for case in cases]


def _log(run: Any) -> Log:
    log = getattr(run, "log", run)
    if not isinstance(log, Log):
        raise TypeError(f"expected a SimulationResult or a Log, got {type(run).__name__}")
    return log


def _phase_log(run: Any, check: str) -> Log:
    log = _log(run)
    missing = sorted(CYCLE_FIELDS - set(log.fields))
    if missing:
        raise RunAssertionError(
            check,
            f"the log has no {', '.join(missing)}: not a run of a phase-machine controller",
            cycle=None,
            time=None,
            value=missing,
        )
    return log


def _cycle_of(log: Log, row: int) -> int | None:
    if "events" not in log.fields:
        return None
    found = None
    for cycle in cycle_events(log):
        if cycle.start <= row:
            found = cycle.index
    return found


def _mid_constrained_time(log: Log, start: int, stop: int, contact: int) -> float:
    from ucontrol.control.phase import Phase

    held = np.flatnonzero(log.contact_phase[start:stop, contact] == Phase.CONSTRAINED)
    if held.size == 0:
        return math.nan
    t = log.t[start:stop][held]
    return float(0.5 * (t[0] + t[-1]))
