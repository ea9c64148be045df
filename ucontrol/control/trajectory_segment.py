r"""Pieces of a one-coordinate desired trajectory, glued by the phase machine.

Each segment maps a time ``t`` [s] and the nominal value of its coordinate at ``t``
(position, velocity, acceleration) to the desired (position, velocity, acceleration) of that
coordinate. Positions are in [m], velocities in [m/s], accelerations in [m/s²]. A segment
started at ``t0`` from the value and velocity of the previous one keeps the desired
trajectory :math:`C^1`, so the Lyapunov function built on it does not jump.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

#: (position, velocity, acceleration) of one coordinate.
Sample = tuple[float, float, float]


def smooth_step(sigma: float) -> tuple[float, float, float]:
    r"""Quintic smooth step :math:`\beta(\sigma) = 10\sigma^3 - 15\sigma^4 + 6\sigma^5` on [0, 1].

    :math:`\beta = \beta' = \beta'' = 0` at 0 and :math:`\beta = 1`, :math:`\beta' =
    \beta'' = 0` at 1; constant outside [0, 1].

    Returns:
        :math:`(\beta, \beta', \beta'')` at ``sigma``.
    """
    if sigma <= 0.0:
        return 0.0, 0.0, 0.0
    if sigma >= 1.0:
        return 1.0, 0.0, 0.0
    return (
        sigma**3 * (10.0 - 15.0 * sigma + 6.0 * sigma**2),
        30.0 * sigma**2 * (1.0 - sigma) ** 2,
        60.0 * sigma * (1.0 - sigma) * (1.0 - 2.0 * sigma),
    )


class TrajectorySegment(Protocol):
    """A desired trajectory of one task coordinate."""

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Desired (position, velocity, acceleration) at time ``t`` [s]."""
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
        """``(value, 0, 0)``."""
        return self.value, 0.0, 0.0


@dataclass(frozen=True)
class RestCubic:
    r"""Hermite cubic from a value and a velocity to a value at rest, then that value.

    From :math:`(p_0, v_0)` at :math:`t_0` to :math:`(p_1, 0)` at :math:`t_0 + T`.

    With :math:`p_1 = p_0 + v_0 T / 2` it is the constant-deceleration stop of a coordinate
    that is frozen; with :math:`p_1 = -d` it is the approach to a virtual target below a surface.

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

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Hermite cubic sample at ``t``; ``(p1, 0, 0)`` once it has ended."""
        T = self.duration
        sigma = (t - self.t0) / T
        if sigma >= 1.0:
            return self.p1, 0.0, 0.0
        sigma = max(sigma, 0.0)
        s2, s3 = sigma * sigma, sigma * sigma * sigma
        p0, v0, p1 = self.p0, self.v0, self.p1
        position = (
            (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + sigma) * T * v0 + (3 * s2 - 2 * s3) * p1
        )
        velocity = (6 * s2 - 6 * sigma) * (p0 - p1) / T + (3 * s2 - 4 * sigma + 1) * v0
        acceleration = (12 * sigma - 6) * (p0 - p1) / T**2 + (6 * sigma - 4) * v0 / T
        return position, velocity, acceleration


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
        return 0.5 * a * tau * tau, a * tau, a


@dataclass(frozen=True)
class BlendToNominal:
    r"""Moves smoothly from ``base`` to the nominal path over ``duration``.

    :math:`x = b + \beta(\sigma)(n - b)`, :math:`\sigma = (t - t_0)/T`, with the quintic
    :func:`smooth_step` :math:`\beta`: the result starts as ``base`` to second order and ends
    on the nominal path to second order.

    Attributes:
        base: The segment left.
        t0: Start time in [s].
        duration: T in [s], > 0.
    """

    base: TrajectorySegment
    t0: float
    duration: float

    def __call__(self, t: float, nominal: Sample) -> Sample:
        """Blended sample at ``t``; the nominal sample once the blend has ended."""
        T = self.duration
        sigma = (t - self.t0) / T
        if sigma >= 1.0:
            return nominal
        beta, d_beta, dd_beta = smooth_step(sigma)
        d_beta /= T  # [1/s]
        dd_beta /= T * T  # [1/s²]
        b, db, ddb = self.base(t, nominal)
        n, dn, ddn = nominal
        return (
            b + beta * (n - b),
            db + beta * (dn - db) + d_beta * (n - b),
            ddb + beta * (ddn - ddb) + 2.0 * d_beta * (dn - db) + dd_beta * (n - b),
        )
