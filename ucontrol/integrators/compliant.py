r"""Compliant contact: the force laws of contact_laws on scipy's stiff solvers.

Every unilateral constraint becomes a one-sided force law in its penetration
:math:`\delta = -g` (in [m], or [rad] for joint stops), one of the laws of
:mod:`~ucontrol.integrators.contact_laws` (docs/compliant_laws.md): ``"linear"``
(Kelvin–Voigt, its damping calibrated so that the one-sided law rebounds with e exactly),
``"hunt_crossley"`` (damping 3(1 - e)/2, exact only as e → 1), ``"hunt_crossley_exact"`` (e at
every impact speed), ``"kuwabara_kono"`` (viscoelastic Hertz, e falls with the speed) or
``"walton_braun"`` (viscoelasto-plastic loading/unloading, e at every speed).

The motion :math:`M \dot v = \tau - h + \sum_a J_a^T \lambda_a` is integrated by
:func:`scipy.integrate.solve_ivp` with an implicit method (Radau, BDF or LSODA). Terminal events
at :math:`g_a = 0` restart the integration where a contact begins or ends (the linear force jumps
there) and record :math:`\dot\delta^-`; for ``walton_braun`` further events where a contact
turns back (:math:`\dot\delta = 0`, the deepest penetration recorded) and where it is pushed
past its deepest penetration again (loading resumes). As k grows the motion tends to the rigid
one with Newton's restitution; the error against k is measured in docs/accuracy.md.

**Flexible joints.** With :class:`~ucontrol.model.FlexibleJoints` the state holds the motor
coordinates after the link ones (:mod:`~ucontrol.integrators.smooth_dynamics`): the spring
torque enters the links' generalized force and the contact forces act on the links only, with
:math:`m_\text{eff}` that of the links. The stiff solver takes the joint springs in its stride.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol._validation import as_positive
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import IntegrationError, InvalidParameterError
from ucontrol.integrators.contact_laws import ContactLaw
from ucontrol.integrators.methods import IVP_METHODS
from ucontrol.integrators.smooth_dynamics import SmoothDynamics
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel
from ucontrol.plant import PlantEvaluation, StepOutcome

Vector = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: The stiff methods of solve_ivp the integrator accepts.
METHODS = IVP_METHODS["compliant"]

#: Events closer than this to their predecessor, in [s], count as a stall.
_STALL_TIME = 1e-14
#: Stalled events tolerated in a row before giving up.
_MAX_STALLS = 50


class Compliant:
    """Compliant-contact integrator of a robot under unilateral constraints.

    Same protocol as :class:`ucontrol.integrators.MoreauJean`: :meth:`evaluate` at (q_k, v_k),
    then :meth:`step` with the generalized forces held over the step.

    Args:
        robot: The robot.
        constraints: Its unilateral constraints, each turned into a force law.
        dt: Step h in [s]: the sampling and zero-order-hold period, not an accuracy parameter.
        stiffness: k, in [N/m] (linear, walton_braun) or [N/m^1.5] (Hunt–Crossley,
            Kuwabara–Kono); [N m/rad] or [N m/rad^1.5] for stops.
        contact_model: One of :data:`~ucontrol.integrators.methods.CONTACT_MODELS`.
        reference_speed: Impact speed in [m/s] at which kuwabara_kono rebounds with the
            contacts' restitutions.
        rtol: Relative tolerance of solve_ivp.
        atol: Absolute tolerance of solve_ivp, in the units of the state.
        method: ``"Radau"``, ``"BDF"`` or ``"LSODA"``.
        max_events: Events allowed in one step before :class:`IntegrationError`.
        flexible: Flexible joints of the robot: the state then holds their motor coordinates.
        joint_friction: Viscous friction of the link coordinates, a smooth force
            (:mod:`~ucontrol.integrators.smooth_dynamics`); Coulomb friction is refused.

    Raises:
        InvalidParameterError: A bad setting, ``joint_friction`` with a Coulomb part, or a
            contact of restitution 0 with ``walton_braun``.
    """

    name = "compliant"
    #: No θ: the value only weighs the actuator work over a step in run summaries.
    theta = 0.5
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
        reference_speed: float = 1.0,
        rtol: float = 1e-8,
        atol: float = 1e-10,
        method: str = "Radau",
        max_events: int = 10_000,
        flexible: FlexibleJoints | None = None,
        joint_friction: JointFriction | None = None,
    ) -> None:
        if method not in METHODS:
            raise InvalidParameterError("method", method, f"one of {list(METHODS)}")
        self.robot = robot
        self.constraints = constraints
        self.flexible = flexible
        self.dt = as_positive("dt", dt)
        self.law = ContactLaw(
            model=contact_model, stiffness=stiffness, reference_speed=reference_speed
        )
        self.stiffness = self.law.stiffness
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
        self._coefficient = np.array([self.law.coefficient(e) for e in constraints.restitution])
        self._carry: tuple[Vector, Vector, Mask, Vector, Vector] | None = None
        #: Largest step solve_ivp took in the last segment, in [s]: the next one starts there.
        self._step_hint: float | None = None

    def evaluate(self, q: Vector, v: Vector, t: float | None = None) -> PlantEvaluation:
        r"""Gaps, normal velocities and energies at (q, v).

        The potential energy includes the elastic energy of the penetrating contacts,
        :math:`k \delta^{p+1} / (p + 1)` (p = 1 linear, 3/2 the Hertz laws; the unloading
        spring's for walton_braun), so that the mechanical energy of the compliant plant never
        rises without work. ``t`` [s] is passed on to the constraints (the scene refuses moving
        surfaces for this integrator).
        """
        state = self._dynamics.evaluate(q, v, t)
        peaks = self._carried_modes(state)[2]
        elastic = self.law.elastic_energy(-state.gap, self._coefficient, peaks)  # [J]
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
        carried_inside, carried_speeds, carried_peaks = self._carried_modes(state)
        inside, speeds, peaks = carried_inside.copy(), carried_speeds.copy(), carried_peaks.copy()
        impulse = np.zeros(self._n)
        active = inside.copy()
        t, events, stalls = 0.0, 0, 0
        start = 0.0 if state.t is None else float(state.t)  # [s], absolute time of the step
        onsets: list[tuple[int, float]] = []  # (constraint, time [s]) where a contact begins
        while h - t > _STALL_TIME:
            q, v, segment_impulse, duration, fired, turned = self._integrate(
                q, v, tau, (inside, speeds, peaks), h - t, t
            )
            impulse += segment_impulse
            t += duration
            if not (fired.any() or turned.any()):
                break
            events += 1
            stalls = stalls + 1 if duration <= _STALL_TIME else 0
            if stalls > _MAX_STALLS or events > self.max_events:
                raise IntegrationError(
                    self.name,
                    t,
                    f"{events} contact events in the step ({stalls} without the time "
                    f"advancing) on {self._names(fired | turned)}: the contacts chatter; lower "
                    "the stiffness or use moreau_jean",
                )
            gap, u = self._dynamics.kinematics(q, v)
            entering = fired & ~inside
            speeds[entering] = np.maximum(-u[entering], self.min_impact_speed)
            onsets += [(int(i), start + t) for i in np.flatnonzero(entering)]
            unloading = turned & np.isinf(peaks)
            peaks[turned] = np.inf  # pushed past the deepest penetration: loading again
            peaks[unloading] = -gap[unloading]  # turned back: the deepest penetration
            peaks[entering] = np.inf
            inside = inside ^ fired
            active |= inside
        self._carry = (q.copy(), v.copy(), inside, speeds, peaks)
        return StepOutcome(q, v, impulse, active, None, events, impacts=tuple(onsets))

    def _carried_modes(self, state: PlantEvaluation) -> tuple[Mask, Vector, Vector]:
        """The contact modes as the last step left them: in contact, δ̇⁻ and δ_m.

        δ_m is the deepest penetration of the unloading walton_braun contacts, inf while
        loading (and for every other law). When the step does not continue the last one, a
        constraint is in contact if it penetrates, loading, and its δ̇⁻ is its current
        penetration speed.
        """
        if self._carry is not None:
            q_end, v_end, inside, speeds, peaks = self._carry
            if np.array_equal(state.q, q_end) and np.array_equal(state.v, v_end):
                return inside, speeds, peaks
        inside = state.gap < 0.0
        speeds = np.maximum(-state.normal_velocity, self.min_impact_speed)
        return inside, speeds, np.full(self._n, np.inf)

    def _integrate(
        self,
        q0: Vector,
        v0: Vector,
        tau: Vector,
        modes: tuple[Mask, Vector, Vector],
        duration: float,
        t_start: float,
    ) -> tuple[Vector, Vector, Vector, float, Mask, Mask]:
        """Integrate with the contact modes fixed until ``duration`` [s] or the first event.

        Args:
            q0: Configuration at the start, shape (nq,).
            v0: Velocity at the start, shape (nv,).
            tau: Generalized forces held, shape (nv,).
            modes: Which constraints are in contact (n,), their δ̇⁻ in [m/s] (n,) and their
                deepest penetration δ_m in [m] (n,), inf while loading.
            duration: Time left in the step, in [s].
            t_start: Time of the start within the step, in [s] (for error messages).

        Returns:
            q, v at the end, the impulse ∫λ dt of each constraint (n,), the duration reached
            in [s], which constraints crossed g = 0 and which walton_braun contacts turned
            (δ̇ = 0 while loading, δ = δ_m while unloading).
        """
        dynamics, nv, n = self._dynamics, self._dynamics.nv, self._n
        inside, speeds, peaks = modes
        contacts = np.flatnonzero(inside)
        cache: dict[str, Any] = {"key": None}

        def evaluate(t: float, y: Vector) -> tuple[Vector, Vector, Vector]:
            key = (t, y.tobytes())
            if cache["key"] != key:
                dq, v = y[:nv], y[nv : 2 * nv]
                q = dynamics.configuration(q0, dq)
                force = np.zeros(n)
                if contacts.size:
                    terms = dynamics.constraint_terms(q, v, tau, contacts, with_drift=False)
                    gap, u = terms.gap, terms.normal_velocity
                    D_diagonal = np.einsum("ij,ji->i", terms.J, terms.Minv_Jt)
                    force[contacts] = self.law.force(
                        -gap[contacts],
                        -u[contacts],
                        1.0 / D_diagonal,
                        self._coefficient[contacts],
                        speeds[contacts],
                        peaks[contacts],
                    )
                    acceleration = terms.a_free + terms.Minv_Jt @ force[contacts]
                else:
                    gap, u = dynamics.kinematics(q, v)
                    acceleration = dynamics.free_acceleration(q, v, tau)
                cache["key"] = key
                cache["value"] = (
                    np.concatenate((dynamics.chart_rate(q0, dq, v), acceleration, force)),
                    gap,
                    u,
                )
            value: tuple[Vector, Vector, Vector] = cache["value"]
            return value

        events = [_event(evaluate, i, 1.0 if inside[i] else -1.0) for i in range(n)]
        turning = contacts if self.law.hysteretic else np.zeros(0, dtype=np.intp)
        events += [_turn_event(evaluate, int(i), float(peaks[i])) for i in turning]
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
        fired, turned = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        if solution.status == 1:
            happened = np.array([times.size > 0 for times in solution.t_events])
            fired = happened[:n]
            turned[turning] = happened[n:]
        return (
            dynamics.configuration(q0, y[:nv]),
            y[nv : 2 * nv].copy(),
            y[2 * nv :].copy(),
            float(solution.t[-1]),
            fired,
            turned,
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


def _turn_event(evaluate: Any, i: int, peak: float) -> Any:
    """Terminal event where walton_braun contact ``i`` turns: δ̇ = 0 while loading, else δ = δ_m."""

    def event(t: float, y: Vector) -> float:
        _, gap, u = evaluate(t, y)
        return float(u[i] if np.isinf(peak) else -gap[i] - peak)

    event.terminal = True  # type: ignore[attr-defined]
    event.direction = 1.0  # type: ignore[attr-defined]
    return event
