"""Sphere–sphere contacts and friction rows of ConstraintSet, against finite differences.

Two free-flying spheres (free-flyer joints, nq = 14, nv = 12) and a sphere against a plane:
gaps, normal rows, tangential rows (velocity of the contact points, rotation included) and the
drift J̇v are compared with finite differences along ``pin.integrate``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.contact import ConstraintSet, Plane, PointContact, SphereSphereContact
from ucontrol.contact.tangent_basis import tangent_basis
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model import RobotModel

_STEP = 1e-7  # finite-difference step [s]
_FD_TOLERANCE = 1e-6  # relative
_R1, _R2 = 0.1, 0.15  # [m]

_TWO_SPHERES = """<?xml version="1.0"?>
<robot name="two_spheres">
  <link name="base"/>
  <joint name="first_joint" type="floating"><parent link="base"/><child link="first"/></joint>
  <link name="first"><inertial><mass value="1.0"/>
    <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.004"/></inertial></link>
  <joint name="second_joint" type="floating"><parent link="base"/><child link="second"/></joint>
  <link name="second"><inertial><mass value="2.0"/>
    <inertia ixx="0.018" ixy="0" ixz="0" iyy="0.018" iyz="0" izz="0.018"/></inertial></link>
</robot>
"""


def _spheres(friction: float = 0.4) -> tuple[RobotModel, ConstraintSet]:
    robot = RobotModel(pin.buildModelFromXML(_TWO_SPHERES))
    ground = Plane(normal=np.array([0.1, 0.2, 1.0]), name="ground")
    contacts = [PointContact(frame="second", surface=ground, radius=_R2, friction=friction)]
    pair = SphereSphereContact(
        frame="first", other_frame="second", radius=_R1, other_radius=_R2, friction=friction
    )
    return robot, ConstraintSet(robot, contacts, sphere_contacts=[pair])


def _state(robot: RobotModel, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    q[:3] = [0.3, 0.1, 0.5]
    q[7:10] = [0.0, 0.0, 0.1]
    return q, rng.standard_normal(robot.nv)


def _kinematics(robot: RobotModel, q: np.ndarray, v: np.ndarray) -> pin.Data:
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    return data


def test_gap_and_normal_velocity() -> None:
    robot, constraints = _spheres()
    q, v = _state(robot)
    data = _kinematics(robot, q, v)
    gap, velocity = constraints.evaluate(data, q, v)
    p1, p2 = (data.oMf[robot.frame_id(name)].translation for name in ("first", "second"))
    assert gap[1] == pytest.approx(np.linalg.norm(p1 - p2) - _R1 - _R2, abs=1e-15)
    q_next = pin.integrate(robot.model, q, _STEP * v)
    numeric = (constraints.gaps(q_next) - constraints.gaps(q)) / _STEP
    assert np.allclose(velocity, numeric, rtol=_FD_TOLERANCE, atol=_FD_TOLERANCE)
    rows = constraints.jacobian(data, [0, 1])
    assert np.allclose(rows @ v, velocity)


def test_tangent_rows_are_contact_point_velocities() -> None:
    """Each row times v is the tangential velocity of the contact point, spin included."""
    robot, constraints = _spheres()
    q, v = _state(robot, 1)
    data = _kinematics(robot, q, v)
    rows, directions = constraints.tangent_rows(data, [0, 1])
    assert rows.shape == (4, robot.nv) and directions.shape == (4, 3)
    first, second = (data.oMf[robot.frame_id(name)] for name in ("first", "second"))
    pair_normal = first.translation - second.translation
    pair_normal /= np.linalg.norm(pair_normal)
    ground = constraints.contacts[0].surface.normal
    # material points: on `second` at -R2 n_ground; on `first` at -R1 n; on `second` at +R2 n
    points = [
        (second, -_R2 * ground, +1.0),
        (first, -_R1 * pair_normal, +1.0),
        (second, _R2 * pair_normal, -1.0),
    ]
    local = [(frame, frame.rotation.T @ offset, sign) for frame, offset, sign in points]

    def positions(q_: np.ndarray) -> list[np.ndarray]:
        data_ = pin.Data(robot.model)
        pin.framesForwardKinematics(robot.model, data_, q_)
        frames = {id(first): "first", id(second): "second"}
        return [
            data_.oMf[robot.frame_id(frames[id(frame)])].act(offset) for frame, offset, _ in local
        ]

    before, after = positions(q), positions(pin.integrate(robot.model, q, _STEP * v))
    velocity = [(b - a) / _STEP for a, b in zip(before, after, strict=True)]
    plane_velocity = velocity[0]
    pair_velocity = velocity[1] - velocity[2]
    assert np.allclose(directions[:2], tangent_basis(ground))
    assert np.allclose(directions[2:], tangent_basis(pair_normal))
    assert np.allclose(rows[:2] @ v, directions[:2] @ plane_velocity, atol=1e-6)
    assert np.allclose(rows[2:] @ v, directions[2:] @ pair_velocity, atol=1e-6)


def test_normal_drift() -> None:
    """J̇v: the derivative of J(q(t)) v along the motion at constant v."""
    robot, constraints = _spheres()
    q, v = _state(robot, 2)
    data = pin.Data(robot.model)
    pin.forwardKinematics(robot.model, data, q, v, np.zeros(robot.nv))
    pin.updateFramePlacements(robot.model, data)
    drift = constraints.normal_drift(data, [0, 1])
    q_next = pin.integrate(robot.model, q, _STEP * v)
    rows = [constraints.jacobian(_kinematics(robot, x, v), [0, 1]) @ v for x in (q, q_next)]
    assert np.allclose(drift, (rows[1] - rows[0]) / _STEP, rtol=1e-5, atol=1e-5)


def test_friction_layout() -> None:
    _, constraints = _spheres()
    assert constraints.names == ["second/ground", "first/second"]
    assert constraints.tangent_count.tolist() == [2, 2] and constraints.has_friction
    _, frictionless = _spheres(friction=0.0)
    assert not frictionless.has_friction


def test_planar_axis_gives_one_tangent_in_the_plane() -> None:
    robot = RobotModel.from_urdf(ROBOTS / "rod.urdf")
    ground = Plane(name="ground")
    contact = PointContact(frame="rod_end", surface=ground, friction=0.5)
    constraints = ConstraintSet(robot, [contact], planar_axis=np.array([0.0, 2.0, 0.0]))
    assert constraints.tangent_count.tolist() == [1]
    data = _kinematics(robot, np.array([0.0, 0.3, 0.4]), np.zeros(3))
    _, directions = constraints.tangent_rows(data, [0])
    assert np.allclose(directions, [[1.0, 0.0, 0.0]])  # y × z


def test_bad_contacts_raise() -> None:
    with pytest.raises(InvalidParameterError, match="`other_frame` must be a frame other"):
        SphereSphereContact(frame="a", other_frame="a")
    with pytest.raises(InvalidParameterError, match="`other_radius` must be >= 0"):
        SphereSphereContact(frame="a", other_frame="b", other_radius=-1.0)
    with pytest.raises(InvalidParameterError, match="`friction` must be >= 0"):
        SphereSphereContact(frame="a", other_frame="b", friction=-0.1)
    robot = RobotModel.from_urdf(ROBOTS / "rod.urdf")
    tilted = Plane(normal=np.array([0.0, 1.0, 1.0]), name="tilted")
    with pytest.raises(InvalidParameterError, match="`planar_axis` must be orthogonal"):
        ConstraintSet(
            robot,
            [PointContact(frame="rod_end", surface=tilted)],
            planar_axis=np.array([0.0, 1.0, 0.0]),
        )
    with pytest.raises(InvalidParameterError, match="`planar_axis` must be a non-zero"):
        ConstraintSet(robot, planar_axis=np.zeros(3))


def test_tangent_bases_of_many_normals_are_each_normals_basis() -> None:
    """One call on normals (k, 3) gives every normal's own right-handed orthonormal basis."""
    rng = np.random.default_rng(7)
    normals = rng.normal(size=(9, 3))
    normals[0] = [0.95, 0.1, 0.0]  # near x: the other helper axis
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    for axis in (None, np.array([0.0, 1.0, 0.0])):
        bases = tangent_basis(normals, axis)
        assert bases.shape == (9, 2 if axis is None else 1, 3)
        for normal, basis in zip(normals, bases, strict=True):
            assert np.array_equal(basis, tangent_basis(normal, axis))
            assert np.allclose(basis @ basis.T, np.eye(basis.shape[0]), atol=1e-15)
            assert np.allclose(basis @ normal, 0.0, atol=1e-15)
        spatial = tangent_basis(normals)
        assert np.allclose(np.cross(spatial[:, 0], spatial[:, 1]), normals, atol=1e-15)


