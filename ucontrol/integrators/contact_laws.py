r"""Compliant normal-force laws of the compliant integrator and their restitution maps.

Each law gives the normal force :math:`\lambda \ge 0` (in [N], or [N m] for joint stops) from
the penetration :math:`\delta = -g \ge 0`, its rate :math:`\dot\delta`, the effective mass
:math:`m = 1/(J M^{-1} J^T)` and the contact's restitution e (docs/compliant_laws.md):

- ``"linear"``: :math:`k\delta + 2\zeta\sqrt{km}\,\dot\delta`, ζ from :func:`damping_ratio`.
- ``"hunt_crossley"``: :math:`k\delta^{3/2}(1 + \tfrac32(1-e)\dot\delta/\dot\delta^-)`, the
  damping of Hunt and Crossley (1975), exact only as e → 1.
- ``"hunt_crossley_exact"``: :math:`k\delta^{3/2}(1 + \chi\dot\delta)` with
  :math:`\chi = x(e)/\dot\delta^-` and x the root of :func:`hunt_crossley_restitution`: the
  requested e at every impact speed.
- ``"kuwabara_kono"``: :math:`k\delta^{3/2} + c\,\delta^{1/2}\dot\delta` (viscoelastic Hertz),
  c chosen so that e holds at the impact speed ``reference_speed``; e falls with the speed.
- ``"walton_braun"``: loading :math:`k\delta`, unloading from the deepest penetration
  :math:`\delta_m` along the stiffer line :math:`k\delta_m + (k/e^2)(\delta - \delta_m)`,
  leaving the permanent set :math:`\delta_m(1 - e^2)`: :math:`e = \sqrt{k/k_u}` at every speed.

Every force is clamped at 0: no law pulls. :meth:`ContactLaw.restitution` integrates one
isolated impact of a mass on the law with :func:`scipy.integrate.solve_ivp`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import lambertw

from ucontrol._validation import as_non_negative, as_positive
from ucontrol.exceptions import IntegrationError, InvalidParameterError
from ucontrol.integrators.methods import CONTACT_MODELS

Vector = NDArray[np.float64]

#: Exponent p of the Hertz laws (a sphere on a plane): λ ∝ δ^p.
HERTZ_EXPONENT = 1.5
#: Largest damping ratio of the linear law: its restitution is then 2.4e-3, and a resting
#: contact settles with time constant 2 ζ sqrt(m_eff / k) (0.02 s for 1 kg at 1e6 N/m).
MAX_DAMPING_RATIO = 10.0
#: Smallest restitution the damped Hertz laws (hunt_crossley_exact, kuwabara_kono) are
#: calibrated for: lower ones (e = 0 included) get the damping of this one.
MIN_RESTITUTION = 1e-3
#: Smallest restitution kuwabara_kono is calibrated for (β = 17): below it the one-sided law
#: creeps out of the contact, δ̇ = -kδ/c, and an impact hardly ends.
MIN_KUWABARA_KONO_RESTITUTION = 1e-2
#: Restitutions closer to 1 than this are elastic (no damping).
_ELASTIC = 1e-12


def damping_ratio(restitution: float) -> float:
    r"""Damping ratio ζ for which the one-sided linear law rebounds with ``restitution``.

    A linear oscillator :math:`\ddot\delta + 2\zeta\omega\dot\delta + \omega^2\delta = 0`
    released when its force :math:`k\delta + c\dot\delta` vanishes (the law never pulls)
    rebounds with (Schwager and Pöschel, Granular Matter 9, 2007)

    .. math:: e(\zeta) = \exp\!\Big(-\frac{\zeta}{\sqrt{1-\zeta^2}}
              \big(\pi - \operatorname{atan2}(2\zeta\sqrt{1-\zeta^2},\, 1 - 2\zeta^2)\big)\Big)

    for ζ < 1 (its analytic continuation beyond), which is inverted here. The value
    :math:`-\ln e / \sqrt{\pi^2 + \ln^2 e}` is that of the oscillator allowed to pull until
    δ = 0; with the one-sided law it rebounds faster (0.902 instead of 0.9, 0.550 instead of 0.5),
    so the compliant motion would not tend to the rigid one as k grows.
    Restitutions below :math:`e(\zeta_{max}) = 2.4 \cdot 10^{-3}` (e = 0 included) get
    :math:`\zeta_{max} = 10`: a one-sided linear law cannot be plastic.
    """
    if restitution >= 1.0:
        return 0.0
    if restitution <= one_sided_restitution(MAX_DAMPING_RATIO):
        return MAX_DAMPING_RATIO
    return float(
        brentq(
            lambda zeta: one_sided_restitution(zeta) - restitution,
            0.0,
            MAX_DAMPING_RATIO,
            xtol=1e-15,
            rtol=1e-15,
        )
    )


def one_sided_restitution(zeta: float) -> float:
    """Restitution of the one-sided linear law with damping ratio ``zeta`` >= 0.

    See :func:`damping_ratio`, its inverse.
    """
    if zeta == 1.0:
        return math.exp(-2.0)
    if zeta < 1.0:
        omega = math.sqrt(1.0 - zeta**2)
        angle = math.pi - math.atan2(2.0 * zeta * omega, 1.0 - 2.0 * zeta**2)
        return math.exp(-zeta / omega * angle)
    omega = math.sqrt(zeta**2 - 1.0)
    return math.exp(-zeta / omega * math.atanh(2.0 * zeta * omega / (2.0 * zeta**2 - 1.0)))


def hunt_crossley_restitution(damping: float) -> float:
    r"""Restitution e(x) of Hunt–Crossley's law for the damping :math:`x = \chi\dot\delta^-`.

    The law is :math:`\lambda = k\delta^p(1 + \chi\dot\delta)`.

    Along the impact :math:`m\dot\delta\,d\dot\delta/(1 + \chi\dot\delta) = -k\delta^p d\delta`;
    integrated from :math:`\dot\delta^-` to the rebound :math:`-e\dot\delta^-` (both at δ = 0)
    it gives :math:`(1 + e)x = \ln\frac{1 + x}{1 - ex}`, whatever k, p and m: e depends on x
    alone. Solved for e with the principal branch :math:`W_0` of Lambert's function,

    .. math:: e(x) = \frac{1 + W_0\big(-(1 + x)\,e^{-(1 + x)}\big)}{x},

    derived from the energy integral in docs/compliant_laws.md and checked against
    :meth:`ContactLaw.restitution`. Since
    :math:`1 - ex > 0`, the force stays positive until δ = 0. Lambert's form loses digits near
    its branch point (x → 0): below x = 0.1 the relation is solved for e instead.

    Args:
        damping: x = χ δ̇⁻ >= 0 (dimensionless).
    """
    x = damping
    if x <= 0.0:
        return 1.0
    if x >= 0.1:
        return float((1.0 + lambertw(-(1.0 + x) * math.exp(-(1.0 + x)), 0).real) / x)
    return float(brentq(lambda e: _hunt_crossley_relation(x, e), 0.0, 1.0, xtol=1e-16))


def hunt_crossley_damping(restitution: float) -> float:
    """The x = χ δ̇⁻ for which Hunt–Crossley's law rebounds with ``restitution`` at every speed.

    The inverse of :func:`hunt_crossley_restitution` (decreasing, from 1 at x = 0 to about 1/x
    as x → ∞); restitutions below :data:`MIN_RESTITUTION` get that of :data:`MIN_RESTITUTION`.
    Below e = 0.1 the root lies within :math:`(1 + x)e^{-(1 + e)x}/e` of 1/e and is the fixed
    point of :math:`x = (1 - (1 + x)e^{-(1 + e)x})/e` (a contraction by :math:`e^{-1/e}/e^2`).
    """
    if restitution >= 1.0 - _ELASTIC:
        return 0.0
    e = max(restitution, MIN_RESTITUTION)
    if e >= 0.1:
        top = (1.0 - 1e-12) / e  # the relation tends to +inf at x = 1/e
        return float(
            brentq(lambda x: _hunt_crossley_relation(x, e), 0.0, top, xtol=1e-15, rtol=1e-14)
        )
    x = 1.0 / e
    for _ in range(50):
        x, previous = (1.0 - (1.0 + x) * math.exp(-(1.0 + e) * x)) / e, x
        if abs(x - previous) <= 1e-15 * x:
            break
    return x


def _hunt_crossley_relation(x: float, e: float) -> float:
    """[ln((1 + x)/(1 - e x)) - (1 + e) x] / x², without cancellation as x → 0."""
    return _log1p_remainder(x) - e**2 * _log1p_remainder(-e * x)


def _log1p_remainder(u: float) -> float:
    """(ln(1 + u) - u) / u², by its series for |u| < 0.1 (30 terms: error < 1e-30)."""
    if abs(u) >= 0.1:
        return (math.log1p(u) - u) / u**2
    return sum((-1.0) ** (n + 1) * u ** (n - 2) / n for n in range(2, 32))


@lru_cache(maxsize=64)
def kuwabara_kono_damping(restitution: float) -> float:
    r"""Dimensionless damping β for which Kuwabara–Kono's law rebounds with ``restitution``.

    With :math:`\delta = L\xi`, :math:`L = (m v^2 / k)^{2/5}` and the time scaled by
    :math:`L/v`, the impact at speed v reads
    :math:`\xi'' = -\xi^{3/2} - \beta\,\xi^{1/2}\xi'` with
    :math:`\beta = (c/k)(k/m)^{2/5}v^{1/5}` (Ramírez et al., Phys. Rev. E 60, 1999): e is a
    function of β alone, computed by :meth:`ContactLaw.restitution` and inverted here.
    Restitutions below :data:`MIN_KUWABARA_KONO_RESTITUTION` get its β.
    """
    if restitution >= 1.0 - _ELASTIC:
        return 0.0
    target = max(restitution, MIN_KUWABARA_KONO_RESTITUTION)
    unit = ContactLaw(model="kuwabara_kono", stiffness=1.0, reference_speed=1.0)

    def excess(beta: float) -> float:
        return unit.rebound(1.0, mass=1.0, coefficient=beta) - target

    high = 1.0
    while excess(high) > 0.0:
        high *= 4.0
    return float(brentq(excess, 0.0, high, xtol=1e-12, rtol=1e-12))


@dataclass(frozen=True, kw_only=True)
class ContactLaw:
    """A normal-force law of the compliant integrator.

    Attributes:
        model: One of :data:`~ucontrol.integrators.methods.CONTACT_MODELS`.
        stiffness: k, in [N/m] (linear, walton_braun loading) or [N/m^1.5] (the Hertz laws);
            [N m/rad] or [N m/rad^1.5] for joint stops.
        reference_speed: Impact speed in [m/s] at which kuwabara_kono rebounds with the
            contact's restitution.

    Raises:
        InvalidParameterError: An unknown model or a non-positive number.
    """

    model: str = "linear"
    stiffness: float = 1e6
    reference_speed: float = 1.0

    def __post_init__(self) -> None:
        if self.model not in CONTACT_MODELS:
            raise InvalidParameterError("contact_model", self.model, f"one of {CONTACT_MODELS}")
        object.__setattr__(self, "stiffness", as_positive("stiffness", self.stiffness))
        object.__setattr__(
            self, "reference_speed", as_positive("reference_speed", self.reference_speed)
        )

    @property
    def exponent(self) -> float:
        """Exponent p of the elastic part k δ^p."""
        return 1.0 if self.model in ("linear", "walton_braun") else HERTZ_EXPONENT

    @property
    def hysteretic(self) -> bool:
        """Whether the force depends on the deepest penetration (walton_braun)."""
        return self.model == "walton_braun"

    def coefficient(self, restitution: float) -> float:
        """The law's damping parameter for a contact of ``restitution`` in [0, 1].

        ζ (linear), 3(1 - e)/2 (hunt_crossley), x = χ δ̇⁻ (hunt_crossley_exact), β
        (kuwabara_kono) or e itself (walton_braun); all dimensionless.

        Raises:
            InvalidParameterError: e outside [0, 1], or e = 0 with walton_braun (a law without
                an unloading branch: the body would hover at its deepest penetration).
        """
        e = as_non_negative("restitution", restitution)
        if e > 1.0:
            raise InvalidParameterError("restitution", restitution, "in [0, 1]")
        if self.model == "linear":
            return damping_ratio(e)
        if self.model == "hunt_crossley":
            return 1.5 * (1.0 - e)
        if self.model == "hunt_crossley_exact":
            return hunt_crossley_damping(e)
        if self.model == "kuwabara_kono":
            return kuwabara_kono_damping(e)
        if e == 0.0:
            raise InvalidParameterError(
                "restitution", e, "in (0, 1] with contact_model 'walton_braun'"
            )
        return e

    def force(
        self,
        depth: Vector,
        rate: Vector,
        mass: Vector,
        coefficient: Vector,
        impact_speed: Vector,
        peak: Vector,
    ) -> Vector:
        """Normal forces, in [N] (or [N m]), shape (m,); every argument has shape (m,).

        Args:
            depth: Penetrations δ in [m].
            rate: Penetration rates δ̇ in [m/s].
            mass: Effective masses 1 / (J M⁻¹ Jᵀ) in [kg].
            coefficient: The :meth:`coefficient` of each contact.
            impact_speed: δ̇⁻ when each contact began, in [m/s] (Hunt–Crossley laws).
            peak: Deepest penetration δ_m of the unloading walton_braun contacts in [m], inf
                while loading; ignored by the other laws.
        """
        k = self.stiffness
        if self.model == "linear":
            force = k * depth + 2.0 * coefficient * np.sqrt(k * mass) * rate
        elif self.model == "walton_braun":
            loading = np.isinf(peak)
            top = np.where(loading, 0.0, peak)
            unloading = k * top + k * (depth - top) / coefficient**2
            force = np.where(loading, k * depth, np.minimum(k * depth, unloading))
        else:
            root = np.sqrt(np.maximum(depth, 0.0))
            spring = k * root**3
            if self.model == "kuwabara_kono":
                # c = β k (m/k)^{2/5} v_ref^{-1/5}, in [N s/m^1.5]
                damping = coefficient * k * (mass / k) ** 0.4 * self.reference_speed**-0.2
                force = spring + damping * root * rate
            else:
                force = spring * (1.0 + coefficient * rate / impact_speed)
        return np.maximum(force, 0.0)

    def elastic_energy(self, depth: Vector, coefficient: Vector, peak: Vector) -> float:
        """Energy the contacts' springs would give back, in [J]; arguments as :meth:`force`.

        k δ^{p+1}/(p + 1). For walton_braun the energy of the unloading spring
        (k/e²)(δ - δ_m(1 - e²))²/2 above the permanent set, which is e² k δ²/2 while loading
        (δ_m = δ): continuous where loading turns to unloading and back, so that the
        mechanical energy with it never rises without work; loading dissipates
        (1 - e²) k δ dδ.
        """
        k, p = self.stiffness, self.exponent
        depth = np.maximum(depth, 0.0)
        if not self.hysteretic:
            return float(np.sum(k * depth ** (p + 1.0) / (p + 1.0)))
        top = np.where(np.isinf(peak), depth, peak)  # δ_m, [m]
        stretch = np.maximum(depth - top * (1.0 - coefficient**2), 0.0)  # δ - δ_0, [m]
        return float(np.sum(0.5 * k * stretch**2 / coefficient**2))

    def rebound(
        self,
        impact_speed: float,
        *,
        mass: float,
        coefficient: float,
        weight: float = 0.0,
        rtol: float = 1e-11,
    ) -> float:
        """Rebound speed over ``impact_speed`` of one isolated impact, by solve_ivp.

        A mass enters the contact at δ = 0 with δ̇ = ``impact_speed`` and a constant
        ``weight`` [N] pressing it in; the impact ends when δ returns to 0.

        Args:
            impact_speed: δ̇⁻ > 0 in [m/s].
            mass: m in [kg].
            coefficient: The law's :meth:`coefficient`.
            weight: Constant force along δ, in [N].
            rtol: Relative tolerance of solve_ivp (the state is scaled to O(1)).

        Raises:
            IntegrationError: The impact does not end (the weight holds the mass in contact).
        """
        v, m, p, k = impact_speed, mass, self.exponent, self.stiffness
        length = (m * v**2 / k) ** (1.0 / (p + 1.0))  # [m], scale of the deepest penetration
        scale = length / v  # [s]
        law = np.array([coefficient])
        speed = np.array([v])
        peak = np.array([np.inf])

        def rhs(_: float, y: Vector) -> Vector:
            force = self.force(y[:1] * length, y[1:] * v, np.array([m]), law, speed, peak)
            return np.array([y[1], (weight - force[0]) * scale / (m * v)])

        def ended(_: float, y: Vector) -> float:
            return float(y[0])

        def turned(_: float, y: Vector) -> float:  # loading: δ̇ = 0, unloading: δ = δ_m
            return float(y[1] if np.isinf(peak[0]) else y[0] - peak[0] / length)

        ended.terminal, ended.direction = True, -1.0  # type: ignore[attr-defined]
        turned.terminal = True  # type: ignore[attr-defined]
        events: list[Any] = [ended, turned] if self.hysteretic else [ended]
        y, duration = np.array([0.0, 1.0]), 200.0
        while duration > 0.0:
            turned.direction = -1.0 if np.isinf(peak[0]) else 1.0  # type: ignore[attr-defined]
            solution = solve_ivp(
                rhs,
                (0.0, duration),
                y,
                method="DOP853",  # the scaled impact is not stiff: 10 ms, not Radau's 200
                rtol=rtol,
                atol=rtol * 1e-2,
                events=events,
            )
            y, duration = solution.y[:, -1], duration - float(solution.t[-1])
            if solution.status != 1 or solution.t_events[0].size:
                break
            peak[0] = y[0] * length if np.isinf(peak[0]) else np.inf
        if solution.status != 1 or not solution.t_events[0].size:
            raise IntegrationError(
                "compliant", float(solution.t[-1]) * scale, "the impact did not end"
            )
        return float(-y[1])

    def restitution(
        self, impact_speed: float, *, restitution: float, mass: float, weight: float = 0.0
    ) -> float:
        """The restitution map e(δ̇⁻) of a contact calibrated on ``restitution``.

        :meth:`rebound` with the :meth:`coefficient` of ``restitution``; arguments as there.
        """
        speed = as_positive("impact_speed", impact_speed)
        mass = as_positive("mass", mass)
        return self.rebound(
            speed, mass=mass, coefficient=self.coefficient(restitution), weight=weight
        )
