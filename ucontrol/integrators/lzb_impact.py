r"""LZB energetic multiple-impact law (Liu–Zhao–Brogliato; Brogliato 2016, §6.3).

During an impact the configuration is frozen and the contact-space velocity
:math:`u = J v` evolves with the normal impulses :math:`P` (shape (m,)) as

.. math::

    M\,dv = J^T dP, \qquad du = D\,dP, \qquad D = J M^{-1} J^T .

Each contact :math:`j` stores a potential energy :math:`E_j` in a local compliance whose force
law is :math:`f_j = K_j \delta_j^{\eta_j}` (:math:`\eta_j = 1` linear, :math:`3/2` Hertz) and
the impulses are distributed in proportion to these forces,
:math:`dP_j / dP_p = f_j / f_p` where :math:`p` is the *primary* contact (largest potential
energy). In compression (:math:`u_j < 0`) :math:`dE_j = -u_j\,dP_j`; in expansion
(:math:`u_j > 0`) :math:`dE_j = -u_j\,dP_j / e_j^2`, so that the work the contact gives back
is :math:`e_j^2` times the largest energy it stored: :math:`e_j` is Stronge's *energetic*
restitution coefficient (equal to Newton's for a single frictionless contact).

Writing the energy through an effective compression :math:`s_j`,
:math:`E_j = K_j s_j^{\eta_j + 1} / (\eta_j + 1)` and :math:`f_j = K_j s_j^{\eta_j}`, the law
is the smooth system, for an impact "time" :math:`\tau` with :math:`dP_p = f_p d\tau`,

.. math::

    \frac{du}{d\tau} = D f, \qquad
    \frac{ds_j}{d\tau} = -c_j u_j, \quad c_j = 1 \text{ if } u_j \le 0,\ 1/e_j^2
    \text{ otherwise}, \qquad \frac{dP}{d\tau} = f,

with :math:`s_j` clipped at 0 (a contact with :math:`s_j = 0` and :math:`u_j \ge 0` is
separated). Only the ratios of the stiffnesses :math:`K_j` matter when all exponents are equal:
multiplying every :math:`K_j` by a constant rescales :math:`\tau` only. The impact ends when
every contact is separated.

Two integrations are offered:

- adaptive (``impulse_step=None``): :func:`scipy.integrate.solve_ivp` (DOP853) on the system
  above, restarted at every compression/expansion switch and separation (terminal events);
  the accuracy reference;
- fixed impulse step (``impulse_step=ΔP``): LZB's own scheme — each step advances the impulse
  of the current primary contact by ΔP (the impact-time step is :math:`\Delta P / f_p`, one
  classical RK4 step of the system above, capped where the primary unloads and
  :math:`f_p \to 0`), a step from zero energy taken with the exact small-impulse expansion.
  First order in ΔP across switches and separations.

Positions do not move during the impact; the post-impact velocity is
:math:`v^+ = v^- + M^{-1} J^T P`. :func:`lzb_impact_with_friction` adds Coulomb friction at the
contacts (planar, stick and slip during the impact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol._validation import as_positive, as_vector
from ucontrol.exceptions import InvalidParameterError, ShapeError, SolverError
from ucontrol.integrators.frictional_impact import stick_force, terminal_event

Vector = NDArray[np.float64]

#: Exponent of a linear contact and of a Hertz sphere–sphere / sphere–plane contact.
LINEAR = 1.0
HERTZ = 1.5

#: Segments (between terminal events) allowed before giving up.
_MAX_SEGMENTS = 10_000


@dataclass(frozen=True)
class LZBImpactResult:
    """Outcome of one multiple impact.

    Attributes:
        v: Post-impact generalized velocity, shape (n,) (None when solved in contact space).
        u: Post-impact contact normal velocities ``J v+`` in [m/s], shape (m,).
        impulse: Normal impulses P in [N s], shape (m,).
        dissipated: Energy dissipated at each contact in [J], shape (m,).
        max_potential: Largest potential energy each contact stored in [J], shape (m,)
            (the largest over the impact when it was compressed more than once).
        compression_work: Work absorbed by each contact in its compressions in [J], shape (m,).
        kinetic_change: Kinetic energy after minus before in [J], ``u-·P + ½ Pᵀ D P``.
        primary: Index of the contact that stored the largest energy.
        steps: Integration steps (solve_ivp steps or fixed impulse steps).
        segments: Integration segments between compression/expansion switches and separations.
    """

    v: Vector | None
    u: Vector
    impulse: Vector
    dissipated: Vector
    max_potential: Vector
    compression_work: Vector
    kinetic_change: float
    primary: int
    steps: int
    segments: int


@dataclass(frozen=True, kw_only=True)
class LZBImpactLaw:
    """Parameters of the LZB law for m contacts; call :meth:`solve` at an impact.

    Attributes:
        restitution: Energetic restitution coefficients e_j in [0, 1], shape (m,) or scalar.
        stiffness: Contact stiffnesses K_j > 0 (only their ratios matter when the exponents are
            equal), in [N/m^η], shape (m,) or scalar.
        exponent: Elasticity exponents η_j > 0 (1 linear, 1.5 Hertz), shape (m,) or scalar.
        impulse_step: Fixed impulse step ΔP of the primary contact in [N s]; None: adaptive.
        rtol: Relative tolerance of the adaptive integration.
        max_steps: Cap on the integration steps of one impact, >= 1: the fixed impulse
            steps, or the solve_ivp steps of the adaptive integration (with or without
            friction); beyond it the impact raises :class:`SolverError`.
        gaps: A contact that separated during the impact keeps its opening (s_j < 0, growing
            with ds_j = -u_j dτ) and is compressed again only once the opening has closed, as
            in the stiff limit of the compliant model; False re-compresses it as soon as it
            approaches again (s_j stays at 0 while separated).
    """

    restitution: float | Vector = 1.0
    stiffness: float | Vector = 1.0
    exponent: float | Vector = HERTZ
    impulse_step: float | None = None
    rtol: float = 1e-13
    max_steps: int = 100_000
    gaps: bool = True

    def __post_init__(self) -> None:
        restitution = np.atleast_1d(as_vector_or_scalar("restitution", self.restitution))
        bad = np.flatnonzero(~((restitution >= 0.0) & (restitution <= 1.0)))
        if bad.size:
            raise InvalidParameterError(
                "restitution", restitution[bad[0]], f"in [0, 1] (contact {int(bad[0])})"
            )
        object.__setattr__(self, "restitution", restitution)
        for name in ("stiffness", "exponent"):
            values = np.atleast_1d(as_vector_or_scalar(name, getattr(self, name)))
            bad = np.flatnonzero(~(values > 0.0))
            if bad.size:
                raise InvalidParameterError(name, values[bad[0]], f"> 0 (contact {int(bad[0])})")
            object.__setattr__(self, name, values)
        if self.impulse_step is not None:
            object.__setattr__(self, "impulse_step", as_positive("impulse_step", self.impulse_step))
        object.__setattr__(self, "rtol", as_positive("rtol", self.rtol))
        if int(self.max_steps) < 1:
            raise InvalidParameterError("max_steps", self.max_steps, ">= 1")

    def parameters(self, m: int) -> tuple[Vector, Vector, Vector]:
        """(e, K, η), each of shape (m,), broadcast from scalars.

        Raises:
            ShapeError: A per-contact vector has a length other than 1 or m.
        """
        out = []
        for name in ("restitution", "stiffness", "exponent"):
            values = np.asarray(getattr(self, name), dtype=float)
            if values.size not in (1, m):
                raise ShapeError(name, (m,), values.shape)
            out.append(np.broadcast_to(values, (m,)).astype(float))
        return out[0], out[1], out[2]

    def select(self, indices: NDArray[np.intp]) -> LZBImpactLaw:
        """The law restricted to the contacts ``indices`` (per-contact vectors sliced)."""
        fields = {}
        for name in ("restitution", "stiffness", "exponent"):
            values = np.asarray(getattr(self, name), dtype=float)
            fields[name] = values if values.size == 1 else values[indices]
        return LZBImpactLaw(
            **fields,
            impulse_step=self.impulse_step,
            rtol=self.rtol,
            max_steps=self.max_steps,
            gaps=self.gaps,
        )

    def solve(self, M: Vector, J: Vector, v_minus: Vector) -> LZBImpactResult:
        """Post-impact velocity and impulses from the pre-impact velocity.

        Args:
            M: Inertia matrix, shape (n, n), symmetric positive definite.
            J: Normal Jacobian of the contacts at contact, shape (m, n).
            v_minus: Pre-impact generalized velocity, shape (n,).
        """
        M = np.asarray(M, dtype=float)
        J = np.atleast_2d(np.asarray(J, dtype=float))
        n = M.shape[0]
        if M.shape != (n, n):
            raise ShapeError("M", (n, n), M.shape)
        if J.shape[1] != n:
            raise ShapeError("J", (J.shape[0], n), J.shape)
        v_minus = as_vector("v_minus", v_minus, n)
        try:
            Minv_Jt = np.linalg.solve(M, J.T)
        except np.linalg.LinAlgError as error:
            raise InvalidParameterError("M", "singular", "positive definite") from error
        result = self.solve_contact_space(J @ Minv_Jt, J @ v_minus)
        return _with_v(result, v_minus + Minv_Jt @ result.impulse)

    def solve_contact_space(self, D: Vector, u_minus: Vector) -> LZBImpactResult:
        """Impulses from the Delassus matrix and the pre-impact normal velocities.

        Args:
            D: Delassus matrix ``J M⁻¹ Jᵀ`` in [1/kg], shape (m, m).
            u_minus: Pre-impact normal velocities ``J v-`` in [m/s], shape (m,); negative
                approaching.

        Raises:
            ShapeError: D or a parameter vector does not match u_minus.
            SolverError: The integration failed or the contacts never separated.
        """
        u_minus = as_vector("u_minus", u_minus)
        m = u_minus.size
        D = np.atleast_2d(np.asarray(D, dtype=float))
        if D.shape != (m, m):
            raise ShapeError("D", (m, m), D.shape)
        e, K, eta = self.parameters(m)
        return _solve(
            D, u_minus, e, K, eta, self.impulse_step, self.rtol, int(self.max_steps), self.gaps
        )


def lzb_impact(
    M: Vector,
    J: Vector,
    v_minus: Vector,
    *,
    restitution: float | Vector = 1.0,
    stiffness: float | Vector = 1.0,
    exponent: float | Vector = HERTZ,
    impulse_step: float | None = None,
    rtol: float = 1e-13,
    max_steps: int = LZBImpactLaw.max_steps,
) -> LZBImpactResult:
    """One LZB multiple impact; see :class:`LZBImpactLaw` for the arguments."""
    law = LZBImpactLaw(
        restitution=restitution,
        stiffness=stiffness,
        exponent=exponent,
        impulse_step=impulse_step,
        rtol=rtol,
        max_steps=max_steps,
    )
    return law.solve(M, J, v_minus)


def as_vector_or_scalar(name: str, value: float | Vector) -> Vector:
    """``value`` as a finite float vector (a scalar gives shape (1,))."""
    return as_vector(name, np.atleast_1d(np.asarray(value, dtype=float)))


def _with_v(result: LZBImpactResult, v: Vector) -> LZBImpactResult:
    return LZBImpactResult(
        v,
        result.u,
        result.impulse,
        result.dissipated,
        result.max_potential,
        result.compression_work,
        result.kinetic_change,
        result.primary,
        result.steps,
        result.segments,
    )


class _Scaled:
    """The impact system in scaled units: u by U, time by T, impulses by U/d."""

    def __init__(
        self, D: Vector, u_minus: Vector, e: Vector, K: Vector, eta: Vector, gaps: bool
    ) -> None:
        self.m = u_minus.size
        self.gaps = gaps
        self.U = float(np.max(-u_minus))  # [m/s]
        self.d = float(np.max(np.diag(D)))  # [1/kg]
        p = int(np.argmin(u_minus))
        # time unit making the primary's scaled stiffness 1: d K_p U^(η-1) T^(η+1) = 1
        self.T = (self.d * K[p] * self.U ** (eta[p] - 1.0)) ** (-1.0 / (eta[p] + 1.0))  # [s]
        self.D = D / self.d
        self.kappa = K * self.d * self.T * (self.U * self.T) ** eta / self.U
        self.eta = eta
        self.inverse_e2 = 1.0 / np.maximum(e, 1e-150) ** 2  # unused where e = 0
        self.plastic = e == 0.0

    def force(self, s: Vector) -> Vector:
        return self.kappa * np.maximum(s, 0.0) ** self.eta

    def rate(self, y: Vector) -> Vector:
        """d/dτ of y = (u, s, P, W_compression, W_restitution), each of shape (m,)."""
        m = self.m
        u, s = y[:m], y[m : 2 * m]
        f = self.force(s)
        expanding = (u > 0.0) & (s > 0.0)
        c = np.where(expanding, np.where(self.plastic, 0.0, self.inverse_e2), 1.0)
        ds = -c * u if self.gaps else np.where((s > 0.0) | (u < 0.0), -c * u, 0.0)
        power = u * f
        return np.concatenate(
            (
                self.D @ f,
                ds,
                f,
                np.where(u > 0.0, 0.0, -power),
                np.where(u > 0.0, power, 0.0),
            )
        )

    def energy(self, s: Vector) -> Vector:
        return self.kappa * np.maximum(s, 0.0) ** (self.eta + 1.0) / (self.eta + 1.0)


def _solve(
    D: Vector,
    u_minus: Vector,
    e: Vector,
    K: Vector,
    eta: Vector,
    impulse_step: float | None,
    rtol: float,
    max_steps: int,
    gaps: bool,
) -> LZBImpactResult:
    m = u_minus.size
    if not np.any(u_minus < 0.0):
        zero = np.zeros(m)
        return LZBImpactResult(None, u_minus.copy(), zero, zero, zero, zero, 0.0, 0, 0, 0)
    sys = _Scaled(D, u_minus, e, K, eta, gaps)
    y = np.concatenate((u_minus / sys.U, np.zeros(4 * m)))
    max_energy = np.zeros(m)
    if impulse_step is None:
        y, steps, segments, max_energy = _adaptive(sys, y, rtol, max_steps)
    else:
        dP = impulse_step * sys.d / sys.U  # scaled
        y, steps, segments, max_energy = _fixed(sys, y, dP, max_steps)
    u_plus = y[:m] * sys.U
    impulse = y[2 * m : 3 * m] * sys.U / sys.d  # [N s]
    energy_unit = sys.U**2 / sys.d  # [J]
    compression = y[3 * m : 4 * m] * energy_unit
    restitution = y[4 * m :] * energy_unit
    kinetic_change = float(u_minus @ impulse + 0.5 * impulse @ D @ impulse)
    return LZBImpactResult(
        None,
        u_plus,
        impulse,
        compression - restitution,
        max_energy * energy_unit,
        compression,
        kinetic_change,
        int(np.argmax(max_energy)),
        steps,
        segments,
    )


def _finished(sys: _Scaled, y: Vector, tolerance: float) -> bool:
    m = sys.m
    return bool(np.all(y[m : 2 * m] <= 0.0) and np.all(y[:m] >= -tolerance))


def _adaptive(
    sys: _Scaled, y: Vector, rtol: float, max_steps: int
) -> tuple[Vector, int, int, Vector]:
    """Integrate with solve_ivp, restarting at every switch and separation."""
    m = sys.m
    atol = rtol * 1e-2
    steps = segments = 0
    max_energy = np.zeros(m)
    horizon = 1e3 * (1.0 + float(np.max(1.0 / np.sqrt(sys.kappa * np.diag(sys.D)))))

    def switch(j: int, y0: Vector, rising: bool) -> tuple[object, object]:
        def u_event(t: float, y: Vector) -> float:
            return float(y[j])

        def s_event(t: float, y: Vector) -> float:
            return float(y[m + j])

        u_event.terminal = True  # type: ignore[attr-defined]
        u_event.direction = 1.0 if rising else -1.0  # type: ignore[attr-defined]
        s_event.terminal = True  # type: ignore[attr-defined]
        s_event.direction = -1.0  # type: ignore[attr-defined]
        return u_event, s_event

    y[:m][np.abs(y[:m]) <= 10.0 * atol] = 0.0  # at rest: not approaching
    while not _finished(sys, y, atol):
        segments += 1
        if segments > _MAX_SEGMENTS:
            raise SolverError("lzb", f"no separation after {_MAX_SEGMENTS} segments")
        events = []
        du = sys.rate(y)[:m]
        for j in range(m):
            u_event, s_event = switch(j, y, y[j] < 0.0 or (y[j] == 0.0 and du[j] < 0.0))
            if y[m + j] > 0.0 or (y[m + j] == 0.0 and y[j] < 0.0):
                events.append(u_event)  # compression / expansion switch
            if y[m + j] > 0.0 and y[j] > 0.0:
                events.append(s_event)  # separation
            elif sys.gaps and y[m + j] < 0.0 and y[j] < 0.0:
                s_event.direction = 1.0  # type: ignore[attr-defined]
                events.append(s_event)  # the opening closes again
        solution = solve_ivp(
            lambda t, y: sys.rate(y),
            (0.0, horizon),
            y,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            events=events or None,
        )
        if solution.status < 0:
            raise SolverError("lzb", solution.message)
        steps += solution.t.size - 1
        _check_steps(steps, max_steps)
        max_energy = np.maximum(max_energy, np.max(sys.energy(solution.y[m : 2 * m].T), axis=0))
        y = solution.y[:, -1].copy()
        s, u = y[m : 2 * m], y[:m]
        # at a switch: exact zero of the switching quantity; plastic contacts lose their energy
        small = 10.0 * atol
        u[np.abs(u) <= small] = 0.0
        s[np.abs(s) <= small] = 0.0
        s[sys.plastic & (u >= 0.0) & (s > 0.0)] = 0.0
        if solution.status == 0 and not _finished(sys, y, atol):
            raise SolverError(
                "lzb", f"contacts not separated at the end of the horizon (u = {y[:m]})"
            )
    return y, steps, segments, max_energy


def _check_steps(steps: int, max_steps: int) -> None:
    """Raise :class:`SolverError` once an adaptive integration has taken over ``max_steps``."""
    if steps > max_steps:
        raise SolverError(
            "lzb", f"no separation after {steps} solve_ivp steps (max_steps = {max_steps})"
        )


def _fixed(sys: _Scaled, y: Vector, dP: float, max_steps: int) -> tuple[Vector, int, int, Vector]:
    """LZB's fixed impulse step of the primary contact (one RK4 step in τ per ΔP)."""
    m = sys.m
    max_energy = np.zeros(m)
    steps = switches = 0
    phase = y[:m] > 0.0
    # cap on the impact-time step where the primary unloads (f_p -> 0 makes dP / f_p large)
    tau_max = 0.05 / math.sqrt(float(np.max(sys.kappa * np.diag(sys.D))))
    while not _finished(sys, y, 1e-14):
        steps += 1
        if steps > max_steps:
            raise SolverError("lzb", f"no separation after {max_steps} impulse steps")
        s, u = y[m : 2 * m], y[:m]
        f = sys.force(s)
        if np.any(f > 0.0):
            p = int(np.argmax(sys.energy(s)))
            tau = min(dP / f[p], tau_max)
        elif np.any(starting := (s >= 0.0) & (u < 0.0)):
            # first step from zero energy, velocities frozen: P_p = κ_p (-u_p)^η τ^(η+1) / (η+1)
            p = int(np.argmin(np.where(starting, u, np.inf)))
            tau = ((sys.eta[p] + 1.0) * dP / (sys.kappa[p] * (-u[p]) ** sys.eta[p])) ** (
                1.0 / (sys.eta[p] + 1.0)
            )
        else:  # every contact open and none loaded: fly to the first closing exactly
            times = np.where((s < 0.0) & (u < 0.0), s / np.where(u < 0.0, u, -1.0), np.inf)
            first = int(np.argmin(times))
            s -= u * times[first]
            s[first] = 0.0
            continue
        k1 = sys.rate(y)
        k2 = sys.rate(y + 0.5 * tau * k1)
        k3 = sys.rate(y + 0.5 * tau * k2)
        k4 = sys.rate(y + tau * k3)
        y = y + tau / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        s, u = y[m : 2 * m], y[:m]
        s[sys.plastic & (u >= 0.0) & (s > 0.0)] = 0.0
        if not sys.gaps:
            s[(s < 0.0) & (u >= 0.0)] = 0.0
        max_energy = np.maximum(max_energy, sys.energy(s))
        switches += int(np.count_nonzero((u > 0.0) != phase))
        phase = u > 0.0
    return y, steps, switches + 1, max_energy


