"""Flexible joints (Spong) in the event-driven and compliant integrators.

Two-link arms with both joints flexible, K = 1e4 N m/rad and B = 0.1 kg m² (the motors ring at
sqrt(K / B) = 316 rad/s), gravity along -y: robots/two_link.urdf without contact, and the drop
of robots/two_link_flexible_drop.toml onto the ground and the wall.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS
from scipy.integrate import solve_ivp

from ucontrol.integrators import EventDriven
from ucontrol.model import FlexibleJoints, RobotModel
from ucontrol.scene import IntegratorSettings, Scene, load_scene
from ucontrol.simulate import simulate

Q0 = np.array([0.9, -1.6])  # link positions [rad]
STIFFNESS, MOTOR_INERTIA = 1e4, 0.1  # [N m/rad], [kg m²]
DEFLECTION = 0.01  # initial motor lead over the links [rad]
GRAVITY = np.array([0.0, -9.81, 0.0])  # [m/s²]


def _arm(name: str, *, duration: float = 1.0, dt: float = 1e-3, **settings: object) -> Scene:
    """The flexible arm without contact, released at rest with the motors 0.01 rad ahead."""
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf", gravity=GRAVITY)
    flexible = FlexibleJoints.from_robot(
        robot, ["shoulder", "elbow"], stiffness=STIFFNESS, motor_inertia=MOTOR_INERTIA
    )
    return Scene(
        name="flexible_arm",
        robot=robot,
        q0=Q0,
        v0=np.zeros(2),
        flexible=flexible,
        motor_q0=Q0 + DEFLECTION,
        integrator=IntegratorSettings(name=name, dt=dt, **settings),
        duration=duration,
    )


def _drop(name: str, **settings: object) -> Scene:
    """robots/two_link_flexible_drop.toml (same K and B) with another integrator."""
    scene = load_scene(ROBOTS / "two_link_flexible_drop.toml")
    integrator = dataclasses.replace(scene.integrator, name=name, **settings)
    return dataclasses.replace(scene, integrator=integrator)


def _states(log) -> np.ndarray:
    """Links' and motors' positions and velocities of every sample, shape (N, 8)."""
    return np.hstack((log.q, log.motor_q, log.v, log.motor_v))


def _spong(scene: Scene, times: np.ndarray) -> np.ndarray:
    """Spong's equations integrated directly (no integrator of ucontrol): states at ``times``."""
    model = scene.robot.model
    data = pin.Data(model)

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        q1, q2, v1, v2 = np.split(y, 4)
        spring = STIFFNESS * (q1 - q2)  # on the motors [N m]
        M = pin.crba(model, data, q1)
        M = np.triu(M) + np.triu(M, 1).T
        a1 = np.linalg.solve(M, -pin.nonLinearEffects(model, data, q1, v1) - spring)
        return np.concatenate((v1, v2, a1, spring / MOTOR_INERTIA))

    y0 = np.concatenate(scene.initial_state())  # (q1, q2, v1, v2)
    solution = solve_ivp(
        rate, (0.0, times[-1]), y0, method="DOP853", rtol=1e-12, atol=1e-14, t_eval=times
    )
    return solution.y.T


def test_event_driven_follows_spongs_equations_and_keeps_the_energy() -> None:
    log = simulate(_arm("event_driven")).log
    reference = _spong(_arm("event_driven"), log.t)
    assert np.max(np.abs(_states(log) - reference)) <= 1e-7  # measured 1.0e-8
    energy = log.energy  # 5.18 J, 0.01 J of it in the springs at the start
    assert np.max(np.abs(energy - energy[0])) <= 1e-9 * energy[0]  # rtol 1e-10: 1.1e-10
    assert np.ptp(log.motor_q - log.q) > DEFLECTION  # the springs do work


@pytest.mark.slow
def test_compliant_agrees_with_event_driven() -> None:
    event_driven = simulate(_arm("event_driven")).log
    compliant = simulate(_arm("compliant")).log  # Radau at rtol 1e-8
    error = np.abs(_states(compliant) - _states(event_driven))  # [rad], [rad/s]
    assert np.max(error[:, :4]) <= 1e-9  # positions: measured 3.3e-11 rad
    assert np.max(error) <= 1e-7  # velocities (up to 8 rad/s): measured 1.1e-8 rad/s
    energy = compliant.energy
    assert np.max(np.abs(energy - energy[0])) <= 1e-8 * energy[0]  # measured 5.1e-10


