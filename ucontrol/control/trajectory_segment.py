r"""Pieces of a one-coordinate desired trajectory, glued by the phase machine.

Each segment maps a time ``t`` [s] and the nominal sample of its coordinate at ``t`` (value and
its first k time derivatives) to the desired sample, of the same length: k = 2 for the rigid
law, 4 for the flexible-joint law. Positions are in [m], velocities in [m/s], the i-th
derivative in [m/s^i].

Two families, picked by the phase machine from its ``order`` k:

- for the rigid law (k = 2): :class:`RestCubic`, :class:`Parabola` and :class:`BlendToNominal`
  with the quintic :func:`smooth_step`. A segment started at ``t0`` from the value and velocity
  of the previous one keeps the desired trajectory :math:`C^1`, which is all the rigid V needs
  (it holds the desired position and velocity); the acceleration jumps at some joins (the
  torque jumps there, not the state);
- for a law that holds k > 2 derivatives (the flexible-joint law, k = 4: its V holds the third
  derivative through the motor reference, its input the fourth): :class:`RestHermite`,
  :class:`SmoothParabola` and :class:`BlendToNominal` with the smooth step of continuity k.
  Every join is :math:`C^k`, so neither V nor the input jumps there.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

from numpy.polynomial import Polynomial

#: A coordinate and its first time derivatives: (position, velocity, acceleration, ...).
Sample = tuple[float, ...]


def smooth_step(sigma: float, order: int = 2, continuity: int = 2) -> Sample:
    r"""Smooth step :math:`\beta_n` from 0 to 1 on [0, 1], :math:`C^n` with n = ``continuity``.

    :math:`\beta_n(\sigma) = \sigma^{n+1} \sum_{k=0}^{n} \binom{n+k}{k} (1 - \sigma)^k` is the
    polynomial of degree 2n + 1 with :math:`\beta_n = \beta_n' = ... = \beta_n^{(n)} = 0` at 0
    and :math:`\beta_n = 1`, :math:`\beta_n' = ... = \beta_n^{(n)} = 0` at 1; constant outside
    [0, 1], so its derivative n + 1 jumps at both ends. n = 2 is the quintic
    :math:`10\sigma^3 - 15\sigma^4 + 6\sigma^5` (:math:`\beta''' = 60` at both ends inside, 0
    outside), evaluated in that closed form (the rigid law's blends and :math:`\lambda_d`);
    n = 4 the nonic :math:`126\sigma^5 - 420\sigma^6 + 540\sigma^7 - 315\sigma^8 + 70\sigma^9`.
    By symmetry, :math:`\beta_n(1 - \sigma) = 1 - \beta_n(\sigma)` and
    :math:`\int_0^1 \beta_n = 1/2`.

    Args:
        sigma: The argument.
        order: Number of derivatives returned, >= 0.
        continuity: n, >= 0.

    Returns:
        :math:`(\beta_n, \beta_n', ..., \beta_n^{(order)})` at ``sigma``.
    """
    if sigma <= 0.0:
        values: Sample = (0.0,)
    elif sigma >= 1.0:
        values = (1.0,)
    elif continuity != 2:
        values = _polynomial_sample(_smooth_step_table(continuity), sigma, order + 1)
    elif order == 0:  # the quintic alone (a desired force)
        return (sigma**3 * (10.0 - 15.0 * sigma + 6.0 * sigma**2),)
    else:  # the quintic in closed form; its derivatives 3 to 5 only when asked for
        values = (
            sigma**3 * (10.0 - 15.0 * sigma + 6.0 * sigma**2),
            30.0 * sigma**2 * (1.0 - sigma) ** 2,
            60.0 * sigma * (1.0 - sigma) * (1.0 - 2.0 * sigma),
        )
        if order > 2:
            values += (
                60.0 * (1.0 - 6.0 * sigma + 6.0 * sigma**2),
                360.0 * (2.0 * sigma - 1.0),
                720.0,
            )
    return _padded(values, order + 1)


def _padded(values: Sample, size: int) -> Sample:
    """``values`` cut or completed with zeros to ``size`` entries."""
    return values[:size] + (0.0,) * (size - len(values))


@functools.cache
def _smooth_step_coefficients(continuity: int) -> tuple[float, ...]:
    r"""Coefficients of :math:`\beta_n` (see :func:`smooth_step`), by increasing degree."""
    n = continuity
    rest = Polynomial([1.0, -1.0])  # 1 - σ
    tail = sum((math.comb(n + k, k) * rest**k for k in range(n + 1)), Polynomial([0.0]))
    return tuple(float(c) for c in (Polynomial([0.0, 1.0]) ** (n + 1) * tail).coef)


@functools.cache
def _smooth_step_table(continuity: int) -> PolynomialTable:
    r"""The :func:`_derivative_table` of :math:`\beta_n` (see :func:`smooth_step`)."""
    return _derivative_table(_smooth_step_coefficients(continuity))


#: A polynomial and its successive derivatives down to a constant, each by decreasing degree.
PolynomialTable = tuple[tuple[float, ...], ...]


def _derivative_table(coefficients: Sequence[float]) -> PolynomialTable:
    """The coefficients of P, P', P'', ... (while not identically 0), by decreasing degree.

    Built once per polynomial so that :func:`_polynomial_sample` only runs Horner's scheme.

    Args:
        coefficients: Those of P, by increasing degree.
    """
    table = []
    c = list(coefficients)
    while c:
        table.append(tuple(reversed(c)))  # in the order of Horner's scheme
        c = [i * a for i, a in enumerate(c)][1:]
    return tuple(table)


def _polynomial_sample(
    table: PolynomialTable, sigma: float, size: int, duration: float = 1.0
) -> Sample:
    r"""A polynomial P of :math:`\sigma = (t - t_0)/T` and its time derivatives at ``sigma``.

    Args:
        table: P and its derivatives (:func:`_derivative_table`).
        sigma: The argument.
        size: Number of values returned.
        duration: T in [s] (1: derivatives with respect to :math:`\sigma`).

    Returns:
        :math:`P^{(k)}(\sigma) / T^k` for k < ``size`` (0 beyond the degree of P).
    """
    values = []
    scale = 1.0  # T^k [s^k]
    for c in table[:size]:
        value = 0.0
        for a in c:  # Horner
            value = value * sigma + a
        values.append(value / scale)
        scale *= duration
    return _padded(tuple(values), size)


class TrajectorySegment(Protocol):
    """A desired trajectory of one task coordinate."""

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Desired sample at time ``t`` [s], as long as ``nominal``."""
        ...


class Nominal:
    """Follows the nominal path."""

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """The nominal sample itself."""
        return nominal


@dataclass(frozen=True)
class Constant:
    """Holds ``value`` with zero velocity (e.g. 0 on a surface during a constrained phase)."""

    value: float

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """``(value, 0, 0, ...)``."""
        return _padded((self.value,), len(nominal))


@dataclass(frozen=True)
class RestCubic:
    r"""Hermite cubic from a value and a velocity to a value at rest, then that value.

    From :math:`(p_0, v_0)` at :math:`t_0` to :math:`(p_1, 0)` at :math:`t_0 + T`.

    With :math:`p_1 = p_0 + v_0 T / 2` it is the constant-deceleration stop of a coordinate
    that is frozen; with :math:`p_1 = -d` it is the approach to a virtual target below a surface.
    Its third derivative is constant on the cubic and jumps to 0 at its end. It is the
    :class:`RestHermite` from (p0, v0) (n = 1) in closed form: the rigid law's piece.

    Attributes:
        t0: Start time in [s].
        p0: Start position.
        v0: Start velocity.
        p1: End position.
        duration: T in [s], > 0.
    """

    t0: float
    p0: float
    v0: float
    p1: float
    duration: float
    _drop: float = field(init=False, repr=False, compare=False)  # p0 - p1
    _jerk: float = field(init=False, repr=False, compare=False)  # the constant third derivative
    _T2: float = field(init=False, repr=False, compare=False)  # T**2 [s²]

    def __post_init__(self) -> None:
        T, drop = self.duration, self.p0 - self.p1
        object.__setattr__(self, "_drop", drop)
        object.__setattr__(self, "_jerk", 12 * drop / T**3 + 6 * self.v0 / T**2)
        object.__setattr__(self, "_T2", T**2)

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Hermite cubic sample at ``t``; ``(p1, 0, 0, ...)`` once it has ended."""
        T = self.duration
        sigma = (t - self.t0) / T
        if sigma >= 1.0:
            return _padded((self.p1,), len(nominal))
        if sigma < 0.0:  # max(sigma, 0.0) without the call (the same for -0.0 and NaN)
            sigma = 0.0
        s2, s3 = sigma * sigma, sigma * sigma * sigma
        p0, v0, p1, drop = self.p0, self.v0, self.p1, self._drop
        position = (
            (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + sigma) * T * v0 + (3 * s2 - 2 * s3) * p1
        )
        velocity = (6 * s2 - 6 * sigma) * drop / T + (3 * s2 - 4 * sigma + 1) * v0
        acceleration = (12 * sigma - 6) * drop / self._T2 + (6 * sigma - 4) * v0 / T
        if len(nominal) == 3:  # the rigid law's sample: _padded, without the call
            return (position, velocity, acceleration)
        return _padded((position, velocity, acceleration, self._jerk), len(nominal))


@dataclass(frozen=True)
class RestHermite:
    r"""Hermite polynomial from a value and n derivatives to a value at rest, then that value.

    The polynomial P of degree 2n + 1 from :math:`(p_0, \dot p_0, ..., p_0^{(n)})` at
    :math:`t_0` to :math:`(p_1, 0, ..., 0)` at :math:`t_0 + T`, then :math:`p_1`: both joins are
    :math:`C^n`. In :math:`\sigma = (t - t_0)/T`, :math:`P = p_1 + (1 - \sigma)^{n+1} R` with R
    of degree n, the Taylor expansion at 0 of :math:`(P - p_1)(1 - \sigma)^{-(n+1)}`:
    :math:`R = \big[\sum_k c_k \sigma^k \sum_j \binom{n+j}{j} \sigma^j\big]_{\deg \le n}`,
    :math:`c_k = T^k p_0^{(k)}/k! - p_1 \delta_{k0}`. With n = 4 (the flexible-joint law) it is
    the degree-9 approach to a virtual target and stop of a frozen coordinate.

    Attributes:
        t0: Start time in [s].
        start: :math:`(p_0, \dot p_0, ..., p_0^{(n)})`, n >= 0 (position, then [1/s^k]).
        p1: End position.
        duration: T in [s], > 0.
    """

    t0: float
    start: Sample
    p1: float
    duration: float
    _table: PolynomialTable = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        n, T = len(self.start) - 1, self.duration
        c = [T**k * p / math.factorial(k) for k, p in enumerate(self.start)]  # [position]
        c[0] -= self.p1
        inverse = [float(math.comb(n + j, j)) for j in range(n + 1)]  # (1 - σ)^-(n+1), deg <= n
        remainder = Polynomial((Polynomial(c) * Polynomial(inverse)).coef[: n + 1])
        hermite = Polynomial([self.p1]) + Polynomial([1.0, -1.0]) ** (n + 1) * remainder
        table = _derivative_table([float(a) for a in hermite.coef])
        object.__setattr__(self, "_table", table)

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Hermite sample at ``t``; ``(p1, 0, 0, ...)`` once it has ended."""
        T = self.duration
        sigma = (t - self.t0) / T
        if sigma >= 1.0:
            return _padded((self.p1,), len(nominal))
        return _polynomial_sample(self._table, max(sigma, 0.0), len(nominal), T)


@dataclass(frozen=True)
class Parabola:
    r""":math:`\tfrac12 a (t - t_0)^2`: leaves 0 at :math:`t_0` with zero velocity.

    Attributes:
        t0: Start time in [s].
        acceleration: a, > 0 for a takeoff.
    """

    t0: float
    acceleration: float

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Parabola sample at ``t`` (``t >= t0``)."""
        tau = t - self.t0
        a = self.acceleration
        return _padded((0.5 * a * tau * tau, a * tau, a), len(nominal))


@dataclass(frozen=True)
class SmoothParabola:
    r"""A takeoff from 0 at rest whose acceleration rises smoothly from 0 to a, then stays a.

    :math:`\ddot x = a\,\beta_n(\sigma)`, :math:`\sigma = (t - t_0)/T_r` (the :func:`smooth_step`
    of continuity n), from :math:`x = \dot x = 0` at :math:`t_0`: x and its first n + 2
    derivatives are 0 at :math:`t_0`, and the acceleration reaches a at :math:`t_0 + T_r`, after
    which :math:`x = a T_r^2 (B(1) + (\sigma - 1)/2 + (\sigma - 1)^2/2)`, with
    :math:`B = \iint \beta_n` from 0 and :math:`\int_0^1 \beta_n = 1/2`: the :class:`Parabola` of
    acceleration a, :math:`T_r/2` late. :math:`\ddot x \ge 0` throughout, so x > 0 after
    :math:`t_0`. With n = k - 2 it leaves a coordinate held at 0 :math:`C^k`.

    Attributes:
        t0: Start time in [s].
        acceleration: a, > 0 for a takeoff.
        ramp_time: :math:`T_r` in [s], > 0.
        continuity: n, >= 0.
    """

    t0: float
    acceleration: float
    ramp_time: float
    continuity: int
    _ramp: PolynomialTable = field(init=False, repr=False, compare=False)
    _parabola: PolynomialTable = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        scale = self.acceleration * self.ramp_time**2  # a T_r² [position]
        ramp = Polynomial(_smooth_step_coefficients(self.continuity)).integ(2)  # B
        # B(1) + (σ - 1)/2 + (σ - 1)²/2 = B(1) - σ/2 + σ²/2
        parabola = (float(ramp(1.0)), -0.5, 0.5)
        object.__setattr__(self, "_ramp", _derivative_table([scale * float(a) for a in ramp.coef]))
        object.__setattr__(self, "_parabola", _derivative_table([scale * a for a in parabola]))

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Takeoff sample at ``t``; 0 at rest before ``t0``."""
        sigma = max((t - self.t0) / self.ramp_time, 0.0)
        table = self._ramp if sigma < 1.0 else self._parabola
        return _polynomial_sample(table, sigma, len(nominal), self.ramp_time)


@dataclass(frozen=True)
class BlendToNominal:
    r"""Moves smoothly from ``base`` to the nominal path over ``duration``.

    :math:`x = b + \beta(\sigma)(y - b)`, :math:`\sigma = (t - t_0)/T`, b the base and y the
    nominal sample, with the :func:`smooth_step` :math:`\beta` of continuity c (the quintic,
    c = 2, by default): the result starts as ``base`` to order c and ends on the nominal path to
    order c. Its derivatives follow Leibniz's rule,
    :math:`x^{(k)} = b^{(k)} + \sum_{i=0}^{k} \binom{k}{i} \beta^{(i)} (y - b)^{(k-i)}`.

    Attributes:
        base: The segment left.
        t0: Start time in [s].
        duration: T in [s], > 0.
        continuity: c of the smooth step, >= 0.
    """

    base: TrajectorySegment
    t0: float
    duration: float
    continuity: int = 2

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Blended sample at ``t``; the nominal sample once the blend has ended."""
        T = self.duration
        sigma = (t - self.t0) / T
        if sigma >= 1.0:
            return nominal
        if self.continuity == 2 and len(nominal) == 3:
            return self._quintic_blend(t, sigma, nominal)
        order = len(nominal) - 1
        beta = smooth_step(sigma, order, self.continuity)
        rates = [beta[0]]  # the time derivatives of β [1/s^i]
        scale = 1.0
        for value in beta[1:]:
            scale *= T
            rates.append(value / scale)
        base = self.base(t, nominal)
        error = [n - b for n, b in zip(nominal, base, strict=True)]
        blended = []
        for k, binomials in enumerate(_binomial_rows(order)):
            value = base[k]
            for i, weight in enumerate(binomials):
                value += weight * rates[i] * error[k - i]
            blended.append(value)
        return tuple(blended)

    def _quintic_blend(self, t: float, sigma: float, nominal: Sample) -> Sample:
        """The rigid law's blend (quintic step, 3 values): the general branch unrolled.

        The same operations in the same order, on Python floats: the rates of the
        :func:`smooth_step` (0 for ``sigma`` <= 0), then Leibniz's rule with the binomial
        weights (1), (1, 1), (1, 2, 1), where a product by the weight 1 is exact.
        """
        T = self.duration
        if sigma <= 0.0:
            r0 = r1 = r2 = 0.0
        else:
            r0 = sigma**3 * (10.0 - 15.0 * sigma + 6.0 * sigma**2)
            r1 = 30.0 * sigma**2 * (1.0 - sigma) ** 2 / T  # [1/s]
            r2 = 60.0 * sigma * (1.0 - sigma) * (1.0 - 2.0 * sigma) / (T * T)  # [1/s²]
        b0, b1, b2 = self.base(t, nominal)
        n0, n1, n2 = nominal
        e0, e1, e2 = n0 - b0, n1 - b1, n2 - b2
        return (b0 + r0 * e0, b1 + r0 * e1 + r1 * e0, b2 + r0 * e2 + 2.0 * r1 * e1 + r2 * e0)


@functools.cache
def _binomial_rows(order: int) -> tuple[tuple[float, ...], ...]:
    r"""Rows 0 to ``order`` of Pascal's triangle: row k holds :math:`\binom{k}{i}`, i <= k."""
    return tuple(tuple(float(math.comb(k, i)) for i in range(k + 1)) for k in range(order + 1))
