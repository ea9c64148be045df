"""Mesh and moving environment shapes of collision pairs, against independent references.

A mesh box (``robots/meshes/unit_box.obj`` scaled) against the analytic box shape; a ball on a
vibrating halfspace or box shape against the same ball on the moving ``[surfaces]`` plane with
a hand-declared point contact (the analytic time-dependent gap); and the typed errors of bad
shapes, pairs and motions.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.contact import CollisionPair, ConstraintSet, EnvironmentShape
from ucontrol.exceptions import InvalidParameterError, NonFiniteValueError
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

_INERTIAL = """<inertial><mass value="1.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"""
# A free body with a box, a sphere and a capsule (Pinocchio's <collision_checking> extension).
_BODY = f"""<?xml version="1.0"?>
<robot name="body">
  <link name="base"/>
  <joint name="free" type="floating"><parent link="base"/><child link="body"/></joint>
  <link name="body">{_INERTIAL}
    <collision><origin xyz="0.01 0.02 -0.03" rpy="0.1 0.2 0.3"/>
      <geometry><box size="0.2 0.1 0.08"/></geometry></collision>
    <collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.1"/></geometry></collision>
    <collision name="arm"><origin xyz="0 0.3 0" rpy="0.4 0 0"/>
      <geometry><cylinder radius="0.05" length="0.2"/></geometry></collision>
    <collision_checking><capsule name="arm"/></collision_checking>
  </link>
  <joint name="tip_joint" type="fixed"><parent link="body"/><child link="bare"/>
    <origin xyz="0 0 0.2"/></joint>
  <link name="bare"/>
</robot>
"""
_POSE = {"position": [0.5, 0.3, 0.3], "rpy": [0.2, 0.1, 0.5]}
_SIZE = [0.4, 0.3, 0.2]  # [m]
# coal's GJK stops at different iterates for a Box and for a Convex hull of the same box: the
# witness points of two polytopes (box, capsule segment) agree to 4.1e-10 over 300 random
# poses (gaps to 2.7e-11); a sphere's rows to 5.9e-15.
_POLYTOPE_TOLERANCE = 4e-9
_SPHERE_TOLERANCE = 1e-13


def _vibrating(**changes: Any) -> dict[str, Any]:
    """The table of robots/ball_vibrating_table.toml, shortened to 0.5 s, with ``changes``."""
    with open(ROBOTS / "ball_vibrating_table.toml", "rb") as file:
        table = tomllib.load(file)
    table["duration"] = 0.5
    table.update(copy.deepcopy(changes))
    return table


def _run(table: dict[str, Any]) -> Any:
    return simulate(Scene.from_dict(table, base_dir=ROBOTS), out=None, progress=False).log


def _collision_table(shape: dict[str, Any] | None) -> dict[str, Any]:
    """The vibrating table as a collision pair of ball_collision.urdf against ``shape``."""
    table = _vibrating()
    table["robot"]["urdf"] = "ball_collision.urdf"
    del table["contacts"]
    if shape is not None:  # else the pair names the moving [surfaces] plane
        del table["surfaces"]
        table["shapes"] = {"table": shape}
    table["collision_pairs"] = [{"link": "ball", "other": "table", "restitution": 0.5}]
    return table


