"""The ``[integrator]`` table of a scene: which integrator, its step and its tolerances."""

from __future__ import annotations

from dataclasses import dataclass
from itertools import chain
from typing import Any

from ucontrol._validation import as_float, as_in_interval, as_int, as_positive, as_vector
from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.integrators.methods import (
    CONTACT_MODELS,
    IMPACT_LAWS,
    INTEGRATORS,
    IVP_METHODS,
    RESTITUTION_LAWS,
)
from ucontrol.integrators.moreau_jean import (
    NEWTON_LAWS,
    ON_UNSOLVED,
    PERSISTENCE_SPEED,
    PERSISTENCE_TOLERANCE,
)
from ucontrol.solvers.contact_solver_choice import check_contact_solver

#: Largest contact or friction tolerance accepted, in [m/s]: looser is no contact solve.
MAX_TOLERANCE = 1e-2


@dataclass(frozen=True, kw_only=True)
class IntegratorSettings:
    """How a scene advances in time.

    Attributes:
        name: Integrator name, one of :data:`INTEGRATORS`.
        dt: Time step in [s].
        theta: θ of the Moreau–Jean position update, in [1/2, 1].
        contact_tolerance: Absolute tolerance of the contact solver in [m/s].
        max_iter: Iteration cap of the contact solver.
        rtol: Relative tolerance of solve_ivp (event_driven, compliant); None: the
            integrator's default (1e-10 event_driven, 1e-8 compliant).
        atol: Absolute tolerance of solve_ivp in the state's units; None: the integrator's
            default (1e-12 event_driven, 1e-10 compliant).
        method: solve_ivp method: ``"DOP853"`` or ``"RK45"`` (event_driven), ``"Radau"``,
            ``"BDF"`` or ``"LSODA"`` (compliant); None: DOP853 or Radau.
        zeno_velocity: Rebound speed in [m/s] below which event_driven makes an impact
            plastic, cutting accumulations of impacts.
        stiffness: Contact stiffness of compliant, in [N/m] (linear, walton_braun) or
            [N/m^1.5] (hunt_crossley, hunt_crossley_exact, kuwabara_kono).
        contact_model: Force law of compliant, one of :data:`CONTACT_MODELS`
            (docs/compliant_laws.md).
        reference_speed: Impact speed in [m/s] at which compliant's ``kuwabara_kono`` law
            rebounds with the contacts' restitutions.
        restitution_threshold: Closing speed in [m/s] below which Moreau–Jean treats a contact
            as persistent (e = 0); 0 applies Newton's law to every closing contact.
        contact_solver: Contact solver of Moreau–Jean: ``"proxsuite"``, ``"pinocchio-admm"``,
            ``"pinocchio-pgs"`` or ``"qpsolvers:<solver>"`` (frictionless scenes only).
        friction_tolerance: Natural-map residual of the Coulomb problem a step must reach,
            in [m/s].
        friction_max_iter: Cap on the fixed-point iterations of the proxsuite friction solver.
        on_unsolved: ``"raise"`` or ``"warn"`` when a contact solve ends above its tolerance.
        midpoint: Moreau–Jean evaluates inertia, gravity and Coriolis forces at the step's
            midpoint: second order between impacts (see :class:`MoreauJean`).
        persistence_tolerance: Predicted gap in [m] up to which Moreau–Jean keeps a constraint
            that carried an impulse in the previous step active, with the band
            ``dt * persistence_speed`` added; both 0 turn persistence off.
        persistence_speed: Speed in [m/s] of Moreau–Jean's release band (see
            :class:`MoreauJean`).
        newton_law: Whom Moreau–Jean's Newton law applies to: ``"closing"`` constraints (with
            the energy guard) or, ``"siconos"``, every active one (Siconos' convention).
        impact_law: Impact law of event_driven, ``"newton"`` (generalized Newton law),
            ``"lzb"`` (Liu–Zhao–Brogliato's energetic law, docs/multiple_impacts.md; the
            contacts' restitutions are then energetic coefficients), ``"poisson"`` (Poisson's
            kinetic coefficients, single impacts only) or ``"energetic"`` (Stronge's
            coefficients; simultaneous impacts by the LZB law), docs/impact_laws.md; or a
            list of ``"newton"``, ``"poisson"``, ``"energetic"``, one per constraint (the
            contacts, then the stops, in the order of the scene).
        tangential_restitution: Brach's tangential coefficient e_t in [-1, 1] as an option of
            Newton's law at event_driven's frictional impacts (docs/impact_laws.md); None:
            none (Newton's law with Coulomb friction).
        lzb_stiffness: Contact stiffness of the LZB law, one or one per constraint (only
            ratios matter with equal exponents).
        lzb_exponent: Elasticity exponent of the LZB law (1 linear, 1.5 Hertz), one or one per
            constraint.
        lzb_impulse_step: Fixed impulse step of the LZB law in [N s]; None: adaptive.
        lzb_max_steps: Cap on the integration steps of one LZB impact (fixed impulse steps or
            adaptive solve_ivp steps), >= 1; beyond it the impact fails (``SolverError``).
        penetration_tolerance: Depth in [m] (or [rad]) beyond which a penetration is reported
            (a :class:`~ucontrol.exceptions.PenetrationWarning` and the summary's
            ``n_penetrations_beyond_tolerance``).

    Keys that do not concern the chosen integrator are checked and ignored, so one scene can
    be run with every integrator.
    """

    name: str = "moreau_jean"
    dt: float = 1e-3
    theta: float = 0.5
    contact_tolerance: float = 1e-10
    max_iter: int = 5000
    rtol: float | None = None
    atol: float | None = None
    method: str | None = None
    zeno_velocity: float = 1e-5
    stiffness: float = 1e6
    contact_model: str = "linear"
    reference_speed: float = 1.0
    restitution_threshold: float = 0.0
    contact_solver: str = "proxsuite"
    friction_tolerance: float = 1e-8
    friction_max_iter: int = 100
    on_unsolved: str = "raise"
    midpoint: bool = False
    persistence_tolerance: float = PERSISTENCE_TOLERANCE
    persistence_speed: float = PERSISTENCE_SPEED
    penetration_tolerance: float = 0.01
    newton_law: str = "closing"
    impact_law: str | list[str] = "newton"
    tangential_restitution: float | None = None
    lzb_stiffness: float | list[float] = 1.0
    lzb_exponent: float | list[float] = 1.5
    lzb_impulse_step: float | None = None
    lzb_max_steps: int = 100_000

    def __post_init__(self) -> None:
        check_contact_solver(self.contact_solver)
        if not isinstance(self.midpoint, bool):
            raise InvalidParameterError("midpoint", self.midpoint, "true or false")
        tolerance = as_float("persistence_tolerance", self.persistence_tolerance)
        if not tolerance >= 0.0:  # also rejects NaN
            raise InvalidParameterError("persistence_tolerance", tolerance, "a length >= 0 in [m]")
        object.__setattr__(self, "persistence_tolerance", tolerance)
        speed = as_float("persistence_speed", self.persistence_speed)
        if not speed >= 0.0:  # also rejects NaN
            raise InvalidParameterError("persistence_speed", speed, "a speed >= 0 in [m/s]")
        object.__setattr__(self, "persistence_speed", speed)
        friction_tolerance = as_positive("friction_tolerance", self.friction_tolerance)
        if friction_tolerance > MAX_TOLERANCE:
            raise InvalidParameterError(
                "friction_tolerance", friction_tolerance, f"in (0, {MAX_TOLERANCE:g}] m/s"
            )
        object.__setattr__(self, "friction_tolerance", friction_tolerance)
        object.__setattr__(
            self, "friction_max_iter", as_int("friction_max_iter", self.friction_max_iter, 1)
        )
        if self.on_unsolved not in ON_UNSOLVED:
            raise InvalidParameterError("on_unsolved", self.on_unsolved, f"one of {ON_UNSOLVED}")
        if self.name not in INTEGRATORS:
            raise NotFoundError("integrator", self.name, INTEGRATORS)
        object.__setattr__(self, "dt", as_positive("dt", self.dt))
        object.__setattr__(self, "theta", as_in_interval("theta", self.theta, 0.5, 1.0))
        object.__setattr__(
            self,
            "contact_tolerance",
            as_in_interval("contact_tolerance", self.contact_tolerance, 0.0, MAX_TOLERANCE),
        )
        if self.contact_tolerance == 0.0:
            raise InvalidParameterError("contact_tolerance", 0.0, f"in (0, {MAX_TOLERANCE:g}]")
        object.__setattr__(
            self,
            "penetration_tolerance",
            as_positive("penetration_tolerance", self.penetration_tolerance),
        )
        object.__setattr__(self, "max_iter", as_int("max_iter", self.max_iter, 1))
        for key in ("rtol", "atol"):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, as_positive(key, getattr(self, key)))
        methods = IVP_METHODS.get(self.name, tuple(chain(*IVP_METHODS.values())))
        if self.method is not None and self.method not in methods:
            raise InvalidParameterError("method", self.method, f"one of {list(methods)}")
        object.__setattr__(self, "zeno_velocity", as_positive("zeno_velocity", self.zeno_velocity))
        if self.newton_law not in NEWTON_LAWS:
            raise InvalidParameterError("newton_law", self.newton_law, f"one of {NEWTON_LAWS}")
        if isinstance(self.impact_law, list):
            for law in self.impact_law:
                if law not in RESTITUTION_LAWS:
                    raise InvalidParameterError(
                        "impact_law", law, f"one of {RESTITUTION_LAWS} in a per-constraint list"
                    )
        elif self.impact_law not in IMPACT_LAWS:
            raise InvalidParameterError("impact_law", self.impact_law, f"one of {IMPACT_LAWS}")
        if self.tangential_restitution is not None:
            object.__setattr__(
                self,
                "tangential_restitution",
                as_in_interval("tangential_restitution", self.tangential_restitution, -1.0, 1.0),
            )
        for key in ("lzb_stiffness", "lzb_exponent"):
            value = getattr(self, key)
            values = as_vector(key, value) if isinstance(value, list) else [as_float(key, value)]
            if not all(v > 0.0 for v in values):
                raise InvalidParameterError(key, value, "a number > 0 or a list of them")
        if self.lzb_impulse_step is not None:
            as_positive("lzb_impulse_step", self.lzb_impulse_step)
        if (
            isinstance(self.lzb_max_steps, bool)
            or not isinstance(self.lzb_max_steps, int)
            or self.lzb_max_steps < 1
        ):
            raise InvalidParameterError("lzb_max_steps", self.lzb_max_steps, "an integer >= 1")
        threshold = as_float("restitution_threshold", self.restitution_threshold)
        if threshold < 0.0:
            raise InvalidParameterError("restitution_threshold", threshold, "a speed >= 0 in [m/s]")
        object.__setattr__(self, "restitution_threshold", threshold)
        object.__setattr__(self, "stiffness", as_positive("stiffness", self.stiffness))
        if self.contact_model not in CONTACT_MODELS:
            raise InvalidParameterError(
                "contact_model", self.contact_model, f"one of {list(CONTACT_MODELS)}"
            )
        object.__setattr__(
            self, "reference_speed", as_positive("reference_speed", self.reference_speed)
        )

    def solver_options(self) -> dict[str, Any]:
        """The solve_ivp settings given (rtol, atol, method), as keyword arguments."""
        return {
            key: getattr(self, key)
            for key in ("rtol", "atol", "method")
            if getattr(self, key) is not None
        }
