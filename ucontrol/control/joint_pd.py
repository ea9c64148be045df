"""Joint-space proportional-derivative control with gravity compensation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ucontrol._validation import as_vector
from ucontrol.control.controller import ContactState, Vector
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.robot_model import RobotModel


class JointPD:
    r"""Regulate the actuated joints to ``q_ref``: :math:`u = K_p (q_{ref} - q) - K_d v + g(q)`.

    Defined for robots whose actuated joints have one configuration coordinate each (revolute,
    prismatic), on a fixed or a free-flyer base (whose 6 coordinates are not actuated). With
    flexible joints the feedback is collocated, on the motors, with the gravity of the target
    (Tomei's law): :math:`u = K_p (q_{2,ref} - q_2) - K_d \dot q_2 + g(q_{ref})`, the motor target
    :math:`q_{2,ref} = q_{ref} + K^{-1} g(q_{ref})` holding the links at :math:`q_{ref}` at rest.

    Args:
        robot: The robot (the controller keeps its own Pinocchio data).
        q_ref: Target configuration, shape (nq,).
        kp: Stiffness gains, scalar or shape (nu,), in [N m/rad] or [N/m].
        kd: Damping gains, scalar or shape (nu,), in [N m s/rad] or [N s/m].
        gravity_compensation: Add the generalized gravity g(q) (g(q_ref) with flexible joints).
        flexible: The robot's flexible joints, if any: q and v then hold the motors last.
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        q_ref: Vector,
        kp: float | Vector,
        kd: float | Vector,
        gravity_compensation: bool = True,
        flexible: FlexibleJoints | None = None,
    ) -> None:
        q_of_v = {  # configuration index of each one-coordinate joint's velocity index
            int(joint.idx_v): int(joint.idx_q)
            for joint in robot.model.joints[1:]
            if joint.nq == 1 and joint.nv == 1
        }
        if any(int(i) not in q_of_v for i in robot.actuated):
            raise InvalidParameterError(
                "robot",
                robot.name,
                "a robot whose actuated joints have one configuration coordinate each "
                "(revolute or prismatic; a free-flyer base is allowed) for JointPD",
            )
        self._model = robot.model
        self._data = pin.Data(robot.model)
        self._actuated = robot.actuated
        self.q_ref = as_vector("q_ref", q_ref, robot.nq)
        self.kp = _gain("kp", kp, robot.nu)
        self.kd = _gain("kd", kd, robot.nu)
        self.gravity_compensation = gravity_compensation
        self._flexible = flexible
        actuated_q = np.array([q_of_v[int(i)] for i in self._actuated], dtype=np.int64)
        self._target = self.q_ref[actuated_q]  # of the measured positions [rad]
        self._measured_q = actuated_q  # indices in the plant's q
        self._measured_v = self._actuated  # and v
        if flexible is not None:
            self._gravity_at_target = pin.computeGeneralizedGravity(
                self._model, self._data, self.q_ref
            )[self._actuated]
            motors = flexible.input_index
            self._target = self._target.copy()
            self._target[motors] += (
                self._gravity_at_target[motors] / flexible.stiffness
                if gravity_compensation
                else 0.0
            )
            self._measured_q = actuated_q.copy()
            self._measured_q[motors] = robot.nq + np.arange(flexible.nf)
            self._measured_v = flexible.input_coordinates(self._actuated)

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Torques, shape (nu,)."""
        torque = self.kp * (self._target - q[self._measured_q]) - self.kd * v[self._measured_v]
        if self.gravity_compensation:
            if self._flexible is None:
                torque += pin.computeGeneralizedGravity(self._model, self._data, q)[self._actuated]
            else:
                torque += self._gravity_at_target
        return torque


def _gain(name: str, value: float | Vector, size: int) -> Vector:
    gain = as_vector(name, np.full(size, value) if np.ndim(value) == 0 else value, size)
    if np.any(gain < 0.0):
        raise InvalidParameterError(name, value, ">= 0")
    return gain
