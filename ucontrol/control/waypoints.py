"""Checks of the waypoints and times shared by the waypoint paths (polyline, spline)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_vector
from ucontrol.exceptions import InvalidParameterError, NonFiniteValueError, ShapeError

#: Two waypoints closer than this are the same point, in [m].
DUPLICATE_TOLERANCE = 1e-12


def as_waypoints(name: str, value: Any, minimum: int = 2) -> NDArray[np.float64]:
    """Return ``value`` as finite waypoints in the world frame, shape (n, 3), n >= ``minimum``.

    Args:
        name: Argument name used in error messages.
        value: Array-like of n points, each (3,), in [m].
        minimum: Smallest number of waypoints.

    Raises:
        ShapeError: ``value`` is not of shape (n, 3).
        NonFiniteValueError: ``value`` holds NaN or infinity.
        InvalidParameterError: Fewer than ``minimum`` waypoints.
    """
    try:
        points = np.array(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError(name, value, "a list of 3-vectors") from error
    if points.ndim != 2 or points.shape[1] != 3:
        raise ShapeError(name, (-1, 3), points.shape)
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if bad.size:
        raise NonFiniteValueError(name, value, bad.tolist())
    if points.shape[0] < minimum:
        raise InvalidParameterError(name, value, f"at least {minimum} waypoints")
    return points


def closed_lengths(name: str, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Lengths [m] of the legs i -> i + 1 of the closed polygon (the last one back to 0), (n,).

    Raises:
        InvalidParameterError: Two consecutive waypoints (cyclically) coincide.
    """
    lengths = np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1)
    same = np.flatnonzero(lengths <= DUPLICATE_TOLERANCE)
    if same.size:
        i = int(same[0])
        j = (i + 1) % len(points)
        raise InvalidParameterError(
            name,
            points.tolist(),
            f"distinct consecutive waypoints (waypoints {i} and {j}, the last one followed by "
            f"the first, are both {points[i].tolist()})",
        )
    return np.asarray(lengths, dtype=float)


def as_times(name: str, value: Any, n: int, period: float) -> NDArray[np.float64]:
    """Return ``value`` as n strictly increasing times within one period, in [s].

    The path passes through waypoint i at ``times[i]``; after the last one it returns to the
    first at ``times[0] + period``, so ``times[-1] < times[0] + period``.

    Raises:
        ShapeError: ``value`` is not of shape (n,).
        NonFiniteValueError: ``value`` holds NaN or infinity.
        InvalidParameterError: The times do not increase strictly or span a period or more.
    """
    times = as_vector(name, value, n)
    steps = np.diff(np.append(times, times[0] + period))
    bad = np.flatnonzero(steps <= 0.0)
    if bad.size:
        i = int(bad[0])
        if i == n - 1:
            raise InvalidParameterError(
                name, times.tolist(), f"times spanning less than the period {period} s"
            )
        raise InvalidParameterError(
            name,
            times.tolist(),
            f"strictly increasing times (times[{i}] = {times[i]} >= times[{i + 1}] = "
            f"{times[i + 1]})",
        )
    return times


def periodic_time(t: float, start: float, period: float) -> float:
    """``t`` [s] brought into [start, start + period)."""
    tau = start + (t - start) % period
    return tau if tau < start + period else start
