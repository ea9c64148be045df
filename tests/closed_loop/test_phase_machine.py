"""The phase machine and the trajectory segments it glues, without a plant."""

from __future__ import annotations

import numpy as np
import pytest
from brogliato_runs import scene

from ucontrol.control import Event, Phase, PhaseMachine
from ucontrol.control.trajectory_segment import (
    BlendToNominal,
    Constant,
    Parabola,
    RestCubic,
    smooth_step,
)

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

DT = 1e-3


def _derivative(segment, t: float, index: int, nominal=lambda t: (0.0, 0.0, 0.0)) -> float:
    h = 1e-6
    return (segment(t + h, nominal(t + h))[index] - segment(t - h, nominal(t - h))[index]) / (2 * h)


def test_smooth_step_joins_zero_and_one_to_second_order() -> None:
    assert smooth_step(0.0) == (0.0, 0.0, 0.0)
    assert smooth_step(1.0) == (1.0, 0.0, 0.0)
    assert smooth_step(-3.0) == (0.0, 0.0, 0.0) and smooth_step(4.0) == (1.0, 0.0, 0.0)
    assert smooth_step(0.5)[0] == pytest.approx(0.5)
    for sigma in (0.2, 0.5, 0.9):
        h = 1e-6
        beta = lambda x: smooth_step(x)[0]  # noqa: E731
        assert smooth_step(sigma)[1] == pytest.approx((beta(sigma + h) - beta(sigma - h)) / (2 * h))


def test_rest_cubic_starts_with_the_given_state_and_ends_at_rest() -> None:
    segment = RestCubic(t0=2.0, p0=0.03, v0=-0.06, p1=-0.01, duration=0.8)
    assert segment(2.0, (0, 0, 0))[:2] == pytest.approx((0.03, -0.06))
    assert segment(2.8, (0, 0, 0))[:2] == pytest.approx((-0.01, 0.0), abs=1e-12)  # C¹ join
    assert segment(5.0, (0, 0, 0)) == (-0.01, 0.0, 0.0)
    for t in (2.1, 2.4, 2.7):
        assert segment(t, (0, 0, 0))[1] == pytest.approx(_derivative(segment, t, 0), rel=1e-6)
        assert segment(t, (0, 0, 0))[2] == pytest.approx(_derivative(segment, t, 1), rel=1e-6)


def test_takeoff_leaves_the_surface_at_rest_with_a_positive_acceleration() -> None:
    def nominal(t: float) -> tuple[float, float, float]:
        omega = 2 * np.pi / 10.0
        phase = omega * t
        return 0.1 * np.sin(phase), 0.1 * omega * np.cos(phase), -0.1 * omega**2 * np.sin(phase)

    segment = BlendToNominal(Parabola(10.0, 1.0), 10.0, 0.4)
    assert segment(10.0, nominal(10.0)) == pytest.approx((0.0, 0.0, 1.0), abs=1e-12)
    assert segment(10.4, nominal(10.4)) == pytest.approx(nominal(10.4))
    for t in (10.1, 10.2, 10.3):
        assert segment(t, nominal(t))[0] > 0.0
        assert segment(t, nominal(t))[1] == pytest.approx(
            _derivative(segment, t, 0, nominal), rel=1e-6
        )
        assert segment(t, nominal(t))[2] == pytest.approx(
            _derivative(segment, t, 1, nominal), rel=1e-6
        )
    assert Constant(0.0)(3.0, (1.0, 2.0, 3.0)) == (0.0, 0.0, 0.0)


@pytest.fixture
def machine() -> PhaseMachine:
    variant = scene("two_link_one_constraint")
    controller = variant.build_controller()
    return PhaseMachine(controller.task, controller.cycle)


def _drive(machine: PhaseMachine, until: float, closed, t0: float = 0.0, V1: float = 0.0):
    """Step the machine at DT with contact closure ``closed(t)``; return the events seen."""
    seen = []
    for t in np.arange(t0, until, DT):
        now = machine.desired(t)
        machine.update(t, np.array([closed(t)]), V1, now)
        events = machine.take_events()
        if events[0]:
            seen.append((round(t, 6), Event(int(events[0]))))
    return seen


def test_machine_runs_the_phases_of_a_cycle(machine: PhaseMachine) -> None:
    bounces = [(4.70, 4.701), (4.80, 4.801), (4.85, 4.851)]

    def closed(t: float) -> bool:
        return any(a <= t < b for a, b in bounces) or t >= 4.9

    seen = _drive(machine, 10.5, closed, V1=1e-6)
    assert seen == [
        (4.2, Event.TAU0),
        (4.7, Event.FIRST_IMPACT),
        (4.91, Event.ACCUMULATION_END),  # closed from 4.9 s for rest_time = 0.01 s
        (10.0, Event.TAKEOFF),
    ]
    assert machine.phases == [Phase.FREE]
    assert machine.approach_time(0) == pytest.approx(14.2)  # the next cycle's τ0
    assert machine.takeoff_time(0) == pytest.approx(20.0)


def test_virtual_target_and_frozen_tangent_during_the_transition(machine: PhaseMachine) -> None:
    _drive(machine, 5.0, lambda t: False, V1=1e-6)  # approaching, no contact yet
    cycle = machine.cycle
    assert machine.phases == [Phase.APPROACH]
    assert machine.depth[0] == cycle.depth(1e-6) == pytest.approx(0.01)  # the floor d_min
    target = machine.desired(5.0).target
    assert target[0][0] == pytest.approx(-0.01)  # reached -d at rest: τ0 + approach_time
    assert target[1][0] == pytest.approx(0.0, abs=1e-12)
    assert target[1][1] == pytest.approx(0.0, abs=1e-12)  # the tangential coordinate is frozen
    reference = machine.desired(5.0).reference
    assert reference[0][0] == 0.0 and reference[1][0] == 0.0  # V is built on the surface
    frozen_x = target[0][1]
    _drive(machine, 7.0, lambda t: True, t0=5.0)
    assert machine.phases == [Phase.CONSTRAINED]
    desired = machine.desired(7.0)
    assert desired.target[0][0] == 0.0
    assert desired.constrained[0] and desired.force[0] == pytest.approx(5.0)
    p, _, _ = cycle.path(7.0)
    assert desired.target[0][1] == pytest.approx(p[0])  # x back on the nominal path
    assert frozen_x != pytest.approx(p[0], abs=1e-3)


def test_missed_contact_takes_off_at_t_d_anyway(machine: PhaseMachine) -> None:
    seen = _drive(machine, 10.01, lambda t: False)
    assert seen == [(4.2, Event.TAU0), (10.0, Event.TAKEOFF)]
    assert machine.phases == [Phase.TAKEOFF]
    assert machine.desired(10.0).target[1][1] == pytest.approx(
        machine.cycle.path(10.0)[1][0], abs=1e-3
    )  # the frozen x was released into the nominal path


def test_desired_force_falls_smoothly_to_zero_at_takeoff(machine: PhaseMachine) -> None:
    cycle = machine.cycle
    phase = cycle.contact_phases[0]
    assert cycle.desired_force(phase, 9.0, 10.0) == pytest.approx(5.0)
    assert cycle.desired_force(phase, 9.75, 10.0) == pytest.approx(2.5)
    assert cycle.desired_force(phase, 10.0, 10.0) == 0.0
