r"""Contact constraints between collision shapes, through Pinocchio's geometry model and coal.

Imported and built only when a scene declares a :class:`~ucontrol.contact.CollisionPair`:
a scene without one loads no geometry model.

The shapes of a link are the ``<collision>`` elements of its URDF (``pin.buildGeomFromUrdf``),
or the colliding ``<geom>`` elements of its MJCF body (``pin.buildGeomFromMJCF``):
spheres, boxes, cylinders and meshes (a mesh stands for its convex hull; URDF has no capsule
element). Each pair of shapes gives unilateral constraints of two kinds.

**Witness rows** (link ↔ link, link ↔ box or sphere, and any pair with ``points =
"witness"``): one row, the signed distance :math:`g = d(A, B)` computed by ``coal.distance``
with its witness points :math:`p_A \in A`, :math:`p_B \in B` and unit normal :math:`n` from
B to A (:math:`p_A - p_B = g\,n`). Its row is

.. math:: J_n = n^T \big(J_{p_A} - J_{p_B}\big), \qquad
          J_p = J_{lin}(j) - [p - o_j]_\times J_{ang}(j),

the velocity of the material point of the body (joint :math:`j`, origin :math:`o_j`, joint
Jacobian in LOCAL_WORLD_ALIGNED) at the witness point: the derivative of the distance between
smooth convex shapes. Friction acts on the relative velocity of the witness points.

**Vertex rows** (``points = "auto"``, a link shape against a halfspace of normal :math:`n`
through :math:`p_0`): one row per support point :math:`c` of the shape with radius :math:`r`,
gap :math:`g = n \cdot (c(q) - p_0) - r` — the 8 corners of a box, the vertices of a mesh's
hull, the centre of a sphere (radius :math:`r`), 16 points on each rim of a cylinder. Each is
exactly the distance of that point, so the minimum over the rows is the exact signed distance
of a polytope; a box lying flat then rests on its four lower corners (a face contact is a
patch of four rows, an edge contact two) instead of on one witness point that jumps between
corners as it rocks. A cylinder is approximated by its rim polygons: penetration up to
:math:`r (1 - \cos(\pi / 16)) \approx 0.019\,r` when it rests on its rim.

**Broad phase.** For witness rows, the bounding spheres of both shapes are checked first: when
they are more than :data:`BROAD_PHASE_MARGIN` apart, coal is not called and the row's gap is
that distance between bounding spheres, a lower bound of the true one (its velocity, the rate
of that distance). Rows of shapes that close get the exact distance.

**Environment meshes** (``type = "mesh"``) stand for the convex hull of the file's vertices,
as the URDF's meshes do; coal's loader reads them (STL, OBJ, DAE, ...).

**Moving environment shapes.** A shape with a motion :math:`x(t)` (a translation,
:mod:`ucontrol.contact.surface_motion`) is placed at its declared pose moved by :math:`x(t)` at
each :meth:`CollisionGeometry.evaluate` or :meth:`CollisionGeometry.gaps` at time t; the gap is
then :math:`g(q, t)`, and the normal velocity the relative one,
:math:`u = J_n v + \partial g / \partial t` with :math:`\partial g / \partial t = -n \cdot
\dot x(t)` (:meth:`CollisionGeometry.normal_rate`; friction rows :math:`-t \cdot \dot x(t)`,
:meth:`CollisionGeometry.tangent_rate`). Rows and contact points are those of the shapes where
the last evaluation at a time placed them, and the rates use the normals of the last rows
computed (:meth:`CollisionGeometry.jacobian`), as a time step asks for them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.collision_pair import CollisionPair, EnvironmentShape
from ucontrol.contact.tangent_basis import cross, tangent_basis
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]
_LWA = pin.LOCAL_WORLD_ALIGNED
#: Distance in [m] between bounding spheres beyond which coal is not called.
BROAD_PHASE_MARGIN = 0.05
#: Tolerance of coal's GJK and EPA iterations in [m] (coal's default, 1e-6, leaves distances
#: between curved shapes too coarse for finite-difference checks of their derivative).
GJK_TOLERANCE = 1e-12
#: Points on each rim of a cylinder against a halfspace.
CYLINDER_RIM_POINTS = 16
#: Thinnest mesh, relative to its largest extent, whose convex hull is built (qhull, through
#: coal, crashes the process on vertices in one plane instead of raising).
MESH_FLATNESS = 1e-9
#: Time step in [s] (at unit speed) of the fourth-order central difference of a witness
#: row's normal velocity along the flow (:meth:`CollisionGeometry.drift`).
WITNESS_DRIFT_STEP = 3e-5


class _Vertex(NamedTuple):
    """A support point of a link's shape against a halfspace (a vertex row)."""

    joint: int
    point: Vector  # in the joint frame [m], (3,)
    radius: float
    normal: Vector  # halfspace normal, (3,)
    offset: float  # normal · p0 [m]
    shape: EnvironmentShape  # the halfspace


