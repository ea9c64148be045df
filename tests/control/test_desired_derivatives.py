"""Derivatives up to order 4 of the desired trajectory against finite differences.

The order-4 machine (the flexible-joint law) joins its pieces C⁴: checked piece by piece
against independent references and at every switch of a cycle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexible_arm import TAU0, cycle, robot, task
from scipy.integrate import quad

from ucontrol.control import Event, Phase, PhaseMachine
from ucontrol.control.trajectory_segment import (
    BlendToNominal,
    Constant,
    Parabola,
    RestCubic,
    RestHermite,
    SmoothParabola,
    _smooth_step_coefficients,
    smooth_step,
)
from ucontrol.exceptions import InvalidParameterError

#: Step of the central differences, in the unit of the argument.
H = 1e-5
#: Relative agreement of a derivative with the central difference of the one below it.
RTOL = 1e-6


def _central(f, x: float, k: int) -> float:
    """Central difference at ``x`` of the k-th entry of ``f``."""
    return (f(x + H)[k] - f(x - H)[k]) / (2 * H)


def _check_chain(f, x: float, order: int) -> None:
    """Entry k + 1 of ``f(x)`` is the derivative of entry k, for k < order."""
    values = f(x)
    assert len(values) == order + 1
    for k in range(order):
        scale = max(1.0, abs(values[k + 1]))
        assert values[k + 1] == pytest.approx(_central(f, x, k), abs=RTOL * scale)


def _nominal(t: float, order: int = 4) -> tuple[float, ...]:
    """A smooth nominal sample: 0.1 sin(ω t) and its derivatives."""
    omega = 2 * np.pi / 10.0
    return tuple(0.1 * omega**k * np.sin(omega * t + k * np.pi / 2) for k in range(order + 1))


def test_smooth_step_derivatives_up_to_order_4() -> None:
    for sigma in (0.1, 0.37, 0.5, 0.93):
        _check_chain(lambda s: smooth_step(s, 4), sigma, 4)
    # C²: the third derivative jumps at both ends (60 inside, 0 outside).
    assert smooth_step(1e-12, 4)[3] == pytest.approx(60.0)
    assert smooth_step(1.0 - 1e-12, 4)[3] == pytest.approx(60.0)
    assert smooth_step(0.0, 4) == (0.0,) * 5 and smooth_step(1.0, 4) == (1.0, 0.0, 0.0, 0.0, 0.0)
    assert smooth_step(0.3) == smooth_step(0.3, 4)[:3]


def test_smooth_step_of_continuity_4_is_the_nonic() -> None:
    # Reference: 126σ⁵ - 420σ⁶ + 540σ⁷ - 315σ⁸ + 70σ⁹; derivatives 1 to 4 vanish at both ends,
    # the fifth does not (so it is C⁴, not C⁵). The general formula gives the quintic for n = 2.
    nonic = np.polynomial.Polynomial([0, 0, 0, 0, 0, 126, -420, 540, -315, 70])
    for sigma in (0.1, 0.37, 0.5, 0.93):
        _check_chain(lambda x: smooth_step(x, 5, continuity=4), sigma, 5)
        expected = [nonic.deriv(k)(sigma) for k in range(6)]
        np.testing.assert_allclose(smooth_step(sigma, 5, continuity=4), expected, atol=1e-9)
        assert smooth_step(1.0 - sigma, 0, 4)[0] == pytest.approx(1.0 - smooth_step(sigma, 0, 4)[0])
    for end, value in ((1e-12, 0.0), (1.0 - 1e-12, 1.0)):
        sample = smooth_step(end, 5, continuity=4)
        assert sample[0] == pytest.approx(value, abs=1e-12)
        np.testing.assert_allclose(sample[1:5], 0.0, atol=1e-6)  # β⁽⁴⁾ = 15120 σ near 0
        assert abs(sample[5]) == pytest.approx(126 * 120, rel=1e-6)
    assert smooth_step(0.0, 4, 4) == (0.0,) * 5 and smooth_step(1.0, 4, 4) == (1.0,) + (0.0,) * 4
    assert _smooth_step_coefficients(2) == (0.0, 0.0, 0.0, 10.0, -15.0, 6.0)


#: A degree-9 approach from a sample with every derivative up to 4, to -1 cm at rest.
HERMITE = RestHermite(t0=2.0, start=(0.03, -0.06, 0.1, -0.2, 0.5), p1=-0.01, duration=0.8)
#: The order-4 takeoff: its acceleration rises to 1 m/s² over 0.1 s.
RAMP = SmoothParabola(t0=10.0, acceleration=1.0, ramp_time=0.1, continuity=2)


@pytest.mark.parametrize(
    ("segment", "times"),
    [
        (RestCubic(t0=2.0, p0=0.03, v0=-0.06, p1=-0.01, duration=0.8), (2.1, 2.5, 2.79, 3.0)),
        (Parabola(10.0, 1.0), (10.1, 10.5)),
        (BlendToNominal(Parabola(10.0, 1.0), 10.0, 0.4), (10.05, 10.2, 10.39, 10.5)),
        (BlendToNominal(RestCubic(1.0, 0.2, 0.1, 0.25, 0.8), 1.5, 0.8), (1.6, 1.79, 2.2)),
        (Constant(0.0), (3.0,)),
        (HERMITE, (2.1, 2.5, 2.79, 3.0)),
        (RAMP, (10.02, 10.05, 10.09, 10.2)),
        (BlendToNominal(RAMP, 10.0, 0.4, continuity=4), (10.02, 10.09, 10.2, 10.39, 10.5)),
        (BlendToNominal(HERMITE, 2.5, 0.8, continuity=4), (2.6, 2.79, 3.0, 3.29, 3.5)),
    ],
)
def test_segment_derivatives_up_to_order_4(segment, times) -> None:
    for t in times:
        _check_chain(lambda x: segment(x, _nominal(x)), t, 4)
        assert segment(t, _nominal(t))[:3] == segment(t, _nominal(t, 2))


def test_rest_hermite_solves_its_interpolation_problem() -> None:
    # Reference: the 10 x 10 linear system of the degree-9 polynomial in σ with the 5 start
    # conditions T^k p0^(k) and the 5 end conditions (p1, 0, 0, 0, 0).
    T, start, p1 = HERMITE.duration, HERMITE.start, HERMITE.p1
    rows, rhs = [], []
    for k in range(5):
        for sigma, value in ((0.0, T**k * start[k]), (1.0, p1 if k == 0 else 0.0)):
            rows.append([math.perm(i, k) * sigma ** max(i - k, 0) * (i >= k) for i in range(10)])
            rhs.append(value)
    solved = np.polynomial.Polynomial(np.linalg.solve(np.array(rows, dtype=float), rhs))
    for t in (2.0, 2.1, 2.5, 2.79):
        sigma = (t - 2.0) / T
        expected = [solved.deriv(k)(sigma) / T**k for k in range(5)]
        np.testing.assert_allclose(HERMITE(t, (0.0,) * 5), expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(HERMITE(2.0, (0.0,) * 5), start, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(HERMITE(2.8 - 1e-9, (0.0,) * 5), (p1, 0, 0, 0, 0), atol=1e-5)
    assert HERMITE(2.9, (0.0,) * 5) == (p1, 0.0, 0.0, 0.0, 0.0)
    # From a value and a velocity only, it is the rigid law's cubic.
    cubic, hermite = (
        RestCubic(2.0, 0.03, -0.06, -0.01, 0.8),
        RestHermite(2.0, (0.03, -0.06), -0.01, 0.8),
    )
    for t in (2.1, 2.5, 2.79):
        np.testing.assert_allclose(hermite(t, (0.0,) * 5), cubic(t, (0.0,) * 5), atol=1e-12)


def test_smooth_parabola_leaves_zero_at_rest_and_reaches_the_takeoff_acceleration() -> None:
    # Reference: x(τ) = ∫_0^τ (τ - s) a β(s/T_r) ds (Cauchy's repeated integral), by quadrature;
    # after the ramp, the parabola of acceleration a delayed by T_r/2.
    a, T = RAMP.acceleration, RAMP.ramp_time
    assert RAMP(10.0, (0.0,) * 5) == (0.0,) * 5
    assert RAMP(9.9, (0.0,) * 5) == (0.0,) * 5
    for tau in (0.01, 0.05, 0.1, 0.3):
        expected, _ = quad(lambda s, tau=tau: (tau - s) * a * smooth_step(s / T, 0)[0], 0, tau)
        assert RAMP(10.0 + tau, (0.0,) * 5)[0] == pytest.approx(expected, rel=1e-9)
    for tau in (0.15, 0.2, 0.5):
        _, dx, ddx, dddx, ddddx = RAMP(10.0 + tau, (0.0,) * 5)
        assert ddx == pytest.approx(a) and dddx == ddddx == 0.0
        assert dx == pytest.approx(a * (tau - T / 2))
    sample = RAMP(10.0 + 1e-12, (0.0,) * 5)  # x⁽⁴⁾ = a β⁽²⁾(σ)/T_r² = 60 a σ/T_r² near t0
    np.testing.assert_allclose(sample, 0.0, atol=1e-6)  # C⁴ at t0
    ddx = [RAMP(10.0 + tau, (0.0,) * 3)[2] for tau in np.linspace(0.0, 0.1, 51)]
    assert np.all(np.diff(ddx) >= 0.0) and ddx[-1] == pytest.approx(a)


@pytest.mark.parametrize(
    ("segment", "start", "base"),
    [
        (BlendToNominal(RAMP, 10.0, 0.4, continuity=4), 10.0, RAMP),
        (BlendToNominal(HERMITE, 2.5, 0.8, continuity=4), 2.5, HERMITE),
    ],
)
def test_order_4_blend_joins_its_base_and_the_nominal_path_to_order_4(segment, start, base) -> None:
    np.testing.assert_allclose(
        segment(start, _nominal(start)), base(start, _nominal(start)), atol=1e-15
    )
    end = start + segment.duration
    for tau in (1e-12, 0.0):  # from inside, then at the end (the nominal sample itself)
        np.testing.assert_allclose(
            segment(end - tau, _nominal(end - tau)), _nominal(end - tau), atol=1e-6
        )


def test_circle_path_derivatives_up_to_order_4() -> None:
    path = cycle().path
    for t in (0.0, 1.3, 7.7):
        for axis in range(3):
            _check_chain(lambda x: [d[axis] for d in path.derivatives(x, 4)], t, 4)
        for a, b in zip(path(t), path.derivatives(t, 2), strict=True):
            assert np.array_equal(a, b)


def test_desired_force_derivatives_up_to_order_2() -> None:
    designed = cycle()
    phase = designed.contact_phases[0]
    for t in (9.55, 9.75, 9.98):
        _check_chain(lambda x: designed.desired_force_derivatives(phase, x, 10.0, 2), t, 2)
        assert designed.desired_force_derivatives(phase, t, 10.0, 2)[0] == pytest.approx(
            designed.desired_force(phase, t, 10.0), abs=0.0
        )


def _drive(machine: PhaseMachine, t: float) -> tuple[int, tuple, tuple]:
    """One update of ``machine`` at ``t`` [s] on a scripted contact.

    The contact bounces at 4.9 and 4.95 s and is held from 5 s. Returns the events, and the
    target just before and just after the update.
    """
    closed = np.array([t >= 5.0 or round(t, 2) in (4.9, 4.95)])
    before = machine.desired(t)
    machine.update(t, closed, 1e-4, before)
    return int(machine.take_events()[0]), before.target, machine.desired(t).target


def test_order_4_machine_joins_its_pieces_to_order_4() -> None:
    # Both machines run the same cycle with the same events and desired forces. At every switch
    # (τ0, t_f, t_d) the order-4 target keeps its value and first 4 derivatives, but for the
    # gap at t_f, which steps from the virtual target -d to the surface by design; the order-2
    # target (the rigid law's C¹ pieces) keeps only the value and velocity.
    arm = robot()
    rigid, flexible = PhaseMachine(task(arm), cycle()), PhaseMachine(task(arm), cycle(), order=4)
    gap = int(flexible.coordinates[0])
    switches = []
    checked = []
    for t in np.arange(0.0, 10.5, 0.01):
        events, before, after = _drive(flexible, t)
        rigid_events, rigid_before, rigid_after = _drive(rigid, t)
        assert rigid.phases == flexible.phases and rigid_events == events
        two, four = rigid.desired(t), flexible.desired(t)
        assert np.array_equal(two.force, four.force) and len(four.force_derivatives) == 2
        if events:
            switches.append(Event(events))
            held = events & Event.ACCUMULATION_END
            if held:
                assert before[0][gap] == pytest.approx(-flexible.cycle.depth(1e-4))
                assert [x[gap] for x in after] == [0.0] * 5
            for k in range(5):
                jump = after[k] - before[k]
                if held:
                    jump[gap] = 0.0
                scale = max(1.0, float(np.max(np.abs(before[k]))))
                np.testing.assert_allclose(jump, 0.0, atol=1e-12 * scale, err_msg=f"{k}")
            assert np.allclose(rigid_after[1], rigid_before[1], atol=1e-12)
            if events & Event.TAU0:
                assert not np.allclose(rigid_after[2], rigid_before[2], atol=1e-3)
        if round(t, 2) in (2.0, TAU0 + 0.3, 7.0, 9.8, 10.05, 10.2):  # free, approach, ...
            for j in range(2):
                _check_chain(lambda x, j=j: [d[j] for d in flexible.desired(x).target], t, 4)
            _check_chain(
                lambda x: [
                    flexible.desired(x).force[0],
                    *(d[0] for d in flexible.desired(x).force_derivatives),
                ],
                t,
                2,
            )
            checked.append(flexible.phases[0])
    assert switches == [Event.TAU0, Event.FIRST_IMPACT, Event.ACCUMULATION_END, Event.TAKEOFF]
    assert checked == [
        Phase.FREE,
        Phase.APPROACH,
        Phase.CONSTRAINED,
        Phase.CONSTRAINED,
        Phase.TAKEOFF,
        Phase.TAKEOFF,
    ]


def test_order_below_2_is_refused() -> None:
    arm = robot()
    with pytest.raises(InvalidParameterError, match=r"`order` must be an integer >= 2, got 1"):
        PhaseMachine(task(arm), cycle(), order=1)
