"""Closed-form motion of a ball bouncing on the ground with Newton's restitution."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ucontrol._validation import as_float, as_in_interval, as_positive
from ucontrol.exceptions import InvalidParameterError


@dataclass(frozen=True, kw_only=True)
class BouncingBall:
    r"""Analytic solution of :math:`\ddot y = -g`, :math:`y \ge 0`, :math:`\dot y^+ = -e \dot y^-`.

    Flight i (i = 0, 1, ...) leaves the ground at :math:`t_i` with speed
    :math:`w_i = e^{i+1} V_0`, :math:`V_0 = \sqrt{v_0^2 + 2 g y_0}` the first impact speed, and
    lasts :math:`2 w_i / g`. For e < 1 impacts accumulate at
    :math:`t_\infty = t_0 + 2 e V_0 / (g (1 - e))`, after which the ball rests.

    Attributes:
        height: Initial height y0 in [m], >= 0.
        velocity: Initial vertical velocity v0 in [m/s].
        restitution: e in [0, 1].
        gravity: g in [m/s²], > 0.
    """

    height: float
    velocity: float = 0.0
    restitution: float
    gravity: float = 9.81

    def __post_init__(self) -> None:
        height = as_float("height", self.height)
        if height < 0.0 or (height == 0.0 and self.velocity <= 0.0):
            raise InvalidParameterError("height", self.height, "> 0 (or 0 with upward velocity)")
        object.__setattr__(self, "height", height)
        object.__setattr__(self, "velocity", as_float("velocity", self.velocity))
        object.__setattr__(
            self, "restitution", as_in_interval("restitution", self.restitution, 0.0, 1.0)
        )
        object.__setattr__(self, "gravity", as_positive("gravity", self.gravity))

    @property
    def impact_speed(self) -> float:
        """Speed at the first impact V0 in [m/s]."""
        return math.sqrt(self.velocity**2 + 2.0 * self.gravity * self.height)

    @property
    def first_impact_time(self) -> float:
        """t0 in [s]."""
        return (self.velocity + self.impact_speed) / self.gravity

    @property
    def accumulation_time(self) -> float:
        """t∞ in [s], the end of the accumulation of impacts (inf for e = 1)."""
        e = self.restitution
        if e == 1.0:
            return math.inf
        return self.first_impact_time + 2.0 * e * self.impact_speed / (self.gravity * (1.0 - e))

    def impact_times(self, until: float) -> NDArray[np.float64]:
        """Impact times t0 < t1 < ... up to ``until`` [s] (finitely many before t∞)."""
        times = [self.first_impact_time]
        speed = self.restitution * self.impact_speed
        while times[-1] <= until and speed > 1e-12 * self.impact_speed:
            times.append(times[-1] + 2.0 * speed / self.gravity)
            speed *= self.restitution
        return np.array([t for t in times if t <= until])

    def state(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Height [m] and velocity [m/s] at times ``t`` (post-impact velocity at an impact)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        g, e = self.gravity, self.restitution
        t_end = float(t.max(initial=0.0))
        impacts = self.impact_times(t_end)
        height = self.height + self.velocity * t - 0.5 * g * t**2
        velocity = self.velocity - g * t
        flight = np.searchsorted(impacts, t, side="right") - 1  # -1 before the first impact
        after = flight >= 0
        s = t[after] - impacts[flight[after]]
        takeoff = self.impact_speed * e ** (flight[after] + 1.0)
        height[after] = takeoff * s - 0.5 * g * s**2
        velocity[after] = takeoff - g * s
        resting = t >= self.accumulation_time
        height[resting] = 0.0
        velocity[resting] = 0.0
        return np.maximum(height, 0.0), velocity
