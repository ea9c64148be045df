"""Assembling closed chains from rough guesses, against the closed-form closures.

The four-bar of ``robots/four_bar.urdf`` (crank a = 0.1 m on A = (0, 0), coupler b = 0.35 m,
rocker c = 0.3 m on D = (0.35, 0)) with its crank held: the coupler's end is the intersection
of the circles of radius b about the crank's tip and c about D. The slider-crank of
``robots/slider_crank.urdf`` (crank 0.1 m, rod 0.3 m) with crank and slider height held: the
slider sits at x = a cos θ + sqrt(l² - (a sin θ - y)²).
"""

from __future__ import annotations

import math
import tomllib
from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.contact import BilateralSet, FrameClosure
from ucontrol.contact.assembly import assemble
from ucontrol.exceptions import AssemblyError, InvalidParameterError, JointNotFoundError
from ucontrol.model.robot_model import RobotModel
from ucontrol.scene import Scene

TOLERANCE = 1e-12  # [m], the closure asked for
A, B, C, D = 0.1, 0.35, 0.3, 0.35  # four-bar: crank, coupler, rocker, ground [m]
ROD = 0.3  # slider-crank rod [m]


def _four_bar_closure(theta: float) -> np.ndarray:
    """(crank, coupler relative to crank, rocker) closing the four-bar, the elbow-up branch."""
    tip = A * np.array([math.cos(theta), math.sin(theta)])
    pivot = np.array([D, 0.0])
    span = pivot - tip
    distance = float(np.linalg.norm(span))
    along = (B**2 - C**2 + distance**2) / (2.0 * distance)  # from the tip, towards D
    across = math.sqrt(B**2 - along**2)
    normal = np.array([-span[1], span[0]]) / distance
    joint = tip + along * span / distance + across * normal  # above the line tip-D
    coupler = math.atan2(*(joint - tip)[::-1])
    rocker = math.atan2(*(joint - pivot)[::-1])
    return np.array([theta, coupler - theta, rocker])


def _table(name: str) -> dict[str, Any]:
    with (ROBOTS / f"{name}.toml").open("rb") as file:
        return tomllib.load(file)


def _four_bar() -> tuple[RobotModel, list[FrameClosure]]:
    robot = RobotModel.from_urdf(ROBOTS / "four_bar.urdf")
    return robot, [FrameClosure(frame="coupler_end", other_frame="rocker_end")]


@pytest.mark.parametrize("theta", [0.0, 1.0, 2.5, -2.0])
def test_the_four_bar_assembles_from_a_rough_guess_with_its_crank_held(theta: float) -> None:
    robot, closure = _four_bar()
    expected = _four_bar_closure(theta)
    guess = expected + np.array([0.0, 0.3, -0.25])  # 17° and 14° off
    q = assemble(robot, closure, guess, fixed=["crank_joint"])
    assert q[0] == theta  # held: not moved by a single bit
    assert np.max(np.abs(BilateralSet(robot, closure).residuals(q))) <= TOLERANCE
    np.testing.assert_allclose(q, expected, rtol=0.0, atol=1e-11)


def test_the_four_bar_assembles_with_every_coordinate_free() -> None:
    robot, closure = _four_bar()
    guess = np.array([1.0, -0.2, 1.5])
    q = assemble(robot, closure, guess, tolerance=1e-13)
    assert np.max(np.abs(BilateralSet(robot, closure).residuals(q))) <= 1e-13
    np.testing.assert_allclose(q, _four_bar_closure(q[0]), rtol=0.0, atol=1e-11)
    assert np.linalg.norm(q - guess) < 0.2  # a closure near the guess


