"""All unilateral constraints of a scene, evaluated together on the robot's data."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.joint_stop import JointStop
from ucontrol.contact.point_contact import PointContact
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]
_LWA = pin.LOCAL_WORLD_ALIGNED


class ConstraintSet:
    """Point contacts followed by joint stops, as one ordered list of unilateral constraints.

    Constraint ``i`` has gap ``g_i(q)`` (>= 0 when admissible), normal velocity
    ``u_i = J_i v`` and restitution ``e_i``. Contacts come first, in the order given, then each
    finite stop bound (lower before upper).

    Attributes:
        robot: The robot whose data buffer is read.
        contacts: The point contacts.
        stops: The joint stops.
        names: One label per constraint.
        restitution: Restitution coefficients, shape (n,).
        size: Number of constraints n.
    """

    def __init__(
        self,
        robot: RobotModel,
        contacts: Sequence[PointContact] = (),
        stops: Sequence[JointStop] = (),
    ) -> None:
        self.robot = robot
        self.contacts = tuple(contacts)
        self.stops = tuple(stops)
        self._frame_ids = [robot.frame_id(contact.frame) for contact in self.contacts]
        self._normals = np.array([c.surface.normal for c in self.contacts]).reshape(-1, 3)
        self._offsets = np.array(
            [c.surface.normal @ c.surface.point + c.radius for c in self.contacts]
        )
        names = [contact.name for contact in self.contacts]
        restitution = [contact.restitution for contact in self.contacts]
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
        self._stop_q = np.array(stop_q, dtype=int)
        self._stop_v = np.array(stop_v, dtype=int)
        self._stop_sign = np.array(stop_sign)
        self._stop_bound = np.array(stop_bound)
        self.names = names
        self.restitution = np.array(restitution, dtype=float)
        self.n_contacts = len(self.contacts)
        self.size = len(names)
        self._has_stops = self.size > self.n_contacts
        self._contact_terms = list(
            zip(self._frame_ids, list(self._normals), self._offsets.tolist(), strict=True)
        )

    def evaluate(self, data: pin.Data, q: Vector, v: Vector) -> tuple[Vector, Vector]:
        """Gaps and normal velocities, each of shape (n,).

        ``data`` must hold forward kinematics with velocity and frame placements at (q, v)
        (``pin.computeAllTerms`` then ``pin.updateFramePlacements``).
        """
        model = self.robot.model
        gap = np.empty(self.size)
        velocity = np.empty(self.size)
        for i, (frame_id, normal, offset) in enumerate(self._contact_terms):
            gap[i] = normal.dot(data.oMf[frame_id].translation) - offset
            velocity[i] = normal.dot(pin.getFrameVelocity(model, data, frame_id, _LWA).linear)
        if self._has_stops:
            k = self.n_contacts
            gap[k:] = self._stop_sign * (q[self._stop_q] - self._stop_bound)
            velocity[k:] = self._stop_sign * v[self._stop_v]
        return gap, velocity

    def jacobian(self, data: pin.Data, indices: Sequence[int] | NDArray[np.intp]) -> Vector:
        """Normal Jacobian rows of the constraints ``indices``, shape (len(indices), nv).

        ``data`` must hold joint Jacobians and frame placements (``pin.computeAllTerms`` then
        ``pin.updateFramePlacements``).
        """
        model = self.robot.model
        rows = np.zeros((len(indices), self.robot.nv))
        k = self.n_contacts
        for row, i in enumerate(indices):
            if i < k:
                frame_id, normal, _ = self._contact_terms[i]
                rows[row] = normal.dot(pin.getFrameJacobian(model, data, frame_id, _LWA)[:3])
            else:
                rows[row, self._stop_v[i - k]] = self._stop_sign[i - k]
        return rows

    def gaps(self, q: Vector) -> Vector:
        """Gaps at configuration ``q``, shape (n,); runs forward kinematics on the robot's data."""
        data = self.robot.data
        pin.framesForwardKinematics(self.robot.model, data, q)
        return self._gap(data, q)

    def _gap(self, data: pin.Data, q: Vector) -> Vector:
        """Gaps from frame placements already in ``data``, shape (n,)."""
        gap = np.empty(self.size)
        for i, (frame_id, normal, offset) in enumerate(self._contact_terms):
            gap[i] = normal.dot(data.oMf[frame_id].translation) - offset
        gap[self.n_contacts :] = self._stop_sign * (q[self._stop_q] - self._stop_bound)
        return gap
