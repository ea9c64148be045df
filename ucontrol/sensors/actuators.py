"""Actuators in the loop: torque saturation and rate limits between controller and plant."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ucontrol.model.robot_model import RobotModel
from ucontrol.sensors.sensor_settings import ActuatorSettings

Vector = NDArray[np.float64]


class Actuators:
    r"""The torque the plant receives from the torque the controller asks for.

    The rate limit acts first (from the torque applied over the previous control period,
    zero before the first), then the saturation: :math:`u = \operatorname{clip}(u_{k-1} +
    \operatorname{clip}(u_c - u_{k-1}, \pm r T), \pm u_{max})`.

    Args:
        settings: The limits.
        robot: The robot (``"urdf"`` limits are its actuated joints' effort limits).
        period: Control period T in [s].
    """

    def __init__(self, settings: ActuatorSettings, robot: RobotModel, period: float) -> None:
        limit = settings.torque_limit
        if isinstance(limit, str):  # "urdf": the effort limit of each actuated coordinate
            limit = np.asarray(robot.model.effortLimit, dtype=float)[robot.actuated]
        self._limit = None if limit is None else np.broadcast_to(limit, (robot.nu,)).copy()
        rate = settings.rate_limit
        self._step = None if rate is None else np.broadcast_to(rate, (robot.nu,)) * period
        self._applied = np.zeros(robot.nu)

    def apply(self, commanded: Vector) -> Vector:
        """The torque applied over the coming control period, shape (nu,)."""
        u = commanded
        if self._step is not None:
            u = self._applied + np.clip(u - self._applied, -self._step, self._step)
        if self._limit is not None:
            u = np.clip(u, -self._limit, self._limit)
        self._applied = np.array(u, dtype=float)
        return self._applied.copy()
