"""Collision pairs from URDF <collision> elements through coal, against independent references.

Gaps and normal rows against finite differences along ``pin.integrate``; the sphere cases
against the analytic point and sphere–sphere contacts; a box dropped flat against the same box
with hand-declared corners; the errors a bad pair raises; and that a scene without pairs loads
no geometry.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.contact import (
    CollisionPair,
    ConstraintSet,
    EnvironmentShape,
    Plane,
    PointContact,
    SphereSphereContact,
)
from ucontrol.contact.collision_geometry import BROAD_PHASE_MARGIN
from ucontrol.exceptions import InvalidParameterError, NotFoundError, URDFError
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

_STEP = 1e-7  # finite-difference step along pin.integrate
_FD_TOLERANCE = 1e-6  # [m] per unit of the tangent direction
_R1, _R2 = 0.1, 0.15  # sphere radii [m]

_INERTIAL = """<inertial><mass value="1.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"""

# Two free-flying bodies: a box with a sphere and a cylinder, and a sphere.
_SHAPES = f"""<?xml version="1.0"?>
<robot name="shapes">
  <link name="base"/>
  <joint name="first_joint" type="floating"><parent link="base"/><child link="first"/></joint>
  <link name="first">{_INERTIAL}
    <collision><origin xyz="0.01 0.02 -0.03" rpy="0.1 0.2 0.3"/>
      <geometry><box size="0.2 0.1 0.08"/></geometry></collision>
    <collision><origin xyz="0.3 0 0"/><geometry><sphere radius="{_R1}"/></geometry></collision>
    <collision><origin xyz="0 0.3 0" rpy="0.4 0 0"/>
      <geometry><cylinder radius="0.05" length="0.2"/></geometry></collision>
  </link>
  <joint name="second_joint" type="floating"><parent link="base"/><child link="second"/></joint>
  <link name="second">{_INERTIAL}
    <collision><origin xyz="0 0 0"/><geometry><sphere radius="{_R2}"/></geometry></collision>
  </link>
  <joint name="tip_joint" type="fixed"><parent link="second"/><child link="bare"/>
    <origin xyz="0 0 0.2"/></joint>
  <link name="bare"/>
</robot>
"""


def _robot(tmp_path: Path, text: str = _SHAPES) -> RobotModel:
    path = tmp_path / "shapes.urdf"
    path.write_text(text, encoding="utf-8")
    return RobotModel.from_urdf(path)


def _configuration(robot: RobotModel, rng: np.random.Generator) -> np.ndarray:
    """Both bodies apart, above the ground, randomly oriented."""
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    q[:3] = [0.1, -0.05, 0.45]
    q[7:10] = [0.9, 0.8, 0.6]
    quaternion = rng.standard_normal(4)
    q[3:7] = quaternion / np.linalg.norm(quaternion)
    return q


def _kinematics(robot: RobotModel, q: np.ndarray, v: np.ndarray) -> pin.Data:
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    return data


def _pairs() -> list[CollisionPair]:
    ground = EnvironmentShape(name="ground", type="halfspace", normal=[0.1, -0.2, 1.0])
    obstacle = EnvironmentShape(
        name="obstacle",
        type="box",
        position=[0.5, 0.3, 0.3],
        rpy=[0.2, 0.1, 0.5],
        size=[0.2, 0.3, 0.1],
    )
    ball = EnvironmentShape(name="ball", type="sphere", position=[-0.3, 0.1, 0.2], radius=0.1)
    return [
        CollisionPair(link="first", other=ground, friction=0.3),
        CollisionPair(link="first", other=obstacle, friction=0.3),
        CollisionPair(link="first", other=ball),
        CollisionPair(link="first", other="second", friction=0.3),
        CollisionPair(link="second", other=ground, points="witness"),
    ]


