"""Constraint accelerations of collision rows (J̇ v), and event-driven runs with collision pairs.

The drift of vertex rows is exact, checked against Richardson-extrapolated central differences
of the normal velocity along the flow q ⊕ s v, t + s (the motion with zero joint
acceleration); that of witness rows (a central difference, documented) against the closed
form of two spheres, fixed and moving, and against finer differences. In a run, the box of
``robots/box_drop_collision.toml`` under event_driven equals its hand-declared corners, and
the ball on the vibrating box equals the ball on the vibrating plane.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS
from test_collision_pairs import _box_scene, _configuration, _pairs, _robot, _two_spheres

from ucontrol.contact import CollisionPair, ConstraintSet, EnvironmentShape
from ucontrol.contact.surface_motion import Sinusoid
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

_MOTION = Sinusoid(amplitude=np.array([0.01, 0.02, 0.03]), frequency=7.0, phase=0.3)
_TIME = 0.37  # [s]
_R1, _R2 = 0.1, 0.15  # radii of the spheres of _SHAPES [m]


def _normal_velocity(constraints: ConstraintSet, q: np.ndarray, v: np.ndarray, t: float):
    robot = constraints.robot
    data = pin.Data(robot.model)
    pin.forwardKinematics(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    return constraints.evaluate(data, q, v, t)[1]


def _flow_derivative(constraints: ConstraintSet, q: np.ndarray, v: np.ndarray, step: float):
    """Central difference of u along (q ⊕ s v, t + s) with step ``step`` [s]."""
    model = constraints.robot.model
    plus = _normal_velocity(constraints, pin.integrate(model, q, step * v), v, _TIME + step)
    minus = _normal_velocity(constraints, pin.integrate(model, q, -step * v), v, _TIME - step)
    return (plus - minus) / (2.0 * step)


def _drift(constraints: ConstraintSet, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    robot = constraints.robot
    data = pin.Data(robot.model)
    pin.forwardKinematics(robot.model, data, q, v, np.zeros(robot.nv))
    pin.updateFramePlacements(robot.model, data)
    indices = np.arange(constraints.size)
    return constraints.normal_drift(data, indices, q=q, v=v, t=_TIME)


def _moving_pairs() -> list[CollisionPair]:
    plate = EnvironmentShape(
        name="plate", type="halfspace", normal=[0.2, 0.1, 1.0], position=[0, 0, -0.1]
    )
    ball = EnvironmentShape(
        name="ball", type="sphere", position=[0.5, 0.5, 0.2], radius=0.1, motion=_MOTION
    )
    return [
        CollisionPair(link="first", other=_with_motion(plate), name="plate"),
        CollisionPair(link="second", other=ball, name="moving_ball"),
    ]


def _with_motion(shape: EnvironmentShape) -> EnvironmentShape:
    return dataclasses.replace(shape, motion=_MOTION)


def test_vertex_drift_is_the_derivative_of_the_normal_velocity(
    tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("ucontrol.contact.collision_geometry.BROAD_PHASE_MARGIN", np.inf)
    robot = _robot(tmp_path)
    constraints = ConstraintSet(robot, collision_pairs=[*_pairs(), *_moving_pairs()])
    vertex = [
        i for i, name in enumerate(constraints.names) if name.startswith(("first/ground", "plate"))
    ]
    assert len(vertex) == 2 * 41  # box corners, sphere centre, cylinder rims; fixed and moving
    for _ in range(3):
        q = _configuration(robot, rng)
        v = rng.standard_normal(robot.nv)
        drift = _drift(constraints, q, v)
        coarse = _flow_derivative(constraints, q, v, 1e-3)
        fine = _flow_derivative(constraints, q, v, 5e-4)
        reference = (4.0 * fine - coarse) / 3.0  # Richardson: O(s^4)
        # Measured 2.8e-12 m/s² over three draws (|drift| up to 9 m/s²).
        np.testing.assert_allclose(drift[vertex], reference[vertex], rtol=0, atol=2e-11)
        # Witness rows of a sphere (smooth distances: a box or a cylinder has witness points
        # that switch features, where the difference is wrong, as documented), a central
        # difference at s = 3e-5 / |v| against one at 1e-6: measured 8.7e-10 m/s².
        witness = [
            i
            for i, name in enumerate(constraints.names)
            if name
            in (
                "first/obstacle#1",
                "first/ball#1",
                "first/second#1",
                "second/ground",
                "moving_ball",
            )
        ]
        assert len(witness) == 5
        reference = _flow_derivative(constraints, q, v, 1e-6)
        np.testing.assert_allclose(drift[witness], reference[witness], rtol=0, atol=5e-9)


def _sphere_drift(p: np.ndarray, w: np.ndarray, a: np.ndarray) -> float:
    """Closed form: g = |p| - r, g̈ at zero joint acceleration for the relative centre p."""
    distance = float(np.linalg.norm(p))
    n = p / distance
    tangential = w - (n @ w) * n
    return float(n @ a + tangential @ tangential / distance)


def _event_driven(scene: Scene) -> Scene:
    integrator = dataclasses.replace(scene.integrator, name="event_driven", dt=1e-3)
    return dataclasses.replace(scene, integrator=integrator)


def test_witness_drift_of_spheres_equals_the_closed_form(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    robot = _two_spheres(tmp_path)
    model = robot.model
    (ball,) = (pair.other for pair in _moving_pairs()[1:])
    constraints = ConstraintSet(
        robot,
        collision_pairs=[
            CollisionPair(link="first", other="second"),
            CollisionPair(link="second", other=ball, name="moving_ball"),
        ],
    )
    first, second = model.getJointId("first_joint"), model.getJointId("second_joint")
    for distance in (0.26, 0.2):  # near, overlapping [m]
        q = _configuration(robot, rng)
        q[7:10] = q[:3] + distance * np.array([0.6, 0.0, 0.8])
        v = rng.standard_normal(robot.nv)
        drift = _drift(constraints, q, v)
        data = pin.Data(model)
        pin.forwardKinematics(model, data, q, v, np.zeros(robot.nv))
        centre, velocity, acceleration = [], [], []
        for joint in (first, second):
            frame = pin.LOCAL_WORLD_ALIGNED
            centre.append(data.oMi[joint].translation)
            velocity.append(pin.getVelocity(model, data, joint, frame).linear)
            acceleration.append(pin.getClassicalAcceleration(model, data, joint, frame).linear)
        expected = _sphere_drift(
            centre[0] - centre[1], velocity[0] - velocity[1], acceleration[0] - acceleration[1]
        )
        # Measured 1.0e-10 m/s² (fixed) and 9.4e-11 m/s² (moving) over 40 draws.
        assert abs(drift[0] - expected) < 1e-9
        x, dx, ddx = _MOTION(_TIME)
        expected = _sphere_drift(
            centre[1] - (np.array([0.5, 0.5, 0.2]) + x), velocity[1] - dx, acceleration[1] - ddx
        )
        assert abs(drift[1] - expected) < 1e-9


def test_drift_of_collision_rows_needs_the_state(tmp_path: Path) -> None:
    robot = _robot(tmp_path)
    constraints = ConstraintSet(robot, collision_pairs=_pairs())
    with pytest.raises(InvalidParameterError, match="q, v"):
        constraints.normal_drift(pin.Data(robot.model), [0])


@pytest.mark.slow
@pytest.mark.parametrize(
    ("q0", "v0", "duration"),
    [
        ([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0], [0.0] * 6, 0.4),  # flat: a face contact
        ([0.0, 0.0, 0.12, 0.0, 0.0873, 0.0, 0.9962], [0.3, 0.0, 0.0, 0.0, 1.0, 0.5], 0.25),
    ],
)
def test_event_driven_box_drop_equals_hand_declared_corners(
    q0: list[float], v0: list[float], duration: float
) -> None:
    q0 = [*q0[:3], *(np.array(q0[3:]) / np.linalg.norm(q0[3:]))]
    scenes = [_box_scene(collision, q0, v0) for collision in (True, False)]
    logs = [
        simulate(_event_driven(scene), duration=duration, out=None, progress=False).log
        for scene in scenes
    ]
    shapes, corners = logs
    q = np.asarray(shapes.q)
    # Flat: measured 0 in q, v and impulses; tilted and spinning: 4.6e-15 in q, 1.8e-11 m/s
    # in v, 9e-13 N s in impulses.
    np.testing.assert_allclose(q, np.asarray(corners.q), rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(shapes.v), np.asarray(corners.v), rtol=0, atol=2e-10)
    lower = np.asarray(shapes.impulse)[:, [0, 2, 4, 6]].sum(axis=1)
    np.testing.assert_allclose(lower, np.asarray(corners.impulse).sum(axis=1), atol=1e-11)
    assert np.all(np.asarray(shapes.impulse)[:, [1, 3, 5, 7]] == 0.0)
    if v0 == [0.0] * 6:
        tilt = 2.0 * np.arcsin(np.linalg.norm(q[:, 3:6], axis=1))  # [rad], measured 3e-17
        assert tilt.max() <= 1e-10
        impulse = np.asarray(shapes.impulse)[-50:-1].sum(axis=1)  # at rest: m g h per step
        np.testing.assert_allclose(impulse, 9.81 * 1e-3, rtol=1e-13)  # measured 2.2e-16


@pytest.mark.slow
def test_event_driven_ball_on_vibrating_box_equals_vibrating_plane() -> None:
    box = _event_driven(Scene.from_toml(ROBOTS / "ball_vibrating_box.toml"))
    plane = _event_driven(Scene.from_toml(ROBOTS / "ball_vibrating_table.toml"))
    logs = [
        simulate(scene, duration=0.6, dt=1e-3, out=None, progress=False).log
        for scene in (box, plane)
    ]
    # Measured bitwise equal (0 in q and v; coal's sphere-box distance is in closed form).
    np.testing.assert_allclose(np.asarray(logs[0].q), np.asarray(logs[1].q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(logs[0].v), np.asarray(logs[1].v), rtol=0, atol=1e-10)