class _Witness(NamedTuple):
    """A pair of shapes whose distance coal computes (a witness row)."""

    first: int  # geometry object of the link
    joint: int
    second: int | None  # geometry object of the other link, or None for an environment shape
    other_joint: int  # 0 (the world) for an environment shape
    shape: Any  # coal geometry of the environment shape, or None
    transform: Any  # its coal.Transform3s, or None
    bound: float  # radius of the environment shape's bounding sphere [m] (inf: halfspace)
    centre: Vector  # centre of that bounding sphere in the world [m], (3,) (at x = 0)
    environment: EnvironmentShape | None  # the environment shape, None for a link


class ContactPoints(NamedTuple):
    """Where the constraint rows act, at the current configuration.

    Attributes:
        normal: Unit normals from the second body to the first, shape (k, 3).
        point: Contact points on the first body in world coordinates [m], shape (k, 3).
        joint: Joint carrying the first body, shape (k,).
        other_point: Contact points on the second body [m], shape (k, 3).
        other_joint: Joint carrying the second body (0: the world), shape (k,).
        gap: Signed distances [m], shape (k,).
    """

    normal: Vector
    point: Vector
    joint: NDArray[np.intp]
    other_point: Vector
    other_joint: NDArray[np.intp]
    gap: Vector


class CollisionGeometry:
    """The rows of declared collision pairs, in the order of the pairs.

    Args:
        robot: The robot; its URDF's ``<collision>`` elements (or its MJCF's colliding
            ``<geom>`` elements) are loaded.
        pairs: The declared pairs.

    Attributes:
        names: One label per row (``"<pair>"`` for a pair of one row, else ``"<pair>#<k>"``).
        restitution: Per row, shape (n,).
        friction: Per row, shape (n,).
        size: Number of rows n.
        geometry_model: Pinocchio's geometry model of the robot's collision shapes.

    Raises:
        RobotFileError: The robot file's collision shapes do not load (a missing mesh file).
        InvalidParameterError: A pair names a link without collision shapes, or the robot
            was not loaded from a file.
    """

    def __init__(self, robot: RobotModel, pairs: Sequence[CollisionPair]) -> None:
        self.robot = robot
        model = robot.model
        geometry_model = robot.geometry_model(pin.COLLISION)
        self.geometry_model = geometry_model
        self._geometry_data = pin.GeometryData(geometry_model)
        self._shapes: list[Any] = []
        by_link: dict[str, list[int]] = {}
        for index, item in enumerate(geometry_model.geometryObjects):
            shape = item.geometry
            if isinstance(shape, coal.BVHModelBase):  # a mesh stands for its convex hull
                shape = _convex_hull(shape, item.meshPath or item.name)
            shape.computeLocalAABB()
            self._shapes.append(shape)
            by_link.setdefault(model.frames[item.parentFrame].name, []).append(index)
        self._request = coal.DistanceRequest()
        self._request.gjk_tolerance = GJK_TOLERANCE
        self._request.epa_tolerance = GJK_TOLERANCE
        self._request.gjk_max_iterations = 1000
        self._request.epa_max_iterations = 1000
        self._result = coal.DistanceResult()
        self._rows: list[_Vertex | _Witness] = []
        self._environment: dict[str, tuple[Any, float, Vector]] = {}
        names: list[str] = []
        restitution: list[float] = []
        friction: list[float] = []
        for pair in pairs:
            rows = self._pair_rows(pair, by_link)
            names += (
                [pair.name] if len(rows) == 1 else [f"{pair.name}#{k}" for k in range(len(rows))]
            )
            restitution += [pair.restitution] * len(rows)
            friction += [pair.friction] * len(rows)
            self._rows += rows
        self.names = names
        self.restitution = np.array(restitution, dtype=float)
        self.friction = np.array(friction, dtype=float)
        self.size = len(names)
        self._vectorize()
        self._moving_rows()

    # -- building ---------------------------------------------------------------------------

    def _link_shapes(self, link: str, by_link: dict[str, list[int]]) -> list[int]:
        if link not in by_link:
            raise InvalidParameterError(
                "link",
                link,
                f"a link with collision shapes in {self.robot.urdf_path or self.robot.mjcf_path}"
                f"; links with some: {sorted(by_link)}",
            )
        return by_link[link]

    def _pair_rows(
        self, pair: CollisionPair, by_link: dict[str, list[int]]
    ) -> list[_Vertex | _Witness]:
        objects = self.geometry_model.geometryObjects
        rows: list[_Vertex | _Witness] = []
        for first in self._link_shapes(pair.link, by_link):
            joint = int(objects[first].parentJoint)
            other = pair.other
            if isinstance(other, str):
                for second in self._link_shapes(other, by_link):
                    rows.append(
                        _Witness(
                            first,
                            joint,
                            second,
                            int(objects[second].parentJoint),
                            None,
                            None,
                            np.inf,
                            np.zeros(3),
                            None,
                        )
                    )
            elif other.type == "halfspace" and pair.points == "auto":
                offset = float(other.normal @ other.position)
                placement = objects[first].placement
                for point, radius in _support_points(self._shapes[first]):
                    local = placement.act(point)
                    rows.append(_Vertex(joint, local, radius, other.normal, offset, other))
            else:
                if other.name not in self._environment:
                    self._environment[other.name] = _environment_shape(other)
                shape, bound, centre = self._environment[other.name]
                # A halfspace is built in world coordinates (its offset holds its point).
                placement = pin.SE3.Identity() if other.type == "halfspace" else other.placement
                rows.append(
                    _Witness(
                        first,
                        joint,
                        None,
                        0,
                        shape,
                        coal.Transform3s(placement.rotation, placement.translation),
                        bound,
                        placement.act(centre),
                        other,
                    )
                )
        return rows

    def _moving_rows(self) -> None:
        """Rows against moving environment shapes, and the buffers of their motion."""
        motions: dict[str, Any] = {}
        #: Per row: the name of its moving shape, or "" (fixed).
        self._row_motion: list[str] = []
        for row in self._rows:
            shape = row.shape if isinstance(row, _Vertex) else row.environment
            moving = shape is not None and shape.motion is not None
            if moving:
                assert shape is not None
                motions[shape.name] = shape.motion
            self._row_motion.append(shape.name if moving and shape is not None else "")
        self._motions = motions
        #: Whether some row is against a moving shape (its gap depends on t).
        self.time_dependent = bool(motions)
        self._moving_vertex = np.array(
            [k for k, i in enumerate(self._vertex_rows) if self._row_motion[i]], dtype=np.intp
        )
        self._moving_witness = np.array(
            [k for k, i in enumerate(self._witness_rows) if self._row_motion[i]], dtype=np.intp
        )
        self._base_centre = self._witness_other_centre.copy()
        self._base_translation = [
            np.array(row.transform.getTranslation())
            if isinstance(row, _Witness) and row.transform is not None
            else np.zeros(3)
            for row in self._rows
        ]
        self._shift = {name: np.zeros(3) for name in motions}  # x(t) [m]
        self._speed = {name: np.zeros(3) for name in motions}  # dx/dt [m/s]
        self._vertex_shift = np.zeros(self._vertex_rows.size)  # n · x(t) [m]
        self._vertex_speed = np.zeros(self._vertex_rows.size)  # n · dx/dt [m/s]
        self._witness_speed = np.zeros((self._witness_rows.size, 3))  # dx/dt [m/s]
        self._normal = np.full((self.size, 3), np.nan)  # normals of the last rows computed
        self._time: float | None = None

    def _at(self, t: float | None) -> None:
        """Place the moving environment shapes at time ``t`` [s] (nothing when none moves)."""
        if not self.time_dependent or (t is not None and t == self._time):
            return
        if t is None:
            raise InvalidParameterError(
                "t",
                t,
                f"the time in [s]: environment shapes {sorted(self._motions)} move",
            )
        for name, motion in self._motions.items():
            displacement, speed, _ = motion(t)
            self._shift[name], self._speed[name] = displacement, speed
        for k in self._moving_vertex.tolist():
            i = self._vertex_rows[k]
            name = self._row_motion[i]
            normal = self._vertex_normal[k]
            self._vertex_shift[k] = normal @ self._shift[name]
            self._vertex_speed[k] = normal @ self._speed[name]
        for k in self._moving_witness.tolist():
            i = self._witness_rows[k]
            row = self._rows[i]
            assert isinstance(row, _Witness)
            shift = self._shift[self._row_motion[i]]
            self._witness_other_centre[k] = self._base_centre[k] + shift
            self._witness_speed[k] = self._speed[self._row_motion[i]]
            row.transform.setTranslation(self._base_translation[i] + shift)
        self._time = t

    def normal_rate(self, rows: Sequence[int], t: float) -> Vector:
        r""":math:`\partial g / \partial t = -n \cdot \dot x(t)` of ``rows`` at t [s], in [m/s].

        Zero for rows against fixed shapes; ``n`` is each row's normal in the last
        :meth:`jacobian` (or :meth:`contact_points`). Shape (len(rows),).
        """
        rate = np.zeros(len(rows))
        for j, i in enumerate(rows):
            name = self._row_motion[i]
            if name:
                rate[j] = -self._normal[i] @ self._motions[name](t)[1]
        return rate

    def tangent_rate(self, rows: Sequence[int], t: float, planar_axis: Vector | None) -> Vector:
        r""":math:`-t \cdot \dot x(t)` of each row's tangents at t [s], stacked, in [m/s].

        The tangents are ``tangent_basis(n, planar_axis)`` of each row's last normal, as
        :meth:`tangent_rows` is given them by :class:`~ucontrol.contact.ConstraintSet`.
        """
        blocks = []
        for i in rows:
            tangents = tangent_basis(self._normal[i], planar_axis)
            name = self._row_motion[i]
            blocks.append(
                -tangents @ self._motions[name](t)[1] if name else np.zeros(len(tangents))
            )
        return np.concatenate(blocks) if blocks else np.zeros(0)

    def _vectorize(self) -> None:
        """Arrays of the rows' data, so that vertex rows and the broad phase run vectorized."""
        objects = self.geometry_model.geometryObjects
        vertices = [i for i, row in enumerate(self._rows) if isinstance(row, _Vertex)]
        witnesses = [i for i, row in enumerate(self._rows) if isinstance(row, _Witness)]
        joints = sorted({0} | {int(getattr(row, "joint", 0)) for row in self._rows})
        joints += sorted(
            {int(row.other_joint) for row in self._rows if isinstance(row, _Witness)} - set(joints)
        )
        self._joints = joints
        position = {joint: k for k, joint in enumerate(joints)}
        self._vertex_rows = np.array(vertices, dtype=np.intp)
        vertex = [row for row in self._rows if isinstance(row, _Vertex)]  # in row order
        self._vertex_joint = np.array([position[row.joint] for row in vertex], dtype=np.intp)
        self._vertex_point = np.array([row.point for row in vertex]).reshape(-1, 3)
        self._vertex_normal = np.array([row.normal for row in vertex]).reshape(-1, 3)
        self._vertex_offset = np.array([row.offset + row.radius for row in vertex])  # [m]
        self._witness_rows = np.array(witnesses, dtype=np.intp)
        witness = [row for row in self._rows if isinstance(row, _Witness)]  # in row order
        centres, radii, other_centres, other_radii, other_joints = [], [], [], [], []
        for row in witness:
            shape = self._shapes[row.first]
            centres.append(objects[row.first].placement.act(np.asarray(shape.aabb_center)))
            radii.append(float(shape.aabb_radius))
            if row.second is None:
                other_centres.append(row.centre)
                other_radii.append(row.bound)
                other_joints.append(0)
            else:
                other = self._shapes[row.second]
                other_centres.append(
                    objects[row.second].placement.act(np.asarray(other.aabb_center))
                )
                other_radii.append(float(other.aabb_radius))
                other_joints.append(row.other_joint)
        self._witness_joint = np.array([position[row.joint] for row in witness], dtype=np.intp)
        self._witness_other_joint = np.array(
            [position[joint] for joint in other_joints], dtype=np.intp
        )
        self._witness_centre = np.array(centres).reshape(-1, 3)
        self._witness_other_centre = np.array(other_centres).reshape(-1, 3)
        self._witness_radii = np.array(radii) + np.array(other_radii)  # [m], inf: halfspace

    def _kinematics(self, data: pin.Data, velocities: bool) -> tuple[Vector, ...]:
        """Rotations (k, 3, 3) and origins (k, 3) of the rows' joints, in the world.

        With ``velocities`` also the world linear velocities of the origins [m/s] and the
        angular velocities [rad/s], each (k, 3).
        """
        placements = [data.oMi[joint] for joint in self._joints]
        rotation = np.array([placement.rotation for placement in placements])
        origin = np.array([placement.translation for placement in placements])
        if not velocities:
            return rotation, origin
        motions = [data.v[joint] for joint in self._joints]
        linear = np.einsum("kij,kj->ki", rotation, np.array([m.linear for m in motions]))
        angular = np.einsum("kij,kj->ki", rotation, np.array([m.angular for m in motions]))
        return rotation, origin, linear, angular

    # -- evaluation -------------------------------------------------------------------------

    def evaluate(self, data: pin.Data, t: float | None = None) -> tuple[Vector, Vector]:
        """Gaps [m] and normal velocities [m/s] of the rows, each of shape (n,).

        ``data`` must hold forward kinematics with velocities (``data.oMi``, ``data.v``).
        Velocities are relative to moving shapes, placed at ``t`` [s] (required when
        :attr:`time_dependent`).
        """
        self._at(t)
        gap = np.empty(self.size)
        velocity = np.empty(self.size)
        rotation, origin, linear, angular = self._kinematics(data, True)
        if self._vertex_rows.size:
            j = self._vertex_joint
            lever = np.einsum("kij,kj->ki", rotation[j], self._vertex_point)
            normal = self._vertex_normal
            gap[self._vertex_rows] = np.einsum("ki,ki->k", normal, lever + origin[j]) - (
                self._vertex_offset
            )
            point_velocity = linear[j] + np.cross(angular[j], lever)
            velocity[self._vertex_rows] = np.einsum("ki,ki->k", normal, point_velocity)
            if self._moving_vertex.size:
                gap[self._vertex_rows] -= self._vertex_shift
                velocity[self._vertex_rows] -= self._vertex_speed
        if self._witness_rows.size:
            lower, normal, first, second = self._bounding_spheres(rotation, origin)
            near = lower <= BROAD_PHASE_MARGIN
            if near.any():
                self._place(data)
                for k in np.flatnonzero(near):
                    row = self._rows[self._witness_rows[k]]
                    assert isinstance(row, _Witness)
                    lower[k], normal[k], first[k], second[k] = self._distance(row)
            j, o = self._witness_joint, self._witness_other_joint
            relative = (linear[j] + np.cross(angular[j], first - origin[j])) - (
                linear[o] + np.cross(angular[o], second - origin[o])
            )
            if self._moving_witness.size:
                relative -= self._witness_speed
            gap[self._witness_rows] = lower
            velocity[self._witness_rows] = np.einsum("ki,ki->k", normal, relative)
        return gap, velocity

    def gaps(self, data: pin.Data, t: float | None = None) -> Vector:
        """Gaps [m] from the joint placements in ``data``, shape (n,).

        Moving shapes are placed at ``t`` [s] (required when :attr:`time_dependent`).
        """
        self._at(t)
        gap = np.empty(self.size)
        rotation, origin = self._kinematics(data, False)
        if self._vertex_rows.size:
            j = self._vertex_joint
            world = np.einsum("kij,kj->ki", rotation[j], self._vertex_point) + origin[j]
            gap[self._vertex_rows] = (
                np.einsum("ki,ki->k", self._vertex_normal, world) - self._vertex_offset
            )
            if self._moving_vertex.size:
                gap[self._vertex_rows] -= self._vertex_shift
        if self._witness_rows.size:
            lower = self._bounding_spheres(rotation, origin)[0]
            near = np.flatnonzero(lower <= BROAD_PHASE_MARGIN)
            if near.size:
                self._place(data)
                for k in near:
                    row = self._rows[self._witness_rows[k]]
                    assert isinstance(row, _Witness)
                    lower[k] = self._distance(row)[0]
            gap[self._witness_rows] = lower
        return gap

    def _bounding_spheres(self, rotation: Vector, origin: Vector) -> tuple[Vector, ...]:
        """Distances [m] between the witness rows' bounding spheres, shape (k,).

        A lower bound of each row's gap (-inf against a halfspace), followed by the unit
        normals and both centres [m], each (k, 3).
        """
        j, o = self._witness_joint, self._witness_other_joint
        first = np.einsum("kij,kj->ki", rotation[j], self._witness_centre) + origin[j]
        second = np.einsum("kij,kj->ki", rotation[o], self._witness_other_centre) + origin[o]
        delta = first - second
        distance = np.sqrt(np.einsum("ki,ki->k", delta, delta))
        lower = distance - self._witness_radii
        lower[~np.isfinite(lower)] = -np.inf
        normal = delta / np.maximum(distance, 1e-300)[:, None]
        return lower, normal, first, second

    def contact_points(self, data: pin.Data, rows: Sequence[int]) -> ContactPoints:
        """Normals and contact points of ``rows`` (exact distances, no broad phase).

        ``data`` must hold the joint placements (``data.oMi``).
        """
        k = len(rows)
        normal, point, other_point = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
        joint, other_joint = np.empty(k, dtype=np.intp), np.zeros(k, dtype=np.intp)
        gap = np.empty(k)
        self._place(data)
        for j, i in enumerate(rows):
            row = self._rows[i]
            if isinstance(row, _Vertex):
                centre = data.oMi[row.joint].act(row.point)
                normal[j] = row.normal
                point[j] = centre - row.radius * row.normal
                other_point[j] = point[j]
                joint[j] = row.joint
                gap[j] = row.normal.dot(centre) - row.offset - row.radius
                if self._row_motion[i]:
                    gap[j] -= row.normal @ self._shift[self._row_motion[i]]
            else:
                gap[j], normal[j], point[j], other_point[j] = self._distance(row)
                joint[j], other_joint[j] = row.joint, row.other_joint
        self._normal[list(rows)] = normal
        return ContactPoints(normal, point, joint, other_point, other_joint, gap)

    def jacobian(self, data: pin.Data, rows: Sequence[int]) -> Vector:
        """Normal rows :math:`n^T (J_{p_A} - J_{p_B})` of ``rows``, shape (len(rows), nv).

        ``data`` must hold joint Jacobians and placements (``pin.computeAllTerms``).
        """
        points = self.contact_points(data, rows)
        rows_out = np.empty((len(rows), self.robot.nv))
        for j in range(len(rows)):
            rows_out[j] = points.normal[j] @ self._relative_jacobian(data, points, j)
        return rows_out

    def tangent_rows(
        self, data: pin.Data, rows: Sequence[int], tangents: Sequence[Vector]
    ) -> Vector:
        """Rows :math:`t^T (J_{p_A} - J_{p_B})` for each row's tangents (k_j, 3), stacked."""
        points = self.contact_points(data, rows)
        blocks = [t @ self._relative_jacobian(data, points, j) for j, t in enumerate(tangents)]
        return np.vstack(blocks) if blocks else np.empty((0, self.robot.nv))

    def normals(self, data: pin.Data, rows: Sequence[int]) -> Vector:
        """Unit normals of ``rows``, shape (len(rows), 3)."""
        return self.contact_points(data, rows).normal

    def drift(
        self,
        data: pin.Data,
        rows: Sequence[int],
        q: Vector,
        v: Vector,
        t: float | None = None,
    ) -> Vector:
        r"""Constraint accelerations of ``rows`` at zero joint acceleration, shape (len(rows),).

        :math:`\dot J v + \partial \dot g / \partial t` in [m/s²]: the rate of the normal
        velocity :math:`u = J v + \partial g / \partial t` along the motion with
        :math:`\ddot q = 0`, so that :math:`\dot u = J \ddot q` + this.

        - Vertex rows, exact: :math:`n \cdot a_c - n \cdot \ddot x(t)`, with :math:`a_c =
          a_o + \alpha \times r + \omega \times (\omega \times r)` the classical
          acceleration of the support point (lever :math:`r` from the joint's origin) and
          :math:`\ddot x` the halfspace's acceleration. The normal of a halfspace does not
          turn (it translates only).
        - Witness rows, by a fourth-order central difference (points :math:`\pm s, \pm 2s`)
          of :math:`u` along the flow :math:`q \oplus s v` (``pin.integrate``, on which
          :math:`\ddot q = 0`) and :math:`t + s`, with
          :math:`s = 3 \times 10^{-5} / \max(1, \|v\|)` [s]: the exact expression needs the
          curvatures of both shapes at the witness points (the rolling of the witness points
          and the turning of the normal), which coal does not give. Truncation error
          :math:`O(s^4)`, round-off about :math:`10^{-16} |u| / s`; wrong where the witness
          points switch features within :math:`2 s` (a box's face to its edge, two flat
          faces in contact).

        Args:
            data: Pinocchio data with ``pin.forwardKinematics(model, data, q, v, 0)`` (joint
                placements, velocities and accelerations at zero joint acceleration).
            rows: Rows of this geometry (0 is its first row).
            q: Configuration of the robot, shape (nq,).
            v: Velocity of the robot, shape (nv,).
            t: Time in [s]; required when :attr:`time_dependent`.
        """
        rows = [int(i) for i in rows]
        drift = np.zeros(len(rows))
        witness: list[int] = []
        for j, i in enumerate(rows):
            row = self._rows[i]
            if not isinstance(row, _Vertex):
                witness.append(j)
                continue
            placement = data.oMi[row.joint]
            rotation = placement.rotation
            omega = rotation @ data.v[row.joint].angular  # [rad/s], world
            local = data.v[row.joint]
            origin_acceleration = rotation @ (
                data.a[row.joint].linear + np.cross(local.angular, local.linear)
            )  # classical [m/s²], world
            alpha = rotation @ data.a[row.joint].angular  # [rad/s²], world
            lever = rotation @ row.point  # [m]
            acceleration = (
                origin_acceleration
                + np.cross(alpha, lever)
                + np.cross(omega, np.cross(omega, lever))
            )
            drift[j] = row.normal @ acceleration
            name = self._row_motion[i]
            if name:
                if t is None:
                    self._at(t)  # raises, naming the moving shapes
                drift[j] -= row.normal @ self._motions[name](float(t))[2]  # type: ignore[arg-type]
        if witness:
            drift[witness] = self._witness_drift(
                [rows[j] for j in witness], np.asarray(q), np.asarray(v), t
            )
        return drift

    def _witness_drift(self, rows: list[int], q: Vector, v: Vector, t: float | None) -> Vector:
        """Central difference of the witness rows' normal velocities along the flow, (k,)."""
        model = self.robot.model
        if not hasattr(self, "_drift_data"):
            self._drift_data = pin.Data(model)
        data = self._drift_data
        step = WITNESS_DRIFT_STEP / max(1.0, float(np.linalg.norm(v)))  # [s]
        velocities = {}
        for k in (-2, -1, 1, 2):
            pin.forwardKinematics(model, data, pin.integrate(model, q, k * step * v), v)
            velocities[k] = self.evaluate(data, None if t is None else t + k * step)[1][rows]
        if t is not None:
            self._at(t)  # the shapes back where the caller placed them
        difference = 8.0 * (velocities[1] - velocities[-1]) - (velocities[2] - velocities[-2])
        return np.asarray(difference / (12.0 * step), dtype=np.float64)

    # -- helpers ----------------------------------------------------------------------------

    def _relative_jacobian(self, data: pin.Data, points: ContactPoints, j: int) -> Vector:
        """:math:`J_{p_A} - J_{p_B}` of entry ``j`` of ``points``, shape (3, nv)."""
        J = _point_jacobian(self.robot.model, data, int(points.joint[j]), points.point[j])
        if points.other_joint[j]:
            J = J - _point_jacobian(
                self.robot.model, data, int(points.other_joint[j]), points.other_point[j]
            )
        return J

    def _place(self, data: pin.Data) -> None:
        pin.updateGeometryPlacements(
            self.robot.model, data, self.geometry_model, self._geometry_data
        )

    def _transform(self, index: int) -> Any:
        placement = self._geometry_data.oMg[index]
        return coal.Transform3s(placement.rotation, placement.translation)

    def _distance(self, row: _Witness) -> tuple[float, Vector, Vector, Vector]:
        """Signed distance [m], normal from the second shape to the first, witness points."""
        result = self._result
        result.clear()
        if row.second is None:
            shape, transform = row.shape, row.transform
        else:
            shape, transform = self._shapes[row.second], self._transform(row.second)
        distance = coal.distance(
            self._shapes[row.first],
            self._transform(row.first),
            shape,
            transform,
            self._request,
            result,
        )
        first = np.array(result.getNearestPoint1())
        second = np.array(result.getNearestPoint2())
        return float(distance), -np.array(result.normal), first, second


