"""Poincaré analysis edge cases: sticking phases, failed solves, Newton's guards, continuation.

References are closed forms (release and take-off phases, the forced response amplitude, the
fixed points of scalar maps) or scipy's own integration of the same linear equation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ucontrol.analysis.poincare import (
    FixedPoint,
    ImpactSystem,
    bifurcation_figure,
    continuation,
    fixed_point,
    flow,
    free_response_amplitude,
    impact_map_jacobian,
    impact_oscillator,
    vibrating_table_ball,
    without_impacts,
)
from ucontrol.exceptions import IntegrationError, InvalidParameterError, SolverError

OSCILLATOR = {"mass": 1.0, "stiffness": 1.0, "frequency": 1.0, "restitution": 0.8}


def test_negative_damping_is_named():
    with pytest.raises(InvalidParameterError, match=r"-0\.5") as caught:
        impact_oscillator(**OSCILLATOR, damping=-0.5, force=1.0, stop=0.5)
    assert caught.value.name == "damping" and caught.value.value == -0.5


def test_the_oscillator_rests_on_the_stop_until_the_net_force_turns_away():
    system = impact_oscillator(**OSCILLATOR, damping=0.0, force=1.0, stop=0.5, stick_velocity=1e-3)
    assert system.sticking is not None
    # a fast rebound does not stick; nor does a mass pulled away from the stop (cos 2 < 0.5)
    assert system.sticking(0.0, np.array([0.5, 0.1])) is None
    assert system.sticking(2.0, np.array([0.5, 0.0])) is None
    t_release, x = system.sticking(0.25, np.array([0.5, 0.0]))
    # F cos(ω t) = k σ at the release, the net force decreasing: ω t = acos(1/2) = π/3
    assert t_release == pytest.approx(math.pi / 3.0, rel=1e-15)
    assert x.tolist() == [0.5, 0.0]
    # a stop below -|F|/k is pushed against for ever
    forever = impact_oscillator(
        **OSCILLATOR, damping=0.0, force=1.0, stop=-2.0, stick_velocity=1e-3
    )
    with pytest.raises(IntegrationError, match="for ever"):
        forever.sticking(0.0, np.array([-2.0, 0.0]))


def test_the_ball_sticks_to_the_table_until_its_acceleration_falls_to_minus_g():
    A, w, g = 0.01, 2.0 * math.pi * 10.0, 9.81  # A ω² = 39.5 m/s² > g
    system = vibrating_table_ball(
        amplitude=A, frequency=w, restitution=0.5, gravity=g, stick_velocity=0.05
    )
    t = 0.01  # table phase ω t = 0.63 rad, sin(ω t) γ = 2.4 > 1: the table pulls away
    assert system.sticking(t, np.array([A * math.sin(w * t), 0.0])) is None
    t = 0.0
    table_velocity = A * w
    assert system.sticking(t, np.array([0.0, table_velocity + 0.1])) is None  # too fast
    t_off, x = system.sticking(t, np.array([0.0, table_velocity + 0.01]))
    # take-off when the table's acceleration -A ω² sin(ω t) reaches -g, sin increasing
    assert -A * w * w * math.sin(w * t_off) == pytest.approx(-g, rel=1e-13)
    assert math.cos(w * t_off) > 0.0 and 0.0 < t_off < 0.25 * 2.0 * math.pi / w
    assert x == pytest.approx([A * math.sin(w * t_off), A * w * math.cos(w * t_off)], rel=1e-15)


def test_no_saltation_matrix_through_a_sticking_phase():
    system = vibrating_table_ball(
        amplitude=0.01, frequency=2.0 * math.pi * 10.0, restitution=0.0, stick_velocity=10.0
    )
    with pytest.raises(SolverError, match="sticking"):
        flow(system, 0.0, np.array([1e-3, 0.0]), 0.1, variational=True)


def test_free_response_amplitude_matches_the_integrated_steady_state():
    m, c, k, F, w = 1.0, 0.5, 4.0, 1.0, 1.5
    period = 2.0 * math.pi / w
    t_end = 60.0  # the transient decays as exp(-c t / 2m) = 3e-7
    solution = solve_ivp(
        lambda t, y: [y[1], (F * math.cos(w * t) - c * y[1] - k * y[0]) / m],
        (0.0, t_end),
        [0.0, 0.0],
        method="DOP853",
        rtol=1e-11,
        atol=1e-13,
        dense_output=True,
    )
    last = solution.sol(np.linspace(t_end - period, t_end, 20001))[0]
    amplitude = free_response_amplitude(mass=m, damping=c, stiffness=k, force=F, frequency=w)
    # measured 2.6e-7 (the transient's remainder and the sampling)
    assert abs(np.max(np.abs(last)) - amplitude) < 2e-6


def _blow_up_system(gap: float = 1.0) -> ImpactSystem:
    """The flow x' = x², x(0) = 1: x = 1 / (1 - t) blows up at t = 1."""
    return ImpactSystem(
        flow=lambda t, x: x**2,
        flow_jacobian=lambda t, x: np.diag(2.0 * x),
        gap=lambda t, x: gap,
        gap_gradient=lambda t, x: (np.zeros(1), 0.0),
        reset=lambda t, x: x,
        reset_jacobian=lambda t, x: (np.eye(1), np.zeros(1)),
        period=1.0,
    )


