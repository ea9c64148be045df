r"""A periodic quintic spline through waypoints: a :math:`C^4` closed path."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_interp_spline

from ucontrol._validation import as_positive
from ucontrol.control.waypoints import as_times, as_waypoints, closed_lengths, periodic_time

Vector = NDArray[np.float64]

#: Degree of the spline: 5, so that the periodic interpolant is :math:`C^4`.
DEGREE = 5


@dataclass(frozen=True, kw_only=True)
class SplinePath:
    r"""The periodic interpolating spline of degree 5 through the waypoints at given times.

    :math:`p(t)` is a polynomial of degree 5 between consecutive waypoint times, passes
    through :math:`w_i` at :math:`t_i` (and :math:`w_0` again at :math:`t_0 + P`), and its
    first four derivatives are continuous at every waypoint and across the period
    (:math:`p^{(k)}(t_0) = p^{(k)}(t_0 + P)`, k <= 4): the periodic spline of odd degree 5
    with knots at the waypoint times, solved as one linear system
    (``scipy.interpolate.make_interp_spline`` with periodic conditions). The fifth derivative
    is piecewise constant. Two waypoints give a closed curve through both.

    Attributes:
        waypoints: Waypoints in the world frame in [m], shape (n, 3), n >= 2.
        period: Period P in [s], > 0.
        times: Time at each waypoint in [s], shape (n,), strictly increasing with
            ``times[-1] < times[0] + period``; default: chord-length times (intervals
            proportional to the distances between consecutive waypoints, the last one back to
            the first), starting at 0. Equal consecutive waypoints need explicit times (the
            path then leaves and comes back to the same point).

    Raises:
        ShapeError: Waypoints not (n, 3) or times not (n,).
        NonFiniteValueError: Non-finite waypoints or times.
        InvalidParameterError: Fewer than two waypoints, non-increasing times, or equal
            consecutive waypoints with default times.
    """

    waypoints: NDArray[np.float64]
    period: float
    times: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        points = as_waypoints("waypoints", self.waypoints)
        period = as_positive("period", self.period)
        if self.times is None:
            lengths = closed_lengths("waypoints", points)  # [m]
            times = np.concatenate(([0.0], np.cumsum(period * lengths / lengths.sum())[:-1]))
        else:
            times = as_times("times", self.times, len(points), period)
        object.__setattr__(self, "waypoints", points)
        object.__setattr__(self, "period", period)
        object.__setattr__(self, "times", times)
        knots = np.append(times, times[0] + period)  # [s]
        spline = make_interp_spline(
            knots, np.vstack([points, points[:1]]), k=DEGREE, bc_type="periodic"
        )
        # Each piece as its Taylor polynomial about the middle of its interval (exact: the
        # piece has degree 5), so that no one-sided value at a knot is needed.
        middles = 0.5 * (knots[:-1] + knots[1:])
        taylor = np.array(
            [spline(middles, nu=j) / math.factorial(j) for j in range(DEGREE + 1)]
        )  # (6, n, 3): coefficient of (t - middle)^j
        object.__setattr__(self, "_starts", times.tolist())
        object.__setattr__(self, "_middles", middles)
        object.__setattr__(self, "_coefficients", np.ascontiguousarray(taylor.transpose(1, 0, 2)))

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at time ``t`` [s], each (3,)."""
        p, dp, ddp = self.derivatives(t, 2)
        return p, dp, ddp

    def derivatives(self, t: float, order: int) -> tuple[Vector, ...]:
        r"""Position [m] and its first ``order`` time derivatives [m/s^k] at ``t`` [s], each (3,).

        Continuous for k <= 4, piecewise constant for k = 5, zero above.
        """
        starts: list[float] = self.__dict__["_starts"]
        tau = periodic_time(float(t), starts[0], self.period)
        i = bisect.bisect_right(starts, tau) - 1
        s = tau - float(self.__dict__["_middles"][i])  # [s] from the middle of the piece
        a = self.__dict__["_coefficients"][i]  # (6, 3)
        values = []
        for k in range(order + 1):
            if k > DEGREE:
                values.append(np.zeros(3))
                continue
            value = np.zeros(3)
            for j in range(DEGREE, k - 1, -1):  # Horner on the k-th derivative
                value = value * s + a[j] * (math.factorial(j) / math.factorial(j - k))
            values.append(value)
        return tuple(values)

    def describe(self) -> dict[str, Any]:
        """The path as a ``[controller.path]`` table."""
        assert self.times is not None
        return {
            "type": "spline",
            "waypoints": self.waypoints.tolist(),
            "period": self.period,
            "times": self.times.tolist(),
        }