def test_the_slider_crank_assembles_with_crank_and_height_held() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "slider_crank.urdf")
    closure = [FrameClosure(frame="rod_end", other_frame="slider")]
    theta, height = 1.0, 0.02  # [rad], [m]
    q = assemble(robot, closure, [theta, -1.0, 0.2, height], fixed=["crank_joint", "slider_y"])
    assert q[0] == theta and q[3] == height
    rise = height - A * math.sin(theta)
    expected_x = A * math.cos(theta) + math.sqrt(ROD**2 - rise**2)
    assert abs(q[2] - expected_x) <= 1e-12
    assert abs(math.sin(theta + q[1]) * ROD - rise) <= 1e-12
    assert np.max(np.abs(BilateralSet(robot, closure).residuals(q))) <= TOLERANCE


def test_an_impossible_closure_raises_with_its_residual() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "slider_crank.urdf")
    closure = [FrameClosure(frame="rod_end", other_frame="slider")]
    theta, height = 1.0, 1.0  # the slider 1 m up: out of the rod's reach
    with pytest.raises(AssemblyError, match="rod_end=slider\\[1\\]") as raised:
        assemble(robot, closure, [theta, -1.0, 0.2, height], fixed=["crank_joint", "slider_y"])
    # The nearest the rod's end gets: straight up from the crank's tip.
    gap = height - A * math.sin(theta) - ROD
    assert abs(raised.value.residual - gap) <= 1e-9
    assert raised.value.constraint == "rod_end=slider[1]"
    assert raised.value.configuration[0] == theta


def test_too_few_iterations_and_bad_arguments_raise() -> None:
    robot, closure = _four_bar()
    with pytest.raises(AssemblyError, match="max_iter = 1") as raised:
        assemble(robot, closure, [1.0, 0.0, 1.0], fixed=["crank_joint"], max_iter=1)
    assert raised.value.iterations == 1 and raised.value.residual > TOLERANCE
    with pytest.raises(JointNotFoundError):
        assemble(robot, closure, [1.0, 0.0, 1.0], fixed=["crank"])
    with pytest.raises(InvalidParameterError, match="q0"):
        assemble(robot, closure, [1.0, 0.0], name="q0")


def test_a_scene_assembles_its_rough_q0() -> None:
    table = _table("four_bar")
    table["robot"]["q0"] = [1.0, -0.3, 1.6]
    with pytest.raises(InvalidParameterError, match="bilateral constraint"):
        Scene.from_dict(table, base_dir=ROBOTS)  # as written: off the closure
    table["robot"]["assemble"] = ["crank_joint"]
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    assert scene.q0[0] == 1.0
    np.testing.assert_allclose(scene.q0, _four_bar_closure(1.0), rtol=0.0, atol=1e-11)
    shipped = Scene.from_dict(_table("four_bar"), base_dir=ROBOTS)
    np.testing.assert_allclose(scene.q0, shipped.q0, rtol=0.0, atol=1e-11)
    table["robot"]["assemble"] = True
    moved = Scene.from_dict(table, base_dir=ROBOTS)
    assert np.max(np.abs(moved.constraints.bilateral.residuals(moved.q0))) <= TOLERANCE
    table["robot"]["assemble"] = False
    with pytest.raises(InvalidParameterError, match="bilateral constraint"):
        Scene.from_dict(table, base_dir=ROBOTS)


def test_a_scene_with_a_bad_assemble_key_or_an_impossible_q0_raises() -> None:
    table = _table("slider_crank")
    table["robot"]["assemble"] = "crank_joint"
    with pytest.raises(InvalidParameterError, match="assemble"):
        Scene.from_dict(table, base_dir=ROBOTS)
    table["robot"]["assemble"] = ["crank_joint", "slider_y"]
    table["robot"]["q0"] = [1.0, -1.0, 0.3, 1.0]
    with pytest.raises(AssemblyError, match="`q0` cannot be assembled"):
        Scene.from_dict(table, base_dir=ROBOTS)
    table["robot"]["q0"] = [1.0, -1.2, 0.3, 0.0]
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    shipped = Scene.from_dict(_table("slider_crank"), base_dir=ROBOTS)
    np.testing.assert_allclose(scene.q0, shipped.q0, rtol=0.0, atol=1e-12)
