r"""The simplest walking model (Garcia, Chatterjee, Ruina, Coleman 1998) and its stride map.

A hip of mass :math:`M`, two massless legs of length :math:`l` with point feet of mass
:math:`m`, on a slope :math:`\gamma`, in the limit :math:`\beta = m/M \to 0` (M. Garcia,
A. Chatterjee, A. Ruina, M. Coleman, *The simplest walking model: stability, complexity, and
scaling*, J. Biomech. Eng. 120(2), 1998). Time in units of :math:`\sqrt{l/g}`. With
:math:`\theta` the stance leg's angle from the slope normal and :math:`\phi` the angle from
the stance leg to the swing leg, the swing foot's height above the slope is
:math:`2 l \sin(\phi/2) \sin(\phi/2 - \theta)`, and

.. math::

    \ddot\theta = \sin(\theta - \gamma), \qquad
    \ddot\phi = \sin(\theta - \gamma) + \sin\phi\,\big(\dot\theta^2 - \cos(\theta - \gamma)\big).

The heel strike is the zero of :math:`\phi - 2\theta` crossed upwards with :math:`\theta < 0`
(the swing foot ahead, falling onto the slope); the other zero of the foot's height near
mid-stance (the swing foot passing the stance foot, a scuff) is ignored, as in the paper. The
strike is plastic, the legs swap, and in the limit :math:`\beta \to 0`

.. math::

    \theta^+ = -\theta^-, \quad \phi^+ = -2\theta^-, \quad
    \dot\theta^+ = \cos 2\theta^-\,\dot\theta^-, \quad
    \dot\phi^+ = \cos 2\theta^- (1 - \cos 2\theta^-)\,\dot\theta^-.

The section's chart is :math:`z = (\theta^+, \dot\theta^+)` (the strike fixes
:math:`\phi^+ = 2\theta^+`, :math:`\dot\phi^+ = (1 - \cos 2\theta^+)\dot\theta^+`), the
state :math:`q = (\theta, \phi)`, :math:`v = (\dot\theta, \dot\phi)`.
:meth:`SimplestWalker.stride` is usable by :func:`~ucontrol.analysis.gait.find_gait`;
:meth:`SimplestWalker.stride_jacobian` gives the stride map's Jacobian from the variational
equations and the saltation matrix of the strike, an independent reference for the central
differences that ``find_gait`` uses.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol._validation import as_in_interval, as_positive, as_vector
from ucontrol.exceptions import StrideError

Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]


@dataclass(frozen=True)
class WalkerStride:
    """One step of the simplest walker, from just after a heel strike to just after the next.

    Attributes:
        duration: Step period in units of sqrt(l/g).
        q: (θ, φ) just after the strike (legs swapped) in [rad], shape (2,).
        v: (θ̇, φ̇) just after the strike in [rad] per unit time, shape (2,).
        state_minus: (θ, φ, θ̇, φ̇) just before the strike, shape (4,).
        mid_stance: Time at which the stance leg passes the slope normal (θ = 0).
    """

    duration: float
    q: Vector
    v: Vector
    state_minus: Vector
    mid_stance: float


@dataclass(frozen=True, kw_only=True)
class SimplestWalker:
    """Garcia et al.'s simplest walker (β → 0) on a slope.

    Args:
        slope: γ in [rad], in [0, π/4].
        rtol: Relative tolerance of solve_ivp (DOP853).
        atol: Absolute tolerance of solve_ivp.
        max_duration: Longest step in units of sqrt(l/g): a walker whose stance leg has not
            passed the slope normal, or whose swing foot has not struck, by then is an error.

    Raises:
        InvalidParameterError: A parameter outside its range.
    """

    slope: float
    rtol: float = 1e-12
    atol: float = 1e-12
    max_duration: float = 20.0

    def __post_init__(self) -> None:
        """Validate the parameters."""
        object.__setattr__(self, "slope", as_in_interval("slope", self.slope, 0.0, math.pi / 4))
        for name in ("rtol", "atol", "max_duration"):
            object.__setattr__(self, name, as_positive(name, getattr(self, name)))

    def rate(self, x: Vector) -> Vector:
        """Time derivative of the state x = (θ, φ, θ̇, φ̇), shape (4,)."""
        theta, phi, dtheta, _ = x
        gravity = math.sin(theta - self.slope)
        swing = gravity + math.sin(phi) * (dtheta**2 - math.cos(theta - self.slope))
        return np.array([x[2], x[3], gravity, swing])

    def rate_jacobian(self, x: Vector) -> Matrix:
        """∂(rate)/∂x at x = (θ, φ, θ̇, φ̇), shape (4, 4)."""
        theta, phi, dtheta, _ = x
        c, s = math.cos(theta - self.slope), math.sin(theta - self.slope)
        A = np.zeros((4, 4))
        A[0, 2] = A[1, 3] = 1.0
        A[2, 0] = c
        A[3, 0] = c + math.sin(phi) * s
        A[3, 1] = math.cos(phi) * (dtheta**2 - c)
        A[3, 2] = 2.0 * dtheta * math.sin(phi)
        return A

    @staticmethod
    def heel_strike(x_minus: Vector) -> Vector:
        """The state (θ, φ, θ̇, φ̇) just after the strike (legs swapped), shape (4,)."""
        theta, _, dtheta, _ = x_minus
        c = math.cos(2.0 * theta)
        return np.array([-theta, -2.0 * theta, c * dtheta, c * (1.0 - c) * dtheta])

    @staticmethod
    def heel_strike_jacobian(x_minus: Vector) -> Matrix:
        """∂(heel_strike)/∂x⁻, shape (4, 4)."""
        theta, _, dtheta, _ = x_minus
        c, s = math.cos(2.0 * theta), math.sin(2.0 * theta)
        D = np.zeros((4, 4))
        D[0, 0], D[1, 0] = -1.0, -2.0
        D[2, 0], D[2, 2] = -2.0 * s * dtheta, c
        D[3, 0], D[3, 2] = 2.0 * s * (2.0 * c - 1.0) * dtheta, c * (1.0 - c)
        return D

    @staticmethod
    def to_state(z: Vector) -> tuple[Vector, Vector]:
        """The post-strike state of the chart z = (θ⁺, θ̇⁺).

        Returns:
            q = (θ, 2θ) and v = (θ̇, (1 - cos 2θ) θ̇), each of shape (2,).
        """
        theta, dtheta = as_vector("z", z, 2)
        return (
            np.array([theta, 2.0 * theta]),
            np.array([dtheta, (1.0 - math.cos(2.0 * theta)) * dtheta]),
        )

    @staticmethod
    def from_state(q: Vector, v: Vector) -> Vector:
        """The chart z = (θ, θ̇) of a post-strike state, shape (2,)."""
        return np.array([q[0], v[0]])

    def stride(self, q: Vector, v: Vector) -> WalkerStride:
        """One step: stance and swing to the next heel strike, then the strike.

        Args:
            q: (θ, φ) in [rad], shape (2,), the stance leg ahead of the slope normal (θ > 0).
            v: (θ̇, φ̇), shape (2,).

        Raises:
            StrideError: The stance leg does not pass the slope normal (the walker falls
                back), the hip reaches the slope, or no heel strike within ``max_duration``.
        """
        x0 = np.concatenate((as_vector("q", q, 2), as_vector("v", v, 2)))
        mid, x_mid = self._flow_to(x0, 0.0, _passes_normal, "the stance leg passes the normal")
        end, x_minus = self._flow_to(x_mid, mid, _foot_lands, "the swing foot strikes")
        x_plus = self.heel_strike(x_minus)
        return WalkerStride(end, x_plus[:2], x_plus[2:], x_minus, mid)

    def _flow_to(
        self, x0: Vector, t0: float, event: Callable[[float, Vector], float], what: str
    ) -> tuple[float, Vector]:
        """Integrate from (t0, x0) to the first zero of ``event``; the hip on the slope fails."""
        solution = solve_ivp(
            lambda _, x: self.rate(x),
            (t0, self.max_duration),
            x0,
            method="DOP853",
            rtol=self.rtol,
            atol=self.atol,
            events=[event, _hip_down],
        )
        if solution.status == -1:
            raise StrideError(float(solution.t[-1]), f"solve_ivp failed: {solution.message}")
        if len(solution.t_events[1]):
            raise StrideError(float(solution.t_events[1][0]), "the hip reached the slope")
        if not len(solution.t_events[0]):
            raise StrideError(self.max_duration, f"no time at which {what}")
        return float(solution.t_events[0][0]), solution.y_events[0][0]

    def stride_jacobian(self, z: Vector) -> Matrix:
        r"""Jacobian of the stride map in the chart z = (θ⁺, θ̇⁺), shape (2, 2).

        From the variational equations :math:`\dot\Phi = A(x)\Phi` along the step and the
        saltation matrix of the strike's switching surface :math:`g = \phi - 2\theta`:
        :math:`DP = C\,DR\,\big(I - f g_x / (g_x f)\big)\,\Phi\,E`, with :math:`E` the chart's
        embedding, :math:`R` the strike and :math:`C` the chart of its image. (The mid-stance
        section θ = 0 is crossed transversally and needs no correction.)
        """
        q, v = self.to_state(z)
        step = self.stride(q, v)
        x0 = np.concatenate((q, v))

        def rate(_: float, y: Vector) -> Vector:
            x, Phi = y[:4], y[4:].reshape(4, 4)
            return np.concatenate((self.rate(x), (self.rate_jacobian(x) @ Phi).ravel()))

        y0 = np.concatenate((x0, np.eye(4).ravel()))
        solution = solve_ivp(
            rate, (0.0, step.duration), y0, method="DOP853", rtol=self.rtol, atol=self.atol
        )
        Phi = solution.y[4:, -1].reshape(4, 4)
        x_minus = step.state_minus
        f = self.rate(x_minus)
        g_x = np.array([-2.0, 1.0, 0.0, 0.0])
        saltation = np.eye(4) - np.outer(f, g_x) / (g_x @ f)
        theta, dtheta = float(z[0]), float(z[1])
        E = np.array(
            [
                [1.0, 0.0],
                [2.0, 0.0],
                [0.0, 1.0],
                [2.0 * math.sin(2.0 * theta) * dtheta, 1.0 - math.cos(2.0 * theta)],
            ]
        )
        C = np.zeros((2, 4))
        C[0, 0] = C[1, 2] = 1.0
        return C @ self.heel_strike_jacobian(x_minus) @ saltation @ Phi @ E


def _passes_normal(_: float, x: Vector) -> float:
    """θ = 0 crossed downwards: the stance leg passes the slope normal (mid-stance)."""
    return float(x[0])


def _foot_lands(_: float, x: Vector) -> float:
    """φ - 2θ = 0 crossed upwards (after mid-stance): the swing foot strikes the slope."""
    return float(x[1] - 2.0 * x[0])


def _hip_down(_: float, x: Vector) -> float:
    """The stance leg lies on the slope (a fall): cos θ = 0 crossed downwards."""
    return math.cos(x[0])


for _event, _direction in ((_passes_normal, -1.0), (_foot_lands, 1.0), (_hip_down, -1.0)):
    _event.terminal, _event.direction = True, _direction  # type: ignore[attr-defined]