@pytest.mark.slow
def test_moreau_jean_midpoint_converges_to_event_driven_at_second_order() -> None:
    duration = 0.5  # [s]
    reference = simulate(_arm("event_driven", duration=duration, rtol=1e-12, atol=1e-14)).log
    errors = []
    for dt in (1e-4, 5e-5, 2.5e-5):
        scene = _arm("moreau_jean", duration=duration, dt=dt, theta=0.5, midpoint=True)
        log = simulate(scene).log
        stride = round(1e-3 / dt)  # the reference's samples
        errors.append(np.max(np.abs(_states(log)[::stride, :4] - _states(reference)[:, :4])))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert errors[0] <= 5e-4  # [rad], measured 1.4e-4
    np.testing.assert_allclose(ratios, 4.0, rtol=0.05)  # measured 3.9995, 3.9999


def test_event_driven_impact_leaves_the_motors_alone() -> None:
    # The tip on the ground (y = 0.5 sin 0.9 + 0.5 sin(-0.9) = 0) coming down at 0.62 m/s, the
    # motors moving on their own and 0.02 rad off their links: one step of 1 ns holds the
    # impact and 1e-9 s of smooth motion.
    scene = _drop("event_driven")
    q = np.array([0.9, -1.8, 0.92, -1.78])  # links, motors [rad]
    v = np.array([-1.0, 0.0, 0.5, -0.3])  # [rad/s]
    integrator = EventDriven(
        scene.robot, scene.constraints, dt=1e-9, flexible=scene.flexible, rtol=1e-12, atol=1e-14
    )
    before = integrator.evaluate(q, v)
    assert before.gap[0] == pytest.approx(0.0, abs=1e-15)
    assert before.normal_velocity[0] == pytest.approx(-np.cos(0.9), rel=1e-12)  # [m/s]
    outcome = integrator.step(before, np.zeros(4))
    after = integrator.evaluate(outcome.q, outcome.v)
    assert after.normal_velocity[0] == pytest.approx(0.7 * np.cos(0.9), rel=1e-6)  # Newton
    motor_acceleration = STIFFNESS * 0.02 / MOTOR_INERTIA  # [rad/s²]
    np.testing.assert_allclose(outcome.v[2:], v[2:], atol=1.01e-9 * motor_acceleration)
    assert np.max(np.abs(outcome.v[:2] - v[:2])) > 0.5  # the links jump
    energy_loss = (before.kinetic_energy + before.potential_energy) - (
        after.kinetic_energy + after.potential_energy
    )  # [J]
    # Newton's law on one contact loses P (1 - e) |u⁻| / 2, all of it from the links.
    speed = np.cos(0.9)  # [m/s]
    assert energy_loss == pytest.approx(0.5 * outcome.impulse[0] * 0.3 * speed, rel=1e-6)


@pytest.mark.slow
def test_event_driven_drop_gains_no_energy_and_the_motors_never_jump() -> None:
    # Sampled every 0.2 ms over the six hardest ground impacts (0.21 to 0.77 s) and four on
    # the wall.
    dt = 2e-4  # [s]
    result = simulate(_drop("event_driven"), duration=0.8, dt=dt)
    log = result.log
    impacts = np.flatnonzero(log.impulse[:-1].max(axis=1) > 0.0)
    assert np.count_nonzero(log.impulse[:-1, 0]) >= 6 and impacts.size >= 10
    energy = log.energy
    assert np.max(np.diff(energy)) <= 1e-12 * energy[0]  # measured 1.1e-14 J of 4.18 J
    assert result.summary["energy_increase_at_impacts"] == 0.0
    assert energy[-1] < 0.9 * energy[0]  # e = 0.7
    assert log.gap.min() >= -1e-12
    # The motor velocity changes by the spring torque alone, B dq2 = K (q1 - q2) dt: the
    # trapezoidal rule integrates it over a step up to its smooth error (measured in the steps
    # without impact) plus, across an impact, the kink of the link velocity: h²/8 K/B |Δdq1|.
    # An impulse reaching the motors would make the change of the order of the links' jump.
    acceleration = STIFFNESS * (log.q - log.motor_q) / MOTOR_INERTIA  # [rad/s²]
    residual = np.abs(
        np.diff(log.motor_v, axis=0) - 0.5 * dt * (acceleration[:-1] + acceleration[1:])
    )
    smooth = np.delete(residual, impacts, axis=0).max()  # [rad/s], measured 3.8e-5
    kink = dt**2 / 8.0 * STIFFNESS / MOTOR_INERTIA * np.abs(np.diff(log.v, axis=0)[impacts])
    assert np.all(residual[impacts] <= 1.5 * (kink + smooth))  # measured: 0.94 of the sum
    assert np.abs(np.diff(log.v, axis=0)[impacts]).max() > 1.0  # [rad/s], the links jump


@pytest.mark.parametrize("name", ["event_driven", "compliant"])
def test_scene_builds_flexible_integrators(name: str) -> None:
    scene = _drop(name)
    integrator = scene.build_integrator()
    assert integrator.flexible is scene.flexible
    state = integrator.evaluate(*scene.initial_state())
    outcome = integrator.step(state, np.zeros(4))
    assert outcome.q.shape == (4,) and outcome.v.shape == (4,)
