r"""Prescribed motions of surfaces: the translation :math:`x(t)` of a moving plane.

A plane through :math:`p_0` with normal :math:`n` carried by the motion :math:`x(t)` passes
through :math:`p_0 + x(t)` at time t: a point contact's gap becomes the time-dependent
:math:`g(q, t) = n \cdot (p_F(q) - p_0 - x(t)) - r`, with :math:`\partial g / \partial t =
-n \cdot \dot x(t)`, and its normal velocity the relative one,
:math:`u_n = n \cdot (v_F - \dot x(t))` (docs/environments.md). A motion gives the
displacement, velocity and acceleration at t; each is checked finite when evaluated.
:class:`MotionSum` adds motions (a ramp plus a sinusoid): displacements, velocities and
accelerations add, as the superposed translations do.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_vector
from ucontrol.exceptions import InvalidParameterError, NonFiniteValueError

Vector = NDArray[np.float64]


class SurfaceMotion(Protocol):
    """A prescribed translation of a surface."""

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Displacement [m], velocity [m/s] and acceleration [m/s²] at t [s], each (3,)."""
        ...


@dataclass(frozen=True, kw_only=True)
class Sinusoid:
    r""":math:`x(t) = a \sin(\omega t + \varphi)`.

    Attributes:
        amplitude: Amplitude a in [m], shape (3,).
        frequency: Angular frequency ω in [rad/s], >= 0.
        phase: Phase φ in [rad].
    """

    amplitude: Vector
    frequency: float
    phase: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", as_vector("amplitude", self.amplitude, 3))
        frequency = as_float("frequency", self.frequency)
        if frequency < 0.0:
            raise InvalidParameterError("frequency", self.frequency, ">= 0 [rad/s]")
        object.__setattr__(self, "frequency", frequency)
        object.__setattr__(self, "phase", as_float("phase", self.phase))

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Displacement [m], velocity [m/s] and acceleration [m/s²] at t [s], each (3,)."""
        omega, angle = self.frequency, self.frequency * t + self.phase
        sine, cosine = np.sin(angle), np.cos(angle)
        a = self.amplitude
        return a * sine, (omega * cosine) * a, (-omega * omega * sine) * a


@dataclass(frozen=True, kw_only=True)
class Polynomial:
    r""":math:`x(t) = \sum_i c_i t^i`.

    Attributes:
        coefficients: :math:`c_0, c_1, \dots` in [m], [m/s], ..., shape (k, 3), k >= 1.
    """

    coefficients: Vector = field(default_factory=lambda: np.zeros((1, 3)))

    def __post_init__(self) -> None:
        c = np.asarray(self.coefficients, dtype=float)
        if c.ndim != 2 or c.shape[1] != 3 or c.shape[0] < 1:
            raise InvalidParameterError(
                "coefficients", self.coefficients, "a list of k >= 1 vectors of 3 components"
            )
        if not np.all(np.isfinite(c)):
            raise NonFiniteValueError(
                "coefficients", self.coefficients, np.flatnonzero(~np.isfinite(c)).tolist()
            )
        object.__setattr__(self, "coefficients", c)

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Displacement [m], velocity [m/s] and acceleration [m/s²] at t [s], each (3,)."""
        c = self.coefficients
        k = np.arange(c.shape[0])
        powers = np.array([t**i for i in range(c.shape[0])])
        x = powers @ c
        v = (k[1:] * powers[:-1]) @ c[1:] if k.size > 1 else np.zeros(3)
        a = (k[2:] * (k[2:] - 1) * powers[:-2]) @ c[2:] if k.size > 2 else np.zeros(3)
        return x, v, a


@dataclass(frozen=True)
class UserMotion:
    """A motion given by a function of t returning displacement, velocity and acceleration.

    Attributes:
        function: ``function(t) -> (x, v, a)``, each of 3 components, in [m], [m/s], [m/s²].
            Its velocity must be the derivative of its displacement (checked where the motion
            is built with :meth:`check`).
    """

    function: Callable[[float], tuple[Vector, Vector, Vector]]

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Displacement [m], velocity [m/s] and acceleration [m/s²] at t [s], each (3,).

        Raises:
            InvalidParameterError: The function does not return three 3-vectors.
            NonFiniteValueError: One of them is not finite.
        """
        values = self.function(t)
        if not isinstance(values, tuple) or len(values) != 3:
            raise InvalidParameterError(
                "surface motion", values, f"(displacement, velocity, acceleration) at t = {t}"
            )
        names = ("displacement", "velocity", "acceleration")
        x, v, a = (as_vector(f"{name} at t = {t}", value, 3) for name, value in zip(names, values))
        return x, v, a


@dataclass(frozen=True)
class MotionSum:
    r""":math:`x(t) = \sum_k x_k(t)`: the sum of several motions (a ramp and a sinusoid).

    Attributes:
        terms: The motions added, at least one.
    """

    terms: tuple[SurfaceMotion, ...]

    def __post_init__(self) -> None:
        terms = tuple(self.terms)
        if not terms:
            raise InvalidParameterError("terms", list(terms), "at least one motion")
        object.__setattr__(self, "terms", terms)

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Displacement [m], velocity [m/s] and acceleration [m/s²] at t [s], each (3,)."""
        x, v, a = np.zeros(3), np.zeros(3), np.zeros(3)
        for term in self.terms:
            x_k, v_k, a_k = term(t)
            x, v, a = x + x_k, v + v_k, a + a_k
        return x, v, a


def check_motion(motion: SurfaceMotion, times: Vector, tolerance: float = 1e-5) -> None:
    """Check that ``motion`` is finite and its velocity and acceleration are its derivatives.

    Central differences with step 1e-6 s at each of ``times`` [s]; the relative disagreement
    must be at most ``tolerance``.

    Raises:
        NonFiniteValueError: A value is not finite.
        InvalidParameterError: The velocity (or acceleration) is not the derivative of the
            displacement (or velocity) at some time: the motion is not differentiable there or
            its derivatives are wrong.
    """
    step = 1e-6  # [s]
    for t in np.asarray(times, dtype=float):
        _, v, a = motion(float(t))
        x_plus, v_plus, _ = motion(float(t) + step)
        x_minus, v_minus, _ = motion(float(t) - step)
        for name, value, derivative in (
            ("velocity", v, (x_plus - x_minus) / (2 * step)),
            ("acceleration", a, (v_plus - v_minus) / (2 * step)),
        ):
            scale = 1.0 + float(np.max(np.abs(value)))
            error = float(np.max(np.abs(value - derivative))) / scale
            if error > tolerance:
                raise InvalidParameterError(
                    f"surface motion {name} at t = {t:g} s",
                    value.tolist(),
                    f"the derivative {derivative.tolist()} (finite differences, relative "
                    f"error {error:.2e} > {tolerance:g})",
                )
