r"""Event-driven integration (the accuracy reference), with planar Coulomb friction.

Between events the set :math:`I_2` of closed constraints (:math:`g_a = 0`, :math:`u_a = 0`) is
fixed and the motion is smooth: :math:`M \dot v = \tau - h + J_{I_2}^T \lambda` with
:math:`J_{I_2} \dot v + \dot J_{I_2} v = 0`, integrated by :func:`scipy.integrate.solve_ivp`
(explicit Runge–Kutta: DOP853 or RK45) with terminal events :math:`g_a = 0` (direction -1) for
the open constraints and :math:`\lambda_a = 0` (direction -1) for the closed ones. At an event:

1. impact: the constraints at contact (:math:`g_a \le \varepsilon_g`) solve the velocity-level
   LCP of Moreau–Jean with :math:`v_\text{free} = v^-`,
   :math:`0 \le P \perp D P + (1 + e) \odot J v^- \ge 0`, Newton's restitution applying to
   the closing constraints only; or, with ``restitution_law`` ``"poisson"`` or
   ``"energetic"``, a single constraint at contact follows that law
   (:func:`~ucontrol.integrators.frictional_impact.frictional_impact`, frictionless here so
   equal to Newton's impulse) and several simultaneous ones the LZB law (energetic) or a
   refusal (Poisson: no multiple-impact Poisson law is provided);
2. active set: the constraints left at contact with :math:`|u_a| \le \varepsilon_u` solve the
   acceleration-level LCP
   :math:`0 \le \lambda \perp D \lambda + (J a_\text{free} + \dot J v) \ge 0`,
   :math:`D = J M^{-1} J^T` (Gauss' principle); those that do not separate form :math:`I_2`;
3. projection: :math:`(q, v)` is projected onto :math:`g_{I_2} = 0`, :math:`J_{I_2} v = 0` in the
   metric of :math:`M`, which removes the drift of the integration of the closed constraints.

Accumulations of impacts (Zeno: a ball with e < 1 bounces infinitely often before
:math:`t_\infty`) are cut by a velocity threshold: an impact whose rebound speed
:math:`e_a |u_a^-|` is below ``zeno_velocity`` is plastic, so the constraint closes instead of
bouncing on. For a ball under gravity g this skips the remaining flights, whose heights are below
``zeno_velocity² / (2 g)`` (5.1e-12 m for the default 1e-5 m/s and g = 9.81 m/s²): that is the
largest height error it costs, before and after :math:`t_\infty`. When impacts pass from one
constraint to another (a table rocking on two feet), the constraints at contact that leave an
impact slower than ``zeno_velocity`` are captured: the velocity is projected onto their
:math:`u = 0` in the metric of M, which lowers the kinetic energy; the impulses of this capture
are of order :math:`m_\text{eff}` ``zeno_velocity`` and may be slightly adhesive.

Each :meth:`EventDriven.step` integrates exactly over :math:`[t_k, t_k + h]` with the torque
held, so :func:`ucontrol.simulate` runs it like Moreau–Jean; the step ``h`` is only the sampling
and control period. Its impulse is that of the step: impacts plus :math:`\int \lambda\,dt`;
its :attr:`~ucontrol.plant.StepOutcome.impacts` are the located times of the step's impacts
(the events at which a closing constraint gets an impulse), to solve_ivp's event accuracy.

**Frictional impacts.** A constraint with a friction coefficient has its impacts integrated
with Coulomb's law: alone at contact, by
:func:`~ucontrol.integrators.frictional_impact.frictional_impact` (Darboux–Keller) with its
restitution law on its normal and tangent rows (the step's impulse logs the normal part);
with other constraints at contact (a journal striking while the slider slides, a heel strike
with the stance foot down) and every law Newton's, by Newton's law with Coulomb friction at
impulse level (Moreau's impact law: :math:`0 \le P_n \perp u_n^+ + e u_n^- \ge 0`, Coulomb on
:math:`u_t^+`), solved by :func:`~ucontrol.integrators.friction_modes.friction_modes`; all
energetic and planar, by the LZB law with planar friction
(:func:`~ucontrol.integrators.lzb_impact.lzb_impact_with_friction`, no bilateral constraints);
otherwise :class:`InvalidParameterError`.

**Sustained friction.** A frictional constraint that stays closed slides or sticks (one
tangent: planar robots, ``planar_axis``, and clearance joints; point contacts against fixed
surfaces). At each event the acceleration-level problem with Coulomb friction is solved by
mode enumeration (:func:`~ucontrol.integrators.friction_modes.friction_modes`): stick
(:math:`\dot u_t = 0`, :math:`|\lambda_t| \le \mu\lambda_n`) or slip
(:math:`\lambda_t = -\mu\,\mathrm{sign}(u_t)\,\lambda_n`); no consistent mode is Painlevé's
inconsistency, a :class:`~ucontrol.exceptions.PainleveError`. Between events a sticking row is
held like a closed one and a slipping row adds its friction to its normal column; the events
are slip → stick or slip reversal (:math:`u_t` crosses 0), stick → slip (:math:`|\lambda_t|`
reaches :math:`\mu\lambda_n`), besides lift-off and impacts. 3D friction (two tangents),
collision shapes, sphere–sphere contacts and moving surfaces have no sustained friction: a
frictional constraint of theirs that stays closed raises :class:`IntegrationError`.

**Contacts that may not close.** A point contact with a scuffing rule (``closes_ahead_of``: a
walker's swing foot passes through the slope near mid-stance, ignored as in Garcia et al.
1998) is barred while its margin :math:`m = a \cdot (p_i - p_j)`
(:meth:`~ucontrol.contact.ConstraintSet.closure_margins`) is below -``rule_slack``, unless
it is closed (a held stance foot stays held). A barred contact has no gap event, so its
crossings of the surface are neither impacts nor closures; it has an event on m rising to 0
instead, at which its bar lifts, and an unbarred one an event on m falling to
-2 ``rule_slack``, at which the bar is set again. A contact whose bar lifts while it is below
its surface (:math:`g < 0`) is left out of the impact and active-set stages until its gap
event, the next crossing of :math:`g = 0` downwards: its strike is the crossing after the
lifting, the stride map's (:class:`~ucontrol.analysis.stance_flow.StanceFlow`).

**Energy ledger.** The friction work :math:`\int \lambda_t u_t\,dt` and the actuator work
:math:`\int \tau \cdot v\,dt` are integrated as extra states, and each impact's (and capture's)
kinetic-energy loss is added up: :attr:`EventDriven.ledger` (:class:`EnergyLedger`) closes
:math:`E(t) - E(0) = W_\tau + W_f - \Delta_\text{impacts}` to the integration's tolerance
(measured 6e-14 relative on the clearance slider-crank over 1 s, docs/clearance.md).

**Bilateral constraints.** With :attr:`~ucontrol.contact.ConstraintSet.bilateral` (loop
closures, joint couplings: rows :math:`J_b`, residual :math:`h(q)`) the bilateral rows are
held at acceleration level (index reduction), :math:`J_b \dot v + \dot J_b v = 0` with free
multipliers and no Baumgarte term, by eliminating them: every term of
:mod:`~ucontrol.integrators.smooth_dynamics` is that of the robot held by them (the
pseudo-inverse of :math:`D_b = J_b M^{-1} J_b^T`, so that dependent rows, a planar closure or
a closure declared twice, are handled). The impact, acceleration and capture problems of the
unilateral rows then use :math:`P J^T` with :math:`J_b P = 0`: an impact obeys Newton's law at
the unilateral rows and keeps :math:`J_b v^+ = 0`. The drift of the integration is removed by
the projection of stage 3, onto :math:`h(q) = 0`, :math:`J_b v = 0` together with the closed
unilateral constraints, at every event and at the end of every step (so the logged states lie
on the constraints to round-off).

**Moving surfaces.** Against surfaces with a prescribed motion
(:attr:`~ucontrol.contact.ConstraintSet.time_dependent`) gaps and normal velocities are
relative, :math:`g(q, t)` and :math:`u = J v + \partial g/\partial t`, evaluated at the
absolute time (the step starts at the evaluation's ``t``): the events are on the moving gap,
Newton's law acts on the relative velocity, and a closed contact's acceleration includes the
surface's, :math:`\dot u = J \dot v + \dot J v - n \cdot \ddot x(t)`.

**Flexible joints.** With :class:`~ucontrol.model.FlexibleJoints` the state holds the motor
coordinates after the link ones (:mod:`~ucontrol.integrators.smooth_dynamics`): the spring
torque enters the links' generalized force, and the impact LCP, the acceleration LCP and the
projection, taken in the metric of the block-diagonal inertia of links and motors, act on the
links only — an impact never changes the motor velocities. Stiff springs make the explicit
Runge–Kutta pairs take steps of about :math:`1/\omega = \sqrt{B/K}`: slow but exact (use
compliant's Radau, or Moreau–Jean, for very stiff ones).
"""

