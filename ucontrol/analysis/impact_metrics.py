r"""Figures of one landing of a frame on a surface, every impact law measured alike.

A *landing* is the part of a run around one nominal impact: the window ``[start, end]`` of a
periodic contact phase (:func:`landing_window`) in which the plant's first impact of the
contact, :math:`t_1`, opens the measurement. From the log (the plant's state, impulses and
impacts; the controller's torques, reference velocity and desired force):

- *velocity-error peak*: :math:`\max \|J\dot q - \dot x_r\|` over the rows of
  :math:`[t_1, t_1 + T_w]` (:data:`WINDOW`), J the frame's translational Jacobian, :math:`\dot
  x_r` the reference velocity the law feeds back at that row, in [m/s];
- *torque jump*: the largest :math:`\|u_k - u_{k-1}\|` over the same rows, in [N m];
- *force overshoot*: the largest :math:`\lambda - \lambda_d` (0 when λ stays below
  :math:`\lambda_d`) over the rows of :math:`[t_1, t_1 + T_f]` (:data:`FORCE_WINDOW`) without
  impact, λ the row's step impulse over the step, in [N];
- *impacts*: the plant's impacts of the contact in the window.

:func:`contact_held` and :func:`settled_error` measure whether the landing completed: the
contact closed on every step of an interval after :math:`t_1`, and the velocity error there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.analysis.impacts import impact_mask
from ucontrol.log import Log

#: Length in [s] of the post-impact window of the velocity-error and torque-jump peaks.
WINDOW = 0.1
#: Length in [s] of the window of the force overshoot.
FORCE_WINDOW = 0.5
#: Largest difference in [m/s] between the one-sided slopes of a smooth logged target
#: (:func:`target_velocities`): 50 m/s² over a 1 ms step; a switch of the target is above it.
SWITCH_SLOPE = 0.05


@dataclass(frozen=True)
class Landing:
    """Figures of one landing (module docstring); NaN and 0 impacts when none was found.

    Attributes:
        t_1: Time of the plant's first impact of the contact in the window, in [s].
        velocity_error: Velocity-error peak in [m/s].
        torque_jump: Largest torque change between two rows in [N m].
        force_overshoot: Largest contact force above the desired one in [N].
        impacts: The plant's impacts of the contact in the window.
    """

    t_1: float
    velocity_error: float  # [m/s]
    torque_jump: float  # [N m]
    force_overshoot: float  # [N]
    impacts: int


def landing_window(start: float, end: float, period: float, k: int) -> tuple[float, float]:
    """The window of landing ``k`` of a contact phase ``[start, end]`` repeated every period.

    It opens half the free flight before the phase (so an early impact on a raised surface
    counts) and closes at the phase's end.

    Args:
        start: Start of the contact phase in the first cycle, in [s].
        end: Its end, in [s].
        period: Period of the cycle in [s].
        k: Index of the landing (0 for the first).

    Returns:
        ``(open, close)`` in [s].
    """
    return k * period + start - 0.5 * (period - (end - start)), k * period + end


def frame_velocities(log: Log, model: Any, frame: str) -> NDArray[np.float64]:
    """World velocity of ``frame``'s origin at every row of ``log``, shape (N, 3) in [m/s].

    Args:
        log: The run (its true ``q`` and ``v``).
        model: The robot's ``pinocchio.Model`` (kinematics only: masses do not matter).
        frame: Name of the frame.
    """
    data = pin.Data(model)
    frame_id = model.getFrameId(frame)
    out = np.empty((len(log), 3))
    for row, (q, v) in enumerate(zip(log.q, log.v, strict=True)):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacement(model, data, frame_id)
        J = pin.getFrameJacobian(model, data, frame_id, pin.LOCAL_WORLD_ALIGNED)
        out[row] = J.reshape(6, model.nv)[:3] @ v  # (6,) when nv = 1
    return out


def target_velocities(
    log: Log, directions: NDArray[np.float64], switch: float = SWITCH_SLOPE
) -> NDArray[np.float64]:
    r"""World velocity of a phase-machine controller's target, shape (N, 3) in [m/s].

    The derivative of the logged ``task_target`` (task coordinates, shape (N, m)) mapped to the
    world by the task's directions, :math:`\dot x = A^T \dot X`. At each row the two
    one-sided slopes (to the previous and to the next row) are compared: where they differ by
    at most ``switch`` their mean, the central difference (error :math:`O(h^2)`); where they
    differ more, the target switched (it jumps, e.g. to the surface at the first impact) and
    the smaller of the two is taken, the slope of the side without the jump. The first and
    last rows take their one one-sided slope.

    Args:
        log: A run of a controller that logs ``task_target``, with at least two rows.
        directions: World directions of the task coordinates, A, shape (m, 3).
        switch: Largest difference in [m/s] of the one-sided slopes of a smooth target: a
            target of acceleration a gives :math:`a h`.
    """
    X, t = np.asarray(log.task_target), np.asarray(log.t)
    slope = np.diff(X, axis=0) / np.diff(t)[:, None]  # [m/s] of the steps, (N - 1, m)
    before = np.vstack([slope[:1], slope])  # the slope to the previous row (first: next)
    after = np.vstack([slope, slope[-1:]])  # the slope to the next row (last: previous)
    smooth = np.linalg.norm(after - before, axis=1) <= switch
    smaller = np.where(
        (np.linalg.norm(before, axis=1) <= np.linalg.norm(after, axis=1))[:, None], before, after
    )
    velocity = np.where(smooth[:, None], 0.5 * (before + after), smaller)
    return velocity @ directions


def first_impact(log: Log, contact: str, window: tuple[float, float]) -> NDArray[np.float64]:
    """The plant's impact times of ``contact`` in ``window`` = (open, close], in [s]."""
    times = log.impact_times_of(contact)
    return times[(times > window[0]) & (times <= window[1])]