def test_a_failed_integration_is_an_integration_error():
    with pytest.raises(IntegrationError, match="poincare") as caught:
        flow(_blow_up_system(), 0.0, np.array([1.0]), 2.0)
    assert caught.value.time == 0.0


def test_an_orbit_that_never_reaches_the_section_is_named():
    system = without_impacts(impact_oscillator(**OSCILLATOR, damping=0.1, force=1.0, stop=10.0))
    with pytest.raises(InvalidParameterError, match="no impact from t = 0") as caught:
        impact_map_jacobian(system, np.array([0.0, 0.0, 0.0]))
    assert caught.value.name == "section"


def test_a_translation_has_no_fixed_point():
    with pytest.raises(SolverError, match="singular") as caught:
        fixed_point(lambda z: z + 1.0, np.zeros(2), jacobian=lambda z: np.eye(2))
    assert caught.value.residual == pytest.approx(math.sqrt(2.0), rel=1e-15)


def test_newton_damps_its_steps_past_a_failing_map():
    """P(z) = z + z³ - 1, whose map fails beyond z = 5: the fixed point z = 1, P'(1) = 4."""

    def P(z):
        if z[0] > 5.0:
            raise IntegrationError("toy", 0.0, "outside the domain")
        return z + z**3 - 1.0

    def jacobian(z):
        return np.array([[1.0 + 3.0 * z[0] ** 2]])

    with pytest.raises(SolverError, match="no convergence in 2 iterations"):
        fixed_point(P, np.array([0.1]), jacobian=jacobian, max_iter=2)
    # the first full step goes to z = 0.1 + 0.999 / 0.03 = 33.4, where P fails
    point = fixed_point(P, np.array([0.1]), jacobian=jacobian)
    assert point.z[0] == pytest.approx(1.0, abs=1e-12)
    assert point.multipliers[0] == pytest.approx(4.0, rel=1e-10)


def _sqrt_branch(mu: float, guess: np.ndarray) -> FixedPoint:
    """The fixed point z = sqrt(1 - mu) of a family that has none beyond mu = 1."""
    if mu > 1.0:
        raise SolverError("toy newton", f"no fixed point at {mu}")
    return FixedPoint(np.array([math.sqrt(1.0 - mu)]), np.eye(1) * 0.5, np.array([0.5 + 0j]), 0, 1)


def test_continuation_halves_failing_steps_then_stops():
    branch = continuation(_sqrt_branch, np.array([0.0, 0.5, 1.5]), np.array([1.0]), max_halvings=3)
    # 1.5 fails, half-way 1.0 succeeds, then 1.25, 1.125, 1.0625 fail: three halvings
    assert branch.parameters.tolist() == [0.0, 0.5, 1.0]
    assert branch.points[:, 0] == pytest.approx(np.sqrt(1.0 - branch.parameters), abs=0)
    assert branch.stopped.startswith("no fixed point at 1.0625")
    first_fails = continuation(_sqrt_branch, np.array([2.0, 3.0]), np.array([1.0]))
    assert first_fails.parameters.size == 0 and "at 2:" in first_fails.stopped


def test_branches_are_drawn_only_with_a_coordinate():
    branch = continuation(_sqrt_branch, np.array([0.0, 0.5]), np.array([1.0]))
    diagram = (np.array([0.0, 0.5]), np.array([1.0, 0.7]))
    bare = bifurcation_figure(diagram, [branch])
    drawn = bifurcation_figure(diagram, [branch], coordinate=lambda z: float(z[0]))
    # the orbit diagram alone; with a coordinate also the branch, stable (multiplier 0.5):
    # every point on the solid line, none on the dashed one
    assert len(bare.axes[0].lines) == 1
    lines = drawn.axes[0].lines
    assert len(lines) == 3
    assert lines[1].get_xdata().tolist() == [0.0, 0.5]
    assert lines[1].get_ydata().tolist() == [1.0, math.sqrt(0.5)]
    assert np.isnan(lines[2].get_xdata()).all()
