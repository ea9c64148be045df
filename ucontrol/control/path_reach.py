r"""Whether a robot frame can follow a desired path: inverse kinematics along its samples."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.control.desired_cycle import NominalPath
from ucontrol.exceptions import InvalidParameterError, PathOutOfReachError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]

#: Samples per period checked by default.
REACH_SAMPLES = 200
#: A sample is reached when the frame ends closer than this to it, in [m].
REACH_TOLERANCE = 1e-6
#: Levenberg–Marquardt iterations per start.
_ITERATIONS = 100
#: Random restarts (within the joint limits) before a sample is declared out of reach.
_RESTARTS = 10
_LWA = pin.LOCAL_WORLD_ALIGNED


def check_reach(
    path: NominalPath,
    robot: RobotModel,
    frame: str,
    q_start: Vector,
    *,
    samples: int = REACH_SAMPLES,
    tolerance: float = REACH_TOLERANCE,
    seed: int = 0,
) -> NDArray[np.float64]:
    r"""Solve the position inverse kinematics of ``frame`` along one period of ``path``.

    Sample j (time :math:`jP/N`) is solved by damped least squares (Levenberg–Marquardt,
    configurations clipped to the URDF's finite joint limits), starting from the solution of
    sample j - 1 (``q_start`` for the first), then, if it fails, from seeded random
    configurations within the limits. A point no start brings the frame within ``tolerance``
    of is out of reach. A sufficient check for a point far out of reach; near the workspace
    boundary, a reachable point may be missed only if every start falls in a local minimum.

    Args:
        path: The desired path of the frame (period P).
        robot: The robot.
        frame: Name of the frame that follows the path.
        q_start: Starting configuration, shape (nq,).
        samples: Number N of samples over one period, >= 1.
        tolerance: Distance in [m] under which a sample counts as reached, > 0.
        seed: Seed of the random restarts.

    Returns:
        The configuration found for each sample, shape (N, nq).

    Raises:
        FrameNotFoundError: ``frame`` is not in the robot model.
        InvalidParameterError: ``samples`` < 1 or ``tolerance`` <= 0.
        PathOutOfReachError: A sample is out of reach (the first one, with the residual).
    """
    if int(samples) < 1:
        raise InvalidParameterError("samples", samples, ">= 1")
    if not tolerance > 0.0:
        raise InvalidParameterError("tolerance", tolerance, "> 0")
    frame_id = robot.frame_id(frame)
    model = robot.model
    data = pin.Data(model)
    low, high = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
    bounded = np.isfinite(low) & np.isfinite(high) & (high > low)
    rng = np.random.default_rng(seed)
    q = robot.check_configuration("q_start", q_start)
    solutions = []
    for time in np.linspace(0.0, path.period, int(samples), endpoint=False):
        target = path(float(time))[0]
        q, residual = _solve(model, data, frame_id, target, q, low, high, bounded)
        for _ in range(_RESTARTS):
            if residual <= tolerance:
                break
            guess = robot.neutral()
            guess[bounded] = rng.uniform(low[bounded], high[bounded])
            candidate, distance = _solve(model, data, frame_id, target, guess, low, high, bounded)
            if distance < residual:
                q, residual = candidate, distance
        if residual > tolerance:
            raise PathOutOfReachError(frame, float(time), target.tolist(), residual)
        solutions.append(q)
    return np.array(solutions)


def _solve(
    model: pin.Model,
    data: pin.Data,
    frame_id: int,
    target: Vector,
    q: Vector,
    low: Vector,
    high: Vector,
    bounded: NDArray[np.bool_],
) -> tuple[Vector, float]:
    """Levenberg–Marquardt on the frame position from ``q``; the best q and its distance [m]."""
    damping = 1e-3
    error = _error(model, data, frame_id, target, q)
    distance = float(np.linalg.norm(error))
    for _ in range(_ITERATIONS):
        if distance <= 1e-12:
            break
        J = pin.computeFrameJacobian(model, data, q, frame_id, _LWA)[:3]
        step = np.linalg.solve(J.T @ J + damping * np.eye(model.nv), -J.T @ error)
        candidate = pin.integrate(model, q, step)
        candidate[bounded] = np.clip(candidate[bounded], low[bounded], high[bounded])
        new_error = _error(model, data, frame_id, target, candidate)
        new_distance = float(np.linalg.norm(new_error))
        if new_distance < distance:
            q, error, distance = candidate, new_error, new_distance
            damping = max(damping / 10.0, 1e-9)
        else:
            damping *= 10.0
            if damping > 1e6:
                break
    return q, distance


def _error(model: pin.Model, data: pin.Data, frame_id: int, target: Vector, q: Vector) -> Vector:
    """Frame position minus target in [m], shape (3,)."""
    pin.framesForwardKinematics(model, data, q)
    return np.asarray(data.oMf[frame_id].translation - target, dtype=float)