def test_rows_of_many_constraints_follow_their_order() -> None:
    """Rows of several contacts in one call, in any order, equal the rows of each alone."""
    robot, constraints = _spheres()
    q, v = _state(robot, 3)
    data = _kinematics(robot, q, v)
    for indices in ([0, 1], [1, 0], [1]):
        rows, directions = constraints.tangent_rows(data, indices)
        normal_rows = constraints.jacobian(data, indices)
        for j, i in enumerate(indices):
            alone, alone_directions = constraints.tangent_rows(data, [i])
            assert np.array_equal(rows[2 * j : 2 * j + 2], alone)
            assert np.array_equal(directions[2 * j : 2 * j + 2], alone_directions)
            assert np.array_equal(normal_rows[j], constraints.jacobian(data, [i])[0])


_INERTIAL = (
    '<inertial><mass value="1.0"/>'
    '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
)
_LIMIT = '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
#: A chain l1 - l2 - l3 (revolute, revolute, prismatic) and a link m1 on its own joint.
_CHAIN = "".join(
    [
        '<?xml version="1.0"?><robot name="chain"><link name="base"/>',
        *(
            f'<joint name="{joint}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{origin}"/><axis xyz="{axis}"/>{_LIMIT}'
            f'</joint><link name="{child}">{_INERTIAL}</link>'
            for joint, kind, parent, child, origin, axis in (
                ("j1", "revolute", "base", "l1", "0 0 0", "0 0 1"),
                ("j2", "revolute", "l1", "l2", "0.5 0 0", "0 1 0"),
                ("j3", "prismatic", "l2", "l3", "0.4 0 0", "1 0 0"),
                ("k1", "revolute", "base", "m1", "0 1 0", "1 0 0"),
            )
        ),
        "</robot>",
    ]
)


