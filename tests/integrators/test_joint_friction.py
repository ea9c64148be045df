"""Friction in the joints under Moreau–Jean, against analytic solutions and the step's balance."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import InvalidParameterError, NotFoundError, SceneError, UnknownKeyError
from ucontrol.integrators.moreau_jean import MoreauJean
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
INERTIA = 0.5  # [kg m^2] of the single joint, or [kg] of the slider
LENGTH = 0.4  # [m], centre of mass of the pendulum from its axis
MASS = 2.0  # [kg] of the pendulum
G = 9.81  # [m/s^2]


def _one_joint(kind: str, gravity: bool = False) -> RobotModel:
    """A slider (``"slider"``, mass INERTIA) or a pendulum about z (``"pendulum"``)."""
    model = pin.Model()
    if kind == "slider":
        joint = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "joint")
        inertia = pin.Inertia(INERTIA, np.zeros(3), np.eye(3))
    else:
        joint = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "joint")
        # About the axis: I_c + m l^2 = INERTIA.
        rotational = np.eye(3) * (INERTIA - MASS * LENGTH**2)
        inertia = pin.Inertia(MASS, np.array([LENGTH, 0.0, 0.0]), rotational)
    model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
    model.gravity = pin.Motion(np.array([0.0, -G, 0.0, 0.0, 0.0, 0.0]) if gravity else np.zeros(6))
    return RobotModel(model)


def _run(
    robot: RobotModel,
    friction: JointFriction,
    q0: float,
    v0: float,
    tau: float,
    steps: int,
    dt: float,
    theta: float = 0.5,
) -> tuple[np.ndarray, np.ndarray, list]:
    """Positions and velocities (steps + 1,) and the step outcomes under a constant torque."""
    integrator = MoreauJean(
        robot, ConstraintSet(robot, (), ()), dt=dt, theta=theta, joint_friction=friction
    )
    q, v = np.array([q0]), np.array([v0])
    qs, vs, outcomes = [q0], [v0], []
    for _ in range(steps):
        outcome = integrator.step(integrator.evaluate(q, v), np.array([tau]))
        q, v = outcome.q, outcome.v
        qs.append(float(q[0]))
        vs.append(float(v[0]))
        outcomes.append(outcome)
    return np.array(qs), np.array(vs), outcomes


@pytest.mark.parametrize(("theta", "order"), [(0.5, 2), (1.0, 1)])
def test_viscous_decay_is_exponential_at_the_scheme_order(theta: float, order: int) -> None:
    D, v0, duration = 1.5, 2.0, 1.0  # [N m s/rad], [rad/s], [s]
    friction = JointFriction(viscous=[D], coulomb=[0.0])
    errors = []
    for dt in (1e-2, 5e-3):
        steps = round(duration / dt)
        q, v, _ = _run(_one_joint("pendulum"), friction, 0.0, v0, 0.0, steps, dt, theta)
        t = dt * np.arange(steps + 1)
        exact_v = v0 * np.exp(-D * t / INERTIA)
        exact_q = v0 * INERTIA / D * (1.0 - np.exp(-D * t / INERTIA))
        errors.append(max(np.max(np.abs(v - exact_v)), np.max(np.abs(q - exact_q))))
    measured = math.log2(errors[0] / errors[1])
    # Measured: orders 2.00 (theta = 1/2, errors 2.2e-4, 5.6e-5) and 1.0 (theta = 1).
    assert abs(measured - order) < 0.1
    # The scheme is unconditionally stable: a step 100 times h D / I = 1 still decays.
    _, v, _ = _run(_one_joint("pendulum"), friction, 0.0, v0, 0.0, 50, 100.0 * INERTIA / D, theta)
    assert np.all(np.abs(v[1:]) < v0)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_coulomb_slider_sticks_below_and_slides_above_the_threshold(sign: float) -> None:
    F_c, dt, steps = 2.0, 1e-3, 200  # [N], [s]
    friction = JointFriction(viscous=[0.0], coulomb=[F_c])
    robot = _one_joint("slider")
    q, v, outcomes = _run(robot, friction, 0.3, 0.0, sign * 0.999 * F_c, steps, dt)
    assert np.max(np.abs(v)) <= 1e-12  # measured 0 to 2e-16
    assert np.max(np.abs(q - 0.3)) <= 1e-12
    assert all(outcome.solution.status == "solved" for outcome in outcomes)
    tau = sign * 1.5 * F_c
    q, v, _ = _run(robot, friction, 0.3, 0.0, tau, steps, dt)
    t = dt * np.arange(steps + 1)
    acceleration = (tau - sign * F_c) / INERTIA  # [m/s^2]
    # Exact: v = a t; the trapezoidal position q0 + a t^2 / 2 too. Measured 1e-16 relative.
    np.testing.assert_allclose(v, acceleration * t, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(q, 0.3 + 0.5 * acceleration * t**2, rtol=1e-12, atol=1e-14)


def test_coulomb_pendulum_holds_where_gravity_is_below_the_threshold() -> None:
    F_c = 1.0  # [N m]
    friction = JointFriction(viscous=[0.0], coulomb=[F_c])
    robot = _one_joint("pendulum", gravity=True)
    # Gravity torque m g l cos(q): 0.98 F_c at the angle below, 1.02 F_c at the other.
    hold = math.acos(0.98 * F_c / (MASS * G * LENGTH))
    q, v, _ = _run(robot, friction, hold, 0.0, 0.0, 300, 1e-3)
    assert np.max(np.abs(v)) <= 1e-12 and np.max(np.abs(q - hold)) <= 1e-12
    slip = math.acos(1.02 * F_c / (MASS * G * LENGTH))
    _, v, _ = _run(robot, friction, slip, 0.0, 0.0, 1, 1e-3)
    # First step from rest: M (v1 - 0) = h (-m g l cos q0 + F_c), exactly.
    assert v[1] == pytest.approx(1e-3 * (-1.02 * F_c + F_c) / INERTIA, rel=1e-12)


def test_viscous_and_coulomb_stop_at_the_analytic_time_and_dissipate_the_energy() -> None:
    D, F_c, v0, dt = 0.8, 0.6, 3.0, 1e-3  # [N m s/rad], [N m], [rad/s], [s]
    friction = JointFriction(viscous=[D], coulomb=[F_c])
    steps = 2500
    _, v, _ = _run(_one_joint("pendulum"), friction, 0.0, v0, 0.0, steps, dt)
    t = dt * np.arange(steps + 1)
    # I dv/dt = -D v - F_c while v > 0: v = (v0 + F_c/D) e^{-Dt/I} - F_c/D until it stops.
    t_stop = INERTIA / D * math.log(1.0 + D * v0 / F_c)
    exact = np.maximum((v0 + F_c / D) * np.exp(-D * t / INERTIA) - F_c / D, 0.0)
    assert np.max(np.abs(v - exact)) < 1e-6  # measured 2.9e-7 (O(h^2))
    stopped = t[np.flatnonzero(np.abs(v) <= 1e-12)[0]]
    assert abs(stopped - t_stop) <= dt
    assert np.max(np.abs(v[t > t_stop + dt])) <= 1e-12  # stays stuck (measured 7e-28)
    # Energy balance: the kinetic energy lost is the integral of D v^2 + F_c |v| (trapezoid).
    lost = 0.5 * INERTIA * (v0**2 - v[-1] ** 2)
    power = np.array([friction.dissipation(np.array([w])) for w in v])
    dissipated = float(np.sum(0.5 * (power[1:] + power[:-1])) * dt)
    assert dissipated == pytest.approx(lost, rel=5e-6)  # measured 9.7e-7 (the stop's kink)
    # And the scheme's own balance, step by step (theta = 1/2): exact but at the stop.
    v_mid = 0.5 * (v[1:] + v[:-1])
    per_step = dt * (D * v_mid**2 + F_c * np.abs(v_mid))
    kinetic = 0.5 * INERTIA * v**2
    moving = v[1:] > 1e-12
    # Measured 7.7e-14 relative.
    np.testing.assert_allclose(-np.diff(kinetic)[moving], per_step[moving], rtol=1e-12)


def _rod_scene(friction: dict, contact_friction: float) -> Scene:
    table = {
        "robot": {
            "urdf": "rod.urdf",
            "q0": [0.0, 0.42073549230394824, 1.0],
            "v0": [0.5, 0.0, -0.5],
            "gravity": [0.0, 0.0, -9.81],
            "planar_axis": [0.0, 1.0, 0.0],
        },
        "surfaces": {"ground": {"type": "plane", "normal": [0.0, 0.0, 1.0]}},
        "contacts": [
            {"frame": "rod_end", "surface": "ground", "friction": contact_friction},
            {"frame": "rod_other_end", "surface": "ground", "friction": contact_friction},
        ],
        "joint_friction": friction,
        "integrator": {"name": "moreau_jean", "dt": 1e-3},
        "duration": 0.3,
    }
    return Scene.from_dict(table, base_dir=ROBOTS)


@pytest.mark.parametrize("contact_friction", [0.0, 0.4])
def test_rod_contact_and_joint_friction_solved_together(contact_friction: float) -> None:
    coulomb = {"x": 3.0, "pitch": 0.3}  # [N], [N m]: x stops at 0.17 s
    scene = _rod_scene({"coulomb": coulomb, "viscous": {"pitch": 0.2}}, contact_friction)
    robot, dt = scene.robot, scene.integrator.dt
    integrator = scene.build_integrator()
    model, data = robot.model, pin.Data(robot.model)
    bound = dt * scene.joint_friction.coulomb  # [N s] or [N m s]
    D = scene.joint_friction.viscous
    ends = [model.getFrameId(name) for name in ("rod_end", "rod_other_end")]
    q, v = scene.q0, scene.v0
    checked = stuck = slid = 0
    for _ in range(300):
        state = integrator.evaluate(q, v)
        outcome = integrator.step(state, np.zeros(robot.nv))
        assert outcome.solution is not None and outcome.solution.status == "solved"
        assert outcome.solution.residual <= 1e-8
        # Independent balance with Pinocchio at q_k: M (v+ - v) - h (-nle - D v_mid) minus the
        # contact impulses leaves the joint friction impulses (on x and pitch only).
        pin.computeAllTerms(model, data, q, v)
        M = np.triu(data.M) + np.triu(data.M, 1).T
        v_mid = 0.5 * (v + outcome.v)
        joint_impulse = M @ (outcome.v - v) + dt * (data.nle + D * v_mid)
        for k, frame in enumerate(ends):
            J = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
            force = np.array([0.0, 0.0, outcome.impulse[k]])
            if outcome.friction_impulse is not None:
                force = force + outcome.friction_impulse[k]
            joint_impulse -= J.T @ force
            u_n = J[2] @ outcome.v  # post-step normal velocity [m/s]
            if outcome.active[k]:  # Signorini at velocity level
                # A held contact barely open may close its gap g in the step: u_n >= -g / h.
                closure = max(float(state.gap[k]), 0.0) / dt  # [m/s]
                assert u_n >= -closure - 1e-8 and outcome.impulse[k] >= 0.0
                P_n = outcome.impulse[k]
                assert min(abs(u_n * P_n), abs((u_n + closure) * P_n)) <= 1e-9
        assert abs(joint_impulse[1]) <= 1e-9  # z has no friction
        for j in (0, 2):
            assert abs(joint_impulse[j]) <= bound[j] * (1.0 + 1e-7)
            if abs(outcome.v[j]) > 1e-9:  # sliding: the impulse opposes v+ at its bound
                assert joint_impulse[j] == pytest.approx(-bound[j] * np.sign(outcome.v[j]), 1e-6)
                slid += 1
            else:
                stuck += 1
        checked += 1
        q, v = outcome.q, outcome.v
    assert checked == 300 and slid > 0 and stuck > 0


def test_scene_table_reads_per_joint_and_scalar_values() -> None:
    scene = _rod_scene({"viscous": 0.1, "coulomb": {"pitch": 0.3}}, 0.0)
    np.testing.assert_array_equal(scene.joint_friction.viscous, [0.1, 0.1, 0.1])
    np.testing.assert_array_equal(scene.joint_friction.coulomb, [0.0, 0.0, 0.3])
    assert _rod_scene({"viscous": 0.1}, 0.0).joint_friction.coulomb_index.size == 0


@pytest.mark.parametrize(
    ("friction", "error", "text"),
    [
        ({"viscous": 0.1, "stiction": 1.0}, UnknownKeyError, "stiction"),
        ({"coulomb": {"knee": 1.0}}, NotFoundError, "knee"),
        ({"coulomb": -1.0}, InvalidParameterError, "-1"),
        ({"viscous": {"x": "0.1"}}, InvalidParameterError, "'x'"),
        ({}, SceneError, "neither"),
        (0.5, SceneError, "must be a table"),
    ],
)
def test_bad_joint_friction_tables_are_typed_errors(friction, error, text) -> None:
    with pytest.raises(error, match=text):
        _rod_scene(friction, 0.0)


@pytest.mark.parametrize("name", ["event_driven", "compliant"])
def test_other_integrators_refuse_coulomb_joint_friction(name: str) -> None:
    scene = _rod_scene({"coulomb": 0.1}, 0.0)
    import dataclasses

    from ucontrol.scene.integrator_settings import IntegratorSettings

    scene = dataclasses.replace(scene, integrator=IntegratorSettings(name=name, dt=1e-3))
    with pytest.raises(InvalidParameterError, match=name):
        scene.build_integrator()


def test_joint_friction_of_another_size_is_refused() -> None:
    robot = _one_joint("slider")
    with pytest.raises(InvalidParameterError, match="joint_friction"):
        MoreauJean(
            robot,
            ConstraintSet(robot, (), ()),
            dt=1e-3,
            joint_friction=JointFriction(viscous=[1.0, 1.0], coulomb=[0.0, 0.0]),
        )
    with pytest.raises(InvalidParameterError, match="viscous"):
        JointFriction(viscous=[-1.0], coulomb=[0.0])