# --- Coulomb friction -------------------------------------------------------------------------


@dataclass(frozen=True)
class LZBFrictionResult:
    """Outcome of one multiple impact with Coulomb friction (planar: one tangent per contact).

    Attributes:
        v: Post-impact generalized velocity, shape (n,).
        u: Post-impact normal velocities in [m/s], shape (m,).
        u_t: Post-impact tangential velocities in [m/s], shape (m,).
        impulse: Normal impulses in [N s], shape (m,).
        impulse_t: Tangential impulses in [N s], shape (m,).
        friction_dissipated: Energy dissipated by friction at each contact in [J], shape (m,).
        kinetic_change: Kinetic energy after minus before in [J].
        steps: solve_ivp steps.
        segments: Integration segments (mode changes: compression, expansion, stick, slip).
    """

    v: Vector
    u: Vector
    u_t: Vector
    impulse: Vector
    impulse_t: Vector
    friction_dissipated: Vector
    kinetic_change: float
    steps: int
    segments: int


def lzb_impact_with_friction(
    law: LZBImpactLaw,
    M: Vector,
    J: Vector,
    J_t: Vector,
    v_minus: Vector,
    friction: float | Vector,
) -> LZBFrictionResult:
    r"""LZB with Coulomb friction at the contacts (Nguyen & Brogliato 2014), planar.

    During the impact each loaded contact's tangential force is, with :math:`f_n` its normal
    compliance force, :math:`f_t = -\mu f_n\,\mathrm{sign}(u_t)` while it slides, and while it
    sticks (:math:`u_t = 0`) the force that keeps :math:`\dot u_t = 0`, as long as
    :math:`|f_t| \le \mu f_n`. Velocities follow :math:`d(u_n, u_t)/d\tau = W (f_n, f_t)`,
    :math:`W = H M^{-1} H^T`, :math:`H = (J; J_t)`. Adaptive integration only. With one
    contact this is Stronge's energetic law with friction
    (:func:`~ucontrol.integrators.frictional_impact.frictional_impact`, tested equal).

    Args:
        law: Restitution, stiffness and exponent of the contacts (``gaps`` and ``rtol`` too).
        M: Inertia matrix, shape (n, n).
        J: Normal rows, shape (m, n).
        J_t: Tangential rows (one tangent per contact), shape (m, n).
        v_minus: Pre-impact velocity, shape (n,).
        friction: Coulomb coefficients μ >= 0, scalar or shape (m,).

    Raises:
        InvalidParameterError: A negative μ, a fixed impulse step (not supported here), or
            two tangent rows per contact at several contacts (3D friction, not provided).
        SolverError: The integration failed.
    """
    if law.impulse_step is not None:
        raise InvalidParameterError(
            "impulse_step", law.impulse_step, "None (friction is integrated adaptively)"
        )
    M = np.asarray(M, dtype=float)
    J = np.atleast_2d(np.asarray(J, dtype=float))
    J_t = np.atleast_2d(np.asarray(J_t, dtype=float))
    n, m = M.shape[0], J.shape[0]
    if m > 1 and J_t.shape == (2 * m, n):
        raise InvalidParameterError(
            "J_t",
            f"{2 * m} rows (two tangents per contact)",
            f"{m} rows, one tangent per contact: the LZB law with 3D friction at several "
            "contacts (the coupled directions in which stuck contacts start slipping) is not "
            "provided; one contact in 3D is ucontrol.integrators.frictional_impact",
        )
    if J.shape != (m, n) or J_t.shape != (m, n):
        raise ShapeError("J_t", (m, n), J_t.shape)
    v_minus = as_vector("v_minus", v_minus, n)
    mu = np.broadcast_to(np.atleast_1d(as_vector_or_scalar("friction", friction)), (m,)).copy()
    if np.any(mu < 0.0):
        raise InvalidParameterError("friction", float(mu.min()), ">= 0")
    e, K, eta = law.parameters(m)
    H = np.vstack((J, J_t))
    Minv_Ht = np.linalg.solve(M, H.T)
    W = H @ Minv_Ht
    w_minus = H @ v_minus
    if not np.any(w_minus[:m] < 0.0):
        zero = np.zeros(m)
        return LZBFrictionResult(
            v_minus.copy(), w_minus[:m], w_minus[m:], zero, zero, zero, 0.0, 0, 0
        )
    sys = _Scaled(W[:m, :m], w_minus[:m], e, K, eta, law.gaps)
    Ws = W / sys.d
    y = np.concatenate((w_minus / sys.U, np.zeros(4 * m)))  # u_n, u_t, s, P_n, P_t, W_f
    y, steps, segments = _adaptive_friction(sys, Ws, mu, y, law.rtol, int(law.max_steps))
    P = np.concatenate((y[3 * m : 4 * m], y[4 * m : 5 * m])) * sys.U / sys.d  # [N s]
    v_plus = v_minus + Minv_Ht @ P
    w_plus = H @ v_plus
    return LZBFrictionResult(
        v_plus,
        w_plus[:m],
        w_plus[m:],
        P[:m],
        P[m:],
        y[5 * m :] * sys.U**2 / sys.d,
        float(w_minus @ P + 0.5 * P @ W @ P),
        steps,
        segments,
    )