def test_pair_rows_where_both_spheres_share_joints() -> None:
    """Spheres on one chain (shared Jacobian columns) and on two: rows from whole Jacobians."""
    robot = RobotModel(pin.buildModelFromXML(_CHAIN))
    pairs = [
        SphereSphereContact(frame=a, other_frame=b, radius=0.1, other_radius=0.2, friction=0.5)
        for a, b in (("l3", "l1"), ("l2", "m1"), ("m1", "l3"))
    ]
    constraints = ConstraintSet(robot, [], sphere_contacts=pairs)
    rng = np.random.default_rng(4)
    q, v = rng.uniform(-1.0, 1.0, robot.nq), rng.uniform(-1.0, 1.0, robot.nv)
    data = _kinematics(robot, q, v)
    normal_rows = constraints.jacobian(data, [2, 0, 1])
    rows, directions = constraints.tangent_rows(data, [2, 0, 1])
    for j, pair in enumerate((pairs[2], pairs[0], pairs[1])):
        first, second = robot.frame_id(pair.frame), robot.frame_id(pair.other_frame)
        J1, J2 = (
            pin.getFrameJacobian(robot.model, data, f, pin.LOCAL_WORLD_ALIGNED)
            for f in (first, second)
        )
        delta = data.oMf[first].translation - data.oMf[second].translation
        normal = delta / np.linalg.norm(delta)
        assert np.allclose(normal_rows[j], normal @ (J1[:3] - J2[:3]), rtol=0.0, atol=1e-14)
        tangents = tangent_basis(normal)
        lever = np.cross(tangents, normal)
        expected = tangents @ (J1[:3] - J2[:3]) + lever @ (0.1 * J1[3:] + 0.2 * J2[3:])
        assert np.allclose(rows[2 * j : 2 * j + 2], expected, rtol=0.0, atol=1e-14)
        assert np.allclose(directions[2 * j : 2 * j + 2], tangents, rtol=0.0, atol=1e-15)


#: _CHAIN with a tip on l2 through a fixed joint: a frame away from its joint, turned.
_CHAIN_TIP = _CHAIN.replace(
    "</robot>",
    '<joint name="tip_joint" type="fixed"><parent link="l2"/><child link="tip"/>'
    '<origin xyz="0.2 -0.1 0.3" rpy="0.3 -0.2 0.5"/></joint>'
    f'<link name="tip">{_INERTIAL}</link></robot>',
)


