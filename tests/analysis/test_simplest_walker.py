"""The simplest walker (Garcia et al. 1998): its gait against the paper and independent checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ucontrol.analysis.gait import find_gait
from ucontrol.analysis.simplest_walker import SimplestWalker
from ucontrol.exceptions import InvalidParameterError, ShapeError, StrideError

#: Garcia et al. 1998, the stable (long-period) gait at γ = 0.009: (θ*, θ̇*) just after the strike.
PAPER_GAIT = np.array([0.2003109, -0.1998325])
#: The paper's numbers have 7 decimals.
PAPER_TOLERANCE = 1e-6
#: Central differences at a relative step 1e-6 against the variational Jacobian (measured
#: 4.2e-8; the error falls as the step squared: 4.3e-6 at 1e-5, 4.3e-4 at 1e-4).
JACOBIAN_TOLERANCE = 1e-6
#: Step period by Radau with the swing foot's height as event, against DOP853 with φ - 2θ
#: (measured 1.9e-12).
PERIOD_TOLERANCE = 1e-9
#: The strike map against the plastic impact of the hip on the new leg (rounding only).
STRIKE_TOLERANCE = 1e-14


@pytest.fixture(scope="module")
def walker() -> SimplestWalker:
    return SimplestWalker(slope=0.009)


@pytest.fixture(scope="module")
def gait(walker: SimplestWalker):  # type: ignore[no-untyped-def]
    return find_gait(walker, walker.to_state, walker.from_state, np.array([0.2, -0.2]), step=1e-6)


def _foot_height(x: np.ndarray) -> float:
    """The swing foot's height above the slope in leg lengths, from the geometry."""
    theta, phi = x[0], x[1]
    return math.cos(theta) - math.cos(theta - phi)


def test_newton_finds_the_papers_stable_gait(gait) -> None:  # type: ignore[no-untyped-def]
    assert np.max(np.abs(gait.z - PAPER_GAIT)) <= PAPER_TOLERANCE
    assert gait.residual <= 1e-10 and gait.iterations <= 6
    # A complex pair inside the unit circle (the gait is stable).
    assert gait.stable
    assert gait.multipliers.shape == (2,)
    assert abs(gait.multipliers[0].imag) > 0.5 and gait.multipliers[0] == np.conj(
        gait.multipliers[1]
    )


def test_stride_jacobian_by_central_differences_matches_the_variational_equations(
    walker: SimplestWalker, gait
) -> None:  # type: ignore[no-untyped-def]
    reference = walker.stride_jacobian(gait.z)
    assert np.max(np.abs(gait.jacobian - reference)) <= JACOBIAN_TOLERANCE
    eigenvalues = np.sort_complex(np.linalg.eigvals(reference))
    assert np.max(np.abs(np.sort_complex(gait.multipliers) - eigenvalues)) <= JACOBIAN_TOLERANCE


def test_step_period_by_a_second_integrator_and_event(walker: SimplestWalker, gait) -> None:  # type: ignore[no-untyped-def]
    q, v = walker.to_state(gait.z)

    def strike(_: float, x: np.ndarray) -> float:
        # The foot's height, counted only with the swing leg ahead (φ < 0): the scuff ignored.
        return _foot_height(x) if x[1] < 0.0 else 1.0

    strike.terminal, strike.direction = True, -1.0  # type: ignore[attr-defined]
    solution = solve_ivp(
        lambda _, x: walker.rate(x),
        (0.0, 10.0),
        np.concatenate((q, v)),
        method="Radau",
        rtol=1e-11,
        atol=1e-12,
        events=strike,
    )
    assert abs(solution.t_events[0][0] - gait.period) <= PERIOD_TOLERANCE
    # The stride ends on the section: the image is the state of the image's chart.
    stride = walker.stride(q, v)
    q_chart, v_chart = walker.to_state(walker.from_state(stride.q, stride.v))
    np.testing.assert_allclose(
        np.concatenate((stride.q, stride.v)), np.concatenate((q_chart, v_chart)), atol=1e-15
    )


