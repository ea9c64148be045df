"""Flexible joints (Spong) in Moreau–Jean: θ-implicit springs, midpoint order, scene and log."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.control import JointPD, ZeroTorque
from ucontrol.exceptions import (
    InvalidParameterError,
    JointNotFoundError,
    SceneError,
    ShapeError,
    UnknownKeyError,
)
from ucontrol.integrators import MoreauJean
from ucontrol.model import FlexibleJoints, RobotModel
from ucontrol.scene import IntegratorSettings, Scene, load_scene
from ucontrol.simulate import simulate

Q0 = np.array([0.9, -1.6])
B = 0.1  # motor inertia [kg m²]


def _arm(
    stiffness: float,
    *,
    gravity: bool = False,
    dt: float = 1e-3,
    theta: float = 0.5,
    midpoint: bool = False,
    damping: float = 0.0,
    duration: float = 2.0,
) -> Scene:
    """The two-link arm of robots/two_link.urdf with both joints flexible, no contact.

    It starts swinging (v0 = (2, -3) rad/s) with its motors 0.05 rad ahead of the links.
    """
    g = np.array([0.0, -9.81 if gravity else 0.0, 0.0])
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf", gravity=g)
    flexible = FlexibleJoints.from_robot(
        robot, ["shoulder", "elbow"], stiffness=stiffness, motor_inertia=B, damping=damping
    )
    return Scene(
        name="flexible_arm",
        robot=robot,
        q0=Q0,
        v0=np.array([2.0, -3.0]),
        flexible=flexible,
        motor_q0=Q0 + 0.05,
        integrator=IntegratorSettings(dt=dt, theta=theta, midpoint=midpoint),
        duration=duration,
    )


def _energy_error(scene: Scene) -> float:
    energy = simulate(scene).log.energy
    return float(np.max(np.abs(energy - energy[0])))


def _explicit_energy(scene: Scene, steps: int) -> np.ndarray:
    """Energy along the symplectic-Euler update of the same plant (springs explicit)."""
    flexible, model = scene.flexible, scene.robot.model
    assert flexible is not None
    data = pin.Data(model)
    q, v = scene.initial_state()
    nq, nv, h = model.nq, model.nv, scene.integrator.dt
    inertia = np.zeros((nv + 2, nv + 2))
    inertia[nv:, nv:] = np.diag(flexible.motor_inertia)
    energies = []
    for _ in range(steps):
        q1, v1, q2, v2 = q[:nq], v[:nv], q[nq:], v[nv:]
        spring = flexible.stiffness * (q1 - q2)  # on the motors
        energies.append(
            0.5 * v1 @ pin.crba(model, data, q1) @ v1
            + 0.5 * v2 @ (B * v2)
            + 0.5 * (q1 - q2) @ (flexible.stiffness * (q1 - q2))
        )
        M = pin.crba(model, data, q1)
        inertia[:nv, :nv] = np.triu(M) + np.triu(M, 1).T
        force = np.concatenate((-pin.nonLinearEffects(model, data, q1, v1) - spring, spring))
        v = v + h * np.linalg.solve(inertia, force)
        q = q + h * v
    return np.array(energies)


def test_stiff_springs_blow_up_an_explicit_update_and_not_moreau_jean() -> None:
    # K = 1e8, B = 0.1: the motor-spring frequency is 3.2e4 rad/s, so omega h = 32 >> 2.
    # The motors start 0.05 rad ahead of the links: 2.5e5 J in the springs.
    scene = _arm(1e8, gravity=True, duration=1.0)
    explicit = _explicit_energy(scene, 4)
    assert explicit[-1] > 1e12 * explicit[0]  # x 1e6 per step (measured), at once
    for theta in (0.5, 1.0):
        log = simulate(dataclasses.replace(scene, integrator=IntegratorSettings(theta=theta))).log
        assert np.all(np.isfinite(log.energy))
        assert np.max(log.energy) < 1.1 * log.energy[0]  # theta = 1/2: kept, up to 5 %
        if theta == 1.0:  # the deflection is an oscillation that theta = 1 damps away
            assert np.all(np.diff(log.energy) <= 1e-12 * log.energy[0])
            assert log.energy[-1] < 1e-3 * log.energy[0]


@pytest.mark.parametrize("theta", [0.5, 1.0])
def test_stiff_springs_add_no_energy_error_to_the_rigid_arm(theta: float) -> None:
    # K = 1e8 at h = 1e-3, motors starting at the links, gravity, no input, no contact.
    flexible = dataclasses.replace(_arm(1e8, gravity=True, theta=theta), motor_q0=Q0)
    rigid = dataclasses.replace(flexible, flexible=None, motor_q0=None, motor_v0=None)
    rise = {}
    for name, scene in (("flexible", flexible), ("rigid", rigid)):
        energy = simulate(scene).log.energy
        assert np.all(np.isfinite(energy))
        rise[name] = np.max(energy - energy[0])  # [J], of 8.0 J
    assert rise["flexible"] <= 1.5 * rise["rigid"] + 1e-9  # the links' O(h) error only
    midpoint = dataclasses.replace(
        flexible, integrator=IntegratorSettings(theta=theta, midpoint=True)
    )
    energy = simulate(midpoint).log.energy
    if theta == 1.0:  # measured: never rises
        assert np.all(np.diff(energy) <= 1e-12 * energy[0])
    else:  # second order: 8e-6 J measured
        assert np.max(energy - energy[0]) < 1e-5 * energy[0]


def test_midpoint_energy_error_is_second_order_and_default_first_order() -> None:
    # Free arm without gravity, K = 2000 (omega h = 0.14 at h = 1e-3), theta = 1/2.
    default = [_energy_error(_arm(2000.0, dt=dt)) for dt in (1e-3, 5e-4)]
    midpoint = [_energy_error(_arm(2000.0, dt=dt, midpoint=True)) for dt in (1e-3, 5e-4)]
    assert 1.7 < default[0] / default[1] < 2.3  # measured 1.99: M and Coriolis at q_k
    assert midpoint[0] / midpoint[1] > 3.5  # measured 3.98
    assert midpoint[1] < 0.5 * default[1]


def test_springs_alone_keep_their_energy_exactly_at_theta_one_half() -> None:
    # A single flexible joint on a body whose inertia does not depend on q (the shoulder of
    # the arm with the elbow locked is not available: use the vertical ball's prismatic joint).
    robot = RobotModel.from_urdf(ROBOTS / "ball.urdf", gravity=np.zeros(3))
    flexible = FlexibleJoints.from_robot(robot, robot.joint_names, stiffness=1e8, motor_inertia=B)
    scene = Scene(
        name="spring",
        robot=robot,
        q0=np.array([1.0]),
        v0=np.array([0.3]),
        flexible=flexible,
        motor_q0=np.array([1.01]),
        integrator=IntegratorSettings(dt=1e-3, theta=0.5),
        duration=1.0,
    )
    energy = simulate(scene).log.energy
    assert np.max(np.abs(energy - energy[0])) < 1e-12 * energy[0]


def test_damping_dissipates_at_its_rate() -> None:
    log = simulate(_arm(2000.0, damping=0.5, midpoint=True, dt=5e-4)).log
    assert np.all(np.diff(log.energy) < 1e-9)
    assert log.energy[-1] < 0.5 * log.energy[0]


def test_impacts_act_on_the_links_only() -> None:
    scene = load_scene(ROBOTS / "two_link_drop.toml")
    flexible = FlexibleJoints.from_robot(
        scene.robot, ["shoulder", "elbow"], stiffness=2000.0, motor_inertia=B
    )
    scene = dataclasses.replace(scene, flexible=flexible, motor_q0=None, motor_v0=None)
    result = simulate(scene, duration=1.5)
    log = result.log
    assert result.summary["n_impacts"] > 3
    assert result.summary["energy_increase_at_impacts"] == 0.0
    impact_steps = np.nonzero(log.impulse[:-1, 0] > 1e-3)[0]
    assert impact_steps.size
    # Across an impact the link velocities jump, the motors' change by the smooth spring
    # torque only (B dq2 = h K (q1 - q2) at a point of the step): at most h K |q1 - q2| / B.
    jump = np.abs(log.motor_v[impact_steps + 1] - log.motor_v[impact_steps])
    deflection = np.abs(log.q - log.motor_q)
    bound = 1e-3 * 2000.0 * np.maximum(deflection[impact_steps], deflection[impact_steps + 1]) / B
    assert np.all(jump <= 1.01 * bound + 1e-12)
    link_jump = np.abs(log.v[impact_steps + 1] - log.v[impact_steps]).max()
    assert link_jump > 10 * jump.max()


def test_log_and_summary_hold_motor_states_and_their_energy() -> None:
    scene = _arm(2000.0, gravity=True, duration=0.2)
    log = simulate(scene, ZeroTorque(2)).log
    assert log.q.shape[1] == 2 and log.motor_q.shape[1] == 2
    assert log.metadata["flexible_joints"] == ["shoulder", "elbow"]
    robot, flexible = scene.robot, scene.flexible
    assert flexible is not None
    k = 57
    kinetic, potential = robot.energy(log.q[k], log.v[k])
    expected = (
        kinetic
        + potential
        + flexible.motor_kinetic_energy(log.motor_v[k])
        + flexible.spring_energy(log.q[k], log.motor_q[k])
    )
    assert log.energy[k] == pytest.approx(expected, rel=1e-12)


def test_input_drives_the_motors() -> None:
    # A constant motor torque on a flexible shoulder, no gravity: the motor accelerates at
    # u / B before the spring has deflected.
    scene = _arm(2000.0, dt=1e-4, duration=1e-3)
    scene = dataclasses.replace(scene, v0=np.zeros(2), motor_q0=Q0, motor_v0=np.zeros(2))

    def push(t, q, v, contacts):
        return np.array([0.1, 0.0])  # [N m]

    log = simulate(scene, push).log
    assert log.motor_v[-1, 0] == pytest.approx(0.1 / B * 1e-3, rel=1e-2)
    assert abs(log.v[-1, 0]) < 1e-2 * log.motor_v[-1, 0]


def test_scene_table(tmp_path: Path) -> None:
    text = (ROBOTS / "two_link_drop.toml").read_text()
    text = text.replace('urdf = "two_link.urdf"', f'urdf = "{ROBOTS / "two_link.urdf"}"')
    table = (
        "[robot.flexible]\n"
        'joints = ["elbow"]\n'
        "stiffness = 1e4\n"
        "motor_inertia = [0.2]\n"
        "damping = 0.1\n"
        "q0 = [-1.5]\n"
    )
    path = tmp_path / "flexible.toml"
    path.write_text(text.replace("[surfaces.ground]", table + "\n[surfaces.ground]"))
    scene = load_scene(path)
    assert scene.flexible is not None
    assert scene.flexible.joints == ("elbow",)
    np.testing.assert_array_equal(scene.flexible.motor_inertia, [0.2])
    q, v = scene.initial_state()
    np.testing.assert_array_equal(q, [0.9, -1.6, -1.5])
    np.testing.assert_array_equal(v, [0.0, 0.0, 0.0])
    assert scene.flexible.input_coordinates(scene.robot.actuated).tolist() == [0, 2]
    path.write_text(text.replace("[surfaces.ground]", table + "spring = 1\n[surfaces.ground]"))
    with pytest.raises(UnknownKeyError, match="spring"):
        load_scene(path)


def test_bad_flexible_joints_raise() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf")
    with pytest.raises(JointNotFoundError, match="wrist"):
        FlexibleJoints.from_robot(robot, ["wrist"], stiffness=1.0, motor_inertia=1.0)
    with pytest.raises(InvalidParameterError, match="stiffness"):
        FlexibleJoints.from_robot(robot, ["elbow"], stiffness=0.0, motor_inertia=1.0)
    with pytest.raises(InvalidParameterError, match="motor_inertia"):
        FlexibleJoints.from_robot(robot, ["elbow"], stiffness=1.0, motor_inertia=float("nan"))
    with pytest.raises(InvalidParameterError, match="damping"):
        FlexibleJoints.from_robot(robot, ["elbow"], stiffness=1.0, motor_inertia=1.0, damping=-1)
    with pytest.raises(ShapeError, match="stiffness"):
        FlexibleJoints.from_robot(robot, ["elbow"], stiffness=[1.0, 2.0], motor_inertia=1.0)
    with pytest.raises(InvalidParameterError, match="distinct"):
        FlexibleJoints.from_robot(robot, ["elbow", "elbow"], stiffness=1.0, motor_inertia=1.0)
    free = RobotModel.from_urdf(ROBOTS / "free_ball.urdf", floating_base=True)
    with pytest.raises(InvalidParameterError, match="revolute or prismatic"):
        FlexibleJoints.from_robot(free, [free.joint_names[0]], stiffness=1.0, motor_inertia=1.0)
    scene = _arm(2000.0)
    with pytest.raises(ShapeError, match="motor_q0"):
        dataclasses.replace(scene, motor_q0=np.zeros(3))
    with pytest.raises(SceneError, match="flexible"):
        dataclasses.replace(scene, flexible=None)


def test_collocated_pd_holds_the_links_at_the_target_against_gravity() -> None:
    scene = _arm(2000.0, gravity=True, theta=1.0, duration=6.0)
    scene = dataclasses.replace(scene, v0=np.zeros(2), motor_q0=Q0, motor_v0=np.zeros(2))
    target = np.array([1.2, -1.0])
    controller = JointPD(scene.robot, q_ref=target, kp=200.0, kd=20.0, flexible=scene.flexible)
    log = simulate(scene, controller).log
    np.testing.assert_allclose(log.q[-1], target, atol=1e-6)  # Tomei: exact at rest
    g = scene.robot.gravity_torque(target)
    np.testing.assert_allclose(log.motor_q[-1], target + g / 2000.0, atol=1e-6)


def test_bad_integrator_settings_raise() -> None:
    with pytest.raises(InvalidParameterError, match="`midpoint` must be true or false, got 'yes'"):
        IntegratorSettings(midpoint="yes")  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError, match=r"`persistence_tolerance`.*-1e-06"):
        IntegratorSettings(persistence_tolerance=-1e-6)
    with pytest.raises(InvalidParameterError, match=r"`persistence_tolerance`.*'far'"):
        IntegratorSettings(persistence_tolerance="far")  # type: ignore[arg-type]
    scene = _arm(2000.0)
    with pytest.raises(InvalidParameterError, match="`persistence_tolerance`"):
        MoreauJean(scene.robot, scene.constraints, dt=1e-3, persistence_tolerance=-1.0)
    with pytest.raises(InvalidParameterError, match=r"`persistence_speed`.*nan"):
        IntegratorSettings(persistence_speed=float("nan"))
    with pytest.raises(InvalidParameterError, match=r"`persistence_speed`.*-0\.1"):
        MoreauJean(scene.robot, scene.constraints, dt=1e-3, persistence_speed=-0.1)