from __future__ import annotations

import dataclasses
import math
import time as time_module
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol._validation import as_in_interval, as_positive
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import (
    IntegrationError,
    InvalidParameterError,
    PainleveError,
    ShapeError,
    SolverError,
)
from ucontrol.integrators.friction_modes import (
    SLIP_NEGATIVE,
    SLIP_POSITIVE,
    STICK,
    friction_modes,
)
from ucontrol.integrators.frictional_impact import (
    FRICTIONAL_IMPACT_LAWS,
    check_restitution,
    frictional_impact,
)
from ucontrol.integrators.lzb_impact import LZBImpactLaw, lzb_impact_with_friction
from ucontrol.integrators.methods import IVP_METHODS
from ucontrol.integrators.smooth_dynamics import ConstraintTerms, SmoothDynamics
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel
from ucontrol.plant import PlantEvaluation, StepOutcome
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

Vector = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: The explicit Runge–Kutta methods of solve_ivp the integrator accepts.
METHODS = IVP_METHODS["event_driven"]

#: Consecutive events closer than this to their predecessor, in [s], count as a stall.
_STALL_TIME = 1e-14
#: Stalled events tolerated in a row before giving up.
_MAX_STALLS = 50
#: Position projection: Gauss–Newton iterations and the gap they aim at, in [m] or [rad].
_PROJECTION_ITERATIONS = 3
_PROJECTION_GAP = 1e-15


@dataclass(frozen=True)
class _Modes:
    """Tangential modes of the closed frictional constraints: stick, or slip along ``sign``."""

    stick: Mask  # shape (n,)
    sign: Vector  # slip direction ±1, 0 in stick or not closed, shape (n,)


@dataclass(frozen=True)
class EnergyLedger:
    r"""Work and losses of an :class:`EventDriven` integrator since its construction, in [J].

    The energy balance of a run from its first step reads
    :math:`E(t) - E(0) = W_\tau + W_f - \Delta_\text{impacts}` (:attr:`balance`), to the
    integration's tolerance, against fixed surfaces (a moving surface works on the robot) and
    without viscous joint friction (which it does not count).

    Attributes:
        actuator_work: :math:`\int \tau \cdot v\,dt` of the generalized forces held.
        friction_work: :math:`\int \lambda_t u_t\,dt` of sustained contacts (<= 0).
        impact_loss: Kinetic energy lost at impacts (:math:`T^- - T^+`, the frictional
            impulses included) and at the captures of the accumulation rule.
    """

    actuator_work: float = 0.0
    friction_work: float = 0.0
    impact_loss: float = 0.0

    @property
    def balance(self) -> float:
        r"""The energy change they account for, :math:`W_\tau + W_f - \Delta`, in [J]."""
        return self.actuator_work + self.friction_work - self.impact_loss


@dataclass(frozen=True)
class _Settled:
    """State after the impact, active-set and projection stages at an event."""

    q: Vector
    v: Vector
    closed: Mask
    impulse: Vector
    max_step: float
    solutions: list[ContactSolution]
    impacts: tuple[int, ...] = ()  # the constraints with an impact (closing, with an impulse)
    modes: _Modes | None = None  # tangential modes of the closed frictional constraints
    impact_loss: float = 0.0  # kinetic energy lost at the impact and capture, in [J]
    barred: Mask | None = None  # open constraints the scuffing rule bars from closing


@dataclass(frozen=True)
class _Segment:
    """End of one smooth integration segment."""

    q: Vector
    v: Vector
    impulse: Vector  # ∫ λ dt of the closed constraints, shape (m,)
    duration: float
    closing: Mask  # open constraints whose gap event fired
    releasing: Mask  # closed constraints whose multiplier event fired
    left_stick: Mask  # sticking constraints whose friction reached the cone
    stopped: Mask  # slipping constraints whose sliding velocity reached zero
    turned: Mask  # open constraints whose scuffing rule lifted or set its bar
    friction_work: float = 0.0  # ∫ λ_t u_t dt [J]
    actuator_work: float = 0.0  # ∫ τ·v dt [J]


