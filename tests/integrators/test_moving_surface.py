"""Moreau–Jean with contacts against moving planes, against analytic solutions.

The 1 kg ball of ``robots/ball.urdf`` (vertical prismatic joint, radius 0.1 m) on a plate
translating along z: resting on a plate at constant speed and at constant acceleration (the
contact force is m (g + a)), impacts on a plate rising at constant speed (closed-form impact
time and Newton's law on the relative velocity), the first impact on a vibrating plate (root
of the closed-form gap), and the period-1 orbit of the bouncing ball on a vibrating table.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import scipy.optimize
from conftest import ROBOTS

from ucontrol.contact import Plane
from ucontrol.contact.surface_motion import Polynomial, Sinusoid, UserMotion, check_motion
from ucontrol.exceptions import InvalidParameterError, NonFiniteValueError, NotFoundError
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

G = 9.81  # [m/s²]
RADIUS = 0.1  # [m]


def _ball(
    motion: dict[str, Any], q0: float, v0: float = 0.0, e: float = 0.0, **integrator: Any
) -> Scene:
    table = {
        "robot": {"urdf": "ball.urdf", "q0": [q0], "v0": [v0], "gravity": [0.0, 0.0, -G]},
        "surfaces": {"plate": {"type": "plane", "normal": [0.0, 0.0, 1.0], "motion": motion}},
        "contacts": [{"frame": "ball", "surface": "plate", "radius": RADIUS, "restitution": e}],
        "integrator": {"name": "moreau_jean", "dt": 1e-3, **integrator},
    }
    return Scene.from_dict(table, base_dir=ROBOTS)


def _run(scene: Scene, duration: float, h: float) -> Any:
    return simulate(scene, duration=duration, dt=h, out=None, progress=False).log


@pytest.mark.parametrize("acceleration", [0.0, 2.0, -3.0])
def test_ball_resting_on_a_moving_plate_carries_m_g_plus_a(acceleration: float) -> None:
    speed, h = 0.5, 1e-3  # [m/s], [s]
    motion = {
        "type": "polynomial",
        "coefficients": [[0.0, 0.0, 0.0], [0.0, 0.0, speed], [0.0, 0.0, 0.5 * acceleration]],
    }
    log = _run(_ball(motion, q0=RADIUS, v0=speed), duration=0.3, h=h)
    impulse = np.asarray(log.impulse)[:-1, 0]  # [N s]; the last row has no step
    np.testing.assert_allclose(impulse / h, 1.0 * (G + acceleration), rtol=1e-9)
    np.testing.assert_allclose(np.asarray(log.gap)[:, 0], 0.0, atol=1e-12)
    t = np.asarray(log.t)
    np.testing.assert_allclose(np.asarray(log.v)[:, 0], speed + acceleration * t, atol=1e-12)


def test_impact_on_a_rising_plate_follows_newton_on_the_relative_velocity() -> None:
    speed, height, e = 0.5, 0.2, 0.8  # [m/s], [m] gap at t = 0, restitution
    motion = {"type": "polynomial", "coefficients": [[0.0, 0.0, 0.0], [0.0, 0.0, speed]]}
    # Closed form: height - g t²/2 = speed t; rebound c + e (g t* + c) [m/s].
    t_star = (-speed + np.sqrt(speed**2 + 2 * G * height)) / G
    rebound = speed + e * (G * t_star + speed)
    for h in (1e-3, 1e-4):
        log = _run(_ball(motion, q0=RADIUS + height, e=e), duration=t_star + 0.01, h=h)
        impulse, t = np.asarray(log.impulse)[:, 0], np.asarray(log.t)
        v, u = np.asarray(log.v)[:, 0], np.asarray(log.normal_velocity)[:, 0]
        k = int(np.flatnonzero(impulse > 0.0)[0])
        # Newton's law on the velocity relative to the plate, to round-off.
        assert abs(u[k + 1] + e * u[k]) <= 1e-12 * abs(u[k])
        np.testing.assert_allclose(u, v - speed, atol=1e-12)
        assert abs(t[k] - t_star) <= h + 1e-12
        assert abs(v[k + 1] - rebound) <= 2 * G * h  # O(h)


def test_first_impact_on_a_vibrating_plate() -> None:
    amplitude, omega, height, e = 0.01, 30.0, 0.05, 0.5  # [m], [rad/s], [m], restitution
    motion = {"type": "sinusoid", "amplitude": [0.0, 0.0, amplitude], "frequency": omega}

    def gap(t: float) -> float:  # [m], closed form
        return height - 0.5 * G * t * t - amplitude * np.sin(omega * t)

    times = np.linspace(0.0, 0.2, 2001)
    first = int(np.flatnonzero(np.array([gap(t) for t in times]) < 0.0)[0])
    t_star = scipy.optimize.brentq(gap, times[first - 1], times[first], xtol=1e-14)
    approach = -G * t_star - amplitude * omega * np.cos(omega * t_star)  # relative [m/s]
    errors = []
    for h in (1e-3, 1e-4):
        log = _run(_ball(motion, q0=RADIUS + height, e=e), duration=t_star + 0.005, h=h)
        impulse, t = np.asarray(log.impulse)[:, 0], np.asarray(log.t)
        u = np.asarray(log.normal_velocity)[:, 0]
        k = int(np.flatnonzero(impulse > 0.0)[0])
        assert abs(u[k + 1] + e * u[k]) <= 1e-12 * abs(u[k])
        assert abs(t[k] - t_star) <= h + 1e-12
        errors.append(abs(u[k] - approach))
    # Order one: ten times smaller steps, about ten times smaller error (at least 5).
    assert errors[1] < errors[0] / 5 and errors[0] < 2 * G * 1e-3


def test_period_one_orbit_of_the_ball_on_a_vibrating_table() -> None:
    e, omega = 0.5, 2 * np.pi * 5  # restitution, [rad/s]
    period = 2 * np.pi / omega  # [s]
    amplitude = 1.3 * G / omega**2  # [m]: Γ = A ω² / g = 1.3, where the orbit is stable
    # The period-1 orbit: an impact every period at phase φ with the ball leaving at g T / 2
    # [m/s]; Newton's law on the relative velocity gives A ω cos φ = (g T / 2)(1 - e)/(1 + e).
    leave = G * period / 2
    phase = np.arccos(leave * (1 - e) / ((1 + e) * amplitude * omega))
    motion = {
        "type": "sinusoid",
        "amplitude": [0.0, 0.0, amplitude],
        "frequency": omega,
        "phase": phase,
    }
    for h in (1e-3, 1e-4):
        scene = _ball(motion, q0=RADIUS + amplitude * np.sin(phase), v0=leave, e=e)
        log = _run(scene, duration=5.2 * period, h=h)
        impulse, t = np.asarray(log.impulse)[:, 0], np.asarray(log.t)
        v, u = np.asarray(log.v)[:, 0], np.asarray(log.normal_velocity)[:, 0]
        impacts = np.flatnonzero(impulse > 0.0)
        assert impacts.size == 5
        for n, k in enumerate(impacts, start=1):
            assert abs(u[k + 1] + e * u[k]) <= 1e-12 * abs(u[k])
            assert abs(t[k] - n * period) <= h + 1e-12  # the impact phase, to the step
            assert abs(v[k + 1] - leave) <= G * h  # the impact velocity, O(h)


def test_time_is_required_and_compliant_refuses_moving_surfaces() -> None:
    motion = {"type": "sinusoid", "amplitude": [0.0, 0.0, 0.01], "frequency": 10.0}
    scene = _ball(motion, q0=0.3)
    integrator = scene.build_integrator()
    with pytest.raises(InvalidParameterError, match="moving"):
        integrator.evaluate(scene.q0, scene.v0)
    state = integrator.evaluate(scene.q0, scene.v0, 0.25)
    np.testing.assert_allclose(state.gap, 0.3 - RADIUS - 0.01 * np.sin(2.5), atol=1e-15)
    other = _ball(motion, q0=0.3, name="compliant")
    with pytest.raises(InvalidParameterError, match="moving surfaces"):
        other.build_integrator()


def test_bad_motions_raise_typed_errors() -> None:
    with pytest.raises(InvalidParameterError, match="frequency"):
        Sinusoid(amplitude=[0.0, 0.0, 1.0], frequency=-1.0)
    with pytest.raises(NonFiniteValueError, match="coefficients"):
        Polynomial(coefficients=[[0.0, 0.0, np.nan]])
    with pytest.raises(InvalidParameterError, match="coefficients"):
        Polynomial(coefficients=[0.0, 0.0, 1.0])
    with pytest.raises(InvalidParameterError, match="motion"):
        Plane(motion=3.0)  # type: ignore[arg-type]
    blowing_up = UserMotion(
        lambda t: (np.zeros(3), np.array([0.0, 0.0, np.inf if t == 0 else 1.0 / t]), np.zeros(3))
    )
    with pytest.raises(NonFiniteValueError, match="velocity at t = 0"):
        blowing_up(0.0)
    # |t| is not differentiable at 0, and a wrong velocity is no derivative anywhere.
    kink = UserMotion(lambda t: (np.array([0, 0, abs(t)]), np.array([0, 0, 1.0]), np.zeros(3)))
    with pytest.raises(InvalidParameterError, match="velocity at t = 0"):
        check_motion(kink, np.array([0.5, 0.0]))
    check_motion(Sinusoid(amplitude=[0.0, 0.0, 0.1], frequency=3.0), np.linspace(0, 1, 5))
    with pytest.raises(NotFoundError, match="spline"):
        _ball({"type": "spline"}, q0=0.3)