def landing(
    log: Log,
    velocities: NDArray[np.float64],
    references: NDArray[np.float64],
    contact: str,
    window: tuple[float, float],
) -> Landing:
    """Figures of one landing (module docstring).

    Args:
        log: The run: ``t``, ``u``, ``impulse``, the plant's impacts and the controller's
            ``lambda_d`` (its first contact's column).
        velocities: World velocity of the landing frame per row, shape (N, 3) in [m/s].
        references: Reference velocity the law feeds back per row, shape (N, 3) in [m/s].
        contact: Name of the constraint that lands.
        window: ``(open, close)`` in [s] (:func:`landing_window`).
    """
    times = first_impact(log, contact, window)
    if times.size == 0:
        return Landing(
            t_1=math.nan,
            velocity_error=math.nan,
            torque_jump=math.nan,
            force_overshoot=math.nan,
            impacts=0,
        )
    t_1 = float(times[0])
    t = log.t
    rows = np.flatnonzero((t >= t_1) & (t <= t_1 + WINDOW))
    error = np.linalg.norm(velocities[rows] - references[rows], axis=1)  # [m/s]
    jumps = np.linalg.norm(log.u[rows] - log.u[rows - 1], axis=1)  # [N m]
    i = log.constraint_index(contact)
    steady = ~impact_mask(log)[:, i]
    force_rows = np.flatnonzero((t >= t_1) & (t <= t_1 + FORCE_WINDOW) & steady)
    force_rows = force_rows[force_rows + 1 < len(log)]  # the last row has no step
    # Row r's impulse is that of the step [t_r, t_r+1], under row r's torque and lambda_d.
    force = log.impulse[force_rows, i] / (t[force_rows + 1] - t[force_rows])  # [N]
    overshoot = force - log.lambda_d[force_rows, 0]
    return Landing(
        t_1=t_1,
        velocity_error=float(error.max()),
        torque_jump=float(jumps.max()),
        force_overshoot=float(max(overshoot.max(initial=0.0), 0.0)),
        impacts=int(times.size),
    )


def contact_held(log: Log, contact: str, interval: tuple[float, float]) -> bool:
    """Whether ``contact`` carries a positive impulse on every step in ``interval`` [s].

    False when the interval holds no complete step of the log (the run ended before it).
    """
    t = log.t
    rows = np.flatnonzero((t >= interval[0]) & (t <= interval[1]))
    rows = rows[rows + 1 < len(log)]  # row r's impulse is the step [t_r, t_r+1]
    if rows.size == 0 or t[-1] < interval[1]:
        return False
    return bool(np.all(log.impulse[rows, log.constraint_index(contact)] > 0.0))


def settled_error(
    log: Log,
    velocities: NDArray[np.float64],
    references: NDArray[np.float64],
    interval: tuple[float, float],
    percentile: float = 95.0,
) -> float:
    r"""The velocity error :math:`\|J\dot q - \dot x_r\|` over ``interval``, in [m/s].

    Its ``percentile`` over the rows of the interval (100: the largest): a percentile below
    100 ignores a few rows where a finite-difference reference (:func:`target_velocities`)
    misses a switch of the target. NaN when the log ends before the interval does.
    """
    t = log.t
    rows = np.flatnonzero((t >= interval[0]) & (t <= interval[1]))
    if rows.size == 0 or t[-1] < interval[1]:
        return math.nan
    error = np.linalg.norm(velocities[rows] - references[rows], axis=1)  # [m/s]
    return float(np.percentile(error, percentile))
