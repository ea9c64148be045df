r"""Task coordinates in which unilateral constraints read :math:`X_1 \ge 0`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from ucontrol.contact.point_contact import PointContact
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]
_LWA = pin.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class TaskState:
    r"""Task coordinates and their derivatives at (q, v).

    Attributes:
        X: Task coordinates, shape (m,), in [m].
        dX: Their velocity :math:`J_X v`, shape (m,), in [m/s].
        J: Task Jacobian :math:`J_X = \partial X / \partial q`, shape (m, nv).
        dJ: Its time derivative along v, shape (m, nv).
    """

    X: Vector
    dX: Vector
    J: Matrix
    dJ: Matrix


class TaskCoordinates:
    r"""Affine task coordinates of one frame: :math:`X = A\,p_F(q) - b`, shape (m,).

    The first rows are the gaps of the point contacts (plane normal :math:`n_i`, offset
    :math:`n_i \cdot p_{0,i} + r_i`), so the constraints read :math:`X_1 = (X_0, ...) \ge 0`
    exactly as in the plant; the remaining rows are the tangential coordinates
    :math:`t_j \cdot p_F` along the given directions. All contacts must act on the same frame.

    Args:
        robot: The robot.
        frame: Name of the frame whose origin is tracked.
        contacts: Point contacts of ``frame`` (their surfaces give :math:`X_1`).
        tangents: Tangential directions in the world frame, shape (k, 3); normalised.

    Raises:
        FrameNotFoundError: ``frame`` is not in the robot model.
        InvalidParameterError: A contact acts on another frame, there are more task
            coordinates than degrees of freedom, or the rows of A are linearly dependent.
    """

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        contacts: Sequence[PointContact],
        tangents: ArrayLike = (),
    ) -> None:
        self.frame = frame
        self.frame_id = robot.frame_id(frame)
        self.contacts = tuple(contacts)
        for contact in self.contacts:
            if contact.frame != frame:
                raise InvalidParameterError(
                    f"contact {contact.name!r} frame", contact.frame, f"the task frame {frame!r}"
                )
        directions = np.array(tangents, dtype=float).reshape(-1, 3)
        norms = np.linalg.norm(directions, axis=1)
        if np.any(norms < 1e-12):
            raise InvalidParameterError("tangents", tangents, "non-zero directions")
        normals = np.array([c.surface.normal for c in self.contacts]).reshape(-1, 3)
        self.A = np.vstack([normals, directions / norms[:, None]])
        self.b = np.concatenate(
            [
                [c.surface.normal @ c.surface.point + c.radius for c in self.contacts],
                np.zeros(len(directions)),
            ]
        )
        self.m = self.A.shape[0]
        self.n_gaps = len(self.contacts)
        if self.m > robot.nv or np.linalg.matrix_rank(self.A) < self.m:
            raise InvalidParameterError(
                "contacts/tangents",
                self.A.tolist(),
                f"at most nv = {robot.nv} linearly independent task directions",
            )
        self.names = [c.name for c in self.contacts] + [
            "tangent (" + ", ".join(f"{x:.3g}" for x in row) + ")" for row in self.A[self.n_gaps :]
        ]

    def of_point(self, p_world: Vector) -> Vector:
        """Task coordinates of a world point ``p_world`` (3,) in [m], shape (m,)."""
        return self.A @ p_world - self.b

    def of_vector(self, d_world: Vector) -> Vector:
        """Task components of a world vector (velocity, acceleration), shape (m,)."""
        return self.A @ d_world

    def evaluate(self, model: pin.Model, data: pin.Data, v: Vector) -> TaskState:
        """Task state from ``data`` holding kinematics at (q, v).

        ``data`` must hold joint Jacobians, their time variation and frame placements at
        (q, v): ``pin.computeAllTerms``, ``pin.computeJointJacobiansTimeVariation`` and
        ``pin.updateFramePlacements``.

        Args:
            model: The Pinocchio model ``data`` belongs to.
            data: Its data buffer.
            v: Velocity, shape (nv,).
        """
        p_world = data.oMf[self.frame_id].translation
        J_lin = pin.getFrameJacobian(model, data, self.frame_id, _LWA)[:3]
        dJ_lin = pin.getFrameJacobianTimeVariation(model, data, self.frame_id, _LWA)[:3]
        J = self.A @ J_lin
        return TaskState(self.A @ p_world - self.b, J @ v, J, self.A @ dJ_lin)
