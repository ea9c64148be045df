"""Event-driven integration against the analytic bouncing ball and its own invariants."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene

from ucontrol.analysis import BouncingBall
from ucontrol.control import JointPD
from ucontrol.exceptions import IntegrationError, InvalidParameterError, SimulationError
from ucontrol.integrators import EventDriven
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

MASS, GRAVITY, RADIUS = 1.0, 9.81, 0.1  # the ball of robots/ball.toml: [kg], [m/s²], [m]


def _event_driven(scene: Scene, **settings: object) -> Scene:
    integrator = dataclasses.replace(scene.integrator, name="event_driven", **settings)
    return dataclasses.replace(scene, integrator=integrator)


def _height_errors(restitution: float, duration: float = 3.0, **settings: object):
    scene = _event_driven(ball_scene(restitution), **settings)
    log = simulate(scene, duration=duration, progress=False).log
    reference = BouncingBall(height=1.0, restitution=restitution, gravity=GRAVITY)
    return log, reference, np.abs(log.gap[:, 0] - reference.state(log.t)[0])


def test_ball_e09_height_error_below_1e9_over_3s() -> None:
    log, reference, errors = _height_errors(0.9)
    assert reference.impact_times(3.0).size >= 4
    assert np.max(errors) <= 1e-9, np.max(errors)
    assert np.max(np.abs(log.v[:, 0] - reference.state(log.t)[1])) <= 1e-9


@pytest.mark.slow
def test_ball_e05_height_error_below_1e8_through_accumulation() -> None:
    log, reference, errors = _height_errors(0.5)
    resting = log.t > reference.accumulation_time
    assert resting.sum() > 1000
    assert np.max(errors) <= 1e-8, np.max(errors)
    assert np.max(errors[resting]) <= 1e-8
    np.testing.assert_array_equal(log.v[resting, 0], 0.0)
    # At rest the contact carries the weight: the impulse of a step is m g h.
    steps = resting[:-1] & (log.t[:-1] > reference.accumulation_time + 0.01)
    np.testing.assert_allclose(log.impulse[:-1][steps, 0], MASS * GRAVITY * 1e-3, rtol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("zeno_velocity", [1e-2, 1e-3])
def test_zeno_threshold_costs_at_most_the_skipped_bounce_height(zeno_velocity: float) -> None:
    # Impacts rebounding slower than the threshold are plastic: the skipped flights are lower
    # than zeno_velocity² / (2 g), which bounds the height error.
    _, _, errors = _height_errors(0.5, zeno_velocity=zeno_velocity)
    bound = zeno_velocity**2 / (2.0 * GRAVITY)
    assert np.max(errors) <= bound * (1.0 + 1e-9) + 1e-12
    if zeno_velocity == 1e-2:  # the skipped flights last 2 ms or less: sampled every 1 ms
        assert np.max(errors) >= 0.1 * bound


@pytest.mark.slow
def test_fewer_events_with_a_larger_zeno_threshold() -> None:
    events = []
    for zeno_velocity in (1e-2, 1e-5):
        scene = _event_driven(ball_scene(0.5), zeno_velocity=zeno_velocity)
        events.append(simulate(scene, duration=2.0, progress=False).summary["n_events"])
    # Rebounds e^k V0 >= v_z: k <= log(v_z / V0) / log(e), V0 = 4.43 m/s.
    assert events == [9, 19]


def test_one_long_step_locates_the_impact_inside_it() -> None:
    scene = ball_scene(0.9)
    integrator = EventDriven(scene.robot, scene.constraints, dt=0.6)
    outcome = integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(1))
    reference = BouncingBall(height=1.0, restitution=0.9, gravity=GRAVITY)
    height, velocity = reference.state(0.6)
    assert outcome.events == 1
    assert outcome.q[0] - RADIUS == pytest.approx(height[0], abs=1e-13)
    assert outcome.v[0] == pytest.approx(velocity[0], abs=1e-13)
    # Newton's law: the impulse is m (1 + e) V0.
    assert outcome.impulse[0] == pytest.approx(1.9 * MASS * reference.impact_speed, rel=1e-13)


def test_sampling_period_does_not_change_the_motion() -> None:
    states = []
    for dt in (1e-3, 0.05):
        log = simulate(_event_driven(ball_scene(0.9)), duration=2.0, dt=dt, progress=False).log
        states.append((log.q[-1, 0], log.v[-1, 0]))
    np.testing.assert_allclose(states[0], states[1], rtol=0.0, atol=1e-12)


def test_free_flyer_ball_height_and_drift() -> None:
    # nq = 7 ≠ nv = 6: the ODE runs on a chart of the configuration space.
    scene = _event_driven(load_scene(ROBOTS / "free_ball.toml"))
    log = simulate(scene, duration=2.5, progress=False).log
    reference = BouncingBall(height=1.0, restitution=0.9, gravity=GRAVITY)
    assert np.max(np.abs(log.q[:, 2] - RADIUS - reference.state(log.t)[0])) <= 1e-9
    np.testing.assert_allclose(log.q[:, 0], 0.3 * log.t, atol=1e-9)  # frictionless: no drag
    np.testing.assert_allclose(np.linalg.norm(log.q[:, 3:], axis=1), 1.0, atol=1e-12)


def test_contact_opens_when_pushed_harder_than_the_weight() -> None:
    def push(t, q, v, contacts):
        return np.array([2.0 * MASS * GRAVITY if t >= 0.2 - 1e-12 else 0.0])

    scene = _event_driven(dataclasses.replace(ball_scene(0.0), q0=np.array([RADIUS])))
    log = simulate(scene, push, duration=0.5, progress=False).log
    after = log.t >= 0.2
    # Net acceleration +g once the push exceeds the weight.
    np.testing.assert_allclose(
        log.gap[after, 0], 0.5 * GRAVITY * (log.t[after] - 0.2) ** 2, atol=1e-12
    )
    np.testing.assert_array_equal(log.gap[~after, 0], 0.0)


def test_sliding_tip_releases_inside_a_step(two_link_scene: Scene) -> None:
    # The tip starts on the ground sliding at 1.6 m/s; the contact force vanishes mid-step
    # (a multiplier event), the tip lifts off, and no energy appears.
    scene = _event_driven(
        dataclasses.replace(two_link_scene, q0=np.array([0.9, -1.8]), v0=np.array([5.0, -10.0])),
        dt=1e-2,
    )
    integrator = scene.build_integrator()
    q, v = scene.q0, scene.v0
    released = False
    for _ in range(30):
        state = integrator.evaluate(q, v)
        outcome = integrator.step(state, np.zeros(2))
        released |= bool(
            outcome.events
            and state.gap[0] == 0.0
            and outcome.impulse[0] > 0.0
            and integrator.evaluate(outcome.q, outcome.v).gap[0] > 0.0
        )
        q, v = outcome.q, outcome.v
    assert released
    log = simulate(scene, duration=0.5, progress=False).log
    assert np.max(np.diff(log.energy)) <= 1e-12 * log.energy[0]
    assert log.gap.min() >= -1e-12


@pytest.mark.slow
def test_arm_drop_agrees_with_fine_moreau_jean(two_link_scene: Scene) -> None:
    event_driven = simulate(_event_driven(two_link_scene), duration=1.5, progress=False)
    fine = simulate(two_link_scene, duration=1.5, dt=1e-4, progress=False).log
    coarse = simulate(two_link_scene, duration=1.5, dt=1e-3, progress=False).log
    log = event_driven.log
    fine_error = np.max(np.abs(fine.q[::10] - log.q))
    coarse_error = np.max(np.abs(coarse.q - log.q))
    assert fine_error <= 2e-4 and coarse_error / fine_error >= 5.0  # Moreau–Jean: order 1
    assert log.gap.min() >= -1e-12  # events land on the surface, no penetration
    assert np.max(np.diff(log.energy)) <= 1e-12 * log.energy[0]
    assert event_driven.summary["n_events"] > 0


@pytest.mark.slow
def test_same_controllers_as_moreau_jean(two_link_scene: Scene) -> None:
    q_ref = np.array([1.5, -1.4])
    controller = JointPD(two_link_scene.robot, q_ref=q_ref, kp=200.0, kd=30.0)
    log = simulate(_event_driven(two_link_scene), controller, duration=4.0, progress=False).log
    np.testing.assert_allclose(log.q[-1], q_ref, atol=1e-4)


def test_too_many_events_in_a_step_is_a_typed_error() -> None:
    scene = ball_scene(0.5)
    integrator = EventDriven(
        scene.robot, scene.constraints, dt=2.0, zeno_velocity=1e-12, max_events=10
    )
    with pytest.raises(IntegrationError, match="zeno_velocity") as info:
        integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(1))
    assert info.value.integrator == "event_driven" and 0.0 < info.value.time < 2.0
    # With the default cap, the flights shrink below the time resolution first.
    with pytest.raises(SimulationError, match=r"without the time advancing.*zeno_velocity"):
        simulate(_event_driven(scene, zeno_velocity=1e-12), duration=2.0, dt=2.0)


def test_bad_settings_are_typed_errors() -> None:
    scene = ball_scene(0.9)
    with pytest.raises(InvalidParameterError, match="`method`"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, method="Radau")
    with pytest.raises(InvalidParameterError, match="`rtol`"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, rtol=0.0)
    with pytest.raises(InvalidParameterError, match="`zeno_velocity`"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, zeno_velocity=-1.0)