def test_the_gait_scuffs_at_mid_stance_and_the_scuff_is_ignored(
    walker: SimplestWalker, gait
) -> None:  # type: ignore[no-untyped-def]
    q, v = walker.to_state(gait.z)
    stride = walker.stride(q, v)
    t = np.linspace(0.0, stride.duration, 2001)
    solution = solve_ivp(
        lambda _, x: walker.rate(x),
        (0.0, stride.duration),
        np.concatenate((q, v)),
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=t,
    )
    # The last sample is the strike itself (height 0 up to rounding): left out.
    height = np.array([_foot_height(x) for x in solution.y.T[:-1]])
    below = t[:-1][height < 0.0]
    # The swing foot dips below the slope once, as the legs cross before mid-stance (measured:
    # from t = 1.8139 to 1.8952, 6.4e-5 leg lengths deep; mid-stance at 2.0508) ...
    assert below.size > 0 and np.all(np.diff(below) < 1.5 * (t[1] - t[0]))
    assert below[-1] < stride.mid_stance
    assert -1e-4 < height.min() < -1e-5
    # ... and the stride goes on to the strike with the swing foot ahead.
    assert stride.state_minus[0] < 0.0 and stride.state_minus[1] < 0.0
    assert abs(stride.state_minus[1] - 2.0 * stride.state_minus[0]) <= 1e-12


def test_the_strike_is_the_plastic_impact_of_the_hip_on_the_new_leg(walker: SimplestWalker) -> None:
    # Hip (point mass) at (-sin θ, cos θ) from the stance foot, x down the slope, y normal; its
    # velocity θ̇ (-cos θ, -sin θ). The strike's impulse acts along the new leg only (massless
    # legs, the old foot leaves): the hip keeps its velocity across the new leg. The old leg
    # (now swinging, massless foot at rest) turns so that its foot keeps no velocity across it.
    rng = np.random.default_rng(3)
    for theta, dtheta in zip(rng.uniform(-0.4, -0.05, 5), rng.uniform(-0.6, -0.1, 5), strict=True):
        x_plus = walker.heel_strike(np.array([theta, 2.0 * theta, dtheta, 0.3]))
        v_hip = dtheta * np.array([-math.cos(theta), -math.sin(theta)])
        new_leg = np.array([-math.sin(-theta), math.cos(-theta)])
        v_plus = v_hip - (v_hip @ new_leg) * new_leg
        dtheta_plus = v_plus @ np.array([-math.cos(-theta), -math.sin(-theta)])
        old_leg_rate = v_plus @ np.array([-math.cos(theta), -math.sin(theta)])
        expected = [-theta, -2.0 * theta, dtheta_plus, dtheta_plus - old_leg_rate]
        assert np.max(np.abs(x_plus - expected)) <= STRIKE_TOLERANCE


def test_a_walker_too_slow_to_pass_the_normal_falls_back(walker: SimplestWalker) -> None:
    with pytest.raises(StrideError, match="hip reached the slope"):
        walker.stride(*walker.to_state(np.array([0.2, -0.05])))


def test_a_stride_without_strike_within_the_time_allowed_is_an_error() -> None:
    walker = SimplestWalker(slope=0.009, max_duration=1.0)
    with pytest.raises(StrideError, match="no time at which"):
        walker.stride(*walker.to_state(PAPER_GAIT))


@pytest.mark.parametrize(
    ("name", "value"), [("slope", -0.1), ("slope", 1.0), ("rtol", 0.0), ("max_duration", -1.0)]
)
def test_bad_parameters_are_refused(name: str, value: float) -> None:
    with pytest.raises(InvalidParameterError, match=name):
        SimplestWalker(**{"slope": 0.009, name: value})


def test_a_chart_of_the_wrong_size_is_refused(walker: SimplestWalker) -> None:
    with pytest.raises(ShapeError, match="z"):
        walker.to_state(np.zeros(3))
