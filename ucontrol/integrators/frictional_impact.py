r"""One impact with Coulomb friction in 3D: Darboux–Keller shock dynamics (Brogliato 2016, §4.3).

During an impact at one point contact the configuration is frozen and the contact velocity
:math:`u = (u_n, u_{t1}, u_{t2}) = H v` (normal first, then an orthonormal tangent basis)
evolves with the impulse :math:`P = (P_n, P_t)` as :math:`du = W\,dP`,
:math:`W = H M^{-1} H^T` (3×3). Taking the normal impulse :math:`p = P_n` as the independent
variable (Keller 1986), Coulomb's law at the contact gives

.. math::

    \frac{du}{dp} = W \begin{pmatrix} 1 \\ \varphi \end{pmatrix}, \qquad
    \varphi = \frac{dP_t}{dp} =
    \begin{cases}
      -\mu\, u_t / \lVert u_t \rVert & \text{slip} \ (u_t \ne 0), \\
      -W_{tt}^{+} W_{tn} & \text{stick, while } \lVert W_{tt}^{+} W_{tn} \rVert \le \mu .
    \end{cases}

The coefficients are constant, so once a contact sticks it sticks to the end of the impact. When
the slip velocity reaches zero and sticking would need more than :math:`\mu`, the contact slips
again in the direction :math:`\sigma` (unit) with :math:`W_{tn} - \mu W_{tt}\sigma = k\sigma`,
:math:`k > 0` (the slip velocity grows along :math:`\sigma`): a *slip reversal* in the plane, a
change of slip direction in 3D; the same rule starts slip from a tangential rest. In 3D the slip
direction also turns continuously while slipping. The compression ends at the first
:math:`u_n = 0` (normal impulse :math:`p_c`, work of the normal force
:math:`W_c = -\int_0^{p_c} u_n\,dp`), and the restitution ends, by the law:

- ``"newton"`` (kinematic): at :math:`u_n = -e\,u_n^-`;
- ``"poisson"`` (kinetic): at :math:`p = (1 + e)\,p_c`;
- ``"energetic"`` (Stronge): when the normal force has given back
  :math:`\int_{p_c} u_n\,dp = e^2 W_c`.

Without friction the three laws give the same impulse. With friction only the energetic law is
dissipative in every case; see docs/impact_laws.md. Each phase between transitions is integrated
by :func:`scipy.integrate.solve_ivp` (DOP853) with terminal events at the end of compression,
the end of restitution and the vanishing of the slip velocity.

:func:`brach_impact` is Newton's law with Brach's tangential (kinematic) restitution instead of
the Darboux–Keller integration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_vector
from ucontrol.exceptions import InvalidParameterError, ShapeError, SolverError
from ucontrol.integrators.methods import RESTITUTION_LAWS

Vector = NDArray[np.float64]

#: Restitution laws of one frictional impact (how the restitution phase ends).
FRICTIONAL_IMPACT_LAWS = RESTITUTION_LAWS

#: Slip speed, relative to the pre-impact speed, at which slip counts as stopped.
_SLIP_ZERO = 1e-13
#: Slip speed, relative to the pre-impact speed, below which a slip whose velocity crossed the
#: normal to its former direction counts as stopped (above it the slip has only turned by 90°).
_SLIP_TURN = 1e-8
#: Phases (stick/slip transitions, compression end, turns of 90° of slip) allowed.
_MAX_PHASES = 1000
#: Largest scaled normal impulse of a phase (the impact's is about 1 + e).
_HORIZON = 1e6
#: Samples of the unit circle searched for the directions of slip from rest.
_DIRECTION_SAMPLES = 720


@dataclass(frozen=True)
class FrictionalImpactResult:
    """Outcome of one impact with friction at one contact.

    Attributes:
        impulse: Impulse (P_n, P_t1, P_t2) in [N s], shape (3,).
        u: Post-impact contact velocity (u_n, u_t1, u_t2) in [m/s], shape (3,).
        compression_impulse: Normal impulse p_c at the end of compression in [N s].
        compression_work: Work W_c absorbed by the normal force in compression in [J].
        restitution_work: Work given back by the normal force in restitution in [J].
        kinetic_change: Kinetic energy after minus before in [J], ``u-·P + ½ Pᵀ W P``.
        transitions: The events of the impact in order, each (name, normal impulse [N s]) with
            name ``"slip"`` (slip starts from rest), ``"stick"``, ``"reversal"`` (slip stops and
            resumes in another direction), ``"compression_end"`` or ``"end"``.
    """

    impulse: Vector
    u: Vector
    compression_impulse: float
    compression_work: float
    restitution_work: float
    kinetic_change: float
    transitions: tuple[tuple[str, float], ...]

    def names(self) -> tuple[str, ...]:
        """The names of :attr:`transitions`, in order."""
        return tuple(name for name, _ in self.transitions)


def check_restitution(law: str, restitution: Any) -> float:
    """``restitution`` as a coefficient in [0, 1] of ``law``.

    Raises:
        InvalidParameterError: An unknown law, or a coefficient outside [0, 1] (named with
            its law: ``energetic restitution``, ...).
    """
    if law not in FRICTIONAL_IMPACT_LAWS:
        raise InvalidParameterError("law", law, f"one of {FRICTIONAL_IMPACT_LAWS}")
    e = as_float(f"{law} restitution", restitution)
    if not 0.0 <= e <= 1.0:
        raise InvalidParameterError(f"{law} restitution", e, "in [0, 1]")
    return e


def _checked_friction(friction: Any) -> float:
    mu = as_float("friction", friction)
    if not mu >= 0.0:
        raise InvalidParameterError("friction", mu, ">= 0")
    return mu


def _no_impact(u_minus: Vector) -> FrictionalImpactResult:
    """A separating contact: no impulse."""
    zero = np.zeros(3)
    return FrictionalImpactResult(zero, u_minus.copy(), 0.0, 0.0, 0.0, 0.0, (("end", 0.0),))


def _checked_block(W: Any, u_minus: Any) -> tuple[Vector, Vector]:
    W = np.asarray(W, dtype=float)
    if W.shape != (3, 3):
        raise ShapeError("W", (3, 3), W.shape)
    if (
        not np.all(np.isfinite(W))
        or not W[0, 0] > 0.0
        or not np.allclose(W, W.T, rtol=1e-10, atol=1e-14 * np.abs(W).max())
        or np.linalg.eigvalsh(W).min() < -1e-12 * np.abs(W).max()
    ):
        raise InvalidParameterError(
            "W", W.tolist(), "a symmetric positive semidefinite matrix with W[0, 0] > 0"
        )
    return W, as_vector("u_minus", u_minus, 3)


def frictional_impact(
    W: Any,
    u_minus: Any,
    *,
    friction: float,
    restitution: float,
    law: str = "energetic",
    rtol: float = 1e-13,
    tangential_restitution: float | None = None,
) -> FrictionalImpactResult:
    """Impulse and post-impact velocity of one frictional impact (Darboux–Keller).

    With ``tangential_restitution`` (Newton's law only) the impact is Brach's instead,
    :func:`brach_impact` with ``friction`` bounding the impulse ratio.

    Args:
        W: Delassus block ``H M⁻¹ Hᵀ`` of the contact in [1/kg], shape (3, 3), rows normal,
            tangent 1, tangent 2 (a planar system has zero tangent-2 row and column).
        u_minus: Pre-impact contact velocity (u_n, u_t1, u_t2) in [m/s], shape (3,); u_n < 0
            approaching (otherwise there is no impact and the impulse is zero).
        friction: Coulomb coefficient μ >= 0.
        restitution: Coefficient e in [0, 1] of ``law``.
        law: ``"newton"``, ``"poisson"`` or ``"energetic"``.
        rtol: Relative tolerance of solve_ivp (absolute: ``rtol`` times 1e-2, scaled units).
        tangential_restitution: Brach's e_t in [-1, 1] as an option of Newton's law, or None.

    Raises:
        InvalidParameterError: An unknown law, e outside [0, 1], μ < 0, a bad W, or a
            tangential restitution with another law than Newton's.
        ShapeError: W or u_minus of the wrong shape.
        SolverError: The restitution never ends (a Newton target the velocity never reaches)
            or the integration failed.
    """
    e = check_restitution(law, restitution)
    if tangential_restitution is not None:
        if law != "newton":
            raise InvalidParameterError(
                "tangential_restitution", tangential_restitution, f"None with the {law} law"
            )
        return brach_impact(
            W,
            u_minus,
            restitution=e,
            tangential_restitution=tangential_restitution,
            friction=friction,
        )
    mu = _checked_friction(friction)
    W, u_minus = _checked_block(W, u_minus)
    if u_minus[0] >= 0.0:
        return _no_impact(u_minus)
    speed = float(np.linalg.norm(u_minus))  # [m/s]
    impulse_unit = speed / W[0, 0]  # [N s]
    state = _Shock(W / W[0, 0], mu)
    y, transitions, p_c, W_c = state.run(u_minus / speed, law, e, rtol, impulse_unit)
    P = np.array([y[4], y[5], y[6]]) * impulse_unit  # [N s]
    u_plus = u_minus + W @ P
    energy_unit = speed * impulse_unit  # [J]
    return FrictionalImpactResult(
        P,
        u_plus,
        p_c * impulse_unit,
        W_c * energy_unit,
        (y[3] + W_c) * energy_unit,
        float(u_minus @ P + 0.5 * P @ W @ P),
        tuple((name, p * impulse_unit) for name, p in transitions),
    )


def frictional_impact_velocity(
    M: Any, H: Any, v_minus: Any, **law: Any
) -> tuple[Vector, FrictionalImpactResult]:
    """Post-impact generalized velocity ``v- + M⁻¹ Hᵀ P`` of :func:`frictional_impact`.

    Args:
        M: Inertia matrix, shape (n, n), symmetric positive definite.
        H: Contact Jacobian, rows normal, tangent 1, tangent 2, shape (3, n).
        v_minus: Pre-impact velocity, shape (n,).
        **law: ``friction``, ``restitution``, ``law``, ``rtol`` of :func:`frictional_impact`.

    Returns:
        v_plus (shape (n,)) and the impact's result.
    """
    M = np.asarray(M, dtype=float)
    H = np.asarray(H, dtype=float)
    n = M.shape[0]
    if M.shape != (n, n):
        raise ShapeError("M", (n, n), M.shape)
    if H.shape != (3, n):
        raise ShapeError("H", (3, n), H.shape)
    v_minus = as_vector("v_minus", v_minus, n)
    Minv_Ht = np.linalg.solve(M, H.T)
    result = frictional_impact(H @ Minv_Ht, H @ v_minus, **law)
    return v_minus + Minv_Ht @ result.impulse, result


def stick_force(W_tt: Vector, W_tn: Vector) -> Vector:
    """Tangential impulse rate keeping the slip velocity at zero, ``-W_tt⁺ W_tn``.

    Args:
        W_tt: Tangent block of the Delassus matrix, shape (k, k) (possibly singular).
        W_tn: Its normal column, shape (k,) or (k, j).
    """
    return np.asarray(-np.linalg.lstsq(W_tt, W_tn, rcond=1e-12)[0], dtype=float)


def slip_direction(W: Vector, mu: float) -> Vector:
    r"""Direction of slip from rest: unit σ with :math:`W_{tn} - \mu W_{tt}\sigma = k\sigma`.

    In polar form :math:`u_t = \rho(\cos\theta, \sin\theta)` the slip turns as
    :math:`d\theta/dp = c(\theta)/\rho`, :math:`c = \sigma \times (W_{tn} - \mu W_{tt}\sigma)`:
    leaving rest along a direction with :math:`c'(\theta) > 0` is unstable (any perturbation
    turns the slip away as :math:`\rho` grows), so among the directions with k > 0 the stable
    ones (:math:`c' < 0`) are preferred, and among those the fastest-growing one is taken.

    Args:
        W: Delassus block (scaled or not), shape (3, 3).
        mu: Coulomb coefficient, > 0.

    Raises:
        SolverError: No direction has k > 0 (sticking is then possible).
    """
    from scipy.optimize import brentq

    a, B = W[1:, 0], W[1:, 1:]

    def terms(theta: float) -> tuple[Vector, Vector]:
        sigma = np.array([math.cos(theta), math.sin(theta)])
        return sigma, a - mu * B @ sigma

    def cross(theta: float) -> float:
        sigma, w = terms(theta)
        return float(sigma[0] * w[1] - sigma[1] * w[0])

    grid = np.linspace(0.0, 2.0 * math.pi, _DIRECTION_SAMPLES + 1)
    sigmas = np.stack((np.cos(grid), np.sin(grid)))  # shape (2, samples)
    rates = a[:, None] - mu * B @ sigmas
    values = sigmas[0] * rates[1] - sigmas[1] * rates[0]
    roots = list(grid[:-1][values[:-1] == 0.0])
    for k in np.flatnonzero(values[:-1] * values[1:] < 0.0):
        roots.append(brentq(cross, grid[k], grid[k + 1], xtol=1e-15))
    step = 1e-7  # [rad], for the slope of the turning rate
    candidates = []
    for theta in roots:
        sigma, w = terms(theta)
        if float(sigma @ w) > 0.0:
            stable = cross(theta + step) - cross(theta - step) < 0.0
            candidates.append((stable, float(sigma @ w), sigma))
    if not candidates:
        raise SolverError("frictional_impact", "no direction of slip from rest")
    return max(candidates, key=lambda candidate: candidate[:2])[2]


def terminal_event(function: Any, direction: float) -> Any:
    """``function(t, y)`` marked as a terminal solve_ivp event crossing in ``direction``."""
    function.terminal = True
    function.direction = direction
    return function


class _Shock:
    """The Darboux–Keller system in scaled units (velocity by |u-|, W by W_nn)."""

    def __init__(self, W: Vector, mu: float) -> None:
        self.W = W
        self.mu = mu
        self.stick_rate = stick_force(W[1:, 1:], W[1:, 0])
        self.can_stick = bool(np.linalg.norm(self.stick_rate) <= mu * (1.0 + 1e-12))

    def rate(self, y: Vector, mode: str, sigma: Vector) -> Vector:
        """d/dp of y = (u_n, u_t1, u_t2, normal work, P_n, P_t1, P_t2)."""
        if mode == "stick":
            phi = self.stick_rate
        elif mode == "free":
            phi = np.zeros(2)
        elif mode == "ray":  # slip from rest along an invariant direction: exactly straight
            phi = -self.mu * sigma
        else:
            slip = y[1:3]
            norm = math.hypot(slip[0], slip[1])
            phi = -self.mu * (slip / norm if norm > 0.0 else sigma)
        du = self.W[:, 0] + self.W[:, 1:] @ phi
        if mode == "stick":
            du[1:] = 0.0
        return np.concatenate((du, [y[0], 1.0], phi))

    def mode_at_rest(self) -> tuple[str, Vector]:
        """Stick, or slip along a ray from rest, when the slip velocity is zero.

        Along an invariant direction σ the slip velocity grows as kσ per unit normal impulse
        to the end of the impact (the rate depends on the direction only), so the phase is
        integrated with σ fixed: near rest the turning rate of the slip, of order 1/|u_t|,
        would make the integration of the free direction unstable.
        """
        if self.mu == 0.0:
            return "free", np.zeros(2)
        if self.can_stick:
            return "stick", np.zeros(2)
        return "ray", slip_direction(self.W, self.mu)

    def run(
        self, u_minus: Vector, law: str, e: float, rtol: float, impulse_unit: float
    ) -> tuple[Vector, list[tuple[str, float]], float, float]:
        """Integrate compression and restitution; (y, transitions, p_c, W_c), scaled."""
        from scipy.integrate import solve_ivp

        y = np.concatenate((u_minus, np.zeros(4)))
        transitions: list[tuple[str, float]] = []
        if self.mu == 0.0:
            mode, sigma = "free", np.zeros(2)
        elif math.hypot(u_minus[1], u_minus[2]) <= _SLIP_ZERO:
            y[1:3] = 0.0
            mode, sigma = self.mode_at_rest()
            transitions.append(("stick" if mode == "stick" else "slip", 0.0))
        else:
            mode, sigma = "slip", u_minus[1:] / math.hypot(u_minus[1], u_minus[2])
        compressing = True
        p_c = W_c = math.nan
        p = 0.0
        horizon = _HORIZON
        for _ in range(_MAX_PHASES):
            events, kinds = [], []
            if compressing:
                events.append(terminal_event(lambda p, y: y[0], 1.0))
                kinds.append("compression_end")
            elif law == "newton":
                events.append(terminal_event(lambda p, y: y[0] + e * u_minus[0], 1.0))
                kinds.append("end")
            elif law == "energetic":  # the normal work has come back to -(1 - e²) W_c
                events.append(terminal_event(lambda p, y: y[3] + (1.0 - e * e) * W_c, 1.0))
                kinds.append("end")
            if mode == "slip":  # the slip along its direction at the start of the phase
                slip = y[1:3] / max(math.hypot(y[1], y[2]), 1e-300) if y[1:3].any() else sigma
                events.append(terminal_event(lambda p, y, slip=slip: y[1:3] @ slip, -1.0))
                kinds.append("slip_turn")
                events.append(
                    terminal_event(lambda p, y: math.hypot(y[1], y[2]) - _SLIP_ZERO, -1.0)
                )
                kinds.append("slip_stop")
            bounded = law == "poisson" and not compressing
            end = (1.0 + e) * p_c if bounded else p + horizon
            solution = solve_ivp(
                lambda p, y, mode=mode, sigma=sigma: self.rate(y, mode, sigma),
                (p, end),
                y,
                method="DOP853",
                rtol=rtol,
                atol=rtol * 1e-2,
                events=events,
            )
            if solution.status < 0 or (solution.status == 0 and not bounded):
                raise SolverError(
                    "frictional_impact",
                    f"the {law} impact (e = {e:g}) did not end by the normal impulse "
                    f"{end * impulse_unit:g} N s: {solution.message}",
                )
            if solution.status == 0:
                y, p = solution.y[:, -1], end
                transitions.append(("end", p))
                return y, transitions, p_c, W_c
            fired = min(
                (times[0], k) for k, times in enumerate(solution.t_events) if times.size > 0
            )
            p, y = fired[0], solution.y_events[fired[1]][0].copy()
            kind = kinds[fired[1]]
            if kind == "compression_end":
                y[0] = 0.0
                compressing, p_c, W_c = False, p, -y[3]
                transitions.append(("compression_end", p))
                if e == 0.0:
                    transitions.append(("end", p))
                    return y, transitions, p_c, W_c
            elif kind == "end":
                transitions.append(("end", p))
                return y, transitions, p_c, W_c
            elif kind == "slip_turn" and math.hypot(y[1], y[2]) > _SLIP_TURN:
                continue  # turned by 90° while slipping: a new phase from the new direction
            else:  # the slip stopped
                y[1:3] = 0.0
                mode, sigma = self.mode_at_rest()
                transitions.append(("stick" if mode == "stick" else "reversal", p))
        raise SolverError("frictional_impact", f"more than {_MAX_PHASES} stick/slip phases")


def brach_impact(
    W: Any,
    u_minus: Any,
    *,
    restitution: float,
    tangential_restitution: float,
    friction: float | None = None,
) -> FrictionalImpactResult:
    r"""Newton's law with Brach's tangential restitution (Brogliato 2016, §4.3.2).

    The post-impact velocity is prescribed, :math:`u_n^+ = -e\,u_n^-` and
    :math:`u_t^+ = -e_t\,u_t^-` (:math:`e_t \in [-1, 1]`: -1 keeps the slip, 0 stops it, 1
    reverses it, a "superball"), so :math:`P = W^{+}(u^+ - u^-)`. With a friction coefficient,
    an impulse outside the cone :math:`\lVert P_t \rVert \le \mu P_n` is replaced by sliding in
    the pre-impact slip direction, :math:`P_t = -\mu P_n u_t^-/\lVert u_t^-\rVert` with
    :math:`u_n^+ = -e u_n^-` (Brach's limiting impulse ratio). Nothing bounds the energy: for
    :math:`e_t > 0` the tangential rebound may return more energy than the impact took (see
    docs/impact_laws.md).

    Args:
        W: Delassus block of the contact in [1/kg], shape (3, 3).
        u_minus: Pre-impact contact velocity in [m/s], shape (3,).
        restitution: Newton's coefficient e in [0, 1].
        tangential_restitution: Brach's e_t in [-1, 1].
        friction: Coulomb coefficient bounding the impulse ratio, or None (unbounded).

    Raises:
        InvalidParameterError: e, e_t or μ out of range, a bad W, or a tangential velocity
            W cannot reach (a singular block with an inconsistent target).
    """
    e = check_restitution("newton", restitution)
    e_t = as_float("tangential_restitution", tangential_restitution)
    if not -1.0 <= e_t <= 1.0:
        raise InvalidParameterError("tangential_restitution", e_t, "in [-1, 1]")
    W, u_minus = _checked_block(W, u_minus)
    if u_minus[0] >= 0.0:
        return _no_impact(u_minus)
    target = np.concatenate(([-e * u_minus[0]], -e_t * u_minus[1:]))
    P = np.linalg.lstsq(W, target - u_minus, rcond=1e-12)[0]
    if not np.allclose(W @ P, target - u_minus, rtol=1e-9, atol=1e-12 * np.abs(u_minus).max()):
        raise InvalidParameterError(
            "tangential_restitution", e_t, "a target the contact's Delassus block can reach"
        )
    transitions = [("end", float(P[0]))]
    if friction is not None:
        mu = _checked_friction(friction)
        slip = float(np.linalg.norm(u_minus[1:]))
        if np.linalg.norm(P[1:]) > mu * P[0] and slip > 0.0:
            phi = np.concatenate(([1.0], -mu * u_minus[1:] / slip))
            P = phi * (-(1.0 + e) * u_minus[0] / float(W[0] @ phi))
            transitions = [("slip", 0.0), ("end", float(P[0]))]
    return FrictionalImpactResult(
        P,
        u_minus + W @ P,
        math.nan,
        math.nan,
        math.nan,
        float(u_minus @ P + 0.5 * P @ W @ P),
        tuple(transitions),
    )
