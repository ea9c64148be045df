"""The takeoff rule of the phase machine (``takeoff_on_opening``), without a plant.

A constrained contact measured open leaves its constrained phase at that sample: once the
desired force falls (from t_d - T_f) the takeoff starts there, before it the contact goes back
to its transition towards the virtual target d_min and settles again for the rest time.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ucontrol.control import Event, Phase, PhaseMachine
from ucontrol.control.desired_cycle import DesiredCycle
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import load_scene

DT = 1e-3  # [s]

#: Steps (of DT) over which the contact is closed: landing at 4.7 s, kicked open at 7.0 s for
#: 3 steps, open again at 9.8 s, in the fall of λ_d (t_d = 10 s, T_f = 0.5 s).
CLOSED = [(4700, 7000), (7003, 9800)]


def _machine(**settings: object) -> PhaseMachine:
    controller = load_scene("two_link_one_constraint").build_controller()
    cycle = dataclasses.replace(controller.cycle, **settings)
    return PhaseMachine(controller.task, cycle)


def _drive(machine: PhaseMachine, stop: int) -> tuple[list[tuple[int, Event]], list[Phase]]:
    """Run the machine to step ``stop``; the events (step, flags) and the phase of each step."""
    events, phases = [], []
    for k in range(stop):
        t = k * DT
        closed = np.array([any(a <= k < b for a, b in CLOSED)])
        machine.update(t, closed, 1e-6, machine.desired(t))
        flags = int(machine.take_events()[0])
        if flags:
            events.append((k, Event(flags)))
        phases.append(machine.phases[0])
    return events, phases


def test_an_opening_takes_off_in_the_fall_and_goes_back_to_transition_before() -> None:
    machine = _machine(force_profile="state")
    assert machine.cycle.ends_on_opening  # on with the state profile
    events, phases = _drive(machine, 10_300)
    assert events == [
        (4200, Event.TAU0),
        (4700, Event.FIRST_IMPACT),
        (4710, Event.ACCUMULATION_END),  # closed for rest_time = 0.01 s
        (7013, Event.ACCUMULATION_END),  # settled again 10 steps after the re-closure
        (9800, Event.TAKEOFF),  # the opening, 0.2 s before t_d, in the fall (from 9.5 s)
    ]
    assert phases[6999] is Phase.CONSTRAINED
    assert phases[7000:7013] == [Phase.TRANSITION] * 13
    assert phases[7013] is Phase.CONSTRAINED and phases[9799] is Phase.CONSTRAINED
    assert phases[9800] is Phase.TAKEOFF and phases[10_199] is Phase.TAKEOFF
    assert phases[10_200] is Phase.FREE  # the takeoff's blend lasts takeoff_time = 0.4 s
    assert machine.approach_time(0) == pytest.approx(14.2)  # the next cycle as declared


def test_the_transition_after_an_opening_pushes_towards_d_min() -> None:
    machine = _machine(takeoff_on_opening=True)  # with the time profile too, when asked
    _drive(machine, 7001)
    desired = machine.desired(7.0)
    d_min = machine.cycle.depth_min
    assert machine.phases == [Phase.TRANSITION]
    assert machine.depth[0] == d_min
    assert desired.target[0][0] == -d_min  # [m] the gap target below the surface
    assert desired.reference[0][0] == 0.0  # V on the surface, as in any transition
    assert not desired.constrained[0] and desired.force[0] == 0.0  # no force term


def test_without_the_rule_the_contact_stays_constrained_until_t_d() -> None:
    machine = _machine()  # the time profile: the rule is off
    assert not machine.cycle.ends_on_opening
    events, phases = _drive(machine, 10_001)
    assert events[-1] == (10_000, Event.TAKEOFF)
    assert set(phases[4710:10_000]) == {Phase.CONSTRAINED}
    machine = _machine(force_profile="state", takeoff_on_opening=False)
    assert not machine.cycle.ends_on_opening


@pytest.mark.parametrize("value", ["yes", 1, 0.0])
def test_takeoff_on_opening_must_be_a_boolean(value: object) -> None:
    cycle = load_scene("two_link_one_constraint").build_controller().cycle
    with pytest.raises(InvalidParameterError, match="takeoff_on_opening"):
        DesiredCycle(path=cycle.path, contact_phases=cycle.contact_phases, takeoff_on_opening=value)
