"""Link masses and inertias overridden in a scene, against URDFs written with the same values.

The reference is Pinocchio's URDF parser on a generated URDF: an override must give the same
M(q) and h(q, v) as the URDF that declares the new values, to round-off.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.campaign import ParameterKeyError, apply_overrides, load_campaign
from ucontrol.campaign.overrides import scene_with_overrides
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidInertiaError,
    InvalidParameterError,
    SceneError,
    ShapeError,
    UnknownKeyError,
)
from ucontrol.model.link_inertia import LinkInertia, with_link_inertias
from ucontrol.model.robot_model import RobotModel
from ucontrol.scene import Scene

TOLERANCE = 1e-12  # relative, on M(q) and h(q, v)
RNG_SEED = 27


def _table(name: str) -> dict[str, Any]:
    with (ROBOTS / f"{name}.toml").open("rb") as file:
        return tomllib.load(file)


def _generated(tmp_path: Path, name: str, replacements: dict[str, str]) -> Path:
    """robots/<name>.urdf with text replaced, written beside the test."""
    text = (ROBOTS / f"{name}.urdf").read_text()
    for old, new in replacements.items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / f"{name}_generated.urdf"
    path.write_text(text)
    return path


def _assert_same_dynamics(robot: RobotModel, reference: RobotModel, samples: int = 5) -> None:
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(samples):
        q = rng.uniform(-1.0, 1.0, robot.nq)
        v = rng.uniform(-2.0, 2.0, robot.nv)
        for got, expected in (
            (robot.mass_matrix(q), reference.mass_matrix(q)),
            (robot.nonlinear_effects(q, v), reference.nonlinear_effects(q, v)),
        ):
            scale = float(np.max(np.abs(expected)))
            np.testing.assert_allclose(got, expected, rtol=0.0, atol=TOLERANCE * scale)


def test_the_mass_ratio_of_a_generated_urdf_is_reproduced_by_set_overrides(
    tmp_path: Path,
) -> None:
    block, bead = 10.0, 0.5  # [kg]: a ratio of 20 instead of 1e6
    urdf = _generated(
        tmp_path,
        "mass_ratio",
        {
            '<mass value="1000.0"/>': f'<mass value="{block}"/>',
            '<inertia ixx="10.0" ixy="0" ixz="0" iyy="10.0" iyz="0" izz="10.0"/>': (
                '<inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.25"/>'
            ),
            '<mass value="0.001"/>': f'<mass value="{bead}"/>',
        },
    )
    table = _table("mass_ratio")
    table["robot"]["urdf"] = str(urdf)
    reference = Scene.from_dict(table, base_dir=ROBOTS)
    scene = scene_with_overrides(
        ROBOTS / "mass_ratio.toml",
        [
            f"robot.links.block.mass={block}",
            "robot.links.block.inertia=[0.1, 0.2, 0.25, 0.0, 0.0, 0.0]",
            f"robot.links.bead.mass={bead}",
        ],
    )
    _assert_same_dynamics(scene.robot, reference.robot)
    M = scene.robot.mass_matrix(scene.q0)
    np.testing.assert_allclose(M, [[block + bead, bead], [bead, bead]], rtol=1e-15)
    unchanged = Scene.from_dict(_table("mass_ratio"), base_dir=ROBOTS)
    assert unchanged.robot.mass_matrix(scene.q0)[0, 0] == pytest.approx(1000.001, rel=1e-15)


def test_a_centre_of_mass_and_a_full_inertia_match_the_urdf(tmp_path: Path) -> None:
    com, inertia = [0.2, 0.03, -0.01], [0.02, 0.015, 0.03, 0.002, -0.001, 0.0015]
    ixx, iyy, izz, ixy, ixz, iyz = inertia
    urdf = _generated(
        tmp_path,
        "four_bar",
        {
            '<origin xyz="0.175 0 0"/>\n      <mass value="1.0"/>\n      <inertia '
            'ixx="0.010208333333333331" ixy="0" ixz="0" iyy="0.010208333333333331" iyz="0" '
            'izz="0.010208333333333331"/>': (
                f'<origin xyz="{com[0]} {com[1]} {com[2]}"/>\n      <mass value="2.5"/>\n'
                f'      <inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" '
                f'izz="{izz}"/>'
            )
        },
    )
    robot = RobotModel.from_urdf(ROBOTS / "four_bar.urdf")
    overridden = with_link_inertias(
        robot, [LinkInertia(link="coupler", mass=2.5, com=com, inertia=inertia)]
    )
    _assert_same_dynamics(overridden, RobotModel.from_urdf(urdf))
    assert robot.model.inertias[2].mass == 1.0  # the robot given is left as it was


def test_a_welded_link_overrides_its_body_in_its_own_frame() -> None:
    # rod_end is welded 0.3 m along the rod: the rod's own values, written from rod_end's
    # frame (centre of mass 0.15 m back), give the robot as loaded.
    robot = RobotModel.from_urdf(ROBOTS / "slider_crank.urdf")
    rod = LinkInertia(
        link="rod_end", mass=1.0, com=[-0.15, 0.0, 0.0], inertia=[0.0075] * 3 + [0] * 3
    )
    _assert_same_dynamics(with_link_inertias(robot, [rod]), robot)
    heavier = with_link_inertias(robot, [LinkInertia(link="rod_end", mass=3.0)])
    assert heavier.model.inertias[2].mass == pytest.approx(3.0, rel=1e-15)
    np.testing.assert_allclose(heavier.model.inertias[2].lever, [0.15, 0.0, 0.0], atol=1e-15)


def test_a_scale_multiplies_mass_and_inertia() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "four_bar.urdf")
    scaled = with_link_inertias(robot, [LinkInertia(link="rocker", scale=3.0)])
    original, new = robot.model.inertias[3], scaled.model.inertias[3]
    assert new.mass == pytest.approx(3.0 * original.mass, rel=1e-15)
    np.testing.assert_allclose(new.lever, original.lever, rtol=1e-15)
    np.testing.assert_allclose(new.inertia, 3.0 * original.inertia, rtol=1e-14)


def test_a_campaign_sweeps_a_link_mass(write_campaign: Any) -> None:
    sweep = '[campaign]\nscene = "ball.toml"\n[grid]\n"robot.links.ball.mass" = {}\n'
    campaign = load_campaign(write_campaign(sweep.format("[2.0, 3.5]")))
    masses = []
    for run in campaign.plan():
        table = apply_overrides(campaign.scene_table, run.parameters)
        scene = Scene.from_dict(table, base_dir=campaign.scene_base_dir())
        masses.append(float(scene.robot.mass_matrix(scene.q0)[0, 0]))
    assert masses == [2.0, 3.5]
    bad = write_campaign(sweep.format("[1.0, -2.0]"), name="bad.toml")
    with pytest.raises(ParameterKeyError, match="mass of link 'ball'"):
        load_campaign(bad)


@pytest.mark.parametrize(
    ("values", "error", "match"),
    [
        ({"mass": -1.0}, InvalidParameterError, "mass of link 'ball'"),
        ({"mass": 0.0}, InvalidParameterError, "mass of link 'ball'"),
        ({"scale": 0.0}, InvalidParameterError, "scale of link 'ball'"),
        ({"mass": 2.0, "scale": 2.0}, InvalidParameterError, "scale of link 'ball'"),
        ({"com": [0.0, 0.0]}, ShapeError, "com of link 'ball'"),
        ({"inertia": [1.0, 1.0, 1.0]}, ShapeError, "inertia of link 'ball'"),
        ({"inertia": [1.0, 1.0, 3.0, 0, 0, 0]}, InvalidInertiaError, "triangle inequality"),
        ({"inertia": [1.0, 1.0, 0.0, 0, 0, 0]}, InvalidInertiaError, "positive definite"),
        ({"inertia": [1.0, 1.0, 1.0, 2.0, 0, 0]}, InvalidInertiaError, "semi-definite"),
        ({"density": 2.0}, UnknownKeyError, "density"),
    ],
)
def test_bad_link_values_are_errors_naming_the_link(
    values: dict[str, Any], error: type[Exception], match: str
) -> None:
    table = _table("ball")
    table["robot"]["links"] = {"ball": values}
    with pytest.raises(error, match=match) as raised:
        Scene.from_dict(table, base_dir=ROBOTS)
    if isinstance(raised.value, InvalidInertiaError):
        assert raised.value.body == "ball"


@pytest.mark.parametrize(
    ("links", "error", "match"),
    [
        ({"wheel": {"mass": 1.0}}, FrameNotFoundError, "wheel"),
        ({"base": {"mass": 1.0}}, InvalidParameterError, "fixed to the world"),
        ({"ball": 2.0}, SceneError, "must be a table"),
        ([1.0], SceneError, "table of link tables"),
    ],
)
def test_bad_links_are_errors(links: Any, error: type[Exception], match: str) -> None:
    table = _table("ball")
    table["robot"]["links"] = links
    with pytest.raises(error, match=match):
        Scene.from_dict(table, base_dir=ROBOTS)


def test_two_links_of_one_body_or_a_joint_frame_are_errors() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "slider_crank.urdf")
    with pytest.raises(InvalidParameterError, match="welded"):
        with_link_inertias(
            robot, [LinkInertia(link="rod", mass=1.0), LinkInertia(link="rod_end", mass=1.0)]
        )
    with pytest.raises(InvalidParameterError, match="a link"):
        with_link_inertias(robot, [LinkInertia(link="rod_joint", mass=1.0)])
