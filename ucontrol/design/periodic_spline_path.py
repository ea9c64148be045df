r"""A periodic path through samples: a periodic quintic spline (C⁴), with its derivatives.

It has the :class:`ucontrol.control.desired_cycle.NominalPath` protocol (``period``,
``__call__``, ``derivatives`` up to order 4, the flexible-joint law's need). Superseded by
:class:`ucontrol.control.SplinePath` (the same interpolant), which
:meth:`ucontrol.design.DesignedCycle.nominal_path` now returns; kept for code that builds one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import BSpline, make_interp_spline

from ucontrol._validation import as_positive
from ucontrol.exceptions import InvalidParameterError, ShapeError

Vector = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class PeriodicSplinePath:
    """The periodic quintic interpolant of positions sampled over one period.

    Attributes:
        times: Sample times in [s], increasing, shape (n,), from 0 (inclusive) to
            ``period`` (exclusive).
        positions: Positions in the world in [m], shape (n, 3).
        period: Period P in [s], > times[-1].
    """

    times: Vector
    positions: NDArray[np.float64]
    period: float
    _spline: BSpline = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=float)
        positions = np.asarray(self.positions, dtype=float)
        period = as_positive("period", self.period)
        if positions.ndim != 2 or positions.shape != (times.size, 3):
            raise ShapeError("positions", (times.size, 3), positions.shape)
        if times.size < 6 or np.any(np.diff(times) <= 0.0) or times[0] < 0.0:
            raise InvalidParameterError("times", times.tolist(), ">= 6 increasing times >= 0")
        if not times[-1] < period:
            raise InvalidParameterError("period", period, f"> the last sample time {times[-1]}")
        closed_t = np.append(times, times[0] + period)
        closed_p = np.vstack((positions, positions[:1]))
        spline = make_interp_spline(closed_t, closed_p, k=5, bc_type="periodic")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "period", period)
        object.__setattr__(self, "_spline", spline)

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at ``t`` [s], each (3,)."""
        p, dp, ddp = self.derivatives(t, 2)
        return p, dp, ddp

    def derivatives(self, t: float, order: int) -> tuple[Vector, ...]:
        """Position [m] and its first ``order`` (<= 4) derivatives [m/s^k] at ``t`` [s]."""
        if not 0 <= order <= 4:
            raise InvalidParameterError("order", order, "in [0, 4] (a quintic spline)")
        s = self.times[0] + np.mod(t - self.times[0], self.period)
        return tuple(np.asarray(self._spline(s, nu=k), dtype=float) for k in range(order + 1))
