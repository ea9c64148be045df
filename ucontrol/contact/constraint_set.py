"""All unilateral constraints of a scene, evaluated together on the robot's data."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_vector
from ucontrol.contact.point_contact import PointContact
from ucontrol.contact.tangent_basis import cross, tangent_basis
from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.model.robot_model import RobotModel

if TYPE_CHECKING:  # the kinds of constraint a scene may not declare, imported by those that do
    from ucontrol.contact.bilateral import BilateralConstraint, BilateralSet
    from ucontrol.contact.clearance_joint import ClearanceJoint
    from ucontrol.contact.collision_pair import CollisionPair
    from ucontrol.contact.joint_stop import JointStop
    from ucontrol.contact.sphere_sphere_contact import SphereSphereContact

Vector = NDArray[np.float64]
_LWA = pin.LOCAL_WORLD_ALIGNED
#: Largest |n · a| of a plane contact of a planar robot (n the plane normal, a the axis).
_PLANAR_TOLERANCE = 1e-9
#: Relative distance to its circle within which a clearance joint's play is on it.
_ON_CIRCLE = 1e-12
#: Most sets of point contacts whose row selections are kept (ConstraintSet._point_selection).
_SELECTIONS = 256


def _along(direction: list[float], vector: list[float]) -> float:
    """The component of a 3-vector along a unit ``direction``, both as Python floats.

    Three products of Python floats cost less than a numpy dot of two 3-vectors (a call into
    BLAS), of which :meth:`ConstraintSet.evaluate` makes two per point contact.
    """
    return direction[0] * vector[0] + direction[1] * vector[1] + direction[2] * vector[2]


class ConstraintSet:
    r"""Point contacts, sphere–sphere contacts, collision pairs, joint stops, then clearances.

    Constraint ``i`` has gap ``g_i(q)`` (>= 0 when admissible), normal velocity
    ``u_i = J_i v`` and restitution ``e_i``. Point contacts come first, in the order given, then
    sphere–sphere contacts, then the rows of the collision pairs
    (:class:`~ucontrol.contact.collision_geometry.CollisionGeometry`, built only when there is
    a pair), then each finite stop bound (lower before upper), then each clearance joint
    (:mod:`~ucontrol.contact.clearance_joint`: the journal in its bearing, one tangential row
    with friction, whatever ``planar_axis``).

    Contacts with a positive friction coefficient also have tangential rows (:meth:`tangent_rows`):
    two (spatial friction) or, when the robot moves in a plane (``planar_axis``), one — the
    tangent :math:`a \times n` in the plane of motion (:mod:`ucontrol.contact.tangent_basis`).
    A contact point is the point of the sphere nearest the other body, so its tangential
    velocity includes the sphere's rotation: :math:`v_F + \omega \times (-r n)`.

    Point contacts against a moving plane (:attr:`Plane.motion`, a translation :math:`x(t)`)
    are time-dependent: :math:`g(q, t) = n \cdot (p_F(q) - p_0 - x(t)) - r`, and their
    velocities are relative to the plane, :math:`u = J v + \partial g / \partial t` with
    :math:`\partial g / \partial t = -n \cdot \dot x(t)` (:meth:`normal_rate`; on tangential
    rows :math:`-t \cdot \dot x(t)`, :meth:`tangent_rate`). :meth:`evaluate` then needs the
    time.

    Args:
        robot: The robot whose data buffer is read.
        contacts: Point contacts against planes.
        stops: Joint stops.
        sphere_contacts: Contacts between two spheres on robot frames.
        planar_axis: Unit normal of the plane the robot moves in, shape (3,), or None: with it
            every frictional contact is planar (one tangent), without it spatial (two).
        collision_pairs: Pairs of collision shapes (link ↔ environment shape or link).
        bilateral: Bilateral constraints h(q) = 0 (loop closures, joint couplings), kept
            apart from the unilateral list (:attr:`bilateral`).
        clearances: Revolute joints with radial clearance; the robot must have their play
            joints (:func:`~ucontrol.model.joint_clearance.with_joint_clearance`).

    Attributes:
        robot: The robot whose data buffer is read.
        contacts: The point contacts.
        sphere_contacts: The sphere–sphere contacts.
        stops: The joint stops.
        clearances: The clearance joints.
        collision_pairs: The collision pairs.
        collision: Their rows' geometry, or None without pairs.
        bilateral: The bilateral constraints'
            :class:`~ucontrol.contact.bilateral.BilateralSet`, or None without any (they are
            not among the n unilateral constraints, gaps and impulses).
        planar_axis: The axis of planar motion, or None.
        names: One label per constraint.
        restitution: Restitution coefficients, shape (n,).
        friction: Coulomb coefficients, shape (n,) (0 for stops).
        tangent_count: Tangential rows of each constraint (0, 1 or 2), shape (n,).
        has_friction: Whether any constraint has tangential rows.
        time_dependent: Whether some contact is against a moving surface or shape.
        n_contacts: Number of point, sphere–sphere and collision contacts (the first
            constraints).
        plane_terms: Each point contact's plane normal and offset
            :math:`n \cdot p_0 + r` in [m] (its gap is :math:`n \cdot p_F - d`), shape
            (len(contacts), 4).
        stop_coordinates: Each stop bound's configuration and velocity index (idx_q, idx_v).
        stop_terms: Each stop bound's sign (+1 lower, -1 upper) and bound in [rad] or [m]
            (its gap is :math:`\sigma (q_j - b)`), shape (len(stop_coordinates), 2).
        size: Number of constraints n.

    Raises:
        InvalidParameterError: A stop is on a joint with more than one degree of freedom, a
            plane contact of a planar robot has a normal out of the plane of motion, the
            robot has no degree of freedom (nv = 0) but constraints, or a clearance joint has
            no play joints.
    """

    def __init__(
        self,
        robot: RobotModel,
        contacts: Sequence[PointContact] = (),
        stops: Sequence[JointStop] = (),
        sphere_contacts: Sequence[SphereSphereContact] = (),
        planar_axis: Vector | None = None,
        collision_pairs: Sequence[CollisionPair] = (),
        bilateral: Sequence[BilateralConstraint] = (),
        clearances: Sequence[ClearanceJoint] = (),
    ) -> None:
        declared = {
            "contacts": len(contacts),
            "stops": len(stops),
            "sphere_contacts": len(sphere_contacts),
            "collision_pairs": len(collision_pairs),
            "bilateral": len(bilateral),
            "clearances": len(clearances),
        }
        if robot.nv == 0 and any(declared.values()):  # nothing can move against them
            raise InvalidParameterError(
                f"constraints of robot {robot.name!r}",
                {kind: n for kind, n in declared.items() if n},
                "none: the robot has no degree of freedom (nv = 0)",
            )
        self.robot = robot
        self.bilateral: BilateralSet | None = None
        if bilateral:
            from ucontrol.contact.bilateral import BilateralSet

            self.bilateral = BilateralSet(robot, bilateral)
        self.collision_pairs = tuple(collision_pairs)
        self.collision = None
        if self.collision_pairs:  # geometry loaded only for declared pairs
            from ucontrol.contact.collision_geometry import CollisionGeometry

            self.collision = CollisionGeometry(robot, self.collision_pairs)
        self.contacts = tuple(contacts)
        self.sphere_contacts = tuple(sphere_contacts)
        self.stops = tuple(stops)
        self.planar_axis = None
        if planar_axis is not None:
            axis = as_vector("planar_axis", planar_axis, 3)
            norm = float(np.linalg.norm(axis))
            if norm < 1e-12:
                raise InvalidParameterError("planar_axis", planar_axis, "a non-zero vector")
            self.planar_axis = axis / norm
        self._frame_ids = [robot.frame_id(contact.frame) for contact in self.contacts]
        self._normals = np.array([c.surface.normal for c in self.contacts]).reshape(-1, 3)
        self._offsets = np.array(
            [c.surface.normal @ c.surface.point + c.radius for c in self.contacts]
        )
        pairs = self.sphere_contacts
        self._pair_terms = [
            (robot.frame_id(c.frame), robot.frame_id(c.other_frame), c.radius + c.other_radius)
            for c in pairs
        ]
        self._pair_frames = np.array([terms[:2] for terms in self._pair_terms], dtype=np.intp)
        self._pair_radius = np.array(
            [(c.radius, c.other_radius) for c in pairs], dtype=float
        ).reshape(-1, 2)
        self._pair_radii_sum = self._pair_radius.sum(axis=1)  # [m]
        self._pair_kinematics = _PairFrames(robot.model, self._pair_frames) if pairs else None
        all_contacts: tuple[PointContact | SphereSphereContact, ...] = (*self.contacts, *pairs)
        names = [contact.name for contact in all_contacts]
        restitution = [contact.restitution for contact in all_contacts]
        friction = [contact.friction for contact in all_contacts]
        self._pairs_end = len(all_contacts)
        self.plane_terms = np.column_stack((self._normals, self._offsets)).reshape(-1, 4)
        if self.collision is not None:
            names += self.collision.names
            restitution += self.collision.restitution.tolist()
            friction += self.collision.friction.tolist()
        n_contacts = len(names)
        stop_q, stop_v, stop_sign, stop_bound = [], [], [], []
        for stop in self.stops:
            joint = robot.model.joints[robot.joint_id(stop.joint)]
            if joint.nq != 1 or joint.nv != 1:
                raise InvalidParameterError(
                    "joint", stop.joint, "a revolute or prismatic joint with nq = nv = 1"
                )
            for sign, bound, side in ((1.0, stop.lower, "lower"), (-1.0, stop.upper, "upper")):
                if bound is None:
                    continue
                stop_q.append(joint.idx_q)
                stop_v.append(joint.idx_v)
                stop_sign.append(sign)
                stop_bound.append(bound)
                names.append(f"{stop.joint}/{side}")
                restitution.append(stop.restitution)
                friction.append(0.0)
        self._stops_end = len(names)
        self.clearances = tuple(clearances)
        self._play = [_PlayTerms(robot, clearance) for clearance in self.clearances]
        for clearance in self.clearances:
            names.append(clearance.name)
            restitution.append(clearance.restitution)
            friction.append(clearance.friction)
        self.stop_coordinates = list(zip(stop_q, stop_v, strict=True))
        self.stop_terms = np.column_stack((stop_sign, stop_bound)).reshape(-1, 2)
        self._stop_q = np.array(stop_q, dtype=int)
        self._stop_v = np.array(stop_v, dtype=int)
        self._stop_sign = np.array(stop_sign)
        self._stop_bound = np.array(stop_bound)
        self.names = names
        self.restitution = np.array(restitution, dtype=float)
        self.friction = np.array(friction, dtype=float)
        self.n_contacts = n_contacts
        self.size = len(names)
        self._n_point = len(self.contacts)
        spatial_rows = 1 if self.planar_axis is not None else 2
        self.tangent_count = np.where(self.friction > 0.0, spatial_rows, 0)
        self.tangent_count[self._stops_end :] = self.friction[self._stops_end :] > 0.0
        self.has_friction = bool(self.tangent_count.any())
        self._has_stops = self._stops_end > self.n_contacts
        self._contact_terms = list(
            zip(self._frame_ids, list(self._normals), self._offsets.tolist(), strict=True)
        )
        # The same with the normals as Python floats (:func:`_along`).
        self._plane_terms = list(
            zip(self._frame_ids, self._normals.tolist(), self._offsets.tolist(), strict=True)
        )
        # The views on the Pinocchio data whose frame origins :meth:`evaluate` last read.
        self._origins = _DataViews()
        self._plane_tangents = [tangent_basis(normal, self.planar_axis) for normal in self._normals]
        self._moving = [
            (i, contact.surface.motion, contact.surface.normal)
            for i, contact in enumerate(self.contacts)
            if contact.surface.motion is not None
        ]
        self._moving_shapes = self.collision is not None and self.collision.time_dependent
        self.time_dependent = bool(self._moving) or self._moving_shapes
        # Contact point p_F - r n: velocity v_F + ω × (-r n), i.e. t·v_F + r (t × n)·ω.
        self._plane_levers = [
            contact.radius * cross(tangents, contact.surface.normal)
            for contact, tangents in zip(self.contacts, self._plane_tangents, strict=True)
        ]
        # Each point contact's rows as directions on its frame Jacobian (LOCAL_WORLD_ALIGNED,
        # linear then angular part): the normal row (n, 0), then each tangent row (t, ℓ), zero
        # past its count; read by :meth:`contact_rows` with one Jacobian per frame.
        counts = self.tangent_count[: self._n_point].tolist()
        width = 1 + max(counts, default=0)
        directions = np.zeros((self._n_point, width, 6))
        self._point_tangential = np.zeros((self._n_point, width - 1), dtype=bool)
        for i, count in enumerate(counts):
            directions[i, 0, :3] = self._normals[i]
            directions[i, 1 : 1 + count, :3] = self._plane_tangents[i][:count]
            directions[i, 1 : 1 + count, 3:] = self._plane_levers[i][:count]
            self._point_tangential[i, :count] = True
        self._point_directions = directions
        # The frame Jacobians of a call, one (6, nv) block per contact read ((6,) when nv = 1,
        # as Pinocchio gives them then), and each active set's selections (_point_selection).
        self._point_jacobians = np.zeros((self._n_point, 6, robot.nv))
        self._point_blocks = [block.reshape(6, -1).squeeze(1) if robot.nv == 1 else block
                              for block in self._point_jacobians]  # fmt: skip
        self._point_selections: dict[tuple[int, ...], tuple[Vector, Any, Vector]] = {}
        self._closure_rules = self._ahead_rules(robot)
        #: Whether some contact closes only ahead of another (:meth:`closure_barred`).
        self.has_closure_rules = bool(self._closure_rules)
        # Frame placements of the rules, on a buffer of their own (built only with rules).
        self._rule_data = pin.Data(robot.model) if self._closure_rules else None
        if self.planar_axis is not None:
            for contact in self.contacts:
                if abs(contact.surface.normal @ self.planar_axis) > _PLANAR_TOLERANCE:
                    raise InvalidParameterError(
                        "planar_axis",
                        self.planar_axis.tolist(),
                        f"orthogonal to the normal {contact.surface.normal.tolist()} of "
                        f"{contact.name!r} (the robot moves in the plane normal to the axis)",
                    )

    def evaluate(
        self, data: pin.Data, q: Vector, v: Vector, t: float | None = None
    ) -> tuple[Vector, Vector]:
        """Gaps and normal velocities (relative to moving surfaces), each of shape (n,).

        ``data`` must hold forward kinematics with velocity and frame placements at (q, v)
        (``pin.computeAllTerms`` then ``pin.updateFramePlacements``).

        Args:
            data: Pinocchio data at (q, v).
            q: Configuration, shape (nq,).
            v: Velocity, shape (nv,).
            t: Time in [s]; required when :attr:`time_dependent`, unused otherwise.

        Raises:
            InvalidParameterError: ``t`` is None and some surface moves.
        """
        model = self.robot.model
        gap = np.empty(self.size)
        velocity = np.empty(self.size)
        origins = self._frame_origins(data)
        for i, (frame_id, n_i, offset) in enumerate(self._plane_terms):
            gap[i] = _along(n_i, origins[i].tolist()) - offset
            linear = pin.getFrameVelocity(model, data, frame_id, _LWA).linear  # [m/s]
            velocity[i] = _along(n_i, linear.tolist())
        if self._pair_kinematics is not None:  # all pairs at once
            pairs = slice(self._n_point, self._pairs_end)
            delta, distance = self._pair_offsets(data)
            first, second = self._pair_kinematics.index.T
            frame_velocities = self._pair_kinematics.velocities(data)  # [m/s]
            relative = frame_velocities[first] - frame_velocities[second]
            gap[pairs] = distance - self._pair_radii_sum
            velocity[pairs] = np.einsum("ij,ij->i", delta, relative) / distance
        if self.collision is not None:
            rows = slice(self._pairs_end, self.n_contacts)
            gap[rows], velocity[rows] = self.collision.evaluate(data, t)
        if self.time_dependent:
            self._move(gap, velocity, t)
        if self._has_stops:
            k, end = self.n_contacts, self._stops_end
            gap[k:end] = self._stop_sign * (q[self._stop_q] - self._stop_bound)
            velocity[k:end] = self._stop_sign * v[self._stop_v]
        for i, play in enumerate(self._play, self._stops_end):
            gap[i], normal = play.gap_normal(data)
            velocity[i] = -normal.dot(v[play.v_xy])
        return gap, velocity

    def _frame_origins(self, data: pin.Data) -> list[Vector]:
        """The point contacts' frame origins in ``data`` [m], each shape (3,), read without a call.

        Views on ``data``'s memory (:class:`_DataViews`): reading them costs no call into
        Pinocchio (two per contact otherwise, most of a call of :meth:`evaluate`:
        docs/benchmarks.md).
        """
        placements = data.oMf
        return self._origins.read(
            data, lambda: [placements[frame_id].translation for frame_id in self._frame_ids]
        )

    def differs_in_numbers_only(self, other: ConstraintSet) -> bool:
        """Whether ``other`` is this set up to its numbers: what an integrator can be given.

        The numbers that may differ: restitutions (0 on the same constraints), friction
        coefficients (> 0 on the same ones), plane points and normals, and stop bounds. The
        rest must be equal: the robot's model, the constraints' names, frames, radii and stop
        coordinates, the closure rules and the axis of planar motion. Only sets of point
        contacts against fixed planes and joint stops qualify (no sphere pair, collision pair,
        bilateral or clearance constraint, no moving surface).
        """
        sets = (self, other)
        if any(
            s.sphere_contacts or s.collision is not None or s.bilateral is not None for s in sets
        ) or any(s.clearances or s.time_dependent for s in sets):
            return False

        def shape(s: ConstraintSet) -> tuple[Any, ...]:
            rules = [(c.closes_ahead_of, c.direction_of_travel, c.ahead_frame) for c in s.contacts]
            axis = None if s.planar_axis is None else s.planar_axis.tolist()
            return (
                s.names, s._frame_ids, [c.radius for c in s.contacts], s.stop_coordinates,
                s.tangent_count.tolist(), (s.restitution != 0.0).tolist(), rules, axis,
            )  # fmt: skip

        same_robot = other.robot is self.robot or other.robot.model == self.robot.model
        return same_robot and shape(self) == shape(other)

    def _ahead_rules(self, robot: RobotModel) -> list[tuple[int, int, int, Vector]]:
        """(constraint, ahead frame, other frame, direction) of each ``closes_ahead_of``."""
        frames = {contact.frame for contact in self.contacts}
        rules = []
        for i, contact in enumerate(self.contacts):
            if not contact.closes_ahead_of:
                continue
            other = contact.closes_ahead_of
            if other not in frames - {contact.frame}:
                raise NotFoundError(
                    f"closes_ahead_of of {contact.name!r}", other, sorted(frames - {contact.frame})
                )
            direction = np.array(contact.direction_of_travel)
            ahead = robot.frame_id(contact.ahead_frame) if contact.ahead_frame else None
            frame = self._frame_ids[i] if ahead is None else ahead
            rules.append((i, frame, robot.frame_id(other), direction))
        return rules

    def closure_barred(self, q: Vector) -> list[int]:
        r"""The contacts that may not close at q: behind the frame their rule names.

        Contact i with ``closes_ahead_of`` (:class:`PointContact`) is barred while
        :math:`a \cdot (p_i - p_j) < 0`, :math:`a` its direction of travel, :math:`p_i` the
        position of its ``ahead_frame`` (its own frame by default) and :math:`p_j` the
        other frame's. The integrator applies the bar to constraints its last step
        did not hold (a held stance foot stays, wherever the swing foot is).

        Args:
            q: Configuration of the robot, shape (nq,).

        Returns:
            The barred constraints' indices (empty without rules).
        """
        margins = self.closure_margins(q)
        return [i for i, *_ in self._closure_rules if margins[i] < 0.0]

    def closure_margins(self, q: Vector) -> Vector:
        r"""How far each contact with a rule is past the frame its rule names, in [m].

        :math:`a \cdot (p_i - p_j)` (:meth:`closure_barred`) for the contacts with
        ``closes_ahead_of``, :math:`+\infty` for the other constraints: a contact is barred
        while its margin is negative.

        Args:
            q: Configuration of the robot, shape (nq,).

        Returns:
            The margins, shape (n,).
        """
        margins = np.full(self.size, np.inf)
        data = self._rule_data
        if data is None:
            return margins
        pin.framesForwardKinematics(self.robot.model, data, q)
        placements = data.oMf
        for i, frame, other, direction in self._closure_rules:
            step = placements[frame].translation - placements[other].translation  # [m]
            margins[i] = direction.dot(step)
        return margins

    def jacobian(self, data: pin.Data, indices: Sequence[int] | NDArray[np.intp]) -> Vector:
        """Normal Jacobian rows of the constraints ``indices``, shape (len(indices), nv).

        ``data`` must hold joint Jacobians and frame placements (``pin.computeAllTerms`` then
        ``pin.updateFramePlacements``).
        """
        index = _index_list(indices)
        if self._point_contacts_only(index):
            return self._point_rows(data, index)[0]
        return self._normal_rows(data, index, None)

    def _normal_rows(self, data: pin.Data, index: list[int], pair_rows: Vector | None) -> Vector:
        """:meth:`jacobian` of ``index``, given the normal rows of its sphere pairs or None."""
        rows = np.zeros((len(index), self.robot.nv))
        k = self.n_contacts
        shapes: list[int] = []  # positions in indices of the collision rows
        pairs: list[int] = []  # positions in indices of the sphere-pair rows
        points: list[int] = []  # positions in indices of the point contacts
        for row, i in enumerate(index):  # Python ints: cheaper comparisons
            if self._pairs_end <= i < k:
                shapes.append(row)
            elif i < self._n_point:
                points.append(row)
            elif i < k:
                pairs.append(row)
            elif i < self._stops_end:
                rows[row, self._stop_v[i - k]] = self._stop_sign[i - k]
            else:
                play = self._play[i - self._stops_end]
                rows[row, play.v_xy] = -play.gap_normal(data)[1]
        if points:  # as without the other constraints, to the last bit
            rows[points] = self._point_rows(data, [index[row] for row in points])[0]
        if pairs:
            if pair_rows is None:
                pair_ids = [index[row] - self._n_point for row in pairs]
                pair_rows = self._pair_block(data, pair_ids, tangential=False)[0]
            rows[pairs] = pair_rows
        if shapes and self.collision is not None:
            rows[shapes] = self.collision.jacobian(
                data, [index[row] - self._pairs_end for row in shapes]
            )
        return rows

    def tangent_rows(
        self, data: pin.Data, indices: Sequence[int] | NDArray[np.intp]
    ) -> tuple[Vector, Vector]:
        """Tangential Jacobian rows of the frictional constraints among ``indices``.

        Constraint ``indices[j]`` contributes ``tangent_count[indices[j]]`` rows, in the order
        of ``indices``: the velocity of its contact point (sphere 1 relative to sphere 2 for a
        sphere–sphere contact) along each tangent. Same requirements on ``data`` as
        :meth:`jacobian`.

        Returns:
            The rows, shape (k, nv), and the unit tangent of each row in world coordinates,
            shape (k, 3).
        """
        indices = _index_list(indices)
        if self._point_contacts_only(indices):
            return self._point_rows(data, indices)[1:]
        return self._tangential_rows(data, indices, None)

    def _tangential_rows(
        self, data: pin.Data, indices: list[int], pair_block: tuple[Vector, Vector] | None
    ) -> tuple[Vector, Vector]:
        """:meth:`tangent_rows` of ``indices``, given its sphere pairs' rows or None.

        ``pair_block``: the tangential rows and tangents of each sphere pair of ``indices``
        (frictional or not, in order), shapes (k, c, nv) and (k, c, 3).
        """
        counts = self.tangent_count[indices].tolist()
        rows = np.empty((sum(counts), self.robot.nv))
        directions = np.empty((rows.shape[0], 3))
        first_pair, pairs_end = self._n_point, self._pairs_end
        is_pair = [first_pair <= i < pairs_end for i in indices]
        frictional = [count > 0 for pair, count in zip(is_pair, counts, strict=True) if pair]
        if any(frictional):  # all sphere pairs at once
            if pair_block is None:
                pair_ids = [
                    i - first_pair
                    for i, pair, count in zip(indices, is_pair, counts, strict=True)
                    if pair and count
                ]
                pair_block = self._pair_block(data, pair_ids, tangential=True)[1:]
            elif not all(frictional):
                pair_block = (pair_block[0][frictional], pair_block[1][frictional])
            pair_rows, pair_tangents = pair_block
            starts = np.cumsum(counts) - counts  # first row of each constraint
            pair_starts = [
                start
                for pair, count, start in zip(is_pair, counts, starts.tolist(), strict=True)
                if pair and count
            ]
            targets = np.array(pair_starts)[:, None] + np.arange(pair_tangents.shape[1])
            rows[targets] = pair_rows
            directions[targets] = pair_tangents
        point_ids: list[int] = []  # the point contacts with tangential rows
        point_targets: list[int] = []  # and the positions of their rows
        start = 0
        for i, count in zip(indices, counts, strict=True):
            if count == 0:
                continue
            end = start + count
            if first_pair <= i < pairs_end:  # above
                start = end
                continue
            if i >= self._stops_end:
                play = self._play[i - self._stops_end]
                rows[start:end] = 0.0
                normal = play.gap_normal(data)[1]
                tangent = np.array([-normal[1], normal[0]])  # a × n in the play plane
                rows[start:end, play.v_xy] = tangent
                rows[start:end, play.v_theta] = play.radius
                directions[start:end] = play.world_direction(data, tangent)
                start = end
                continue
            if self._pairs_end <= i < self.n_contacts and self.collision is not None:
                row = i - self._pairs_end
                normal = self.collision.normals(data, [row])[0]
                tangents = tangent_basis(normal, self.planar_axis)
                rows[start:end] = self.collision.tangent_rows(data, [row], [tangents])
            else:  # a point contact: below
                point_ids.append(i)
                point_targets.extend(range(start, end))
                start = end
                continue
            directions[start:end] = tangents
            start = end
        if point_ids:  # as without the other constraints, to the last bit
            _, rows[point_targets], directions[point_targets] = self._point_rows(data, point_ids)
        return rows, directions

    def contact_rows(
        self, data: pin.Data, indices: Sequence[int] | NDArray[np.intp]
    ) -> tuple[Vector, Vector, Vector]:
        r"""Normal and tangential rows of the constraints ``indices``, read together.

        :meth:`jacobian` and :meth:`tangent_rows` in one call: each contact frame's Jacobian
        is read once for both kinds of rows (the normal row is :math:`n^T J_{lin}`, the
        tangential ones :math:`t^T J_{lin} + \ell^T J_{ang}`, as one product of stacked
        directions with the stacked frame Jacobians), for point contacts and sphere pairs.
        Same requirements on ``data`` as :meth:`jacobian`.

        Returns:
            The normal rows, shape (len(indices), nv), the tangential rows, shape (k, nv),
            and the unit tangent of each tangential row in world coordinates, shape (k, 3).
        """
        indices = _index_list(indices)
        if self._point_contacts_only(indices):
            return self._point_rows(data, indices)
        pair_ids = [i - self._n_point for i in indices if self._n_point <= i < self._pairs_end]
        if not pair_ids:
            return self._normal_rows(data, indices, None), *self._tangential_rows(
                data, indices, None
            )
        # The sphere pairs' normal and tangential rows from one reading of their frames.
        normal_rows, tangent_rows, tangents = self._pair_block(data, pair_ids, tangential=True)
        return (
            self._normal_rows(data, indices, normal_rows),
            *self._tangential_rows(data, indices, (tangent_rows, tangents)),
        )

    def _point_contacts_only(self, indices: list[int]) -> bool:
        """Whether ``indices`` are point contacts against planes, at least one."""
        return bool(indices) and max(indices) < self._n_point

    def _point_rows(self, data: pin.Data, indices: list[int]) -> tuple[Vector, Vector, Vector]:
        """:meth:`contact_rows` of point contacts ``indices``, one frame Jacobian each.

        The rows are one batched product of the contacts' stacked directions (normal, then
        tangents with their levers; shape (m, 1 + c, 6)) with their frame Jacobians (m, 6, nv).
        """
        model, frames, blocks = self.robot.model, self._frame_ids, self._point_blocks
        for k, i in enumerate(indices):
            blocks[k][...] = pin.getFrameJacobian(model, data, frames[i], _LWA)
        directions, tangential, tangents = self._point_selection(indices)
        rows = np.matmul(directions, self._point_jacobians[: len(indices)])  # (m, 1 + c, nv)
        if tangential is None:  # every contact's tangential rows
            return rows[:, 0], rows[:, 1:].reshape(-1, self.robot.nv), tangents
        return rows[:, 0], rows[:, 1:][tangential], tangents

    def _point_selection(self, indices: list[int]) -> tuple[Vector, Any, Vector]:
        """Directions (m, 1 + c, 6), tangential-row mask (m, c) or None (all) and tangents.

        Of the point contacts ``indices``; kept for each set of indices met (a few active
        sets of feet), at most :data:`_SELECTIONS` of them.
        """
        key = tuple(indices)
        selection = self._point_selections.get(key)
        if selection is None:
            if len(self._point_selections) >= _SELECTIONS:
                self._point_selections.clear()
            directions = self._point_directions[indices]
            mask = self._point_tangential[indices]
            tangents = directions[:, 1:, :3][mask]
            tangents.flags.writeable = False  # shared by the calls with these indices
            selection = directions, None if mask.all() else mask, tangents
            self._point_selections[key] = selection
        return selection

    @property
    def point_directions(self) -> Vector:
        r"""The directions of each point contact's rows on its frame Jacobian (read-only).

        Shape (len(contacts), 1 + c, 6), in LOCAL_WORLD_ALIGNED (linear, then angular part):
        the normal row's (n, 0), then each tangential row's (t, ℓ) with the lever
        :math:`\ell = r\, t \times n`, zero past the contact's ``tangent_count``; the
        definition :meth:`contact_rows` reads (and the compiled rows,
        :mod:`~ucontrol.contact.compiled_rows`).
        """
        directions = self._point_directions.view()
        directions.flags.writeable = False
        return directions

    def normal_drift(
        self,
        data: pin.Data,
        indices: Sequence[int] | NDArray[np.intp],
        *,
        q: Vector | None = None,
        v: Vector | None = None,
        t: float | None = None,
    ) -> Vector:
        r"""``J̇ v`` of the constraints ``indices`` in [m/s²] or [rad/s²], shape (len(indices),).

        The constraint accelerations at zero joint acceleration: :math:`n \cdot a_F` for a plane
        contact, :math:`n \cdot (a_1 - a_2) + \|(I - n n^T)(v_1 - v_2)\|^2 / \|p_1 - p_2\|` for a
        sphere–sphere contact (the normal turns), 0 for stops; :math:`a_F` are classical frame
        accelerations. ``data`` must hold ``pin.forwardKinematics(model, data, q, v, 0)`` and the
        frame placements. Collision rows delegate to
        :meth:`~ucontrol.contact.collision_geometry.CollisionGeometry.drift` (which includes
        the acceleration of a moving shape, and needs ``q`` (nq,), ``v`` (nv,) and, against
        moving shapes, ``t`` [s]).
        """
        model = self.robot.model
        drift = np.zeros(len(indices))
        shapes = [row for row, i in enumerate(indices) if self._pairs_end <= i < self.n_contacts]
        if shapes and self.collision is not None:
            if q is None or v is None:
                raise InvalidParameterError(
                    "q, v", None, "the state (q, v) for the drift of collision rows"
                )
            local = [int(indices[row]) - self._pairs_end for row in shapes]
            drift[shapes] = self.collision.drift(data, local, q, v, t)
        for row, i in enumerate(indices):
            if self._pairs_end <= i < self._stops_end:  # collision rows above, stops 0
                continue
            if i >= self._stops_end:
                if v is None:
                    raise InvalidParameterError(
                        "v", None, "the velocity for the drift of clearance joints"
                    )
                play = self._play[int(i) - self._stops_end]
                gap, normal = play.gap_normal(data)
                distance = play.clearance - gap  # |p| [m]
                sliding = v[play.v_xy[1]] * normal[0] - v[play.v_xy[0]] * normal[1]  # t·ṗ
                drift[row] = -(sliding**2) / distance if distance > 0.0 else 0.0
            elif i < self._n_point:
                frame_id, normal, _ = self._contact_terms[i]
                acceleration = pin.getFrameClassicalAcceleration(model, data, frame_id, _LWA)
                drift[row] = normal @ acceleration.linear
            elif i < self.n_contacts:
                first, second, _ = self._pair_terms[i - self._n_point]
                delta = data.oMf[first].translation - data.oMf[second].translation
                distance = np.sqrt(delta.dot(delta))
                normal = delta / distance
                relative = (
                    pin.getFrameVelocity(model, data, first, _LWA).linear
                    - pin.getFrameVelocity(model, data, second, _LWA).linear
                )
                tangential = relative - normal.dot(relative) * normal
                acceleration = (
                    pin.getFrameClassicalAcceleration(model, data, first, _LWA).linear
                    - pin.getFrameClassicalAcceleration(model, data, second, _LWA).linear
                )
                drift[row] = normal @ acceleration + tangential.dot(tangential) / distance
        return drift

    def sustains_friction(self, i: int) -> bool:
        """Whether constraint ``i`` has the tangential drift :meth:`tangent_drift` gives.

        A point contact against a fixed surface or a clearance joint, with one tangent (planar
        friction); not collision rows, sphere–sphere contacts, moving surfaces or 3D friction.
        """
        if self.tangent_count[i] != 1:
            return False
        if i >= self._stops_end:
            return True
        return i < self._n_point and self.contacts[i].surface.motion is None

    def tangent_drift(
        self, data: pin.Data, indices: Sequence[int] | NDArray[np.intp], v: Vector
    ) -> Vector:
        r"""``J̇_t v`` of the tangential rows of ``indices`` in [m/s²], shape (len(indices),).

        For constraints with :meth:`sustains_friction` (one tangential row each, in the order of
        :meth:`tangent_rows`): :math:`t \cdot a_F + \ell \cdot \dot\omega_F` for a point
        contact (t and the lever :math:`\ell` are fixed with the surface; classical
        accelerations at zero joint acceleration), and for a clearance joint
        :math:`\dot t \cdot \dot p = -(t \cdot \dot p)(n \cdot \dot p) / \|p\|` (the
        tangent turns with the normal, :math:`\dot n = t\,(t \cdot \dot p)/\|p\|`).
        ``data`` must hold ``pin.forwardKinematics(model, data, q, v, 0)`` and the frame
        placements; ``v`` is the velocity, shape (nv,).
        """
        model = self.robot.model
        drift = np.zeros(len(indices))
        for row, i in enumerate(_index_list(indices)):
            if i >= self._stops_end:
                play = self._play[i - self._stops_end]
                gap, normal = play.gap_normal(data)
                distance = play.clearance - gap  # |p| [m]
                rate = v[play.v_xy]  # ṗ [m/s]
                sliding = rate[1] * normal[0] - rate[0] * normal[1]  # t·ṗ
                drift[row] = -sliding * normal.dot(rate) / distance if distance > 0.0 else 0.0
            else:
                acceleration = pin.getFrameClassicalAcceleration(
                    model, data, self._frame_ids[i], _LWA
                )
                drift[row] = (
                    self._plane_tangents[i][0] @ acceleration.linear
                    + self._plane_levers[i][0] @ acceleration.angular
                )
        return drift

    def clamp_play(self, q: Vector) -> Vector:
        r"""``q`` with each clearance joint's play moved back into its disc :math:`\|p\| \le c`.

        A time-stepping scheme holds a sliding journal at :math:`\dot g \ge 0` only to first
        order: on the bearing's circle each step leaves it :math:`O(h^2)` outside. The play
        :math:`p` is scaled back onto the circle (a radial move, which changes no other
        coordinate); ``q`` is returned unchanged without clearance joints or penetration.

        Args:
            q: Configuration, shape (nq,) (or longer: the entries after the robot's are kept).
        """
        for play in self._play:
            offset = q[play.q_xy]
            distance = float(np.sqrt(offset.dot(offset)))
            if distance > play.clearance:
                q = q.copy()
                q[play.q_xy] = offset * (play.clearance / distance)
        return q

    def play_rows(self, q: Vector) -> Vector:
        r"""Normal rows :math:`-n^T` of the clearance joints on their circle at ``q``, (k, nv).

        Those whose play is at :math:`\|p\| = c` (as :meth:`clamp_play` leaves it): a
        projection that keeps :math:`J_n \delta q = 0` keeps them on it to first order.
        """
        rows = []
        for play in self._play:
            offset = q[play.q_xy]
            distance = float(np.sqrt(offset.dot(offset)))
            if distance >= play.clearance * (1.0 - _ON_CIRCLE):
                row = np.zeros(self.robot.nv)
                row[play.v_xy] = -offset / distance
                rows.append(row)
        return np.array(rows).reshape(-1, self.robot.nv)

    def has_drift(self, indices: Sequence[int] | NDArray[np.intp]) -> bool:
        r"""Whether some constraint of ``indices`` has a drift :math:`\dot J v` (not a stop)."""
        index = np.asarray(indices)
        return bool(np.any((index < self.n_contacts) | (index >= self._stops_end)))

    def gaps(self, q: Vector, t: float = 0.0) -> Vector:
        """Gaps at configuration ``q``, shape (n,); runs forward kinematics on the robot's data.

        Args:
            q: Configuration, shape (nq,).
            t: Time in [s] of the moving surfaces' positions; default 0, the start of a run.
        """
        data = self.robot.data
        pin.framesForwardKinematics(self.robot.model, data, q)
        gap = self._gap(data, q, t)
        if self.time_dependent:
            self._move(gap, None, t)
        return gap

    def normal_rate(self, indices: Sequence[int] | NDArray[np.intp], t: float) -> Vector:
        r""":math:`\partial g / \partial t = -n \cdot \dot x(t)` of ``indices`` at t [s], in [m/s].

        Zero for constraints against fixed surfaces; shape (len(indices),).
        """
        rate = np.zeros(len(indices))
        for i, motion, normal in self._moving:
            rows = np.flatnonzero(np.asarray(indices) == i)
            if rows.size:
                rate[rows] = -normal.dot(motion(t)[1])
        if self._moving_shapes and self.collision is not None:  # moving collision shapes
            shapes = [j for j, i in enumerate(indices) if self._pairs_end <= i < self.n_contacts]
            if shapes:
                local = [int(indices[j]) - self._pairs_end for j in shapes]
                rate[shapes] = self.collision.normal_rate(local, t)
        return rate

    def tangent_rate(self, indices: Sequence[int] | NDArray[np.intp], t: float) -> Vector:
        r""":math:`-t \cdot \dot x(t)` of the tangential rows of ``indices`` at t [s], in [m/s].

        In the order of :meth:`tangent_rows`; zero for fixed surfaces.
        """
        counts = self.tangent_count[np.asarray(indices, dtype=np.intp)]
        rate = np.zeros(int(counts.sum()))
        moving = {i: motion for i, motion, _ in self._moving}
        start = 0
        for i, count in zip(indices, counts.tolist(), strict=True):
            if count and int(i) in moving:
                tangents = self._plane_tangents[int(i)]
                rate[start : start + count] = -tangents @ moving[int(i)](t)[1]
            elif count and self._moving_shapes and self._pairs_end <= i < self.n_contacts:
                assert self.collision is not None
                row = [int(i) - self._pairs_end]
                rate[start : start + count] = self.collision.tangent_rate(row, t, self.planar_axis)
            start += count
        return rate

    def _move(self, gap: Vector, velocity: Vector | None, t: float | None) -> None:
        """Subtract the moving surfaces' displacement (and velocity) at t from the contacts."""
        if t is None:
            raise InvalidParameterError(
                "t",
                t,
                "the time in [s]: contacts "
                f"{[self.names[i] for i, _, _ in self._moving]} are against moving surfaces",
            )
        for i, motion, normal in self._moving:
            displacement, speed, _ = motion(t)
            gap[i] -= normal.dot(displacement)
            if velocity is not None:
                velocity[i] -= normal.dot(speed)

    def _gap(self, data: pin.Data, q: Vector, t: float = 0.0) -> Vector:
        """Gaps from frame placements already in ``data``, shape (n,)."""
        gap = np.empty(self.size)
        for i, (frame_id, normal, offset) in enumerate(self._plane_terms):
            gap[i] = _along(normal, data.oMf[frame_id].translation.tolist()) - offset
        if self._pair_kinematics is not None:
            gap[self._n_point : self._pairs_end] = (
                self._pair_offsets(data)[1] - self._pair_radii_sum
            )
        if self.collision is not None:
            gap[self._pairs_end : self.n_contacts] = self.collision.gaps(data, t)
        gap[self.n_contacts : self._stops_end] = self._stop_sign * (
            q[self._stop_q] - self._stop_bound
        )
        for i, play in enumerate(self._play, self._stops_end):
            gap[i] = play.gap_normal(data)[0]
        return gap

    def _pair_offsets(self, data: pin.Data) -> tuple[Vector, Vector]:
        """Each sphere pair's centre offset p1 - p2 in [m], (pairs, 3), and its length (pairs,)."""
        assert self._pair_kinematics is not None
        origins = self._pair_kinematics.origins(data)
        first, second = self._pair_kinematics.index.T
        delta = origins[first] - origins[second]
        return delta, np.sqrt(np.einsum("ij,ij->i", delta, delta))

    def _pair_block(
        self, data: pin.Data, pairs: list[int], *, tangential: bool
    ) -> tuple[Vector, Vector, Vector]:
        r"""Normal rows, and tangential rows with their tangents, of the sphere pairs ``pairs``.

        The normal :math:`n = (p_1 - p_2) / \|p_1 - p_2\|` and the frames' Jacobians are read
        once for both kinds of rows: :math:`n \cdot (v_1 - v_2)` and, through the contact points
        :math:`p_1 - r_1 n` and :math:`p_2 + r_2 n`,
        :math:`t \cdot (v_1 - v_2) + (t \times n) \cdot (r_1 \omega_1 + r_2 \omega_2)`.

        Args:
            data: As for :meth:`jacobian`.
            pairs: Sphere contacts (their positions among the sphere contacts), k of them.
            tangential: Whether the tangential rows are wanted (else they are empty, c = 0).

        Returns:
            The normal rows (k, nv), the tangential rows (k, c, nv) and the unit tangents
            (k, c, 3) in world coordinates.
        """
        assert self._pair_kinematics is not None
        frames = self._pair_kinematics
        origins = frames.origins(data)  # [m]
        first, second = frames.index[pairs].T
        delta = origins[first] - origins[second]
        normals = delta / np.sqrt(np.einsum("ij,ij->i", delta, delta))[:, None]
        tangents = (
            tangent_basis(normals, self.planar_axis) if tangential else np.empty((len(pairs), 0, 3))
        )
        directions = np.concatenate((normals[:, None, :], tangents), axis=1)  # (k, 1 + c, 3)
        J = frames.jacobians(data, origins)  # (f, 6, w)
        parts = [
            np.einsum("kcj,kjw->kcw", directions, J[first, :3]),
            -np.einsum("kcj,kjw->kcw", directions, J[second, :3]),
        ]
        if tangential:
            levers = cross(tangents, normals[:, None, :])
            radius = self._pair_radius[pairs]
            parts[0][:, 1:] += radius[:, 0, None, None] * np.einsum(
                "kcj,kjw->kcw", levers, J[first, 3:]
            )
            parts[1][:, 1:] += radius[:, 1, None, None] * np.einsum(
                "kcj,kjw->kcw", levers, J[second, 3:]
            )
        k, c, nv = len(pairs), directions.shape[1], self.robot.nv
        rows = np.zeros((k, c, nv + 1))  # last column: sink of the padding
        at_rows = np.arange(k)[:, None, None], np.arange(c)[None, :, None]
        for ids, part in zip((first, second), parts, strict=True):
            np.add.at(rows, (*at_rows, frames.columns[ids][:, None, :]), part)
        return rows[:, 0, :nv], rows[:, 1:, :nv], tangents


class _PairFrames:
    r"""The frames of the sphere pairs: their origins, velocities and Jacobians, read in bulk.

    The frames' origins, their joints' rotations and velocities are views on ``data``'s memory
    (:class:`_DataViews`), stacked by a call instead of calling Pinocchio twice per pair (a
    column of 100 beads: docs/benchmarks.md).

    A frame's Jacobian is zero outside the columns of the joints that support it (its
    kinematic chain to the root); only those are read, from the joint Jacobians ``data.J``
    (WORLD convention: the velocity of the point at the world origin) moved to the frame's
    origin :math:`p`, :math:`J_{lin} - p \times J_{ang}` (LOCAL_WORLD_ALIGNED, as
    ``pin.getFrameJacobian``), all frames in one gather.

    Attributes:
        frames: Frame ids, shape (f,).
        index: The two frames of each pair (positions in ``frames``), shape (pairs, 2).
        columns: Each frame's support columns, padded with nv (a sink), shape (f, w).
    """

    def __init__(self, model: pin.Model, frame_pairs: NDArray[np.intp]) -> None:
        frames, index = np.unique(frame_pairs, return_inverse=True)
        self.frames = frames.tolist()
        self.index = index.reshape(-1, 2)
        self._joints = [model.frames[frame].parentJoint for frame in self.frames]
        # Each frame's origin in its joint's frame [m] (its velocity: v + ω × t, then rotated).
        self._offsets = np.array(
            [model.frames[frame].placement.translation for frame in self.frames]
        )
        self._offset = bool(np.any(self._offsets))
        supports = [
            [
                column
                for j in model.supports[joint]
                if j > 0
                for column in range(
                    model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv
                )
            ]
            for joint in self._joints
        ]
        width = max(1, *(len(columns) for columns in supports))
        self.columns = np.full((len(self.frames), width), model.nv, dtype=np.intp)
        for row, columns in zip(self.columns, supports, strict=True):
            row[: len(columns)] = columns
        self._views = _DataViews()

    def _read(self, data: pin.Data) -> list[list[Vector]]:
        """Views on ``data``: frame origins, joint rotations, joints' linear, angular velocities."""

        def take() -> list[list[Vector]]:
            velocities = [data.v[joint] for joint in self._joints]
            return [
                [data.oMf[frame].translation for frame in self.frames],
                [data.oMi[joint].rotation for joint in self._joints],
                [velocity.linear for velocity in velocities],
                [velocity.angular for velocity in velocities],
            ]

        views: list[list[Vector]] = self._views.read(data, take)
        return views

    def origins(self, data: pin.Data) -> Vector:
        """The frames' origins in [m], shape (f, 3); ``data`` must hold frame placements."""
        return np.array(self._read(data)[0])

    def velocities(self, data: pin.Data) -> Vector:
        r"""The frames' linear velocities (LOCAL_WORLD_ALIGNED) in [m/s], shape (f, 3).

        :math:`R_j (v_j + \omega_j \times t)` of each frame's joint j (rotation
        :math:`R_j`, local velocity :math:`(v_j, \omega_j)`) and origin t in the joint's
        frame, as ``pin.getFrameVelocity``; ``data`` must hold forward kinematics with
        velocity.
        """
        _, rotations, linear, angular = self._read(data)
        local = np.array(linear)
        if self._offset:
            local += cross(np.array(angular), self._offsets)
        return np.einsum("fij,fj->fi", np.array(rotations), local)

    def jacobians(self, data: pin.Data, origins: Vector) -> Vector:
        """The frames' Jacobians (LOCAL_WORLD_ALIGNED) on their support columns, (f, 6, w).

        Args:
            data: Holding the joint Jacobians (``pin.computeJointJacobians`` or
                ``pin.computeAllTerms``).
            origins: The frames' origins in [m], shape (f, 3) (:meth:`origins`).
        """
        world = np.zeros((6, data.J.shape[1] + 1))  # last column: the padding's zeros
        world[:, :-1] = data.J
        compact = world[:, self.columns].transpose(1, 0, 2)  # (f, 6, w)
        linear, angular = compact[:, :3], compact[:, 3:]
        linear -= cross(origins[:, None, :], angular.transpose(0, 2, 1)).transpose(0, 2, 1)
        return compact


class _DataViews:
    """Views on the memory of the Pinocchio data buffer read last, kept with the buffer.

    Pinocchio's ``data.oMf[f].translation`` (and the like) are views on ``data``'s own memory,
    which every later kinematics call on ``data`` updates: taken once per buffer, they cost no
    call into Pinocchio afterwards. The buffer is kept so that its memory outlives them; a copy
    (pickle) drops both, as it would not follow them.
    """

    def __init__(self) -> None:
        self._read: tuple[pin.Data | None, Any] = (None, None)

    def read(self, data: pin.Data, take: Callable[[], Any]) -> Any:
        """The views on ``data``: those kept when it was read last, else ``take()``'s."""
        read, views = self._read
        if read is not data:
            views = take()
            self._read = (data, views)
        return views

    def __getstate__(self) -> dict[str, Any]:
        """No views, no buffer."""
        return {"_read": (None, None)}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """As built."""
        self._read = state["_read"]


class _PlayTerms:
    """The play coordinates and geometry of a clearance joint (module clearance_joint)."""

    def __init__(self, robot: RobotModel, clearance: ClearanceJoint) -> None:
        from ucontrol.model.joint_clearance import play_joints

        model = robot.model
        ids = []
        for name in play_joints(clearance.joint):
            if name not in robot.joint_names:
                raise InvalidParameterError(
                    "clearances",
                    clearance.joint,
                    f"a joint the robot gives play to (no joint {name!r}: build the robot "
                    "with ucontrol.model.joint_clearance.with_joint_clearance)",
                )
            ids.append(robot.joint_id(name))
        self.x_joint, self.y_joint = ids
        joints = model.joints
        self.v_xy = np.array([joints[j].idx_v for j in ids], dtype=np.intp)
        self.q_xy = np.array([joints[j].idx_q for j in ids], dtype=np.intp)
        self.v_theta = int(joints[robot.joint_id(clearance.joint)].idx_v)
        self.axes = np.array([np.asarray(joints[j].extract().axis) for j in ids])  # (2, 3)
        self.placement = model.jointPlacements[self.x_joint]
        self.clearance = clearance.clearance
        self.radius = clearance.journal_radius

    def offset(self, data: pin.Data) -> Vector:
        """The journal centre's offset (x, y) from the bearing's in [m], shape (2,).

        Read from the joints' local placements in ``data`` (after forward kinematics).
        """
        placement = self.placement
        x = self.axes[0].dot(
            placement.rotation.T.dot(data.liMi[self.x_joint].translation - placement.translation)
        )
        y = self.axes[1].dot(data.liMi[self.y_joint].translation)
        return np.array([x, y])

    def gap_normal(self, data: pin.Data) -> tuple[float, Vector]:
        """The gap c - |p| in [m] and the unit normal p / |p| (e1 at p = 0), shape (2,)."""
        offset = self.offset(data)
        distance = float(np.sqrt(offset.dot(offset)))
        normal = offset / distance if distance > 0.0 else np.array([1.0, 0.0])
        return self.clearance - distance, normal

    def world_direction(self, data: pin.Data, tangent: Vector) -> Vector:
        """The play-plane direction ``tangent`` (shape (2,)) in world coordinates, shape (3,)."""
        return np.asarray(data.oMi[self.x_joint].rotation.dot(tangent.dot(self.axes)))


def _index_list(indices: Sequence[int] | NDArray[np.intp]) -> list[int]:
    """``indices`` as a list of Python integers."""
    if isinstance(indices, np.ndarray):
        return indices.tolist()
    return [int(i) for i in indices]