def _friction_forces(
    Ws: Vector, mu: Vector, f_n: Vector, stick: NDArray[np.bool_], sigma: Vector
) -> Vector:
    """Tangential forces: -μ f_n σ where sliding, the sticking ones by a linear solve."""
    m = f_n.size
    f_t = -mu * f_n * sigma
    f_t[stick] = 0.0
    if stick.any():
        S = np.flatnonzero(stick)
        load = Ws[m + S, :m] @ f_n + Ws[np.ix_(m + S, m + np.flatnonzero(~stick))] @ f_t[~stick]
        f_t[S] = stick_force(Ws[np.ix_(m + S, m + S)], load)
    return f_t


def _adaptive_friction(
    sys: _Scaled, Ws: Vector, mu: Vector, y: Vector, rtol: float, max_steps: int
) -> tuple[Vector, int, int]:
    m = sys.m
    atol = rtol * 1e-2
    small = 10.0 * atol
    steps = segments = 0
    horizon = 1e3 * (1.0 + float(np.max(1.0 / np.sqrt(sys.kappa * np.diag(sys.D)))))
    y[: 2 * m][np.abs(y[: 2 * m]) <= small] = 0.0

    def finished(y: Vector) -> bool:
        return bool(np.all(y[2 * m : 3 * m] <= 0.0) and np.all(y[:m] >= -atol))

    while not finished(y):
        segments += 1
        if segments > _MAX_SEGMENTS:
            raise SolverError("lzb", f"no separation after {_MAX_SEGMENTS} segments")
        u_n, u_t, s = y[:m], y[m : 2 * m], y[2 * m : 3 * m]
        loaded = (s > 0.0) | ((s >= 0.0) & (u_n < 0.0))
        sigma = np.where(loaded, np.sign(u_t), 0.0)
        stick = loaded & (u_t == 0.0)
        f_probe = sys.force(s)
        if not np.any(f_probe > 0.0):  # the start of a compression: the forces' direction
            f_probe = np.where(loaded, sys.kappa * np.maximum(-u_n, 0.0) ** sys.eta, 0.0)
        while stick.any():  # release the worst violator of the cone until none is left
            f_t = _friction_forces(Ws, mu, f_probe, stick, sigma)
            excess = np.where(stick, np.abs(f_t) - mu * f_probe * (1.0 + 1e-12), -np.inf)
            worst = int(np.argmax(excess))
            if excess[worst] <= 0.0:
                break
            stick[worst] = False
            sigma[worst] = -np.sign(f_t[worst])  # it slips against the force it needed

        def rate(t: float, y: Vector, stick: NDArray[np.bool_] = stick, sigma: Vector = sigma):
            u_n, u_t, s = y[:m], y[m : 2 * m], y[2 * m : 3 * m]
            f_n = sys.force(s)
            f_t = _friction_forces(Ws, mu, f_n, stick, sigma)
            f = np.concatenate((f_n, f_t))
            expanding = (u_n > 0.0) & (s > 0.0)
            c = np.where(expanding, np.where(sys.plastic, 0.0, sys.inverse_e2), 1.0)
            ds = -c * u_n if sys.gaps else np.where((s > 0.0) | (u_n < 0.0), -c * u_n, 0.0)
            return np.concatenate((Ws @ f, ds, f_n, f_t, -u_t * f_t))

        events = []
        du = rate(0.0, y)[:m]
        for j in range(m):
            if s[j] > 0.0 or (s[j] == 0.0 and u_n[j] < 0.0):
                rising = u_n[j] < 0.0 or (u_n[j] == 0.0 and du[j] < 0.0)
                events.append(_crossing(j, 1.0 if rising else -1.0))
            if s[j] > 0.0 and u_n[j] > 0.0:
                events.append(_crossing(2 * m + j, -1.0))
            elif sys.gaps and s[j] < 0.0 and u_n[j] < 0.0:
                events.append(_crossing(2 * m + j, 1.0))
            if loaded[j] and not stick[j] and sigma[j] != 0.0:
                events.append(_crossing(m + j, -sigma[j]))
            if stick[j] and mu[j] > 0.0:
                events.append(_cone_event(j, Ws, mu, stick, sigma, sys))
        solution = solve_ivp(
            rate, (0.0, horizon), y, method="DOP853", rtol=rtol, atol=atol, events=events or None
        )
        if solution.status < 0:
            raise SolverError("lzb", solution.message)
        steps += solution.t.size - 1
        _check_steps(steps, max_steps)
        y = solution.y[:, -1].copy()
        u_n, u_t, s = y[:m], y[m : 2 * m], y[2 * m : 3 * m]
        u_n[np.abs(u_n) <= small] = 0.0
        u_t[(np.abs(u_t) <= small) | stick] = 0.0
        s[np.abs(s) <= small] = 0.0
        s[sys.plastic & (u_n >= 0.0) & (s > 0.0)] = 0.0
        if solution.status == 0 and not finished(y):
            raise SolverError("lzb", "contacts not separated at the end of the horizon")
    return y, steps, segments


def _crossing(k: int, direction: float) -> Any:
    return terminal_event(lambda t, y: float(y[k]), direction)


def _cone_event(
    j: int, Ws: Vector, mu: Vector, stick: NDArray[np.bool_], sigma: Vector, sys: _Scaled
) -> Any:
    m = sys.m

    def event(t: float, y: Vector) -> float:
        f_n = sys.force(y[2 * m : 3 * m])
        f_t = _friction_forces(Ws, mu, f_n, stick, sigma)
        return float(mu[j] * f_n[j] - abs(f_t[j]))

    return terminal_event(event, -1.0)