def _point_jacobian(model: pin.Model, data: pin.Data, joint: int, point: Vector) -> Vector:
    r""":math:`J_{lin} - [p - o]_\times J_{ang}` of the material point ``point`` of ``joint``."""
    J = pin.getJointJacobian(model, data, joint, _LWA)
    lever = point - data.oMi[joint].translation
    return J[:3] + cross(J[3:].T, lever).T


def _support_points(shape: Any) -> list[tuple[Vector, float]]:
    """Support points (in the shape's frame [m]) and radii of a shape against a halfspace."""
    if isinstance(shape, coal.Sphere):
        return [(np.zeros(3), float(shape.radius))]
    if isinstance(shape, coal.Box):
        half_sides = np.asarray(shape.halfSide)
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        return [(s * half_sides, 0.0) for s in signs]
    if isinstance(shape, coal.Cylinder):
        angles = 2.0 * np.pi * np.arange(CYLINDER_RIM_POINTS) / CYLINDER_RIM_POINTS
        r, half = float(shape.radius), float(shape.halfLength)
        return [
            (np.array([r * np.cos(a), r * np.sin(a), z]), 0.0)
            for z in (-half, half)
            for a in angles
        ]
    if isinstance(shape, coal.Capsule):
        half = float(shape.halfLength)
        return [(np.array([0.0, 0.0, z]), float(shape.radius)) for z in (-half, half)]
    if isinstance(shape, coal.ConvexBase):
        return [(np.array(p), 0.0) for p in np.asarray(shape.points())]
    raise InvalidParameterError(
        "collision shape", type(shape).__name__, "a sphere, box, cylinder, capsule or mesh"
    )