class EventDriven:
    """Event-driven integrator of a robot under unilateral (and bilateral) constraints.

    Same protocol as :class:`ucontrol.integrators.MoreauJean`: :meth:`evaluate` at (q_k, v_k),
    then :meth:`step` with the generalized forces held over the step.

    Args:
        robot: The robot.
        constraints: Its unilateral constraints, and its bilateral ones in
            :attr:`~ucontrol.contact.ConstraintSet.bilateral`.
        dt: Step h in [s]: the sampling and zero-order-hold period, not an accuracy parameter.
        rtol: Relative tolerance of solve_ivp.
        atol: Absolute tolerance of solve_ivp, in the units of the state ([m], [rad], [m/s]...).
        method: ``"DOP853"`` or ``"RK45"``.
        zeno_velocity: Rebound speed in [m/s] (or [rad/s]) below which an impact is plastic.
        impact_solver: Velocity-level LCP solver; default a :class:`ProxsuiteLCPSolver`.
        acceleration_solver: Acceleration-level LCP solver; default a second one.
        max_events: Events allowed in one step before :class:`IntegrationError`.
        flexible: Flexible joints of the robot: the state then holds their motor coordinates.
        impact_law: The LZB impact law in place of Newton's, or None; with
            ``restitution_law = "energetic"`` the law of simultaneous impacts.
        restitution_law: ``"newton"``, ``"poisson"`` or ``"energetic"``, one for every
            constraint or one per constraint (shape (n,)): the law of an impact at a single
            constraint, its restitution then Poisson's or Stronge's coefficient
            (docs/impact_laws.md). Simultaneous impacts need one law among the constraints at
            contact: Newton's (generalized, or LZB's with ``impact_law`` and every law
            ``"newton"``) or the energetic one (LZB's ``impact_law``).
        tangential_restitution: Brach's e_t in [-1, 1], the option of Newton's law at the
            impacts of frictional constraints (:func:`frictional_impact`), or None.
        joint_friction: Viscous friction of the link coordinates, a smooth force
            (:mod:`~ucontrol.integrators.smooth_dynamics`); Coulomb friction is refused.

    Raises:
        InvalidParameterError: A bad setting, or ``joint_friction`` with a Coulomb part.
    """

    name = "event_driven"
    #: No θ: the value only weighs the actuator work over a step in run summaries.
    theta = 0.5
    #: A constraint within this gap, in [m] or [rad], is at contact.
    closure_gap = 1e-10
    #: A constraint at contact with a normal speed below this, in [m/s] or [rad/s], may close.
    closure_velocity = 1e-9
    #: A constraint at contact whose acceleration is below this, in [m/s²] or [rad/s²], closes.
    closure_acceleration = 1e-8
    #: Closed constraints whose multiplier starts below this, in [N] or [N m], get no release
    #: event (a release from zero force is caught by the next active-set solve).
    release_force = 1e-12
    #: A contact with a scuffing rule is barred once its margin is below minus this, in [m],
    #: and its bar is set again when the margin falls to minus twice this (a hysteresis, so
    #: that the located event leaves the contact on its new side).
    rule_slack = 1e-10

    def __init__(
        self,
        robot: RobotModel,
        constraints: ConstraintSet,
        *,
        dt: float,
        rtol: float = 1e-10,
        atol: float = 1e-12,
        method: str = "DOP853",
        zeno_velocity: float = 1e-5,
        impact_solver: ProxsuiteLCPSolver | None = None,
        acceleration_solver: ProxsuiteLCPSolver | None = None,
        max_events: int = 10_000,
        flexible: FlexibleJoints | None = None,
        impact_law: LZBImpactLaw | None = None,
        joint_friction: JointFriction | None = None,
        restitution_law: str | Sequence[str] = "newton",
        tangential_restitution: float | None = None,
    ) -> None:
        if method not in METHODS:
            raise InvalidParameterError("method", method, f"one of {list(METHODS)}")
        laws = (
            [restitution_law] * constraints.size
            if isinstance(restitution_law, str)
            else list(restitution_law)
        )
        if len(laws) != constraints.size:
            raise ShapeError("restitution_law", (constraints.size,), (len(laws),))
        for law, e in zip(laws, constraints.restitution, strict=True):
            if law not in FRICTIONAL_IMPACT_LAWS:
                raise InvalidParameterError(
                    "restitution_law", law, f"one of {FRICTIONAL_IMPACT_LAWS}"
                )
            check_restitution(law, e)
        self.restitution_law = np.array(laws)
        self.tangential_restitution = (
            None
            if tangential_restitution is None
            else as_in_interval("tangential_restitution", tangential_restitution, -1.0, 1.0)
        )
        self.robot = robot
        self.constraints = constraints
        self.flexible = flexible
        self.dt = as_positive("dt", dt)
        self.rtol = as_positive("rtol", rtol)
        self.atol = as_positive("atol", atol)
        self.method = method
        self.zeno_velocity = as_positive("zeno_velocity", zeno_velocity)
        self.max_events = int(as_positive("max_events", max_events))
        self.impact_solver = impact_solver if impact_solver is not None else ProxsuiteLCPSolver()
        self.acceleration_solver = (
            acceleration_solver if acceleration_solver is not None else ProxsuiteLCPSolver()
        )
        self.impact_law = impact_law
        # ``impact_law`` alone (every restitution law Newton's): LZB for every impact
        self._lzb_for_newton = impact_law is not None and bool(
            np.all(self.restitution_law == "newton")
        )
        self.joint_friction = joint_friction
        self._dynamics = SmoothDynamics(
            robot, constraints, flexible, joint_friction, integrator=self.name
        )
        self._n = constraints.size
        self._bilateral = constraints.bilateral is not None
        #: The contacts with a scuffing rule (``closes_ahead_of``), shape (n,).
        self._ruled = np.zeros(self._n, dtype=bool)
        self._ruled[: len(constraints.contacts)] = [
            bool(contact.closes_ahead_of) for contact in constraints.contacts
        ]
        self._carry: tuple[Vector, Vector, Mask, _Modes | None] | None = None
        #: Work and losses since construction (:class:`EnergyLedger`).
        self.ledger = EnergyLedger()

    def evaluate(self, q: Vector, v: Vector, t: float | None = None) -> PlantEvaluation:
        """Gaps, normal velocities and energies at (q, v) (at time t [s] with moving surfaces)."""
        return self._dynamics.evaluate(q, v, t)

    def step(self, state: PlantEvaluation, tau: Vector) -> StepOutcome:
        """Integrate over one step from ``state`` with ``tau`` held.

        Args:
            state: The evaluation at the start of the step.
            tau: Generalized forces (actuation plus external), shape (nv,), in [N m] or [N]
                (nv + nf with flexible joints: the motor torques last).

        Raises:
            IntegrationError: solve_ivp failed, the events stalled, more than
                ``max_events`` events fell in the step, or a frictional constraint without
                sustained friction (3D, collision shapes, moving surfaces) stays closed.
            PainleveError: No contact mode with Coulomb friction is consistent.
            InvalidParameterError: Simultaneous impacts the restitution laws do not cover
                (Poisson's or mixed laws; with friction, not all energetic or spatial).
            SolverError: An impact or acceleration LCP was not solved.
        """
        q, v, h = state.q, state.v, self.dt
        start = 0.0 if state.t is None else float(state.t)  # [s], absolute time of the step
        impulse = np.zeros(self._n)
        active = np.zeros(self._n, dtype=bool)
        closed, modes = self._carried_closed_set(q, v)
        none = np.zeros(self._n, dtype=bool)
        closing = releasing = left_stick = stopped = turned = none
        solutions: list[ContactSolution] = []
        impacts: list[tuple[int, float]] = []  # (constraint, absolute time [s])
        t, events, stalls = 0.0, 0, 0
        actuator_work = friction_work = impact_loss = 0.0  # [J]
        while True:
            settled = self._settle(
                q, v, tau, closed, closing, releasing, start + t, modes, left_stick, stopped
            )
            q, v, closed, modes = settled.q, settled.v, settled.closed, settled.modes
            impulse += settled.impulse
            impact_loss += settled.impact_loss
            active |= closed | (settled.impulse > 0.0)
            solutions += settled.solutions
            impacts += [(i, start + t) for i in settled.impacts]
            if h - t <= _STALL_TIME:
                break
            segment = self._integrate(
                q, v, tau, closed, modes, h - t, settled.max_step, start, t, settled.barred
            )
            q, v = segment.q, segment.v
            impulse[closed] += segment.impulse
            actuator_work += segment.actuator_work
            friction_work += segment.friction_work
            t += segment.duration
            closing, releasing = segment.closing, segment.releasing
            left_stick, stopped, turned = segment.left_stick, segment.stopped, segment.turned
            if not (closing | releasing | left_stick | stopped | turned).any():
                break
            events += 1
            stalls = stalls + 1 if segment.duration <= _STALL_TIME else 0
            if stalls > _MAX_STALLS:
                raise IntegrationError(
                    self.name,
                    start + t,
                    f"{stalls} events without the time advancing (constraints "
                    f"{self._names(closing | releasing | left_stick | stopped | turned)}): impacts "
                    f"accumulate faster than the time resolution (raise zeno_velocity = "
                    f"{self.zeno_velocity:g} m/s) or the active set chatters in a degenerate "
                    "configuration (use moreau_jean)",
                )
            if events > self.max_events:
                raise IntegrationError(
                    self.name,
                    start + t,
                    f"more than {self.max_events} events in one step of {h:g} s: an "
                    f"accumulation of impacts faster than zeno_velocity = "
                    f"{self.zeno_velocity:g} m/s catches; raise zeno_velocity or max_events",
                )
        if closed.any() or self._bilateral:  # the step's end on the constraint manifold
            q, v = self._project(q, v, closed, start + h, modes)
        self._carry = (q.copy(), v.copy(), closed.copy(), modes)
        self.ledger = EnergyLedger(
            actuator_work=self.ledger.actuator_work + actuator_work,
            friction_work=self.ledger.friction_work + friction_work,
            impact_loss=self.ledger.impact_loss + impact_loss,
        )
        worst = max(solutions, key=lambda solution: solution.residual, default=None)
        return StepOutcome(q, v, impulse, active, worst, events, impacts=tuple(impacts))

    def _carried_closed_set(self, q: Vector, v: Vector) -> tuple[Mask | None, _Modes | None]:
        """The closed set and modes the last step ended with, if this step continues it."""
        if self._carry is None:
            return None, None
        q_end, v_end, closed, modes = self._carry
        if np.array_equal(q, q_end) and np.array_equal(v, v_end):
            return closed, modes
        return None, None

    def _settle(
        self,
        q: Vector,
        v: Vector,
        tau: Vector,
        closed: Mask | None,
        closing: Mask,
        releasing: Mask,
        time: float,
        modes: _Modes | None = None,
        left_stick: Mask | None = None,
        stopped: Mask | None = None,
    ) -> _Settled:
        """Impact, active set and projection at an event (or at the start of a step).

        ``time`` is the absolute time in [s] (the moving surfaces' positions); ``modes`` the
        tangential modes before the event, ``left_stick`` and ``stopped`` the constraints
        whose friction events fired.
        """
        dynamics = self._dynamics
        gap, u = dynamics.kinematics(q, v, time)
        if closed is None:
            closed = (gap <= self.closure_gap) & (np.abs(u) <= self.closure_velocity)
        impulse = np.zeros(self._n)
        barred, submerged = self._scuffing(q, gap, closed | closing)
        near = (closed | closing | (gap <= self.closure_gap)) & ~(barred | submerged)
        if not near.any():
            if self._bilateral:
                q, v = self._project(q, v, near, time)
            return _Settled(q, v, near, impulse, math.inf, [], barred=barred)
        indices = np.flatnonzero(near)
        terms = dynamics.constraint_terms(q, v, tau, indices, t=time)
        u_near = u[indices]
        solutions = []
        impacts: tuple[int, ...] = ()
        loss = 0.0
        if np.any(u_near < -self.closure_velocity):
            kinetic = self._kinetic_energy(q, v, time)
            if self.constraints.friction[indices].any():
                solution, jump = self._frictional_impact(q, v, tau, terms, u_near, indices, time)
            else:
                solution = self._checked(self.impact_solver, self._impact(terms, u_near, indices))
                jump = terms.Minv_Jt @ solution.impulses
            solutions.append(solution)
            impulse[indices] = solution.impulses
            hit = (u_near < -self.closure_velocity) & (solution.impulses > 0.0)
            impacts = tuple(int(i) for i in indices[hit])
            v = v + jump
            v, capture = self._capture(terms, v)
            impulse[indices] += capture
            terms = dynamics.constraint_terms(q, v, tau, indices, t=time)
            u_near = terms.velocity(v)
            loss = kinetic - self._kinetic_energy(q, v, time)
        candidates = (np.abs(u_near) <= self.closure_velocity) & ~releasing[indices]
        closed = np.zeros(self._n, dtype=bool)
        new_modes = None
        if candidates.any():
            rows = np.flatnonzero(candidates)
            if self.constraints.friction[indices[rows]].any():
                closed, new_modes = self._frictional_modes(
                    q, v, tau, indices[rows], time, modes, left_stick, stopped
                )
            else:
                D = terms.delassus()[np.ix_(rows, rows)]
                solution = self._checked(
                    self.acceleration_solver,
                    self.acceleration_solver.solve(D, terms.acceleration_bias()[rows]),
                )
                solutions.append(solution)
                closed[indices[rows[solution.velocity <= self.closure_acceleration]]] = True
        if closed.any() or self._bilateral:
            q, v = self._project(q, v, closed, time, new_modes)
        return _Settled(
            q,
            v,
            closed,
            impulse,
            self._max_step(terms, u_near, closed[indices]),
            solutions,
            impacts,
            new_modes,
            loss,
            barred,
        )

    def _scuffing(self, q: Vector, gap: Vector, held: Mask) -> tuple[Mask, Mask]:
        """The contacts the scuffing rule bars at q, and those it let through under the surface.

        A contact with ``closes_ahead_of`` not in ``held`` (closed or closing) is barred while
        its margin (:meth:`~ucontrol.contact.ConstraintSet.closure_margins`) is below
        -``rule_slack``. Once its bar lifts, a contact still below its surface
        (g < -``closure_gap``: the swing foot passing through the slope) is left out too,
        until its gap event (g crossing 0 downwards) marks the strike. Both masks shape (n,).
        """
        none = np.zeros(self._n, dtype=bool)
        if not self._ruled.any():
            return none, none
        margins = self.constraints.closure_margins(q[: self.robot.nq])  # [m]
        free = self._ruled & ~held
        barred = free & (margins < -self.rule_slack)
        return barred, free & ~barred & (gap < -self.closure_gap)

    def _kinetic_energy(self, q: Vector, v: Vector, time: float) -> float:
        """The kinetic energy at (q, v) in [J] (motors included), at the absolute time [s]."""
        return float(self._dynamics.evaluate(q, v, time).kinetic_energy)

    def _frictional_modes(
        self,
        q: Vector,
        v: Vector,
        tau: Vector,
        candidates: NDArray[np.intp],
        time: float,
        modes: _Modes | None,
        left_stick: Mask | None,
        stopped: Mask | None,
    ) -> tuple[Mask, _Modes]:
        r"""Closed set and stick/slip modes of the constraints at rest, some frictional.

        The acceleration-level problem with planar Coulomb friction
        (:func:`~ucontrol.integrators.friction_modes.friction_modes`): a contact sliding
        (:math:`|u_t| >` ``closure_velocity``) keeps its direction; one whose stick just
        reached the cone slips, one whose slip just stopped sticks or slips back.

        Raises:
            IntegrationError: A frictional constraint at rest without sustained friction (3D
                friction, collision rows, sphere–sphere contacts, moving surfaces).
            PainleveError: No consistent mode.
        """
        constraints = self.constraints
        frictional = candidates[constraints.friction[candidates] > 0.0]
        unsupported = [int(i) for i in frictional if not constraints.sustains_friction(int(i))]
        if unsupported:
            mask = np.isin(np.arange(self._n), unsupported)
            raise IntegrationError(
                self.name,
                time,
                f"constraints {self._names(mask)} with friction stay at contact: event_driven's "
                "sustained friction covers one tangent (planar robots, planar_axis) at point "
                "contacts against fixed surfaces and clearance joints; 3D friction (two "
                "tangents), collision shapes, sphere–sphere contacts and moving surfaces have "
                "no sliding or sticking phases here (use moreau_jean)",
            )
        terms = self._dynamics.constraint_terms(q, v, tau, candidates, t=time, tangents=frictional)
        rows = np.vstack((terms.J, terms.T))
        W = rows @ np.hstack((terms.Minv_Jt, terms.Minv_Tt))
        b = np.concatenate((terms.acceleration_bias(), terms.T @ terms.a_free + terms.drift_t))
        u_t = terms.T @ v
        sliding = np.abs(u_t) > self.closure_velocity
        allowed = np.ones((frictional.size, 3), dtype=bool)
        allowed[sliding] = False
        allowed[sliding, np.where(u_t[sliding] > 0.0, SLIP_POSITIVE, SLIP_NEGATIVE)] = True
        if left_stick is not None:
            allowed[left_stick[frictional] & ~sliding, STICK] = False
        if stopped is not None and modes is not None:
            for r in np.flatnonzero(stopped[frictional] & ~sliding):
                previous = modes.sign[frictional[r]]
                allowed[r, SLIP_POSITIVE if previous > 0.0 else SLIP_NEGATIVE] = False
        try:
            found = friction_modes(
                W,
                b,
                constraints.friction[frictional],
                np.searchsorted(candidates, frictional),
                allowed,
                sliding,
                value_tolerance=self.closure_acceleration,
            )
        except PainleveError as error:
            raise PainleveError(self.name, time, error.reason) from None
        closed = np.zeros(self._n, dtype=bool)
        closed[candidates[found.closed]] = True
        stick = np.zeros(self._n, dtype=bool)
        stick[frictional[found.stick]] = True
        sign = np.zeros(self._n)
        sign[frictional] = found.sign
        return closed, _Modes(stick, sign)

    def _impact(
        self, terms: ConstraintTerms, u_minus: Vector, indices: NDArray[np.intp]
    ) -> ContactSolution:
        """Impulses of the impact law (Newton's, or LZB's) on the constraints at contact.

        A rebound slower than ``zeno_velocity`` is plastic under either law (the accumulation
        rule of the module docstring).
        """
        restitution = self.constraints.restitution[indices]
        laws = self.restitution_law[indices]
        if indices.size == 1 and laws[0] != "newton":
            return self._single_impact(terms, u_minus, restitution, str(laws[0]))
        newton = bool(np.all(laws == "newton"))
        if not (newton or (np.all(laws == "energetic") and self.impact_law is not None)):
            raise InvalidParameterError(
                "restitution_law",
                sorted(set(laws.tolist())),
                f"one law for simultaneous impacts, 'newton' or 'energetic' (constraints "
                f"{self._names(np.isin(np.arange(self._n), indices))} at contact together): "
                "Poisson's law and mixed laws are provided for a single contact only",
            )
        if self.impact_law is not None and (not newton or self._lzb_for_newton):
            law = self.impact_law.select(indices)
            if np.max(-restitution * u_minus) < self.zeno_velocity:  # an accumulation: plastic
                law = dataclasses.replace(law, restitution=np.zeros(indices.size))
            start = time_module.perf_counter()
            result = law.solve_contact_space(terms.delassus(), u_minus)
            elapsed = time_module.perf_counter() - start
            return ContactSolution(result.impulse, result.u, "solved", result.steps, 0.0, elapsed)
        bounces = (u_minus < 0.0) & (-restitution * u_minus >= self.zeno_velocity)
        e = np.where(bounces, restitution, 0.0)
        return self.impact_solver.solve(terms.delassus(), (1.0 + e) * u_minus)

    def _frictional_impact(
        self,
        q: Vector,
        v: Vector,
        tau: Vector,
        terms: ConstraintTerms,
        u_minus: Vector,
        indices: NDArray[np.intp],
        time: float,
    ) -> tuple[ContactSolution, Vector]:
        """Impulse and velocity jump of an impact at constraints, some with Coulomb friction.

        One constraint at contact: Darboux–Keller integration (:func:`frictional_impact`) with
        its law. Several, every law Newton's without tangential restitution and one tangent
        each: Newton's law with Coulomb friction at impulse level (:meth:`_coulomb_impact`).
        Several, all energetic: the LZB law with planar friction
        (:func:`lzb_impact_with_friction`). The rows are those of the robot held by its
        bilateral constraints.

        Raises:
            InvalidParameterError: Several constraints at contact together, one with friction,
                and none of the cases above.
        """
        if indices.size > 1:
            laws = self.restitution_law[indices]
            if (
                np.all(laws == "newton")
                and self.tangential_restitution is None
                and np.all(self.constraints.tangent_count[indices] <= 1)
            ):
                return self._coulomb_impact(q, v, tau, u_minus, indices, time)
            return self._lzb_frictional_impact(v, terms, u_minus, indices)
        index = int(indices[0])
        full = self._dynamics.constraint_terms(
            q, v, tau, indices, with_drift=False, t=time, tangents=indices
        )
        H = np.vstack((full.J, full.T))
        Minv_Ht = np.hstack((full.Minv_Jt, full.Minv_Tt))
        W = np.zeros((3, 3))
        W[: H.shape[0], : H.shape[0]] = H @ Minv_Ht
        u = np.zeros(3)
        u[: H.shape[0]] = np.concatenate((u_minus, full.T @ v))
        e = float(self.constraints.restitution[index])
        law = str(self.restitution_law[index])
        if -e * u_minus[0] < self.zeno_velocity:  # an accumulation: plastic
            e = 0.0
        start = time_module.perf_counter()
        result = frictional_impact(
            W,
            u,
            friction=float(self.constraints.friction[index]),
            restitution=e,
            law=law,
            tangential_restitution=self.tangential_restitution if law == "newton" else None,
        )
        elapsed = time_module.perf_counter() - start
        solution = ContactSolution(result.impulse[:1], result.u[:1], "solved", 1, 0.0, elapsed)
        return solution, Minv_Ht @ result.impulse[: H.shape[0]]

    def _coulomb_impact(
        self,
        q: Vector,
        v: Vector,
        tau: Vector,
        u_minus: Vector,
        indices: NDArray[np.intp],
        time: float,
    ) -> tuple[ContactSolution, Vector]:
        r"""Simultaneous impacts under Newton's law with planar Coulomb friction.

        The impulse problem of :func:`~ucontrol.integrators.friction_modes.friction_modes`:
        :math:`0 \le P_n \perp u_n^+ + e\,u_n^- \ge 0` (e zero for constraints not
        approaching or below ``zeno_velocity``) and Coulomb's law on :math:`u_t^+` (stick,
        or slip opposite to it), Moreau's impact law with friction.

        Raises:
            PainleveError: No consistent mode.
        """
        constraints = self.constraints
        frictional = indices[constraints.tangent_count[indices] == 1]
        full = self._dynamics.constraint_terms(
            q, v, tau, indices, with_drift=False, t=time, tangents=frictional
        )
        H = np.vstack((full.J, full.T))
        Minv_Ht = np.hstack((full.Minv_Jt, full.Minv_Tt))
        restitution = constraints.restitution[indices]
        bounces = (u_minus < 0.0) & (-restitution * u_minus >= self.zeno_velocity)
        e = np.where(bounces, restitution, 0.0)
        b = np.concatenate(((1.0 + e) * u_minus, full.T @ v))
        start = time_module.perf_counter()
        try:
            found = friction_modes(
                H @ Minv_Ht,
                b,
                constraints.friction[frictional],
                np.searchsorted(indices, frictional),
                np.ones((frictional.size, 3), dtype=bool),
                np.zeros(frictional.size, dtype=bool),
                value_tolerance=self.closure_velocity,
            )
        except PainleveError as error:
            raise PainleveError(self.name, time, error.reason) from None
        elapsed = time_module.perf_counter() - start
        P = np.concatenate((found.lambda_n, found.lambda_t))  # [N s]
        u_plus = full.J @ (v + Minv_Ht @ P)
        solution = ContactSolution(found.lambda_n, u_plus, "solved", 1, 0.0, elapsed)
        return solution, Minv_Ht @ P

    def _lzb_frictional_impact(
        self, v: Vector, terms: ConstraintTerms, u_minus: Vector, indices: NDArray[np.intp]
    ) -> tuple[ContactSolution, Vector]:
        """Simultaneous impacts with friction: the LZB law with one tangent per contact."""
        names = self._names(np.isin(np.arange(self._n), indices))
        if self._bilateral:
            raise InvalidParameterError(
                "restitution_law",
                sorted(set(self.restitution_law[indices].tolist())),
                f"'newton' at simultaneous frictional impacts with bilateral constraints "
                f"(constraints {names} at contact together): the LZB law with friction is "
                "not provided for a robot held by bilateral constraints",
            )
        if self.impact_law is None or not np.all(self.restitution_law[indices] == "energetic"):
            raise InvalidParameterError(
                "restitution_law",
                sorted(set(self.restitution_law[indices].tolist())),
                f"'energetic' at simultaneous impacts with friction (constraints {names} at "
                "contact together): only the LZB law takes them",
            )
        if np.any(self.constraints.tangent_count[indices] > 1):
            raise InvalidParameterError(
                "[[contacts]] friction",
                self.constraints.friction[indices].tolist(),
                f"0 at simultaneous impacts of a spatial robot (constraints {names} at contact "
                "together): the LZB law with 3D friction (two tangents per contact) is not "
                "provided; a planar robot (planar_axis) has it",
            )
        dynamics = self._dynamics
        nv = dynamics.model.nv
        M = np.triu(dynamics.data.M) + np.triu(dynamics.data.M, 1).T
        frictional = indices[self.constraints.tangent_count[indices] == 1]
        rows, _ = self.constraints.tangent_rows(dynamics.data, frictional)
        J_t = np.zeros((indices.size, nv))
        J_t[np.isin(indices, frictional)] = rows
        law = self.impact_law.select(indices)
        if np.max(-self.constraints.restitution[indices] * u_minus) < self.zeno_velocity:
            law = dataclasses.replace(law, restitution=np.zeros(indices.size))
        start = time_module.perf_counter()
        result = lzb_impact_with_friction(
            law, M, terms.J[:, :nv], J_t, v[:nv], self.constraints.friction[indices]
        )
        elapsed = time_module.perf_counter() - start
        solution = ContactSolution(result.impulse, result.u, "solved", result.steps, 0.0, elapsed)
        jump = np.zeros(v.size)
        jump[:nv] = result.v - v[:nv]  # motor coordinates: untouched
        return solution, jump

    def _single_impact(
        self, terms: ConstraintTerms, u_minus: Vector, restitution: Vector, law: str
    ) -> ContactSolution:
        """The impulse of Poisson's or the energetic ``law`` at one frictionless constraint."""
        e = float(restitution[0]) if -restitution[0] * u_minus[0] >= self.zeno_velocity else 0.0
        W = np.zeros((3, 3))
        W[0, 0] = terms.delassus()[0, 0]
        start = time_module.perf_counter()
        result = frictional_impact(W, [u_minus[0], 0.0, 0.0], friction=0.0, restitution=e, law=law)
        elapsed = time_module.perf_counter() - start
        return ContactSolution(result.impulse[:1], result.u[:1], "solved", 1, 0.0, elapsed)

    def _capture(self, terms: ConstraintTerms, v: Vector) -> tuple[Vector, Vector]:
        """Stop the constraints at contact that leave an impact slower than ``zeno_velocity``.

        The velocity is projected, in the metric of M, onto ``u = 0`` for them and for those
        at rest, adding any constraint the projection sets approaching; the projection lowers
        the kinetic energy, and its impulses (shape (m,)) are of order m_eff zeno_velocity,
        possibly slightly adhesive. This ends accumulations where impacts pass from one
        constraint to another (a rocking table) as the plastic threshold ends a ball's.
        """
        u = terms.velocity(v)
        slow = (u > self.closure_velocity) & (u < self.zeno_velocity)
        impulse = np.zeros(u.size)
        if not slow.any():
            return v, impulse
        captured = slow | (np.abs(u) <= self.closure_velocity)
        while True:
            rows = np.flatnonzero(captured)
            D = terms.delassus()[np.ix_(rows, rows)]
            step = -_solve(D, u[rows])  # [N s]
            impulse[rows] += step
            v = v + terms.Minv_Jt[:, rows] @ step
            u = terms.velocity(v)
            approaching = ~captured & (u < -self.closure_velocity)
            if not approaching.any():
                return v, impulse
            captured |= approaching

    @staticmethod
    def _checked(solver: ProxsuiteLCPSolver, solution: ContactSolution) -> ContactSolution:
        """``solution``, or :class:`SolverError` when the solver did not solve its LCP."""
        if solution.status != "solved":
            raise SolverError(solver.name, solution.status, solution.residual)
        return solution

    def _project(
        self, q: Vector, v: Vector, closed: Mask, time: float, modes: _Modes | None = None
    ) -> tuple[Vector, Vector]:
        r"""Project (q, v) onto the closed and bilateral constraints in the metric of M.

        Gauss–Newton steps :math:`q \leftarrow q \ominus M^{-1} J^T D^+ r` on the stacked
        residuals r (closed gaps, then :math:`h(q)`), then :math:`v \leftarrow v - M^{-1} J^T
        D^+ (J v + \partial g/\partial t)`, at the absolute ``time`` [s]; the tangential rows
        of the sticking constraints of ``modes`` join the velocity rows (:math:`u_t = 0`).
        """
        dynamics = self._dynamics
        indices = np.flatnonzero(closed)
        for _ in range(_PROJECTION_ITERATIONS):
            terms = dynamics.manifold_terms(q, v, indices, time)
            if terms.residual.size == 0 or np.max(np.abs(terms.residual)) <= _PROJECTION_GAP:
                break
            q = dynamics.configuration(q, -terms.Minv_Jt @ _solve(terms.delassus(), terms.residual))
        else:
            terms = dynamics.manifold_terms(q, v, indices, time)
        J, Minv_Jt, velocity = terms.J, terms.Minv_Jt, terms.velocity
        if modes is not None and modes.stick.any():  # (manifold_terms left data at q)
            sticking = np.flatnonzero(modes.stick)
            rows = self.constraints.tangent_rows(dynamics.data, sticking)[0]
            nv = rows.shape[1]
            Minv_rows = np.zeros((Minv_Jt.shape[0], rows.shape[0]))
            for k, row in enumerate(rows):
                Minv_rows[:nv, k] = pin.cholesky.solve(dynamics.model, dynamics.data, row)
            rows = np.hstack((rows, np.zeros((rows.shape[0], J.shape[1] - nv))))
            J = np.vstack((J, rows))
            Minv_Jt = np.hstack((Minv_Jt, Minv_rows))
            velocity = np.concatenate((velocity, rows @ v))
        if velocity.size:
            v = v - Minv_Jt @ _solve(J @ Minv_Jt, velocity)
        return q, v

    def _max_step(self, terms: ConstraintTerms, u_near: Vector, closed_near: Mask) -> float:
        """A quarter of the shortest flight of a constraint leaving contact, in [s].

        Keeps solve_ivp from stepping over a whole flight, whose landing event it would miss.
        """
        acceleration = terms.acceleration_bias()
        flying = ~closed_near & (u_near > self.closure_velocity) & (acceleration < 0.0)
        if not flying.any():
            return math.inf
        return float(np.min(0.5 * u_near[flying] / -acceleration[flying]))

    def _integrate(
        self,
        q0: Vector,
        v0: Vector,
        tau: Vector,
        closed: Mask,
        modes: _Modes | None,
        duration: float,
        max_step: float,
        start: float,
        t_start: float,
        barred: Mask | None = None,
    ) -> _Segment:
        r"""Integrate with the closed set and modes fixed until ``duration`` [s] or an event.

        ``start + t_start`` is the absolute time in [s] of the segment's start (``start`` that
        of the step).

        The gap event of an open constraint resting on its surface (g and u within the
        closure tolerances: it just released, or its acceleration barely opened it) fires at
        g = -closure_gap rather than at g = 0, which it starts on: it marks the constraint
        coming back, not its start. The next active-set solve and projection then close it.

        A closed frictional constraint in stick holds :math:`\dot u_t = 0` with a free
        multiplier :math:`\lambda_t` (events :math:`\mu \lambda_n \mp \lambda_t = 0`); one
        in slip along s gets :math:`\lambda_t = -\mu s \lambda_n` in its normal column
        (event :math:`s u_t = 0`, at :math:`-` ``closure_velocity`` when it starts from rest).
        The state carries :math:`\int \lambda_n dt`, :math:`\int \lambda_t u_t dt` and
        :math:`\int \tau \cdot v\,dt`.

        An open contact with a scuffing rule that ``barred`` (n,) bars has no gap event but an
        event on its margin m rising to 0 (the bar lifts); an unbarred one has its gap event
        and one on m falling to -2 ``rule_slack`` (the bar is set again).
        """
        dynamics, nv = self._dynamics, self._dynamics.nv
        closed_indices = np.flatnonzero(closed)
        open_indices = np.flatnonzero(~closed)
        m = closed_indices.size
        origin = start + t_start  # [s]
        gap0, u0 = dynamics.kinematics(q0, v0, origin)
        resting = (gap0 <= self.closure_gap) & (np.abs(u0) <= self.closure_velocity)
        offsets = np.where(resting, self.closure_gap, 0.0)[open_indices]  # [m] or [rad]
        frictional = closed_indices[self.constraints.friction[closed_indices] > 0.0]
        k = frictional.size
        stick = modes.stick[frictional] if modes is not None else np.zeros(k, dtype=bool)
        sign = modes.sign[frictional] if modes is not None else np.zeros(k)
        mu_s = self.constraints.friction[frictional] * sign  # μ s of the slipping rows
        owner = np.searchsorted(closed_indices, frictional)
        sticking = np.flatnonzero(stick)
        slipping = np.flatnonzero(~stick)
        tangents = frictional if k else None
        slip_offsets = np.zeros(slipping.size)  # [m/s]
        barred = np.zeros(self._n, dtype=bool) if barred is None else barred
        ruled = open_indices[self._ruled[open_indices]]
        lifting = barred[ruled]
        rule_sign = np.where(lifting, -1.0, 1.0)  # events on -m (barred) or m + 2 slack
        rule_offset = np.where(lifting, 0.0, 2.0 * self.rule_slack)  # [m]
        link_nq = self.robot.nq
        cache: dict[str, Any] = {"key": None}

        def evaluate(t: float, y: Vector) -> tuple[Vector, Vector]:
            key = (t, y.tobytes())
            if cache["key"] != key:
                dq, v = y[:nv], y[nv : 2 * nv]
                q = dynamics.configuration(q0, dq)
                friction_power = 0.0  # [W]
                margins = np.zeros(0)
                if m or self._bilateral:
                    terms = dynamics.constraint_terms(
                        q, v, tau, closed_indices, t=origin + t, tangents=tangents
                    )
                    if k:
                        forces = terms.Minv_Jt.copy()  # the slipping rows' friction joins
                        forces[:, owner[slipping]] -= terms.Minv_Tt[:, slipping] * mu_s[slipping]
                        G = np.hstack((forces, terms.Minv_Tt[:, sticking]))
                        A = np.vstack((terms.J, terms.T[sticking]))
                        bias = np.concatenate(
                            (
                                terms.acceleration_bias(),
                                terms.T[sticking] @ terms.a_free + terms.drift_t[sticking],
                            )
                        )
                        x = _solve(A @ G, -bias)
                        multipliers = x[:m]
                        lambda_t = -mu_s * multipliers[owner]
                        lambda_t[sticking] = x[m:]
                        u_t = terms.T @ v
                        friction_power = float(lambda_t @ u_t)
                        cone = self.constraints.friction[frictional] * multipliers[owner]
                        margins = np.concatenate(
                            (
                                cone[sticking] - lambda_t[sticking],
                                cone[sticking] + lambda_t[sticking],
                                sign[slipping] * u_t[slipping] + slip_offsets,
                            )
                        )
                        acceleration = terms.a_free + G @ x
                    else:
                        multipliers = (
                            _solve(terms.delassus(), -terms.acceleration_bias())
                            if m
                            else np.zeros(0)
                        )
                        acceleration = terms.a_free + terms.Minv_Jt @ multipliers
                    gap = terms.gap
                else:
                    multipliers = np.zeros(0)
                    gap, _ = dynamics.kinematics(q, v, origin + t)
                    acceleration = dynamics.free_acceleration(q, v, tau)
                rules = np.zeros(0)
                if ruled.size:
                    rules = rule_sign * self.constraints.closure_margins(q[:link_nq])[ruled]
                    rules += rule_offset
                rate = np.concatenate(
                    (
                        dynamics.chart_rate(q0, dq, v),
                        acceleration,
                        multipliers,
                        [friction_power, float(tau @ v)],
                    )
                )
                cache["key"] = key
                cache["value"] = (
                    rate,
                    np.concatenate((gap[open_indices] + offsets, multipliers, margins, rules)),
                )
            value: tuple[Vector, Vector] = cache["value"]
            return value

        y0 = np.concatenate((np.zeros(nv), v0, np.zeros(m + 2)))
        initial = evaluate(0.0, y0)[1]
        slip_start = open_indices.size + m + 2 * sticking.size
        at_rest = np.abs(initial[slip_start : slip_start + slipping.size]) <= (
            self.closure_velocity
        )
        slip_offsets[at_rest] = self.closure_velocity  # s u_t starts at 0: fire at -ε
        cache["key"] = None
        initial = evaluate(0.0, y0)[1]
        watched = np.concatenate(
            (
                ~barred[open_indices],
                initial[open_indices.size : open_indices.size + m + 2 * sticking.size]
                > self.release_force,
                np.ones(slipping.size + ruled.size, dtype=bool),
            )
        )
        events = [_event(evaluate, int(j)) for j in np.flatnonzero(watched)]
        solution = solve_ivp(
            lambda t, y: evaluate(t, y)[0],
            (0.0, duration),
            y0,
            method=self.method,
            rtol=self.rtol,
            atol=self.atol,
            events=events or None,
            max_step=max_step,
            first_step=min(duration, max_step),
        )
        if solution.status < 0:
            raise IntegrationError(self.name, origin + float(solution.t[-1]), solution.message)
        y = solution.y[:, -1]
        fired = np.zeros(watched.size, dtype=bool)
        if solution.status == 1:
            watched_indices = np.flatnonzero(watched)
            for j, times in enumerate(solution.t_events):
                fired[watched_indices[j]] = times.size > 0
        closing = np.zeros(self._n, dtype=bool)
        releasing = np.zeros(self._n, dtype=bool)
        left_stick = np.zeros(self._n, dtype=bool)
        stopped = np.zeros(self._n, dtype=bool)
        turned = np.zeros(self._n, dtype=bool)
        n_open, n_stick = open_indices.size, sticking.size
        closing[open_indices[fired[:n_open]]] = True
        releasing[closed_indices[fired[n_open : n_open + m]]] = True
        cone_fired = fired[n_open + m : n_open + m + 2 * n_stick]
        left_stick[frictional[sticking[cone_fired[:n_stick] | cone_fired[n_stick:]]]] = True
        slip_end = slip_start + slipping.size
        stopped[frictional[slipping[fired[slip_start:slip_end]]]] = True
        turned[ruled[fired[slip_end:]]] = True
        return _Segment(
            q=dynamics.configuration(q0, y[:nv]),
            v=y[nv : 2 * nv].copy(),
            impulse=y[2 * nv : 2 * nv + m].copy(),
            duration=float(solution.t[-1]),
            closing=closing,
            releasing=releasing,
            left_stick=left_stick,
            stopped=stopped,
            turned=turned,
            friction_work=float(y[-2]),
            actuator_work=float(y[-1]),
        )

    def _names(self, mask: Mask) -> list[str]:
        return [self.constraints.names[i] for i in np.flatnonzero(mask)]


def _event(evaluate: Any, k: int) -> Any:
    """Terminal event function on entry ``k`` of the event values, crossing downwards."""

    def event(t: float, y: Vector) -> float:
        return float(evaluate(t, y)[1][k])

    event.terminal = True  # type: ignore[attr-defined]
    event.direction = -1.0  # type: ignore[attr-defined]
    return event


def _solve(D: Vector, rhs: Vector) -> Vector:
    """``D x = rhs`` for a Delassus matrix D (m, m); least squares when D is singular."""
    if rhs.size == 1:
        return rhs / D[0, 0]
    return np.asarray(np.linalg.lstsq(D, rhs, rcond=1e-12)[0], dtype=np.float64)
