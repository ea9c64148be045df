"""Energy balance of a run: the work done by the actuators."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import ShapeError
from ucontrol.log import Log


def input_velocities(log: Log) -> NDArray[np.float64]:
    """Velocity of the coordinate each input drives, in [rad/s] or [m/s], shape (N, nu).

    The actuated link coordinates (``actuated`` metadata), except for flexible joints, whose
    inputs drive their motors (``motor_v``, inputs listed in the ``motor_inputs`` metadata).
    """
    actuated = np.asarray(log.metadata.get("actuated", []), dtype=int)
    velocities = log.v[:, actuated]
    motor_inputs = log.metadata.get("motor_inputs")
    if motor_inputs is not None:
        velocities[:, np.asarray(motor_inputs, dtype=int)] = log.motor_v
    return velocities


def step_work(log: Log, theta: float | None = None) -> NDArray[np.float64]:
    r"""Work of the actuators over each step, in [J], shape (N - 1,).

    Over step k the torque :math:`u_k` (zero-order hold) works
    :math:`h\, u_k \cdot ((1 - \theta) w_k + \theta w_{k+1})`, w the :func:`input_velocities`:
    the velocity Moreau–Jean moves the configuration with.

    Args:
        log: The run's log.
        theta: θ of the position update; default the log's ``theta`` metadata (1/2 if absent).
    """
    if len(log) < 2:
        return np.zeros(0)
    if theta is None:
        theta = float(log.metadata.get("theta", 0.5))
    w = input_velocities(log)
    w_mid = (1.0 - theta) * w[:-1] + theta * w[1:]  # [rad/s]
    return np.einsum("ij,ij->i", log.u[:-1], w_mid) * np.diff(log.t)


def work_of(log: Log, theta: float | None, work: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """The actuators' work over each step of ``log``: ``work`` when a caller computed it already.

    Args:
        log: The run's log.
        theta: θ of the position update (:func:`step_work`), used when ``work`` is None.
        work: ``step_work(log, theta)`` in [J], shape (N - 1,), or None.

    Raises:
        ShapeError: ``work`` does not have one entry per step of ``log``.
    """
    if work is None:
        return step_work(log, theta)
    expected = (max(len(log) - 1, 0),)
    if np.shape(work) != expected:
        raise ShapeError("work", expected, np.shape(work))
    return work


def actuator_work(log: Log) -> NDArray[np.float64]:
    """Work of the actuators from ``t[0]`` to each sample, in [J], shape (N,).

    Without impacts or friction, ``energy - actuator_work`` stays at its initial value (to the
    scheme's accuracy); every impact can only lower it.
    """
    return np.concatenate([[0.0], np.cumsum(step_work(log))])
