"""The open-loop controller."""

from __future__ import annotations

import numpy as np

from ucontrol.control.controller import ContactState, Vector


class ZeroTorque:
    """Applies no torque: the robot falls freely under gravity and contacts.

    Args:
        nu: Number of actuated coordinates.
    """

    def __init__(self, nu: int) -> None:
        self._torque = np.zeros(nu)

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Zero torques, shape (nu,)."""
        return self._torque