def test_gaps_and_rows_match_finite_differences(
    tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Exact distances everywhere (no broad phase): the bodies are up to 1 m apart.
    monkeypatch.setattr("ucontrol.contact.collision_geometry.BROAD_PHASE_MARGIN", np.inf)
    robot = _robot(tmp_path)
    constraints = ConstraintSet(robot, collision_pairs=_pairs())
    # 8 corners + 1 sphere + 32 rim points on the ground, 3 witness rows each for the
    # obstacle, the ball and the second link, one witness row of the second link.
    assert constraints.size == 8 + 1 + 32 + 3 + 3 + 3 + 1
    q = _configuration(robot, rng)
    v = rng.standard_normal(robot.nv)
    data = _kinematics(robot, q, v)
    gap, velocity = constraints.evaluate(data, q, v)
    np.testing.assert_allclose(constraints.gaps(q), gap, rtol=0, atol=1e-14)
    rows = np.arange(constraints.size)
    J = constraints.jacobian(data, rows)
    np.testing.assert_allclose(J @ v, velocity, rtol=0, atol=1e-12)
    for _ in range(3):
        direction = rng.standard_normal(robot.nv)
        plus = constraints.gaps(pin.integrate(robot.model, q, _STEP * direction))
        minus = constraints.gaps(pin.integrate(robot.model, q, -_STEP * direction))
        derivative = (plus - minus) / (2 * _STEP)
        error = np.abs(derivative - J @ direction) / _FD_TOLERANCE
        assert error.max() < 1.0, (error.max(), constraints.names[int(error.argmax())])


def test_tangent_rows_are_velocities_of_the_contact_points(
    tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("ucontrol.contact.collision_geometry.BROAD_PHASE_MARGIN", np.inf)
    robot = _robot(tmp_path)
    constraints = ConstraintSet(robot, collision_pairs=_pairs())
    q = _configuration(robot, rng)
    v = rng.standard_normal(robot.nv)
    data = _kinematics(robot, q, v)
    geometry = constraints.collision
    assert geometry is not None
    rows = [0, 41, 47]  # a box corner on the ground, a box witness (obstacle), link ↔ link
    T, directions = constraints.tangent_rows(data, rows)
    assert T.shape == (6, robot.nv)
    points = geometry.contact_points(data, rows)
    for j in range(3):
        t = directions[2 * j : 2 * j + 2]
        np.testing.assert_allclose(t @ points.normal[j], 0.0, atol=1e-12)

        # Relative velocity of the contact points by finite differences of their motion.
        def relative_position(q_: np.ndarray, j: int = j) -> np.ndarray:
            d = pin.Data(robot.model)
            pin.forwardKinematics(robot.model, d, q_)
            first = d.oMi[int(points.joint[j])].act(
                data.oMi[int(points.joint[j])].actInv(points.point[j])
            )
            other = int(points.other_joint[j])
            second = (
                d.oMi[other].act(data.oMi[other].actInv(points.other_point[j]))
                if other
                else points.other_point[j]
            )
            return first - second

        q_plus = pin.integrate(robot.model, q, _STEP * v)
        q_minus = pin.integrate(robot.model, q, -_STEP * v)
        relative = (relative_position(q_plus) - relative_position(q_minus)) / (2 * _STEP)
        np.testing.assert_allclose(T[2 * j : 2 * j + 2] @ v, t @ relative, atol=1e-6)


def test_sphere_rows_equal_the_analytic_contacts(tmp_path: Path, rng: np.random.Generator) -> None:
    robot = _robot(tmp_path)
    plane = Plane(normal=np.array([0.1, -0.2, 1.0]), name="ground")
    ground = EnvironmentShape(name="ground", type="halfspace", normal=plane.normal)
    pairs = [
        CollisionPair(link="second", other=ground),  # the sphere's centre row
        CollisionPair(link="second", other=ground, points="witness", name="coal"),
    ]
    shapes = ConstraintSet(robot, collision_pairs=pairs)
    analytic = ConstraintSet(
        robot, [PointContact(frame="second", surface=plane, radius=_R2, name="point")]
    )
    q = _configuration(robot, rng)
    v = rng.standard_normal(robot.nv)
    data = _kinematics(robot, q, v)
    gap, velocity = shapes.evaluate(data, q, v)
    reference_gap, reference_velocity = analytic.evaluate(data, q, v)
    np.testing.assert_allclose(gap, np.repeat(reference_gap, 2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(velocity, np.repeat(reference_velocity, 2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        shapes.jacobian(data, [0, 1]),
        np.repeat(analytic.jacobian(data, [0]), 2, axis=0),
        atol=1e-12,
    )


def _two_spheres(tmp_path: Path) -> RobotModel:
    """The robot of _SHAPES with only its two spheres, each centred on its link's origin."""
    text = _SHAPES.replace(
        '<collision><origin xyz="0.01 0.02 -0.03" rpy="0.1 0.2 0.3"/>\n      '
        '<geometry><box size="0.2 0.1 0.08"/></geometry></collision>',
        "",
    ).replace('<origin xyz="0.3 0 0"/><geometry><sphere', '<origin xyz="0 0 0"/><geometry><sphere')
    text = text.replace(
        '<collision><origin xyz="0 0.3 0" rpy="0.4 0 0"/>\n      '
        '<geometry><cylinder radius="0.05" length="0.2"/></geometry></collision>',
        "",
    )
    return _robot(tmp_path, text)


def test_link_pair_of_spheres_equals_the_sphere_sphere_contact(tmp_path: Path) -> None:
    robot = _two_spheres(tmp_path)
    rng = np.random.default_rng(3)
    shapes = ConstraintSet(robot, collision_pairs=[CollisionPair(link="first", other="second")])
    analytic = ConstraintSet(
        robot,
        sphere_contacts=[
            SphereSphereContact(frame="first", other_frame="second", radius=_R1, other_radius=_R2)
        ],
    )
    for distance in (0.6, 0.26, 0.2):  # apart, near (no broad phase), overlapping [m]
        q = _configuration(robot, rng)
        q[7:10] = q[:3] + distance * np.array([0.6, 0.0, 0.8])
        v = rng.standard_normal(robot.nv)
        data = _kinematics(robot, q, v)
        gap, velocity = shapes.evaluate(data, q, v)
        reference = analytic.evaluate(data, q, v)
        np.testing.assert_allclose(gap, reference[0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(velocity, reference[1], rtol=0, atol=1e-9)
        np.testing.assert_allclose(
            shapes.jacobian(data, [0]), analytic.jacobian(data, [0]), rtol=0, atol=1e-9
        )


def test_broad_phase_gives_a_lower_bound_and_exact_distances_when_near(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    robot = _robot(tmp_path)
    ball = EnvironmentShape(name="ball", type="sphere", position=[0.0, 0.0, 0.0], radius=0.1)
    constraints = ConstraintSet(robot, collision_pairs=[CollisionPair(link="second", other=ball)])
    q = _configuration(robot, rng)
    for height, exact in ((1.0, False), (0.25 + 0.5 * BROAD_PHASE_MARGIN, True)):
        q[7:10] = [0.0, 0.0, height]
        gap = constraints.gaps(q)[0]
        true = height - 0.1 - _R2
        assert gap <= true + 1e-12
        if exact:
            assert abs(gap - true) < 1e-12


def _box_scene(collision: bool, q0: list[float], v0: list[float]) -> Scene:
    table: dict = {
        "duration": 0.4,
        "robot": {
            "urdf": "box_collision.urdf" if collision else "block.urdf",
            "floating_base": True,
            "q0": q0,
            "v0": v0,
        },
        "integrator": {"name": "moreau_jean", "dt": 1e-3},
    }
    if collision:
        table["shapes"] = {"ground": {"type": "halfspace", "normal": [0.0, 0.0, 1.0]}}
        table["collision_pairs"] = [{"link": "box", "other": "ground", "restitution": 0.5}]
    else:
        table["surfaces"] = {"ground": {"type": "plane", "normal": [0.0, 0.0, 1.0]}}
        # In the order of the box's corner rows: (-x, -y), (-x, +y), (+x, -y), (+x, +y).
        table["contacts"] = [
            {"frame": frame, "surface": "ground", "restitution": 0.5}
            for frame in ("corner_br", "corner_bl", "corner_fr", "corner_fl")
        ]
    return Scene.from_dict(table, base_dir=ROBOTS)


@pytest.mark.parametrize(
    ("q0", "v0"),
    [
        ([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0], [0.0] * 6),  # flat: a face contact
        ([0.0, 0.0, 0.12, 0.0, 0.0873, 0.0, 0.9962], [0.3, 0.0, 0.0, 0.0, 1.0, 0.5]),  # tilted
    ],
)
def test_box_drop_equals_hand_declared_corners(q0: list[float], v0: list[float]) -> None:
    norm = np.linalg.norm(q0[3:])
    q0 = [*q0[:3], *(np.array(q0[3:]) / norm)]
    shapes = simulate(_box_scene(True, q0, v0), dt=1e-3, out=None, progress=False).log
    corners = simulate(_box_scene(False, q0, v0), dt=1e-3, out=None, progress=False).log
    np.testing.assert_allclose(np.asarray(shapes.q), np.asarray(corners.q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(shapes.v), np.asarray(corners.v), rtol=0, atol=1e-12)
    # The four lower corners carry the normal impulses of the hand-declared corners.
    lower = np.asarray(shapes.impulse)[:, [0, 2, 4, 6]].sum(axis=1)
    np.testing.assert_allclose(lower, np.asarray(corners.impulse).sum(axis=1), atol=1e-12)
    assert np.all(np.asarray(shapes.impulse)[:, [1, 3, 5, 7]] == 0.0)


def test_box_dropped_flat_rests_without_rocking() -> None:
    scene = _box_scene(True, [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0], [0.0] * 6)
    log = simulate(scene, duration=0.5, dt=1e-3, out=None, progress=False).log
    q = np.asarray(log.q)
    tilt = 2.0 * np.arcsin(np.linalg.norm(q[:, 3:6], axis=1))  # [rad]
    assert tilt.max() <= 1e-10
    impulse = np.asarray(log.impulse).sum(axis=1)  # [N s]
    h, weight = 1e-3, 1.0 * 9.81  # [s], [N]
    # At rest (the last 0.1 s) the corners carry the weight over each step.
    np.testing.assert_allclose(impulse[-100:-1], weight * h, rtol=1e-9)  # last row: no step
    np.testing.assert_allclose(q[-1, 2], 0.05, atol=1e-6)


def test_scene_without_pairs_loads_no_geometry() -> None:
    code = (
        "import sys\n"
        "from ucontrol.scene import Scene\n"
        f"scene = Scene.from_toml({str(ROBOTS / 'table_drop.toml')!r})\n"
        "scene.build_integrator()\n"
        "print('ucontrol.contact.collision_geometry' in sys.modules)\n"
    )
    output = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert output.strip() == "False"


def test_bad_pairs_raise_typed_errors(tmp_path: Path) -> None:
    robot = _robot(tmp_path)
    ground = EnvironmentShape(name="ground", type="halfspace")
    with pytest.raises(InvalidParameterError, match="bare"):
        ConstraintSet(robot, collision_pairs=[CollisionPair(link="bare", other=ground)])
    with pytest.raises(InvalidParameterError, match="other"):
        CollisionPair(link="first", other="first")
    with pytest.raises(InvalidParameterError, match="points"):
        CollisionPair(link="first", other=ground, points="corners")
    with pytest.raises(InvalidParameterError, match="cone"):
        EnvironmentShape(name="x", type="cone")
    with pytest.raises(InvalidParameterError, match="size"):
        EnvironmentShape(name="x", type="box", size=[0.1, 0.0, 0.1])
    missing = _SHAPES.replace('<sphere radius="0.15"/>', '<mesh filename="missing.stl"/>')
    path = tmp_path / "missing.urdf"
    path.write_text(missing, encoding="utf-8")
    with pytest.raises(URDFError, match=r"missing\.stl"):
        ConstraintSet(
            RobotModel.from_urdf(path), collision_pairs=[CollisionPair(link="first", other=ground)]
        )
    table = {
        "robot": {"urdf": "box_collision.urdf", "floating_base": True},
        "shapes": {"ground": {"type": "torus"}},
        "collision_pairs": [{"link": "box", "other": "ground"}],
    }
    with pytest.raises(NotFoundError, match="torus"):
        Scene.from_dict(table, base_dir=ROBOTS)
    scene = Scene.from_toml(ROBOTS / "box_drop_collision.toml")
    assert scene.constraints.size == 8


def test_mesh_hull_vertices_are_rows(tmp_path: Path) -> None:
    vertices = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], dtype=float)
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    lines = ["solid t"]
    for a, b, c in faces:
        n = np.cross(vertices[b] - vertices[a], vertices[c] - vertices[a])
        lines.append("facet normal {} {} {}\n outer loop".format(*(n / np.linalg.norm(n))))
        lines += ["  vertex {} {} {}".format(*vertices[i]) for i in (a, b, c)]
        lines.append(" endloop\nendfacet")
    lines.append("endsolid t")
    (tmp_path / "tetra.stl").write_text("\n".join(lines), encoding="utf-8")
    text = _SHAPES.replace('<sphere radius="0.15"/>', '<mesh filename="tetra.stl"/>')
    robot = _robot(tmp_path, text)
    ground = EnvironmentShape(name="ground", type="halfspace")
    constraints = ConstraintSet(robot, collision_pairs=[CollisionPair(link="second", other=ground)])
    q = pin.neutral(robot.model)
    q[7:10] = [0.0, 0.0, 0.3]
    np.testing.assert_allclose(np.sort(constraints.gaps(q)), [0.3, 0.3, 0.3, 0.4], atol=1e-12)
