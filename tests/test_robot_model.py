"""Robot model and constraint kinematics against finite differences on the manifold."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.contact import ConstraintSet, JointStop, Plane, PointContact
from ucontrol.model import RobotModel

FD_STEP = 1e-7


def _free_ball() -> RobotModel:
    return RobotModel.from_urdf(ROBOTS / "free_ball.urdf", floating_base=True)


def _two_link() -> RobotModel:
    return RobotModel.from_urdf(ROBOTS / "two_link.urdf", gravity=np.array([0.0, -9.81, 0.0]))


def test_dimensions_with_and_without_free_flyer() -> None:
    arm, ball = _two_link(), _free_ball()
    assert (arm.nq, arm.nv, arm.nu) == (2, 2, 2)
    assert (ball.nq, ball.nv, ball.nu) == (7, 6, 0)
    np.testing.assert_array_equal(arm.actuated, [0, 1])
    np.testing.assert_allclose(arm.gravity, [0.0, -9.81, 0.0])


def test_two_link_mass_matrix_matches_the_textbook_formula() -> None:
    # Planar arm, l = 0.5, lc = 0.25, m = 1, I = 1 about the centre of mass (Spong's formulas).
    arm = _two_link()
    m, l1, lc, inertia = 1.0, 0.5, 0.25, 1.0
    for q2 in (-0.3, -1.6, -2.9):
        M = arm.mass_matrix(np.array([0.4, q2]))
        d11 = m * lc**2 + m * (l1**2 + lc**2 + 2 * l1 * lc * np.cos(q2)) + 2 * inertia
        d12 = m * (lc**2 + l1 * lc * np.cos(q2)) + inertia
        d22 = m * lc**2 + inertia
        np.testing.assert_allclose(M, [[d11, d12], [d12, d22]], rtol=1e-12)


def test_gravity_torque_is_the_gradient_of_the_potential_energy() -> None:
    arm = _two_link()
    q = np.array([0.7, -1.1])
    gradient = [
        (arm.energy(q + FD_STEP * e, np.zeros(2))[1] - arm.energy(q - FD_STEP * e, np.zeros(2))[1])
        / (2 * FD_STEP)
        for e in np.eye(2)
    ]
    np.testing.assert_allclose(arm.gravity_torque(q), gradient, atol=1e-6)
    np.testing.assert_allclose(arm.nonlinear_effects(q, np.zeros(2)), arm.gravity_torque(q))


@pytest.mark.parametrize("robot_factory", [_two_link, _free_ball])
def test_frame_jacobian_against_finite_differences_on_the_manifold(robot_factory) -> None:
    robot = robot_factory()
    frame = "end_effector" if robot.nq == 2 else "ball"
    rng = np.random.default_rng(3)
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    J = robot.frame_jacobian(q, frame)[:3]
    for direction in rng.standard_normal((3, robot.nv)):
        plus = robot.frame_position(robot.integrate(q, FD_STEP * direction), frame)
        minus = robot.frame_position(robot.integrate(q, -FD_STEP * direction), frame)
        np.testing.assert_allclose((plus - minus) / (2 * FD_STEP), J @ direction, atol=1e-6)


@pytest.mark.parametrize("robot_factory", [_two_link, _free_ball])
def test_constraint_gaps_velocities_and_jacobians_agree(robot_factory) -> None:
    robot = robot_factory()
    frame = "end_effector" if robot.nq == 2 else "ball"
    tilted = Plane(point=[0.1, -0.2, 0.05], normal=[0.3, 1.0, 0.5], name="tilted")
    contacts = [PointContact(frame=frame, surface=tilted, radius=0.05)]
    stops = [JointStop(joint="elbow", lower=-3.0, upper=-0.1)] if robot.nq == 2 else []
    constraints = ConstraintSet(robot, contacts, stops)
    rng = np.random.default_rng(5)
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    v = rng.standard_normal(robot.nv)
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    gap, velocity = constraints.evaluate(data, q, v)
    J = constraints.jacobian(data, range(constraints.size))
    np.testing.assert_allclose(gap, constraints.gaps(q), atol=1e-14)
    np.testing.assert_allclose(velocity, J @ v, atol=1e-12)
    p = robot.frame_position(q, frame)
    assert gap[0] == pytest.approx(tilted.normal @ (p - tilted.point) - 0.05)
    for direction in rng.standard_normal((3, robot.nv)):
        plus = constraints.gaps(robot.integrate(q, FD_STEP * direction))
        minus = constraints.gaps(robot.integrate(q, -FD_STEP * direction))
        np.testing.assert_allclose((plus - minus) / (2 * FD_STEP), J @ direction, atol=1e-6)


def test_frame_path_is_the_tip_of_the_two_link_arm() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf")
    q = np.array([[0.9, -1.6], [0.0, 0.0], [1.5, -0.9]])
    expected = np.stack(  # l1 = l2 = 0.5 m, joints about z
        [
            0.5 * np.cos(q[:, 0]) + 0.5 * np.cos(q[:, 0] + q[:, 1]),
            0.5 * np.sin(q[:, 0]) + 0.5 * np.sin(q[:, 0] + q[:, 1]),
            np.zeros(3),
        ],
        axis=1,
    )
    np.testing.assert_allclose(robot.frame_path(q, "end_effector"), expected, atol=1e-14)


_SAME_NAME_URDF = """<robot name="same">
  <link name="base"/>
  <link name="arm">
    <inertial><origin xyz="0.5 0 0"/><mass value="1"/>
      <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="arm" type="revolute">
    <origin xyz="0 0 1"/><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/>
  </joint>
</robot>
"""


def test_a_joint_named_as_its_link_gives_the_link_frame(tmp_path) -> None:
    """Pinocchio refuses to choose between the joint's and the link's frame: the link's is taken."""
    import pinocchio as pin

    from ucontrol.model.robot_model import RobotModel

    path = tmp_path / "same.urdf"
    path.write_text(_SAME_NAME_URDF)
    robot = RobotModel.from_urdf(path)
    with pytest.raises(ValueError, match="Several frames"):
        robot.model.getFrameId("arm")  # the leak this guards against
    frame = robot.model.frames[robot.frame_id("arm")]
    assert frame.name == "arm" and frame.type == pin.FrameType.BODY
