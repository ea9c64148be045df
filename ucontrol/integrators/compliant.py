r"""Compliant contact: spring-dashpot or Hunt–Crossley forces on scipy's stiff solvers.

Every unilateral constraint becomes a one-sided force law in its penetration
:math:`\delta = -g` (in [m], or [rad] for joint stops):

- ``"linear"`` (Kelvin–Voigt): :math:`\lambda = \max(0, k\delta + c\dot\delta)` with
  :math:`c = 2\zeta\sqrt{k\,m_\text{eff}}`, :math:`m_\text{eff} = 1/(J M^{-1} J^T)` and ζ the
  damping ratio for which this one-sided law rebounds with restitution e exactly (see
  :func:`damping_ratio`; DESIGN's :math:`-\ln e / \sqrt{\pi^2 + \ln^2 e}` holds for a law
  that may pull). Stiffness k in [N/m].
- ``"hunt_crossley"``: :math:`\lambda = \max(0, k\delta^p (1 + \tfrac32 (1 - e)\dot\delta /
  \dot\delta^-))` with p = 3/2 (Hertz) and :math:`\dot\delta^-` the penetration speed when the
  contact began. Stiffness k in [N/m^1.5].

The motion :math:`M \dot v = \tau - h + \sum_a J_a^T \lambda_a` is integrated by
:func:`scipy.integrate.solve_ivp` with an implicit method (Radau, BDF or LSODA). Terminal events
at :math:`g_a = 0` restart the integration where a contact begins or ends (the linear force jumps
there) and record :math:`\dot\delta^-`. As k grows the motion tends to the rigid one with
Newton's restitution; the error against k is measured in docs/accuracy.md.

**Flexible joints.** With :class:`~ucontrol.model.FlexibleJoints` the state holds the motor
coordinates after the link ones (:mod:`~ucontrol.integrators.smooth_dynamics`): the spring
torque enters the links' generalized force and the contact forces act on the links only, with
:math:`m_\text{eff}` that of the links. The stiff solver takes the joint springs in its stride.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from ucontrol._validation import as_positive
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import IntegrationError, InvalidParameterError
from ucontrol.integrators.methods import CONTACT_MODELS, IVP_METHODS
from ucontrol.integrators.smooth_dynamics import SmoothDynamics
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel
from ucontrol.plant import PlantEvaluation, StepOutcome

Vector = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: The stiff methods of solve_ivp the integrator accepts.
METHODS = IVP_METHODS["compliant"]

#: Largest damping ratio of the linear law: its restitution is then 2.4e-3, and a resting
#: contact settles with time constant 2 ζ sqrt(m_eff / k) (0.02 s for 1 kg at 1e6 N/m).
MAX_DAMPING_RATIO = 10.0

#: Events closer than this to their predecessor, in [s], count as a stall.
_STALL_TIME = 1e-14
#: Stalled events tolerated in a row before giving up.
_MAX_STALLS = 50


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


class Compliant:
    """Compliant-contact integrator of a robot under unilateral constraints.

    Same protocol as :class:`ucontrol.integrators.MoreauJean`: :meth:`evaluate` at (q_k, v_k),
    then :meth:`step` with the generalized forces held over the step.

    Args:
        robot: The robot.
        constraints: Its unilateral constraints, each turned into a force law.
        dt: Step h in [s]: the sampling and zero-order-hold period, not an accuracy parameter.
        stiffness: k, in [N/m] (linear) or [N/m^1.5] (Hunt–Crossley); [N m/rad] for stops.
        contact_model: ``"linear"`` or ``"hunt_crossley"``.
        rtol: Relative tolerance of solve_ivp.
        atol: Absolute tolerance of solve_ivp, in the units of the state.
        method: ``"Radau"``, ``"BDF"`` or ``"LSODA"``.
        max_events: Events allowed in one step before :class:`IntegrationError`.
        flexible: Flexible joints of the robot: the state then holds their motor coordinates.
        joint_friction: Viscous friction of the link coordinates, a smooth force
            (:mod:`~ucontrol.integrators.smooth_dynamics`); Coulomb friction is refused.

    Raises:
        InvalidParameterError: A bad setting, or ``joint_friction`` with a Coulomb part.
    """

    name = "compliant"
    #: No θ: the value only weighs the actuator work over a step in run summaries.
    theta = 0.5
    #: Exponent p of the Hunt–Crossley law (Hertz contact of a sphere).
    hunt_crossley_exponent = 1.5
    #: Floor of the Hunt–Crossley reference speed δ̇⁻, in [m/s]: contacts beginning slower
    #: (resting, grazing) are damped as if they had begun at this speed.
    min_impact_speed = 1e-3

    def __init__(
        self,
        robot: RobotModel,
        constraints: ConstraintSet,
        *,
        dt: float,
        stiffness: float = 1e6,
        contact_model: str = "linear",
        rtol: float = 1e-8,
        atol: float = 1e-10,
        method: str = "Radau",
        max_events: int = 10_000,
        flexible: FlexibleJoints | None = None,
        joint_friction: JointFriction | None = None,
    ) -> None:
        if method not in METHODS:
            raise InvalidParameterError("method", method, f"one of {list(METHODS)}")
        if contact_model not in CONTACT_MODELS:
            raise InvalidParameterError(
                "contact_model", contact_model, f"one of {list(CONTACT_MODELS)}"
            )
        self.robot = robot
        self.constraints = constraints
        self.flexible = flexible
        self.dt = as_positive("dt", dt)
        self.stiffness = as_positive("stiffness", stiffness)
        self.contact_model = contact_model
        self.rtol = as_positive("rtol", rtol)
        self.atol = as_positive("atol", atol)
        self.method = method
        self.max_events = int(as_positive("max_events", max_events))
        self.joint_friction = joint_friction
        self._dynamics = SmoothDynamics(
            robot, constraints, flexible, joint_friction, integrator=self.name
        )
        self._n = constraints.size
        self._zeta = np.array([damping_ratio(e) for e in constraints.restitution])
        self._carry: tuple[Vector, Vector, Mask, Vector] | None = None
        #: Largest step solve_ivp took in the last segment, in [s]: the next one starts there.
        self._step_hint: float | None = None

    def evaluate(self, q: Vector, v: Vector, t: float | None = None) -> PlantEvaluation:
        r"""Gaps, normal velocities and energies at (q, v).

        The potential energy includes the elastic energy of the penetrating contacts,
        :math:`k \delta^{p+1} / (p + 1)` (p = 1 linear, 3/2 Hunt–Crossley), so that the
        mechanical energy of the compliant plant never rises without work. ``t`` [s] is
        passed on to the constraints (the scene refuses moving surfaces for this integrator).
        """
        state = self._dynamics.evaluate(q, v, t)
        p = 1.0 if self.contact_model == "linear" else self.hunt_crossley_exponent
        depth = np.maximum(-state.gap, 0.0)  # [m]
        elastic = float(np.sum(self.stiffness * depth ** (p + 1.0) / (p + 1.0)))  # [J]
        return state._replace(potential_energy=state.potential_energy + elastic)

    def step(self, state: PlantEvaluation, tau: Vector) -> StepOutcome:
        """Integrate over one step from ``state`` with ``tau`` held.

        Args:
            state: The evaluation at the start of the step.
            tau: Generalized forces (actuation plus external), shape (nv,), in [N m] or [N]
                (nv + nf with flexible joints: the motor torques last).

        Raises:
            IntegrationError: solve_ivp failed, the events stalled, or more than
                ``max_events`` events fell in the step.
        """
        q, v, h = state.q, state.v, self.dt
        inside, speeds = self._carried_modes(state)
        impulse = np.zeros(self._n)
        active = inside.copy()
        t, events, stalls = 0.0, 0, 0
        start = 0.0 if state.t is None else float(state.t)  # [s], absolute time of the step
        onsets: list[tuple[int, float]] = []  # (constraint, time [s]) where a contact begins
        while h - t > _STALL_TIME:
            q, v, segment_impulse, duration, fired = self._integrate(
                q, v, tau, inside, speeds, h - t, t
            )
            impulse += segment_impulse
            t += duration
            if not fired.any():
                break
            events += 1
            stalls = stalls + 1 if duration <= _STALL_TIME else 0
            if stalls > _MAX_STALLS or events > self.max_events:
                raise IntegrationError(
                    self.name,
                    t,
                    f"{events} contact events in the step ({stalls} without the time "
                    f"advancing) on {self._names(fired)}: the contacts chatter; lower the "
                    "stiffness or use moreau_jean",
                )
            entering = fired & ~inside
            if entering.any():
                _, u = self._dynamics.kinematics(q, v)
                speeds = speeds.copy()
                speeds[entering] = np.maximum(-u[entering], self.min_impact_speed)
                onsets += [(int(i), start + t) for i in np.flatnonzero(entering)]
            inside = inside ^ fired
            active |= inside
        self._carry = (q.copy(), v.copy(), inside.copy(), speeds.copy())
        return StepOutcome(q, v, impulse, active, None, events, impacts=tuple(onsets))

    def _carried_modes(self, state: PlantEvaluation) -> tuple[Mask, Vector]:
        """Which constraints are in contact, and their δ̇⁻, as the last step left them.

        When the step does not continue the last one, a constraint is in contact if it
        penetrates, and its δ̇⁻ is its current penetration speed.
        """
        if self._carry is not None:
            q_end, v_end, inside, speeds = self._carry
            if np.array_equal(state.q, q_end) and np.array_equal(state.v, v_end):
                return inside, speeds
        inside = state.gap < 0.0
        speeds = np.maximum(-state.normal_velocity, self.min_impact_speed)
        return inside, speeds

    def _forces(
        self,
        gap: Vector,
        u: Vector,
        D_diagonal: Vector,
        indices: NDArray[np.intp],
        speeds: Vector,
    ) -> Vector:
        """Contact forces of the constraints ``indices`` (m,) in [N] or [N m], shape (m,).

        Args:
            gap: Gaps of every constraint, shape (n,).
            u: Normal velocities of every constraint, shape (n,).
            D_diagonal: ``J_a M⁻¹ J_aᵀ`` of the constraints ``indices``, shape (m,).
            indices: The constraints in contact, shape (m,).
            speeds: Hunt–Crossley reference speeds δ̇⁻ of every constraint, shape (n,).
        """
        k = self.stiffness
        depth = -gap[indices]  # [m]
        rate = -u[indices]  # [m/s]
        if self.contact_model == "linear":
            damping = 2.0 * self._zeta[indices] * np.sqrt(k / D_diagonal)  # [N s/m]
            force = k * depth + damping * rate
        else:
            e = self.constraints.restitution[indices]
            spring = k * np.maximum(depth, 0.0) ** self.hunt_crossley_exponent
            force = spring * (1.0 + 1.5 * (1.0 - e) * rate / speeds[indices])
        return np.maximum(force, 0.0)

    def _integrate(
        self,
        q0: Vector,
        v0: Vector,
        tau: Vector,
        inside: Mask,
        speeds: Vector,
        duration: float,
        t_start: float,
    ) -> tuple[Vector, Vector, Vector, float, Mask]:
        """Integrate with the contact modes fixed until ``duration`` [s] or the first event.

        Returns:
            q, v at the end, the impulse ∫λ dt of each constraint (n,), the duration reached
            in [s] and which constraints crossed g = 0.
        """
        dynamics, nv, n = self._dynamics, self._dynamics.nv, self._n
        contacts = np.flatnonzero(inside)
        cache: dict[str, Any] = {"key": None}

        def evaluate(t: float, y: Vector) -> tuple[Vector, Vector]:
            key = (t, y.tobytes())
            if cache["key"] != key:
                dq, v = y[:nv], y[nv : 2 * nv]
                q = dynamics.configuration(q0, dq)
                force = np.zeros(n)
                if contacts.size:
                    terms = dynamics.constraint_terms(q, v, tau, contacts, with_drift=False)
                    gap, u = terms.gap, terms.normal_velocity
                    D_diagonal = np.einsum("ij,ji->i", terms.J, terms.Minv_Jt)
                    force[contacts] = self._forces(gap, u, D_diagonal, contacts, speeds)
                    acceleration = terms.a_free + terms.Minv_Jt @ force[contacts]
                else:
                    gap, _ = dynamics.kinematics(q, v)
                    acceleration = dynamics.free_acceleration(q, v, tau)
                cache["key"] = key
                cache["value"] = (
                    np.concatenate((dynamics.chart_rate(q0, dq, v), acceleration, force)),
                    gap,
                )
            value: tuple[Vector, Vector] = cache["value"]
            return value

        events = [_event(evaluate, i, 1.0 if inside[i] else -1.0) for i in range(n)]
        solution = solve_ivp(
            lambda t, y: evaluate(t, y)[0],
            (0.0, duration),
            np.concatenate((np.zeros(nv), v0, np.zeros(n))),
            method=self.method,
            rtol=self.rtol,
            atol=self.atol,
            events=events or None,
            first_step=None if self._step_hint is None else min(duration, self._step_hint),
        )
        if solution.t.size > 2:  # the last interval may be cut short by the end or an event
            self._step_hint = float(np.max(np.diff(solution.t[:-1])))
        if solution.status < 0:
            raise IntegrationError(self.name, t_start + float(solution.t[-1]), solution.message)
        y = solution.y[:, -1]
        fired = np.zeros(n, dtype=bool)
        if solution.status == 1:
            fired = np.array([times.size > 0 for times in solution.t_events])
        return (
            dynamics.configuration(q0, y[:nv]),
            y[nv : 2 * nv].copy(),
            y[2 * nv :].copy(),
            float(solution.t[-1]),
            fired,
        )

    def _names(self, mask: Mask) -> list[str]:
        return [self.constraints.names[i] for i in np.flatnonzero(mask)]


def _event(evaluate: Any, i: int, direction: float) -> Any:
    """Terminal event function on the gap of constraint ``i``."""

    def event(t: float, y: Vector) -> float:
        return float(evaluate(t, y)[1][i])

    event.terminal = True  # type: ignore[attr-defined]
    event.direction = direction  # type: ignore[attr-defined]
    return event
