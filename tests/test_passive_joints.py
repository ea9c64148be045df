"""Passive joints: the selection S of the actuated coordinates, from code and from a scene."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol import simulate
from ucontrol.campaign.overrides import apply_overrides
from ucontrol.exceptions import (
    InvalidParameterError,
    JointNotFoundError,
    SceneError,
    ShapeError,
    SimulationError,
)
from ucontrol.model import RobotModel
from ucontrol.scene import Scene

SHOULDER_TORQUE = 0.3  # [N m], a constant input that moves the arm off its rest


def _two_link_table(**robot: Any) -> dict[str, Any]:
    table = tomllib.loads((ROBOTS / "two_link_drop.toml").read_text(encoding="utf-8"))
    table["robot"].update(robot)
    table["duration"] = 0.3
    return table


def _scene(**robot: Any) -> Scene:
    return Scene.from_dict(_two_link_table(**robot), base_dir=ROBOTS)


def _constant(u: list[float]) -> Any:
    torque = np.array(u)
    return lambda t, q, v, contacts: torque


def test_the_selection_follows_the_passive_or_actuated_joints() -> None:
    arm = RobotModel.from_urdf(ROBOTS / "two_link.urdf")
    elbow_passive = arm.with_actuation(passive=["elbow"])
    assert (elbow_passive.nu, elbow_passive.passive_joints) == (1, ("elbow",))
    np.testing.assert_array_equal(elbow_passive.actuated, [0])
    np.testing.assert_array_equal(arm.with_actuation(actuated=["elbow"]).actuated, [1])
    assert arm.with_actuation(actuated=[]).nu == 0
    # A modified copy keeps its passive joints.
    np.testing.assert_array_equal(elbow_passive.with_scaled_inertia(2.0).actuated, [0])


def test_a_free_flyer_is_never_actuated() -> None:
    ball = RobotModel.from_urdf(ROBOTS / "free_ball.urdf", floating_base=True)
    root = ball.joint_names[0]
    assert ball.with_actuation(passive=[root]).nu == 0
    with pytest.raises(InvalidParameterError, match="free-flyer"):
        ball.with_actuation(actuated=[root])


def test_an_arm_with_a_passive_elbow_runs_as_the_full_arm_with_no_elbow_torque() -> None:
    # Independent reference: the fully actuated arm driven by (u, 0) must move exactly as the
    # arm whose elbow is passive driven by u (tau = S^T u).
    passive = simulate(_scene(passive=["elbow"]), _constant([SHOULDER_TORQUE]))
    full = simulate(_scene(), _constant([SHOULDER_TORQUE, 0.0]))
    assert passive.log.u.shape[1] == 1
    assert passive.log.metadata["actuated"] == [0]
    np.testing.assert_array_equal(passive.log.q, full.log.q)
    np.testing.assert_array_equal(passive.log.v, full.log.v)
    assert np.ptp(full.log.q[:, 0]) > 1e-3  # the input did something


def test_a_controller_of_the_full_input_size_is_refused() -> None:
    with pytest.raises((ShapeError, SimulationError), match=r"\(1,\)"):
        simulate(_scene(actuated=["shoulder"]), _constant([SHOULDER_TORQUE, 0.0]))


def test_a_robot_without_inputs_runs_under_the_zero_controller() -> None:
    scene = _scene(actuated=[])
    assert scene.robot.nu == 0
    assert scene.build_controller()(0.0, scene.q0, scene.v0, None).shape == (0,)
    passive = simulate(scene)
    reference = simulate(_scene())  # the zero controller on the fully actuated arm
    assert passive.log.u.shape == (len(passive.log.t), 0)
    np.testing.assert_array_equal(passive.log.q, reference.log.q)


@pytest.mark.parametrize(
    ("robot", "error", "message"),
    [
        (
            {"passive": ["knee"]},
            JointNotFoundError,
            "unknown joint 'knee'; available: elbow, shoulder",
        ),
        ({"actuated": ["shoulder", "hip"]}, JointNotFoundError, "'hip'"),
        ({"passive": ["elbow"], "actuated": ["shoulder"]}, SceneError, "not both"),
        ({"passive": "elbow"}, InvalidParameterError, "a list of joint names"),
    ],
)
def test_wrong_joint_lists_are_typed_errors(
    robot: dict[str, Any], error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=message):
        _scene(**robot)


def test_with_actuation_takes_exactly_one_list() -> None:
    arm = RobotModel.from_urdf(ROBOTS / "two_link.urdf")
    with pytest.raises(InvalidParameterError, match="exactly one"):
        arm.with_actuation()
    with pytest.raises(InvalidParameterError, match="exactly one"):
        arm.with_actuation(actuated=["elbow"], passive=["shoulder"])


def test_the_scene_format_documents_both_keys() -> None:
    text = (Path(__file__).resolve().parents[1] / "docs" / "scene_format.md").read_text()
    assert "passive" in text and "actuated" in text


def test_a_campaign_override_sets_the_passive_joints() -> None:
    table = apply_overrides(_two_link_table(), {"robot.passive": ["shoulder"]})
    robot = Scene.from_dict(table, base_dir=ROBOTS).robot
    assert robot.passive_joints == ("shoulder",)
    np.testing.assert_array_equal(robot.actuated, [1])
