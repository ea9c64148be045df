"""Joint-space proportional-derivative control with gravity compensation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ucontrol._validation import as_vector
from ucontrol.control.controller import ContactState, Vector
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel


class JointPD:
    r"""Regulate the actuated joints to ``q_ref``: :math:`u = K_p (q_{ref} - q) - K_d v + g(q)`.

    Defined for robots whose actuated joints have nq = nv (revolute, prismatic).

    Args:
        robot: The robot (the controller keeps its own Pinocchio data).
        q_ref: Target configuration, shape (nq,).
        kp: Stiffness gains, scalar or shape (nu,), in [N m/rad] or [N/m].
        kd: Damping gains, scalar or shape (nu,), in [N m s/rad] or [N s/m].
        gravity_compensation: Add the generalized gravity g(q).
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        q_ref: Vector,
        kp: float | Vector,
        kd: float | Vector,
        gravity_compensation: bool = True,
    ) -> None:
        if robot.nq != robot.nv:
            raise InvalidParameterError("robot", robot.name, "a robot with nq = nv for JointPD")
        self._model = robot.model
        self._data = robot.model.createData()
        self._actuated = robot.actuated
        self.q_ref = as_vector("q_ref", q_ref, robot.nq)
        self.kp = _gain("kp", kp, robot.nu)
        self.kd = _gain("kd", kd, robot.nu)
        self.gravity_compensation = gravity_compensation

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Torques, shape (nu,)."""
        a = self._actuated
        torque = self.kp * (self.q_ref[a] - q[a]) - self.kd * v[a]
        if self.gravity_compensation:
            torque += pin.computeGeneralizedGravity(self._model, self._data, q)[a]
        return torque


def _gain(name: str, value: float | Vector, size: int) -> Vector:
    gain = as_vector(name, np.full(size, value) if np.ndim(value) == 0 else value, size)
    if np.any(gain < 0.0):
        raise InvalidParameterError(name, value, ">= 0")
    return gain