def test_mesh_box_rows_equal_the_box_shape(
    tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("ucontrol.contact.collision_geometry.BROAD_PHASE_MARGIN", np.inf)
    path = tmp_path / "body.urdf"
    path.write_text(_BODY, encoding="utf-8")
    robot = RobotModel.from_urdf(path)
    box = EnvironmentShape(name="obstacle", type="box", size=_SIZE, **_POSE)
    mesh = EnvironmentShape(
        name="obstacle", type="mesh", mesh=ROBOTS / "meshes" / "unit_box.obj", scale=_SIZE, **_POSE
    )
    analytic = ConstraintSet(robot, collision_pairs=[CollisionPair(link="body", other=box)])
    hull = ConstraintSet(robot, collision_pairs=[CollisionPair(link="body", other=mesh)])
    assert hull.size == analytic.size == 3  # one witness row per link shape
    rows = [0, 1, 2]
    tolerance = np.array([_POLYTOPE_TOLERANCE, _SPHERE_TOLERANCE, _POLYTOPE_TOLERANCE])
    penetrating = 0
    for _ in range(40):
        q = pin.neutral(robot.model)
        quaternion = rng.standard_normal(4)
        q[3:7] = quaternion / np.linalg.norm(quaternion)
        q[:3] = np.array(_POSE["position"]) + rng.uniform(-0.5, 0.5, 3)
        v = rng.standard_normal(robot.nv)
        data = pin.Data(robot.model)
        pin.computeAllTerms(robot.model, data, q, v)
        gap, velocity = hull.evaluate(data, q, v)
        reference_gap, reference_velocity = analytic.evaluate(data, q, v)
        penetrating += int(np.sum(reference_gap < 0.0))
        assert np.all(np.abs(gap - reference_gap) <= tolerance)
        assert np.all(np.abs(velocity - reference_velocity) <= tolerance)
        J, J_ref = hull.jacobian(data, rows), analytic.jacobian(data, rows)
        assert np.all(np.abs(J - J_ref).max(axis=1) <= tolerance)
    assert penetrating > 0  # overlapping poses (EPA) were checked too


def test_mesh_scene_loads_its_file_relative_to_the_scene(tmp_path: Path) -> None:
    mesh = tmp_path / "meshes" / "box.obj"
    mesh.parent.mkdir()
    mesh.write_bytes((ROBOTS / "meshes" / "unit_box.obj").read_bytes())
    table = _collision_table(  # a fixed mesh table, its top face at z = 0
        {"type": "mesh", "file": "meshes/box.obj", "scale": _SIZE, "position": [0.0, 0.0, -0.1]}
    )
    table["robot"]["urdf"] = str(ROBOTS / "ball_collision.urdf")
    scene = Scene.from_dict(table, base_dir=tmp_path)
    # q0 = 0.10765... m: the sphere (r = 0.1 m) is 7.66e-3 m above the top face z = 0.
    np.testing.assert_allclose(scene.constraints.gaps(scene.q0), [0.10765657818966341 - 0.1])


@pytest.mark.slow
def test_ball_on_a_vibrating_halfspace_equals_the_moving_plane() -> None:
    reference = _run(_vibrating())
    halfspace = {
        "type": "halfspace",
        "normal": [0.0, 0.0, 1.0],
        "motion": _vibrating()["surfaces"]["table"]["motion"],
    }
    for shape in (halfspace, None):  # a [shapes] halfspace, then the [surfaces] plane itself
        log = _run(_collision_table(shape))
        assert np.count_nonzero(np.asarray(reference.impulse)) >= 2  # impacts and contact
        for key in ("q", "v", "gap", "impulse"):
            np.testing.assert_allclose(
                np.asarray(getattr(log, key)),
                np.asarray(getattr(reference, key)),
                rtol=0,
                atol=1e-12,
            )


def test_box_vibrating_under_a_ball_equals_the_moving_plane() -> None:
    reference = _run(_vibrating())
    with open(ROBOTS / "ball_vibrating_box.toml", "rb") as file:
        table = tomllib.load(file)
    table["duration"] = 0.5
    log = _run(table)
    for key in ("q", "v", "gap", "impulse"):
        # Measured: 0 (q, v, impulse) and 2.1e-17 m (gap) over 2 s.
        np.testing.assert_allclose(
            np.asarray(getattr(log, key)), np.asarray(getattr(reference, key)), rtol=0, atol=1e-12
        )
    assert np.count_nonzero(np.asarray(log.impulse)) >= 2  # impacts and contact


def test_moving_shape_rows_use_the_relative_velocity(
    tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Normal velocity and ∂g/∂t against finite differences of the gap in q and t."""
    monkeypatch.setattr("ucontrol.contact.collision_geometry.BROAD_PHASE_MARGIN", np.inf)
    from ucontrol.contact.surface_motion import Sinusoid

    path = tmp_path / "body.urdf"
    path.write_text(_BODY, encoding="utf-8")
    robot = RobotModel.from_urdf(path)
    motion = Sinusoid(amplitude=[0.05, -0.02, 0.03], frequency=7.0, phase=0.3)
    box = EnvironmentShape(name="obstacle", type="box", size=_SIZE, motion=motion, **_POSE)
    ground = EnvironmentShape(
        name="ground", type="halfspace", normal=[0.1, 0.0, 1.0], motion=motion
    )
    pairs = [CollisionPair(link="body", other=box), CollisionPair(link="body", other=ground)]
    constraints = ConstraintSet(robot, collision_pairs=pairs)
    assert constraints.time_dependent
    q = pin.neutral(robot.model)
    q[:3] = [0.5, 0.3, 0.62]
    v = rng.standard_normal(robot.nv)
    t, step = 0.4, 1e-6  # [s]
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, q, v)
    velocity = constraints.evaluate(data, q, v, t)[1]
    rows = np.arange(constraints.size)
    J = constraints.jacobian(data, rows)
    rate = constraints.normal_rate(rows, t)
    plus = constraints.gaps(pin.integrate(robot.model, q, step * v), t + step)
    minus = constraints.gaps(pin.integrate(robot.model, q, -step * v), t - step)
    total = (plus - minus) / (2 * step)  # dg/dt along the motion [m/s]
    np.testing.assert_allclose(velocity, J @ v + rate, rtol=0, atol=1e-12)
    # Central differences: error O(step²) plus rounding 1e-16 / 1e-6; measured 2e-10.
    np.testing.assert_allclose(velocity, total, rtol=0, atol=2e-9)
    assert np.abs(rate).max() > 0.1  # the motion matters


def test_bad_shapes_pairs_and_motions_raise_typed_errors(tmp_path: Path) -> None:
    # A pair naming a link without <collision> elements.
    table = _collision_table({"type": "box", "size": [0.4, 0.4, 0.2]})
    table["robot"]["urdf"] = "ball.urdf"
    with pytest.raises(InvalidParameterError, match="'ball'"):
        Scene.from_dict(table, base_dir=ROBOTS)
    # A mesh file that does not load: missing, then not a mesh.
    (tmp_path / "bad.obj").write_text("not a mesh\n", encoding="utf-8")
    for name in ("missing.obj", "bad.obj"):
        table = _collision_table({"type": "mesh", "file": name})
        table["robot"]["urdf"] = str(ROBOTS / "ball_collision.urdf")
        with pytest.raises(InvalidParameterError, match=name.replace(".", r"\.")):
            Scene.from_dict(table, base_dir=tmp_path)
    with pytest.raises(InvalidParameterError, match="mesh"):
        EnvironmentShape(name="x", type="mesh")
    with pytest.raises(InvalidParameterError, match="scale"):
        EnvironmentShape(name="x", type="mesh", mesh=Path("x.obj"), scale=[1.0, 0.0, 1.0])
    # A motion that is not finite: in a scene, and a user function.
    moving = {"type": "polynomial", "coefficients": [[0.0, 0.0, float("nan")]]}
    table = _collision_table({"type": "box", "size": [0.4, 0.4, 0.2], "motion": moving})
    with pytest.raises(NonFiniteValueError, match="coefficients"):
        Scene.from_dict(table, base_dir=ROBOTS)

    def diverging(t: float) -> tuple[np.ndarray, ...]:
        return np.zeros(3), np.array([0.0, 0.0, np.inf]), np.zeros(3)

    with pytest.raises(NonFiniteValueError, match="velocity at t = 0"):
        EnvironmentShape(name="x", type="box", motion=diverging)
    with pytest.raises(InvalidParameterError, match="motion of shape 'x'"):
        EnvironmentShape(name="x", type="box", motion=3.0)  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError, match="file"):
        Scene.from_dict(_collision_table({"type": "mesh", "file": 3}), base_dir=ROBOTS)
    # The time is required once a shape moves.
    scene = Scene.from_toml(ROBOTS / "ball_vibrating_box.toml")
    data = pin.Data(scene.robot.model)
    q, v = scene.q0, scene.v0
    pin.computeAllTerms(scene.robot.model, data, q, v)
    with pytest.raises(InvalidParameterError, match="move"):
        scene.constraints.evaluate(data, q, v)
