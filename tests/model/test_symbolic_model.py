"""The casadi model of a robot against Pinocchio: M, h, C, g, V, frame positions and Jacobians."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from ucontrol.exceptions import FrameNotFoundError, InvalidParameterError, URDFError
from ucontrol.model import RobotModel, SymbolicModel, example_robot_data_dir, resolve_urdf
from ucontrol.model.symbolic_model import INERTIA_SIZE, inertia_parameters

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
_LWA = pin.LOCAL_WORLD_ALIGNED
#: Agreement with Pinocchio, relative to the size of the compared quantity.
TOLERANCE = 1e-12


def _two_link(rng: np.random.Generator) -> RobotModel:
    return RobotModel.from_urdf(ROBOTS / "two_link.urdf", gravity=[0.0, -9.81, 0.0])


def _panda(rng: np.random.Generator) -> RobotModel:
    try:
        example_robot_data_dir()
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")
    return RobotModel.from_urdf(
        resolve_urdf("example-robot-data:panda_description/urdf/panda.urdf", ROBOTS)
    )


def _placement(rng: np.random.Generator) -> pin.SE3:
    """A random placement: a uniformly random rotation and a translation of order 1 m."""
    quaternion = rng.standard_normal(4)
    rotation = pin.Quaternion(*(quaternion / np.linalg.norm(quaternion))).matrix()
    return pin.SE3(rotation, rng.standard_normal(3))


def _inertia(rng: np.random.Generator) -> pin.Inertia:
    """A random physical inertia: mass in [0.5, 2] kg, COM offset, positive definite I_c."""
    A = rng.standard_normal((3, 3))
    mass, lever = rng.uniform(0.5, 2.0), 0.1 * rng.standard_normal(3)
    return pin.Inertia(mass, lever, A @ A.T + 0.1 * np.eye(3))


def _every_joint_type(rng: np.random.Generator) -> RobotModel:
    """A random tree with every supported joint type, random placements and inertias."""
    model = pin.Model()
    joints = [
        pin.JointModelRX(),
        pin.JointModelRY(),
        pin.JointModelRZ(),
        pin.JointModelRevoluteUnaligned(*rng.standard_normal(3)),
        pin.JointModelPX(),
        pin.JointModelPY(),
        pin.JointModelPZ(),
        pin.JointModelPrismaticUnaligned(*rng.standard_normal(3)),
    ]
    parents = [0, 1, 2, 3, 2, 5, 1, 7]  # a tree in depth-first order: 3 branches
    for k, (joint, parent) in enumerate(zip(joints, parents, strict=True)):
        joint_id = model.addJoint(parent, joint, _placement(rng), f"joint{k}")
        model.appendBodyToJoint(joint_id, _inertia(rng), pin.SE3.Identity())
        model.addFrame(pin.Frame(f"tip{k}", joint_id, 0, _placement(rng), pin.FrameType.OP_FRAME))
    model.gravity.linear = rng.standard_normal(3)
    model.armature = rng.uniform(0.0, 0.5, model.nv)  # rotor inertias [kg m²] or [kg]
    return RobotModel(model)


ROBOTS_UNDER_TEST = {"two_link": _two_link, "panda": _panda, "every_joint_type": _every_joint_type}


def _state(robot: RobotModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    low = np.maximum(robot.model.lowerPositionLimit, -3.0)
    high = np.minimum(robot.model.upperPositionLimit, 3.0)
    return rng.uniform(low, high), rng.standard_normal(robot.nv)


def _close(actual: ca.DM | np.ndarray, expected: np.ndarray) -> None:
    actual = np.asarray(actual).reshape(expected.shape)
    scale = max(1.0, float(np.max(np.abs(expected))))
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=TOLERANCE * scale)


@pytest.mark.parametrize("name", list(ROBOTS_UNDER_TEST))
def test_dynamics_match_pinocchio(name: str, rng: np.random.Generator) -> None:
    robot = ROBOTS_UNDER_TEST[name](rng)
    model, data = robot.model, robot.data
    symbolic = SymbolicModel(robot)
    for _ in range(5):
        q, v = _state(robot, rng)
        _close(symbolic.mass_matrix(q), robot.mass_matrix(q))
        _close(symbolic.gravity(q), pin.computeGeneralizedGravity(model, data, q))
        _close(symbolic.nonlinear_effects(q, v), robot.nonlinear_effects(q, v))
        _close(symbolic.potential_energy(q), np.array(pin.computePotentialEnergy(model, data, q)))
        C = np.asarray(symbolic.coriolis_matrix(q, v))
        _close(C @ v + np.asarray(symbolic.gravity(q)).ravel(), robot.nonlinear_effects(q, v))
        # Both are the Christoffel matrix C_kj = Σ_i Γ_ijk v_i.
        _close(C, pin.computeCoriolisMatrix(model, data, q, v))


@pytest.mark.parametrize("name", list(ROBOTS_UNDER_TEST))
def test_inertias_as_an_input_give_pinocchio_on_other_inertias(
    name: str, rng: np.random.Generator
) -> None:
    """One set of Functions with ``inertia`` an input: any bodies' inertias, Pinocchio's terms."""
    robot = ROBOTS_UNDER_TEST[name](rng)
    symbolic = SymbolicModel(robot, inertia_input=True)
    for _ in range(3):
        other = pin.Model(robot.model)
        for joint in range(1, other.njoints):  # new random bodies, the same kinematic tree
            other.inertias[joint] = _inertia(rng)
        data = other.createData()
        x = inertia_parameters(other)
        assert x.shape == (INERTIA_SIZE * (other.njoints - 1),)
        q, v = _state(robot, rng)
        _close(symbolic.mass_matrix(q, x), pin.crba(other, data, q))
        _close(symbolic.nonlinear_effects(q, v, x), pin.nonLinearEffects(other, data, q, v))
        _close(symbolic.gravity(q, x), pin.computeGeneralizedGravity(other, data, q))
        _close(symbolic.coriolis_matrix(q, v, x), pin.computeCoriolisMatrix(other, data, q, v))
        potential = pin.computePotentialEnergy(other, data, q)
        _close(symbolic.potential_energy(q, x), np.array(potential))


@pytest.mark.parametrize("name", list(ROBOTS_UNDER_TEST))
def test_mass_matrix_rate_minus_twice_coriolis_is_skew_symmetric(
    name: str, rng: np.random.Generator
) -> None:
    robot = ROBOTS_UNDER_TEST[name](rng)
    symbolic = SymbolicModel(robot)
    q, v = _state(robot, rng)
    h = 1e-6
    M_dot = (
        robot.mass_matrix(pin.integrate(robot.model, q, h * v))
        - robot.mass_matrix(pin.integrate(robot.model, q, -h * v))
    ) / (2 * h)  # central difference of Pinocchio's M along v
    N = M_dot - 2.0 * np.asarray(symbolic.coriolis_matrix(q, v))
    scale = float(np.max(np.abs(M_dot)))
    np.testing.assert_allclose(N + N.T, 0.0, atol=1e-8 * scale)


@pytest.mark.parametrize("name", list(ROBOTS_UNDER_TEST))
def test_frame_positions_and_jacobians_match_pinocchio(name: str, rng: np.random.Generator) -> None:
    robot = ROBOTS_UNDER_TEST[name](rng)
    symbolic = SymbolicModel(robot)
    q_sym = ca.SX.sym("q", robot.nv)
    frames = [frame.name for frame in robot.model.frames][1:]
    for frame in frames:
        position = symbolic.frame_position(frame)
        jacobian = ca.Function("J", [q_sym], [ca.jacobian(position(q_sym), q_sym)])
        q, _ = _state(robot, rng)
        _close(position(q), robot.frame_position(q, frame))
        _close(jacobian(q), robot.frame_jacobian(q, frame)[:3])


def test_unsupported_joint_is_named() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf", floating_base=True)
    with pytest.raises(InvalidParameterError, match=r"`joint 'root_joint'` must be one of") as info:
        SymbolicModel(robot)
    assert info.value.value == "JointModelFreeFlyer"


def test_missing_frame_lists_the_frames() -> None:
    symbolic = SymbolicModel(_two_link(np.random.default_rng(0)))
    with pytest.raises(FrameNotFoundError, match="unknown frame 'tool'") as info:
        symbolic.frame_position("tool")
    assert "end_effector" in info.value.available