def _environment_shape(shape: EnvironmentShape) -> tuple[Any, float, Vector]:
    """The coal geometry of an environment shape and its bounding sphere.

    Returns:
        The geometry (in the shape's frame, but for a halfspace, in the world), the radius
        of its bounding sphere in [m] (inf for a halfspace) and that sphere's centre in the
        shape's frame in [m], shape (3,).

    Raises:
        InvalidParameterError: A mesh file does not load.
    """
    if shape.type == "sphere":
        return coal.Sphere(shape.radius), shape.radius, np.zeros(3)
    if shape.type == "box":
        return coal.Box(*shape.size), 0.5 * float(np.linalg.norm(shape.size)), np.zeros(3)
    if shape.type == "mesh":
        hull = load_mesh_hull(str(shape.mesh), shape.scale)
        return hull, float(hull.aabb_radius), np.asarray(hull.aabb_center, dtype=float)
    return coal.Halfspace(shape.normal, float(shape.normal @ shape.position)), np.inf, np.zeros(3)


def _convex_hull(mesh: Any, path: str) -> Any:
    """The convex hull (``coal.ConvexBase``) of a loaded mesh (``coal.BVHModelBase``).

    Qhull, through coal, ends the process on vertices that span no volume, so they are
    refused first: fewer than four, or all within :data:`MESH_FLATNESS` of one plane.

    Raises:
        InvalidParameterError: The mesh spans no volume, naming ``path``, the number of
            vertices and the thickness.
    """
    vertices = np.asarray(mesh.vertices(), dtype=float).reshape(-1, 3)
    thickness = extent = 0.0
    if vertices.shape[0] >= 4:
        centred = vertices - vertices.mean(axis=0)
        axes = np.linalg.svd(centred, full_matrices=False)[2]  # principal directions
        spans = np.ptp(centred @ axes.T, axis=0)  # [m] along each, widest first
        thickness, extent = float(spans[2]), float(spans[0])
    if not thickness > MESH_FLATNESS * extent:  # also fewer than four vertices: 0 > 0
        raise InvalidParameterError(
            "mesh",
            path,
            f"a mesh with a volume (its convex hull stands for it); its {vertices.shape[0]} "
            f"vertices lie in one plane (thickness {thickness:.3g} m across {extent:.3g} m)",
        )
    mesh.buildConvexHull(True, "Qt")
    return mesh.convex


def load_mesh_hull(path: str, scale: Vector) -> Any:
    """The convex hull (``coal.ConvexBase``) of the mesh file ``path``, scaled by ``scale``.

    Args:
        path: A mesh file coal's loader reads (STL, OBJ, DAE, ...).
        scale: Scale factors along the mesh's axes, shape (3,).

    Raises:
        InvalidParameterError: The file does not load or has fewer than four vertices not
            in one plane (no hull), naming the path and coal's reason.
    """
    try:
        mesh = coal.MeshLoader().load(path, np.asarray(scale, dtype=float))
    except (ValueError, RuntimeError) as error:
        lines = [line.strip() for line in str(error).splitlines() if line.strip()]
        reason = next((line for line in lines if line.startswith("message:")), str(error))
        raise InvalidParameterError(
            "mesh", path, f"a mesh file coal can load (STL, OBJ, DAE); {reason}"
        ) from error
    hull = _convex_hull(mesh, path)
    hull.computeLocalAABB()
    return hull
