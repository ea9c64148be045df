r"""A periodic straight segment run back and forth with a :math:`C^4` timing law."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_positive, as_vector
from ucontrol.control.polyline_path import PolylinePath
from ucontrol.exceptions import InvalidParameterError

Vector = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class SegmentPath:
    r"""From ``start`` to ``end`` and back, once per period, at rest at both ends.

    The polyline (:class:`PolylinePath`) of the two waypoints (start, end): it leaves ``start``
    at ``rest_time`` after t = 0, arrives at ``end`` at ``period / 2``, rests there, and is
    back at ``start`` at ``period``; each way follows the nonic smooth step, so the path is
    :math:`C^4` (velocity and the next three derivatives vanish at both ends).

    Attributes:
        start: First end in the world frame in [m], shape (3,).
        end: Second end in [m], shape (3,), different from ``start``.
        period: Period P in [s], > 0 (one way takes P / 2 including its rest).
        rest_time: Time at rest on each end in [s], in [0, P/2).

    Raises:
        ShapeError: ``start`` or ``end`` not of shape (3,).
        NonFiniteValueError: Non-finite ``start`` or ``end``.
        InvalidParameterError: ``start`` equals ``end``, or a rest time leaving no time to move.
    """

    start: Vector
    end: Vector
    period: float
    rest_time: float = 0.0

    def __post_init__(self) -> None:
        start = as_vector("start", self.start, 3)
        end = as_vector("end", self.end, 3)
        if np.linalg.norm(end - start) <= 1e-12:
            raise InvalidParameterError("end", self.end, f"a point different from start {start}")
        period = as_positive("period", self.period)
        rest = as_float("rest_time", self.rest_time)
        if not 0.0 <= rest < 0.5 * period:
            raise InvalidParameterError("rest_time", self.rest_time, f"in [0, {0.5 * period}) s")
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "period", period)
        object.__setattr__(self, "rest_time", rest)
        polyline = PolylinePath(
            waypoints=np.array([start, end]),
            period=period,
            times=np.array([0.0, 0.5 * period]),
            rest_time=rest,
        )
        object.__setattr__(self, "_polyline", polyline)

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at time ``t`` [s], each (3,)."""
        p, dp, ddp = self.derivatives(t, 2)
        return p, dp, ddp

    def derivatives(self, t: float, order: int) -> tuple[Vector, ...]:
        """Position [m] and its first ``order`` time derivatives [m/s^k] at ``t`` [s], each (3,)."""
        polyline: PolylinePath = self.__dict__["_polyline"]
        return polyline.derivatives(t, order)

    def describe(self) -> dict[str, Any]:
        """The path as a ``[controller.path]`` table."""
        return {
            "type": "segment",
            "start": self.start.tolist(),
            "end": self.end.tolist(),
            "period": self.period,
            "rest_time": self.rest_time,
        }
