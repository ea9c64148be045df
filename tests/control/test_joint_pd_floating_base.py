"""JointPD on a free-flyer base: the Solo-12 quadruped standing on four feet."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.control import ContactState, JointPD
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


@pytest.fixture(scope="module")
def quadruped() -> Scene:
    return Scene.from_toml(ROBOTS / "quadruped_stand.toml")


def test_torque_reads_the_joint_coordinates_after_the_base(quadruped):
    """The torque is Kp (q_ref - q) - Kd v + g(q) on the joints, after the 7 + 6 of the base."""
    robot = quadruped.robot
    rng = np.random.default_rng(0)
    controller = JointPD(robot, q_ref=quadruped.q0, kp=20.0, kd=0.5)
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    v = rng.standard_normal(robot.nv)
    contacts = ContactState([], np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, bool), 1e-3)
    gravity = pin.computeGeneralizedGravity(robot.model, pin.Data(robot.model), q)
    expected = 20.0 * (quadruped.q0[7:] - q[7:]) - 0.5 * v[6:] + gravity[6:]
    np.testing.assert_allclose(controller(0.0, q, v, contacts), expected, rtol=0, atol=1e-12)


def test_quadruped_stands_on_four_feet(quadruped):
    """The feet carry the weight m g (Newton on the whole robot at rest) and the posture holds."""
    result = simulate(quadruped, duration=1.0, progress=False)
    log = result.log
    mass = sum(inertia.mass for inertia in quadruped.robot.model.inertias)  # [kg]
    late = slice(len(log) // 2, len(log) - 1)
    normal_force = log.impulse[late].sum(axis=1) / log.metadata["dt"]  # [N]
    assert np.mean(normal_force) == pytest.approx(mass * 9.81, rel=1e-3)
    assert np.all(log.impulse[late] > 0.0)  # every foot in contact
    assert np.max(np.abs(log.v[-1])) < 1e-3  # at rest
    assert np.max(np.abs(log.q[-1, 7:] - quadruped.q0[7:])) < 0.05  # the PD's static error
    assert result.summary["max_penetration"] < 1e-4  # velocity-level scheme: O(h) drift


def test_joint_with_two_coordinates_is_refused():
    model = pin.Model()
    model.addJoint(0, pin.JointModelRUBZ(), pin.SE3.Identity(), "wheel")  # nq = 2, nv = 1
    model.appendBodyToJoint(1, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    with pytest.raises(InvalidParameterError, match="one configuration coordinate"):
        JointPD(RobotModel(model), q_ref=np.array([1.0, 0.0]), kp=1.0, kd=1.0)
