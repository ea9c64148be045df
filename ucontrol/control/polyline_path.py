r"""A periodic path along a closed polyline of waypoints, at rest at each waypoint."""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_positive
from ucontrol.control.trajectory_segment import smooth_step
from ucontrol.control.waypoints import as_times, as_waypoints, closed_lengths, periodic_time
from ucontrol.exceptions import InvalidParameterError

Vector = NDArray[np.float64]

#: Continuity of the timing law: the position and its first four derivatives are continuous.
CONTINUITY = 4


@dataclass(frozen=True, kw_only=True)
class PolylinePath:
    r"""Waypoints :math:`w_0, ..., w_{n-1}` visited in turn, then back to :math:`w_0`.

    The path arrives at :math:`w_i` at ``times[i]``, rests there for ``rest_time``, then runs
    the straight leg to :math:`w_{i+1}` (the last leg back to :math:`w_0`, arriving at
    ``times[0] + period``) with the :math:`C^4` timing law

    .. math::

        p(t) = w_i + (w_{i+1} - w_i)\,\beta_4(\sigma), \qquad
        \sigma = \frac{t - t_i - t_r}{t_{i+1} - t_i - t_r},

    where :math:`\beta_4` is the nonic smooth step
    (:func:`ucontrol.control.trajectory_segment.smooth_step`, continuity 4): the velocity and
    the next three derivatives vanish at each waypoint, so the path is :math:`C^4` everywhere,
    also across the period (the fifth derivative jumps at the ends of each leg).

    Attributes:
        waypoints: Waypoints in the world frame in [m], shape (n, 3), n >= 2, no two
            consecutive ones (the last followed by the first) equal.
        period: Period P in [s], > 0.
        times: Arrival time at each waypoint in [s], shape (n,), strictly increasing with
            ``times[-1] < times[0] + period``; default: the legs' durations proportional to
            their lengths, arriving at :math:`w_0` at t = 0.
        rest_time: Time spent at rest on each waypoint in [s], >= 0, shorter than every leg's
            interval.

    Raises:
        ShapeError: Waypoints not (n, 3) or times not (n,).
        NonFiniteValueError: Non-finite waypoints or times.
        InvalidParameterError: Fewer than two waypoints, equal consecutive waypoints,
            non-increasing times, or a rest time leaving no time to move.
    """

    waypoints: NDArray[np.float64]
    period: float
    times: NDArray[np.float64] | None = None
    rest_time: float = 0.0

    def __post_init__(self) -> None:
        points = as_waypoints("waypoints", self.waypoints)
        period = as_positive("period", self.period)
        rest = as_float("rest_time", self.rest_time)
        if rest < 0.0:
            raise InvalidParameterError("rest_time", self.rest_time, ">= 0")
        lengths = closed_lengths("waypoints", points)  # [m]
        n = len(points)
        if self.times is None:
            moving = period - n * rest  # [s] of motion per period
            if moving <= 0.0:
                raise InvalidParameterError(
                    "rest_time", self.rest_time, f"< period / n = {period / n} s"
                )
            times = np.concatenate(([0.0], np.cumsum(rest + moving * lengths / lengths.sum())))
            times = times[:-1]
        else:
            times = as_times("times", self.times, n, period)
        durations = np.diff(np.append(times, times[0] + period)) - rest  # [s] per leg
        short = np.flatnonzero(durations <= 0.0)
        if short.size:
            i = int(short[0])
            raise InvalidParameterError(
                "rest_time",
                self.rest_time,
                f"shorter than the interval {durations[i] + rest} s between waypoints {i} and "
                f"{(i + 1) % n}",
            )
        object.__setattr__(self, "waypoints", points)
        object.__setattr__(self, "period", period)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "rest_time", rest)
        object.__setattr__(self, "_legs", np.roll(points, -1, axis=0) - points)
        object.__setattr__(self, "_durations", durations)
        object.__setattr__(self, "_starts", times.tolist())

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at time ``t`` [s], each (3,)."""
        p, dp, ddp = self.derivatives(t, 2)
        return p, dp, ddp

    def derivatives(self, t: float, order: int) -> tuple[Vector, ...]:
        r"""Position [m] and its first ``order`` time derivatives [m/s^k] at ``t`` [s], each (3,).

        :math:`p^{(k)} = (w_{i+1} - w_i)\,\beta_4^{(k)}(\sigma) / T_i^k` on leg i of duration
        :math:`T_i` (continuous for k <= 4).
        """
        starts: list[float] = self.__dict__["_starts"]
        tau = periodic_time(float(t), starts[0], self.period)
        i = bisect.bisect_right(starts, tau) - 1
        T = float(self.__dict__["_durations"][i])  # [s]
        leg = self.__dict__["_legs"][i]
        beta = smooth_step((tau - starts[i] - self.rest_time) / T, order, CONTINUITY)
        point = self.waypoints[i] + leg * beta[0]
        return (point, *(leg * (beta[k] / T**k) for k in range(1, order + 1)))

    def describe(self) -> dict[str, Any]:
        """The path as a ``[controller.path]`` table."""
        assert self.times is not None
        return {
            "type": "polyline",
            "waypoints": self.waypoints.tolist(),
            "period": self.period,
            "times": self.times.tolist(),
            "rest_time": self.rest_time,
        }
