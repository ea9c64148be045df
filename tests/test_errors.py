"""Every bad input gets a typed error from ucontrol.exceptions that names the value."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene

from ucontrol import exceptions
from ucontrol.contact import JointStop, Plane, PointContact
from ucontrol.exceptions import (
    FrameNotFoundError,
    InitialPenetrationError,
    InvalidParameterError,
    JointNotFoundError,
    NonFiniteValueError,
    NotFoundError,
    SceneError,
    ShapeError,
    UnknownKeyError,
    URDFError,
)
from ucontrol.integrators import MoreauJean
from ucontrol.model import RobotModel
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

BALL_TOML = (ROBOTS / "ball.toml").read_text()


def _scene_from_text(tmp_path: Path, text: str) -> Scene:
    path = tmp_path / "scene.toml"
    path.write_text(text)
    for urdf in ("ball.urdf", "two_link.urdf"):
        (tmp_path / urdf).write_text((ROBOTS / urdf).read_text())
    return load_scene(path)


def test_unknown_frame_lists_existing_frames() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf")
    with pytest.raises(FrameNotFoundError) as info:
        robot.frame_id("tool0")
    assert info.value.name == "tool0"
    assert "end_effector" in info.value.available
    assert "tool0" in str(info.value) and "end_effector" in str(info.value)


def test_unknown_frame_in_a_scene(tmp_path: Path) -> None:
    with pytest.raises(FrameNotFoundError, match=r"'hand'.*ball"):
        _scene_from_text(tmp_path, BALL_TOML.replace('frame = "ball"', 'frame = "hand"'))


def test_unknown_joint_in_a_stop() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf")
    from ucontrol.contact import ConstraintSet

    with pytest.raises(JointNotFoundError, match=r"wrist.*elbow"):
        ConstraintSet(robot, stops=[JointStop(joint="wrist", lower=0.0)])


def test_missing_urdf(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match=r"does not exist") as info:
        RobotModel.from_urdf(tmp_path / "nothing.urdf")
    assert info.value.path.endswith("nothing.urdf")


def test_malformed_urdf(tmp_path: Path) -> None:
    path = tmp_path / "broken.urdf"
    path.write_text('<robot name="x"><link name="a"></robot>')
    with pytest.raises(URDFError, match=r"broken.urdf"):
        RobotModel.from_urdf(path)


@pytest.mark.parametrize("restitution", [-0.1, 1.5, math.nan])
def test_restitution_outside_unit_interval(restitution: float) -> None:
    with pytest.raises(InvalidParameterError, match=r"restitution") as info:
        PointContact(frame="ball", surface=Plane(), restitution=restitution)
    assert info.value.name == "restitution"
    with pytest.raises(InvalidParameterError, match=r"restitution"):
        JointStop(joint="elbow", lower=0.0, restitution=restitution)


def test_restitution_outside_unit_interval_in_a_scene(tmp_path: Path) -> None:
    with pytest.raises(InvalidParameterError, match=r"`restitution` must be in \[0, 1\], got 1.2"):
        _scene_from_text(tmp_path, BALL_TOML.replace("restitution = 0.9", "restitution = 1.2"))


@pytest.mark.parametrize("dt", [0.0, -1e-3, math.inf])
def test_non_positive_time_step(dt: float) -> None:
    scene = ball_scene(0.9)
    with pytest.raises(InvalidParameterError, match=r"`dt`"):
        simulate(scene, dt=dt)
    with pytest.raises(InvalidParameterError, match=r"`dt`"):
        MoreauJean(scene.robot, scene.constraints, dt=dt)


def test_non_positive_time_step_in_a_scene(tmp_path: Path) -> None:
    with pytest.raises(InvalidParameterError, match=r"`dt` must be > 0, got 0"):
        _scene_from_text(tmp_path, BALL_TOML.replace("dt = 1e-3", "dt = 0"))


def test_q0_of_the_wrong_size(tmp_path: Path) -> None:
    with pytest.raises(ShapeError, match=r"`q0` must have shape \(1,\), got \(2,\)"):
        _scene_from_text(tmp_path, BALL_TOML.replace("q0 = [1.1]", "q0 = [1.1, 0.0]"))
    with pytest.raises(ShapeError, match=r"`v0`"):
        dataclasses.replace(ball_scene(0.9), v0=np.zeros(3))


def test_nan_in_the_state() -> None:
    with pytest.raises(NonFiniteValueError, match=r"`q0` must be finite") as info:
        dataclasses.replace(ball_scene(0.9), q0=np.array([np.nan]))
    assert info.value.indices == [0]
    with pytest.raises(NonFiniteValueError, match=r"`v0`"):
        dataclasses.replace(ball_scene(0.9), v0=np.array([np.inf]))


def test_initial_penetration_is_an_error() -> None:
    scene = dataclasses.replace(ball_scene(0.9), q0=np.array([0.05]))
    with pytest.raises(InitialPenetrationError, match=r"ball/ground") as info:
        simulate(scene)
    assert info.value.gap == pytest.approx(-0.05)


def test_unknown_toml_key_is_named(tmp_path: Path) -> None:
    with pytest.raises(UnknownKeyError, match=r"'restitutoin'.*contacts") as info:
        _scene_from_text(tmp_path, BALL_TOML.replace("restitution = 0.9", "restitutoin = 0.9"))
    assert info.value.keys == ["restitutoin"]
    with pytest.raises(UnknownKeyError, match=r"'colour'"):
        _scene_from_text(tmp_path, 'colour = "red"\n' + BALL_TOML)
    with pytest.raises(UnknownKeyError, match=r"\[integrator\]"):
        _scene_from_text(tmp_path, BALL_TOML.replace("theta = 0.5", "theta = 0.5\nstep = 1"))


def test_scene_file_errors(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match=r"does not exist"):
        load_scene(tmp_path / "missing.toml")
    with pytest.raises(SceneError, match=r"not valid TOML"):
        _scene_from_text(tmp_path, "duration = = 3")
    with pytest.raises(SceneError, match=r"'robot'"):
        _scene_from_text(tmp_path, "duration = 3")


def test_unknown_names_list_the_known_ones(tmp_path: Path) -> None:
    with pytest.raises(NotFoundError, match=r"integrator 'rk4'.*moreau_jean"):
        _scene_from_text(tmp_path, BALL_TOML.replace('name = "moreau_jean"', 'name = "rk4"'))
    with pytest.raises(NotFoundError, match=r"surface 'table'.*ground"):
        _scene_from_text(tmp_path, BALL_TOML.replace('surface = "ground"', 'surface = "table"'))
    with pytest.raises(NotFoundError, match=r"controller type 'mpc'"):  # when the file is read
        _scene_from_text(tmp_path, BALL_TOML + '\n[controller]\ntype = "mpc"\n')


def test_bad_geometry_parameters() -> None:
    with pytest.raises(InvalidParameterError, match=r"`normal` must be a non-zero vector"):
        Plane(normal=[0.0, 0.0, 0.0])
    with pytest.raises(ShapeError, match=r"`point`"):
        Plane(point=[0.0, 0.0])
    with pytest.raises(InvalidParameterError, match=r"`radius` must be >= 0"):
        PointContact(frame="ball", surface=Plane(), radius=-0.1)
    with pytest.raises(InvalidParameterError, match=r"`upper`"):
        JointStop(joint="elbow", lower=1.0, upper=0.0)
    with pytest.raises(InvalidParameterError, match=r"at least one bound"):
        JointStop(joint="elbow")


def test_stop_on_a_multi_dof_joint_is_rejected() -> None:
    from ucontrol.contact import ConstraintSet

    robot = RobotModel.from_urdf(ROBOTS / "free_ball.urdf", floating_base=True)
    with pytest.raises(InvalidParameterError, match=r"nq = nv = 1"):
        ConstraintSet(robot, stops=[JointStop(joint="root_joint", lower=0.0)])


def test_theta_outside_its_range() -> None:
    scene = ball_scene(0.9)
    with pytest.raises(InvalidParameterError, match=r"`theta` must be in \[0.5, 1\]"):
        MoreauJean(scene.robot, scene.constraints, dt=1e-3, theta=0.3)


@pytest.mark.parametrize(
    ("error", "builtin"),
    [
        (NotFoundError("frame", "toe", ["foot", "hand"]), KeyError),
        (exceptions.UserFunctionError("m:f", "no module m"), LookupError),
        (exceptions.ParameterKeyError("contacts.0.mu", "no such key"), KeyError),
        (exceptions.UnknownMetricError("gap", "not in summary.json", ["steps"]), KeyError),
        (exceptions.OutputDirectoryError("/out", "read-only"), OSError),
        (exceptions.SchedulerUnreachableError("tcp://x:1", "refused"), ConnectionError),
    ],
)
def test_errors_read_as_their_message_whatever_builtin_they_extend(error, builtin) -> None:
    """One message text for every error, not KeyError's repr of it (quotes, escapes)."""
    assert isinstance(error, builtin)
    assert str(error) == error.args[0]
    assert not str(error).startswith(("'", '"'))
