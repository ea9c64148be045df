r"""A controller that also compensates the joint friction its model believes in.

A controller built on a model with friction in the joints (``[controller.model]
joint_friction``) adds to its torque the friction that model predicts,

.. math:: u = u_0 + S\big(D \dot q + F_c \,\mathrm{sat}(\dot q / \epsilon)\big),

:math:`u_0` the law computed on the frictionless model (its own dynamics compensation), S the
selection of the actuated coordinates, :math:`\dot q` the measured link velocity and
:math:`\mathrm{sat}` the sign clipped to [-1, 1] over a band :math:`\epsilon`
(``velocity_band``, 0.01 rad/s by default). The viscous term cancels the plant's exactly where
the model is right; the Coulomb term is the plant's friction wherever the joint moves faster
than :math:`\epsilon`, and fades to 0 inside the band, so that a joint at rest (or measured
with noise around 0) does not chatter between :math:`\pm F_c`: there the feedback of the law
overcomes the static friction. With flexible joints the compensation of a flexible joint's
friction goes through its motor torque (exact at steady state, where the spring transmits
it).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ucontrol.control.controller import ContactState, Controller, Vector
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel


class FrictionCompensation:
    """Wraps a controller and adds the joint friction of its model to its torques.

    Every other attribute (``reset``, ``prepare_log``, ``record``, ``phase``, ...) is the
    wrapped controller's.

    Args:
        controller: The law computed on the frictionless model.
        robot: The controller's model of the robot (its actuated coordinates).
        friction: The joint friction the controller believes in.

    Attributes:
        controller: The wrapped controller.
        friction: The friction compensated.
    """

    def __init__(self, controller: Controller, robot: RobotModel, friction: JointFriction) -> None:
        self.controller = controller
        self.friction = friction
        self._nv = robot.nv
        # The actuated link coordinates, or None when they are all of them, in order.
        self._actuated = (
            None if np.array_equal(robot.actuated, np.arange(robot.nv)) else robot.actuated
        )

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Torques of the wrapped law plus the believed friction, shape (nu,)."""
        torque = self.controller(t, q, v, contacts)
        friction = self.friction.model_torque(v[: self._nv])  # [N m] on the link coordinates
        return torque + (friction if self._actuated is None else friction[self._actuated])

    def __getattr__(self, name: str) -> Any:
        controller = self.__dict__.get("controller")
        if controller is None:
            raise AttributeError(name)
        return getattr(controller, name)
