r"""McGeer's rimless wheel (robots/rimless_wheel.toml) against its closed forms.

References written here from angular momentum and energy (docs/legged.md), independent of the
code under test: the strike ratio :math:`\eta = (\cos 2\alpha + \rho^2)/(1 + \rho^2)`, the
steady post-strike speed :math:`\omega^{*2} = \eta^2 \beta / (1 - \eta^2)` with
:math:`\beta = 4 g \sin\alpha \sin\gamma / (l (1 + \rho^2))`, the stride map's multiplier
:math:`\eta^2`, and the step period as a quadrature of the energy integral.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import ROBOTS
from scipy.integrate import quad

from ucontrol import simulate
from ucontrol.analysis.poincare import finite_difference_jacobian
from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.exceptions import InvalidParameterError, StrideError
from ucontrol.scene import Scene

# The wheel of robots/rimless_wheel.urdf and its scene.
N_SPOKES, LENGTH, RHO, GRAVITY, SLOPE = 8, 1.0, 0.5, 9.81, 0.1  # [-], [m], [-], [m/s²], [rad]
ALPHA = math.pi / N_SPOKES
ETA = (math.cos(2 * ALPHA) + RHO**2) / (1 + RHO**2)
BETA = 4 * GRAVITY * math.sin(ALPHA) * math.sin(SLOPE) / (LENGTH * (1 + RHO**2))  # [rad²/s²]
OMEGA_STAR = math.sqrt(ETA**2 * BETA / (1 - ETA**2))  # [rad/s]

STEADY_TOLERANCE = 1e-9  # relative (measured 2e-12 after 45 strides, 7e-13 from the gait)
MULTIPLIER_TOLERANCE = 1e-6  # measured 7e-10 (central differences, step 1e-4 relative)
PERIOD_TOLERANCE = 1e-9  # [s], measured 5e-13


def _scene() -> Scene:
    return Scene.from_toml(ROBOTS / "rimless_wheel.toml")


def _post_strike_velocity(omega: float) -> np.ndarray:
    """Rotation at omega [rad/s] about spoke 0's foot from the scene's strike configuration."""
    return omega * np.array([LENGTH * math.cos(ALPHA), LENGTH * math.sin(ALPHA), 1.0])


def _step_period(omega_plus: float) -> float:
    """Time from strike to strike: the energy integral over the stance angle, by quadrature."""
    k = 2 * GRAVITY / (LENGTH * (1 + RHO**2))  # [1/s²]

    def dt_dphi(phi: float) -> float:
        return 1.0 / math.sqrt(omega_plus**2 + k * (math.cos(ALPHA - SLOPE) - math.cos(phi)))

    return quad(dt_dphi, SLOPE - ALPHA, SLOPE + ALPHA, epsabs=1e-14, epsrel=1e-13)[0]


def test_the_scene_is_the_wheel_of_the_closed_forms() -> None:
    scene = _scene()
    assert scene.robot.nu == 0
    M = scene.robot.mass_matrix(scene.q0)
    np.testing.assert_allclose(M, np.diag([1.0, 1.0, (RHO * LENGTH) ** 2]), atol=1e-15)
    np.testing.assert_allclose(scene.constraints.gaps(scene.q0)[[0, -1]], 0.0, atol=1e-15)
    # Speed threshold to pass over the top, below the gait's: the gait exists.
    assert OMEGA_STAR**2 > 2 * GRAVITY * (1 - math.cos(ALPHA - SLOPE)) / (LENGTH * (1 + RHO**2))


@pytest.mark.slow
def test_event_driven_strides_reach_the_steady_speed_of_the_closed_form() -> None:
    scene = _scene()
    flow = StanceFlow(scene.constraints)
    q, v = scene.q0, scene.v0  # 1 rad/s, 23 % below the gait's speed
    stances = []
    for _ in range(45):
        stride = flow.stride(q, v)
        q, v = stride.q, stride.v
        stances.append(stride.stance)
    assert stances[:9] == [1, 2, 3, 4, 5, 6, 7, 0, 1]  # spoke after spoke
    assert abs(v[2] - OMEGA_STAR) <= STEADY_TOLERANCE * OMEGA_STAR
    assert abs(stride.duration - _step_period(OMEGA_STAR)) <= 1e-6  # still converging
    # Rolling without slip: the hub advanced by one step length 2 l sin(alpha) per stride.
    np.testing.assert_allclose(q[0] - scene.q0[0], 45 * 2 * LENGTH * math.sin(ALPHA), rtol=1e-9)


def test_the_fixed_point_is_a_fixed_point_with_the_closed_form_period() -> None:
    scene = _scene()
    stride = StanceFlow(scene.constraints).stride(scene.q0, _post_strike_velocity(OMEGA_STAR))
    assert abs(stride.v[2] - OMEGA_STAR) <= STEADY_TOLERANCE * OMEGA_STAR
    assert abs(stride.duration - _step_period(OMEGA_STAR)) <= PERIOD_TOLERANCE
    # Angular momentum about the new foot is kept by the strike: omega+ = eta omega-.
    assert abs(stride.v[2] - ETA * stride.v_minus[2]) <= 1e-12


def test_the_stride_map_multiplier_is_eta_squared() -> None:
    scene = _scene()
    flow = StanceFlow(scene.constraints)

    def next_speed(omega: np.ndarray) -> np.ndarray:
        return flow.stride(scene.q0, _post_strike_velocity(float(omega[0]))).v[2:3]

    multiplier = finite_difference_jacobian(next_speed, np.array([OMEGA_STAR]), step=1e-4)[0, 0]
    assert abs(multiplier - ETA**2) <= MULTIPLIER_TOLERANCE


@pytest.mark.slow
def test_moreau_jean_converges_at_order_one_to_the_steady_speed() -> None:
    # Started on the gait; error = largest |omega+ - omega*| over the strikes of 4 s.
    # Measured (theta = 0.5): h = 4, 2, 1 ms -> 2.25e-2, 1.42e-2, 5.90e-3 rad/s (3.08e-2,
    # 1.34e-2, 7.33e-3 when the stance spoke was released and re-closed, docs/legged.md).
    scene = dataclasses.replace(_scene(), v0=_post_strike_velocity(OMEGA_STAR))
    steps = np.array([4e-3, 2e-3, 1e-3])  # [s]
    errors = []
    for h in steps:
        omega = simulate(scene, duration=4.0, dt=float(h)).log.v[:, 2]
        strikes = np.flatnonzero(np.diff(omega) < -0.05) + 1  # the strike drops omega by ~25 %
        assert strikes.size >= 5
        errors.append(np.max(np.abs(omega[strikes] - OMEGA_STAR)))
    order = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert 0.75 <= order <= 1.25, (errors, order)
    assert errors[-1] <= 0.01 * OMEGA_STAR


@pytest.mark.slow
@pytest.mark.parametrize("h", [4e-3, 1e-3])
def test_moreau_jean_impacts_are_the_strikes_and_the_stance_spoke_stays_held(h: float) -> None:
    # Before the release band (persistence_speed) the stance spoke was released whenever its
    # O(h²) drift passed 1 µm and re-closed a step later: 223 "impacts" in 6 s at 1 ms.
    result = simulate(_scene(), duration=6.0, dt=h)
    log = result.log
    strikes = np.flatnonzero(np.diff(log.v[:, 2]) < -0.05)  # the strike drops omega by ~25 %
    np.testing.assert_array_equal(log.impacts.t, log.t[strikes])
    assert list(log.impacts.constraint) == [f"foot_{i % 8}/ground" for i in range(1, 9)]
    assert result.summary["n_impacts"] == 8
    # At every step the stance spoke (0, then the last struck) is pressed: never released.
    stance = np.searchsorted(strikes, np.arange(len(log) - 1), side="right") % 8
    assert np.all(log.impulse[np.arange(len(log) - 1), stance] > 0.0)


def test_stride_errors() -> None:
    scene = _scene()
    with pytest.raises(StrideError, match="no foot struck"):
        StanceFlow(scene.constraints, max_duration=0.1).stride(scene.q0, scene.v0)
    with pytest.raises(StrideError, match="would lift off"):  # l omega² > g cos(...)
        StanceFlow(scene.constraints).stride(scene.q0, _post_strike_velocity(5.0))
    slippery = dataclasses.replace(
        scene,
        contacts=tuple(dataclasses.replace(c, friction=0.05) for c in scene.contacts),
    )
    with pytest.raises(StrideError, match="would slip"):
        StanceFlow(slippery.constraints).stride(scene.q0, scene.v0)
    with pytest.raises(InvalidParameterError, match="a foot on the ground"):
        StanceFlow(scene.constraints).stride(scene.q0 + np.array([0.0, 0.1, 0.0]), scene.v0)
    frictionless = dataclasses.replace(
        scene, contacts=tuple(dataclasses.replace(c, friction=0.0) for c in scene.contacts)
    )
    with pytest.raises(InvalidParameterError, match="friction > 0"):
        StanceFlow(frictionless.constraints)