def test_pair_kinematics_follow_the_data_buffer() -> None:
    """Gaps, normal velocities and rows of pairs (a frame off its joint) on one buffer, twice.

    References: each frame's ``pin.getFrameVelocity`` and ``pin.getFrameJacobian``
    (LOCAL_WORLD_ALIGNED), read anew at each of two states of the same data buffer, and the
    gaps' finite differences along ``pin.integrate``.
    """
    robot = RobotModel(pin.buildModelFromXML(_CHAIN_TIP))
    radii = {"tip": 0.05, "l1": 0.1, "m1": 0.2, "l3": 0.15}
    pairs = [
        SphereSphereContact(
            frame=a, other_frame=b, radius=radii[a], other_radius=radii[b], friction=mu
        )
        for a, b, mu in (("tip", "m1", 0.5), ("l3", "l1", 0.0), ("m1", "tip", 0.3))
    ]
    ground = Plane(normal=np.array([0.0, 0.3, 1.0]), point=np.array([0.0, 0.0, -2.0]))
    contacts = [PointContact(frame="l3", surface=ground, radius=0.1, friction=0.4)]
    constraints = ConstraintSet(robot, contacts, sphere_contacts=pairs)
    data = pin.Data(robot.model)
    rng = np.random.default_rng(7)
    model = robot.model
    for _ in range(2):  # the second state on the buffer the first one filled
        q, v = rng.uniform(-1.0, 1.0, robot.nq), rng.uniform(-1.0, 1.0, robot.nv)
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        gap, velocity = constraints.evaluate(data, q, v)
        numeric = constraints.gaps(pin.integrate(model, q, _STEP * v)) - constraints.gaps(q)
        assert np.allclose(velocity, numeric / _STEP, rtol=0.0, atol=_FD_TOLERANCE)
        indices = [2, 0, 3, 1]
        normal_rows, tangent_rows, directions = constraints.contact_rows(data, indices)
        expected_normal, expected_tangent, expected_directions = [], [], []
        for j, pair in enumerate(pairs, 1):
            first, second = robot.frame_id(pair.frame), robot.frame_id(pair.other_frame)
            delta = data.oMf[first].translation - data.oMf[second].translation
            normal = delta / np.linalg.norm(delta)
            assert gap[j] == pytest.approx(
                np.linalg.norm(delta) - pair.radius - pair.other_radius, abs=1e-15
            )
            relative = (
                pin.getFrameVelocity(model, data, first, pin.LOCAL_WORLD_ALIGNED).linear
                - pin.getFrameVelocity(model, data, second, pin.LOCAL_WORLD_ALIGNED).linear
            )
            assert velocity[j] == pytest.approx(normal @ relative, abs=1e-14)
            J1, J2 = (
                pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)
                for f in (first, second)
            )
            expected_normal.append(normal @ (J1[:3] - J2[:3]))
            if pair.friction > 0.0:
                tangents = tangent_basis(normal)
                lever = np.cross(tangents, normal)
                expected_tangent.append(
                    tangents @ (J1[:3] - J2[:3])
                    + lever @ (pair.radius * J1[3:] + pair.other_radius * J2[3:])
                )
                expected_directions.append(tangents)
        point_rows = constraints.jacobian(data, [0])
        point_tangent_rows, point_directions = constraints.tangent_rows(data, [0])
        # indices [2, 0, 3, 1]: pairs 1 and 2 (positions 1, 2 among the pairs above), the
        # point contact, the frictional pair 0; pair 1 is frictionless.
        order = [expected_normal[1], point_rows[0], expected_normal[2], expected_normal[0]]
        assert np.allclose(normal_rows, order, rtol=0.0, atol=1e-14)
        assert np.allclose(
            tangent_rows,
            np.vstack((point_tangent_rows, expected_tangent[1], expected_tangent[0])),
            rtol=0.0,
            atol=1e-14,
        )
        assert np.allclose(
            directions,
            np.vstack((point_directions, expected_directions[1], expected_directions[0])),
            rtol=0.0,
            atol=1e-15,
        )
        assert np.array_equal(normal_rows, constraints.jacobian(data, indices))
        assert all(
            np.array_equal(a, b)
            for a, b in zip(
                (tangent_rows, directions), constraints.tangent_rows(data, indices), strict=True
            )
        )
