"""Robots read from MJCF against their URDF twins; files Pinocchio cannot read; SDF refused."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.exceptions import (
    InvalidParameterError,
    MJCFError,
    RobotFileError,
    SceneError,
    SDFError,
)
from ucontrol.model import RobotModel
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

GRAVITY = np.array([0.0, -9.81, 0.0])  # [m/s²] the arm's vertical plane is xy
#: M(q), h(q, v) and frame positions of the two files: the same floating-point operations
#: on the same numbers, measured equal to the bit (0.0); the acceptance bound is 1e-12.
TWIN_TOLERANCE = 1e-12

#: box_collision.urdf in MJCF: a 1 kg box of 0.2 x 0.1 x 0.1 m (half sizes in MJCF).
BOX_MJCF = """<mujoco model="box_collision">
  <worldbody>
    <body name="box">
      <freejoint/>
      <inertial pos="0 0 0" mass="1.0"
                diaginertia="0.0016666666666666668 0.004166666666666667 0.004166666666666667"/>
      <geom type="box" size="0.1 0.05 0.05"/>
    </body>
  </worldbody>
</mujoco>
"""


def _twins() -> tuple[RobotModel, RobotModel]:
    urdf = RobotModel.from_urdf(ROBOTS / "two_link.urdf", gravity=GRAVITY)
    mjcf = RobotModel.from_mjcf(ROBOTS / "two_link.xml", gravity=GRAVITY)
    return urdf, mjcf


def test_mjcf_arm_has_the_urdf_twins_dynamics(rng: np.random.Generator) -> None:
    urdf, mjcf = _twins()
    assert (mjcf.nq, mjcf.nv, mjcf.nu, mjcf.name) == (2, 2, 2, "two_link")
    assert mjcf.joint_names == urdf.joint_names == ["shoulder", "elbow"]
    assert mjcf.mjcf_path == (ROBOTS / "two_link.xml").resolve() and mjcf.urdf_path is None
    for name in ("lowerPositionLimit", "upperPositionLimit", "effortLimit"):
        np.testing.assert_array_equal(getattr(mjcf.model, name), getattr(urdf.model, name))
    for q, v in zip(rng.uniform(-np.pi, np.pi, (20, 2)), rng.normal(0.0, 3.0, (20, 2))):
        M_urdf = urdf.mass_matrix(q)
        assert np.max(np.abs(mjcf.mass_matrix(q) - M_urdf)) <= TWIN_TOLERANCE * np.max(M_urdf)
        np.testing.assert_allclose(
            mjcf.nonlinear_effects(q, v), urdf.nonlinear_effects(q, v), rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(
            mjcf.frame_position(q, "end_effector"),
            urdf.frame_position(q, "end_effector"),
            rtol=0,
            atol=1e-15,
        )


@pytest.mark.slow
def test_shipped_mjcf_scene_tracks_like_its_urdf_twin() -> None:
    # 6 s: the free motion, the approach and the first impacts on the ground (at ~5 s)
    mjcf = simulate(load_scene("two_link_mjcf_one_constraint"), duration=6.0)
    urdf = simulate(load_scene("two_link_one_constraint"), duration=6.0)
    assert mjcf.summary["n_impacts"] >= 1
    assert mjcf.summary["n_impacts"] == urdf.summary["n_impacts"]
    np.testing.assert_allclose(mjcf.log.q, urdf.log.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mjcf.log.impulse, urdf.log.impulse, rtol=0, atol=1e-12)


def test_mjcf_collision_shapes_make_the_same_contacts(tmp_path: Path) -> None:
    (tmp_path / "box.xml").write_text(BOX_MJCF)
    table = tomllib.loads((ROBOTS / "box_drop_collision.toml").read_text())
    urdf_scene = Scene.from_dict(table, base_dir=ROBOTS)
    del table["robot"]["urdf"]
    table["robot"]["mjcf"] = str(tmp_path / "box.xml")
    mjcf_scene = Scene.from_dict(table, base_dir=ROBOTS)
    assert mjcf_scene.robot.mjcf_path is not None
    mjcf, urdf = simulate(mjcf_scene, duration=0.3), simulate(urdf_scene, duration=0.3)
    assert mjcf.log.gap.shape[1] == urdf.log.gap.shape[1] == 8  # the box's corners
    assert mjcf.summary["n_impacts"] >= 1
    np.testing.assert_allclose(mjcf.log.gap, urdf.log.gap, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mjcf.log.q, urdf.log.q, rtol=0, atol=1e-12)


def test_floating_base_must_match_the_files_freejoint(tmp_path: Path) -> None:
    (tmp_path / "box.xml").write_text(BOX_MJCF)
    box = RobotModel.from_mjcf(tmp_path / "box.xml", floating_base=True)
    assert (box.nq, box.nv, box.nu) == (7, 6, 0)
    with pytest.raises(MJCFError, match=r"floating_base is True but the root body has no"):
        RobotModel.from_mjcf(ROBOTS / "two_link.xml", floating_base=True)
    with pytest.raises(MJCFError, match=r"floating_base is False but the root body has a"):
        RobotModel.from_mjcf(tmp_path / "box.xml")


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ('<mujoco><worldbody><body name="a"><joint type="hinge"/>', "unexpected end of data"),
        ('<robot name="x"><link name="a"/></robot>', "not a standard mujoco model"),
        (
            '<mujoco><worldbody><body name="a"><joint name="j" type="hinge"/>'
            '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
            '<body name="b" pos="1 0 0"><joint name="k" type="hinge"/>'
            '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></body></worldbody>'
            '<equality><connect body1="a" body2="b" anchor="0 0 0"/></equality></mujoco>',
            "1 equality constraint(s)",
        ),
    ],
    ids=["truncated", "not-mjcf", "equality"],
)
def test_unreadable_mjcf_is_a_typed_error(tmp_path: Path, text: str, reason: str) -> None:
    path = tmp_path / "robot.xml"
    path.write_text(text)
    with pytest.raises(MJCFError) as info:
        RobotModel.from_mjcf(path)
    assert info.value.path == str(path) and info.value.format == "MJCF"
    assert reason in info.value.reason, info.value.reason
    assert "From file" not in str(info.value)  # Pinocchio's C++ location is left out


def test_missing_mjcf_and_missing_mesh(tmp_path: Path) -> None:
    with pytest.raises(MJCFError, match=r"does not exist"):
        RobotModel.from_mjcf(tmp_path / "nothing.xml")
    path = tmp_path / "mesh.xml"
    path.write_text(
        '<mujoco><asset><mesh name="m" file="missing.stl"/></asset><worldbody>'
        '<body name="a"><joint type="hinge"/><geom type="mesh" mesh="m"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>'
    )
    robot = RobotModel.from_mjcf(path)
    with pytest.raises(MJCFError, match=r"missing\.stl"):
        robot.geometry_model(pin.COLLISION)


def test_geometry_of_a_model_built_otherwise_is_refused() -> None:
    urdf, _ = _twins()
    with pytest.raises(InvalidParameterError, match=r"loaded from a URDF or MJCF file"):
        RobotModel(urdf.model).geometry_model(pin.COLLISION)
    with pytest.raises(InvalidParameterError, match=r"mjcf_path"):
        RobotModel(urdf.model, urdf_path=Path("a.urdf"), mjcf_path=Path("a.xml"))


@pytest.mark.parametrize("with_sdformat", [False, True])
def test_sdf_is_a_typed_error(monkeypatch: pytest.MonkeyPatch, with_sdformat: bool) -> None:
    monkeypatch.setattr(pin, "WITH_SDFORMAT", with_sdformat, raising=False)
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    del table["robot"]["urdf"]
    table["robot"]["sdf"] = "two_link.sdf"
    with pytest.raises(SDFError, match=r"two_link\.sdf") as info:
        Scene.from_dict(table, base_dir=ROBOTS)
    assert isinstance(info.value, RobotFileError) and info.value.format == "SDF"
    assert ("has no SDF parser" in info.value.reason) is not with_sdformat


@pytest.mark.parametrize("files", [{}, {"urdf": "two_link.urdf", "mjcf": "two_link.xml"}])
def test_robot_table_names_exactly_one_file(files: dict[str, str]) -> None:
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    del table["robot"]["urdf"]
    table["robot"].update(files)
    with pytest.raises(SceneError, match=r"exactly one of the keys 'urdf', 'mjcf', 'sdf'"):
        Scene.from_dict(table, base_dir=ROBOTS)
