"""A periodic nominal path: a circle in the world frame."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_positive, as_vector
from ucontrol.exceptions import InvalidParameterError

Vector = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class CirclePath:
    r"""A circle run counter-clockwise in the plane of its axes (u, w).

    :math:`p(t) = c + r (\cos\varphi\,u + \sin\varphi\,w)` with
    :math:`\varphi = \varphi_0 + 2\pi t / P`.

    It is the *nominal* path of a cycle: it may cross obstacles, where the desired trajectory
    is its projection on the surface during a declared contact phase.

    Attributes:
        centre: Centre c in the world frame in [m], shape (3,).
        radius: Radius r in [m], > 0.
        period: Period P in [s], > 0.
        axes: Orthonormal in-plane directions (u, w), shape (2, 3); normalised and checked.
        start_angle: Angle :math:`\varphi_0` at t = 0 in [rad].
    """

    centre: Vector
    radius: float
    period: float
    axes: NDArray[np.float64] = field(
        default_factory=lambda: np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    )
    start_angle: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", as_vector("centre", self.centre, 3))
        object.__setattr__(self, "radius", as_positive("radius", self.radius))
        object.__setattr__(self, "period", as_positive("period", self.period))
        object.__setattr__(self, "start_angle", as_float("start_angle", self.start_angle))
        axes = np.array(self.axes, dtype=float)
        if axes.shape != (2, 3):
            raise InvalidParameterError("axes", self.axes, "two 3-vectors (u, w)")
        norms = np.linalg.norm(axes, axis=1)
        if np.any(norms < 1e-12) or abs(axes[0] @ axes[1]) > 1e-9 * norms.prod():
            raise InvalidParameterError("axes", self.axes, "two orthogonal non-zero vectors")
        object.__setattr__(self, "axes", axes / norms[:, None])
        object.__setattr__(self, "_plane_tables", {})  # order -> plane_table(order)

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at time ``t`` [s], each (3,)."""
        p, dp, ddp = self.derivatives(t, 2)
        return p, dp, ddp

    def derivatives(self, t: float, order: int) -> tuple[Vector, ...]:
        r"""Position [m] and its first ``order`` time derivatives [m/s^k] at ``t`` [s], each (3,).

        :math:`p^{(k)} = r \omega^k (\cos(\varphi + k\pi/2)\,u + \sin(\varphi + k\pi/2)\,w)`
        for k >= 1, with :math:`\omega = 2\pi/P`.
        """
        return tuple(self.derivative_matrix(t, order))

    def derivative_matrix(self, t: float, order: int) -> NDArray[np.float64]:
        """:meth:`derivatives` stacked, shape (order + 1, 3): row k is the k-th derivative.

        Row k is :math:`a_k u + b_k w` (plus c for k = 0) with the :meth:`plane_coefficients`
        :math:`(a_k, b_k)`: one small matrix product instead of a dozen operations on
        3-vectors.
        """
        rows = self.plane_coefficients(t, order) @ self.axes
        rows[0] += self.centre
        return rows

    def plane_coefficients(self, t: float, order: int) -> NDArray[np.float64]:
        r"""Coordinates along (u, w) of :math:`p - c` and of its derivatives, (order + 1, 2).

        Row k is :math:`r \omega^k (\cos(\varphi + k\pi/2), \sin(\varphi + k\pi/2))`: the
        :meth:`plane_table` applied to :math:`(\cos\varphi, \sin\varphi)`.
        """
        angle = self.angle(t)
        return np.dot(self.plane_table(order), np.array([math.cos(angle), math.sin(angle)]))

    def angle(self, t: float) -> float:
        r"""The angle :math:`\varphi = \varphi_0 + 2\pi t / P` at time ``t`` [s], in [rad]."""
        omega = 2.0 * math.pi / self.period  # [rad/s]
        return self.start_angle + omega * t

    def plane_table(self, order: int) -> NDArray[np.float64]:
        r"""The constant part of the :meth:`plane_coefficients`, shape (order + 1, 2, 2).

        Entry k is :math:`r \omega^k R^k` with R the rotation by :math:`\pi/2`, so that
        row k of the coefficients is entry k applied to :math:`(\cos\varphi, \sin\varphi)`:
        each coefficient is one product :math:`\pm r \omega^k \cos\varphi` or
        :math:`\pm r \omega^k \sin\varphi`, and the whole trajectory's time dependence is the
        pair :math:`(\cos\varphi, \sin\varphi)` (one matrix product per sample). Built once per
        order, read-only.
        """
        tables: dict[int, NDArray[np.float64]] = self.__dict__["_plane_tables"]
        if order not in tables:
            omega = 2.0 * math.pi / self.period  # [rad/s]
            r = self.radius
            quarter_turn = np.array([[0.0, -1.0], [1.0, 0.0]])  # (cos, sin) -> (-sin, cos)
            table = [r * np.eye(2)]
            for k in range(1, order + 1):
                table.append(r * omega**k * np.linalg.matrix_power(quarter_turn, k))
            tables[order] = np.array(table)
            tables[order].flags.writeable = False
        return tables[order]
