r"""Event-driven integration (the accuracy reference), frictionless between impacts.

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

**Frictional impacts.** A constraint with a friction coefficient and the ``"poisson"`` or
``"energetic"`` restitution law has its impacts integrated with Coulomb's law by
:func:`~ucontrol.integrators.frictional_impact.frictional_impact` on its normal and tangent rows
(the step's impulse logs the normal part). There are no sliding or sticking phases between
impacts: a frictional constraint that stays closed raises :class:`IntegrationError`. An
impact at several constraints, one frictional, takes the LZB law with planar friction
(:func:`~ucontrol.integrators.lzb_impact.lzb_impact_with_friction`) when all are energetic and
the robot planar, and raises :class:`InvalidParameterError` otherwise. Fixed surfaces and no
bilateral constraints (the scene builder checks both).

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
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol._validation import as_in_interval, as_positive
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import IntegrationError, InvalidParameterError, ShapeError, SolverError
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
class _Settled:
    """State after the impact, active-set and projection stages at an event."""

    q: Vector
    v: Vector
    closed: Mask
    impulse: Vector
    max_step: float
    solutions: list[ContactSolution]
    impacts: tuple[int, ...] = ()  # the constraints with an impact (closing, with an impulse)


@dataclass(frozen=True)
class _Segment:
    """End of one smooth integration segment."""

    q: Vector
    v: Vector
    impulse: Vector  # ∫ λ dt of the closed constraints, shape (m,)
    duration: float
    closing: Mask  # open constraints whose gap event fired
    releasing: Mask  # closed constraints whose multiplier event fired


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
        self._carry: tuple[Vector, Vector, Mask] | None = None

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
                ``max_events`` events fell in the step, or a frictional constraint stays
                closed (no sliding or sticking phases).
            InvalidParameterError: Simultaneous impacts the restitution laws do not cover
                (Poisson's or mixed laws; with friction, not all energetic or spatial).
            SolverError: An impact or acceleration LCP was not solved.
        """
        q, v, h = state.q, state.v, self.dt
        start = 0.0 if state.t is None else float(state.t)  # [s], absolute time of the step
        impulse = np.zeros(self._n)
        active = np.zeros(self._n, dtype=bool)
        closed = self._carried_closed_set(q, v)
        closing = releasing = np.zeros(self._n, dtype=bool)
        solutions: list[ContactSolution] = []
        impacts: list[tuple[int, float]] = []  # (constraint, absolute time [s])
        t, events, stalls = 0.0, 0, 0
        while True:
            settled = self._settle(q, v, tau, closed, closing, releasing, start + t)
            q, v, closed = settled.q, settled.v, settled.closed
            impulse += settled.impulse
            active |= closed | (settled.impulse > 0.0)
            solutions += settled.solutions
            impacts += [(i, start + t) for i in settled.impacts]
            if h - t <= _STALL_TIME:
                break
            segment = self._integrate(q, v, tau, closed, h - t, settled.max_step, start, t)
            q, v = segment.q, segment.v
            impulse[closed] += segment.impulse
            t += segment.duration
            closing, releasing = segment.closing, segment.releasing
            if not (closing.any() or releasing.any()):
                break
            events += 1
            stalls = stalls + 1 if segment.duration <= _STALL_TIME else 0
            if stalls > _MAX_STALLS:
                raise IntegrationError(
                    self.name,
                    start + t,
                    f"{stalls} events without the time advancing (constraints "
                    f"{self._names(closing | releasing)}): impacts accumulate faster than the "
                    f"time resolution (raise zeno_velocity = {self.zeno_velocity:g} m/s) or the "
                    "active set chatters in a degenerate configuration (use moreau_jean)",
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
            q, v = self._project(q, v, closed, start + h)
        self._carry = (q.copy(), v.copy(), closed.copy())
        worst = max(solutions, key=lambda solution: solution.residual, default=None)
        return StepOutcome(q, v, impulse, active, worst, events, impacts=tuple(impacts))

    def _carried_closed_set(self, q: Vector, v: Vector) -> Mask | None:
        """The closed set the last step ended with, if this step continues it exactly."""
        if self._carry is None:
            return None
        q_end, v_end, closed = self._carry
        if np.array_equal(q, q_end) and np.array_equal(v, v_end):
            return closed
        return None

    def _settle(
        self,
        q: Vector,
        v: Vector,
        tau: Vector,
        closed: Mask | None,
        closing: Mask,
        releasing: Mask,
        time: float,
    ) -> _Settled:
        """Impact, active set and projection at an event (or at the start of a step).

        ``time`` is the absolute time in [s] (the moving surfaces' positions).
        """
        dynamics = self._dynamics
        gap, u = dynamics.kinematics(q, v, time)
        if closed is None:
            closed = (gap <= self.closure_gap) & (np.abs(u) <= self.closure_velocity)
        impulse = np.zeros(self._n)
        near = closed | closing | (gap <= self.closure_gap)
        if not near.any():
            if self._bilateral:
                q, v = self._project(q, v, near, time)
            return _Settled(q, v, near, impulse, math.inf, [])
        indices = np.flatnonzero(near)
        terms = dynamics.constraint_terms(q, v, tau, indices, t=time)
        u_near = u[indices]
        solutions = []
        impacts: tuple[int, ...] = ()
        if np.any(u_near < -self.closure_velocity):
            if self.constraints.friction[indices].any():
                solution, jump = self._frictional_impact(v, terms, u_near, indices)
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
        candidates = (np.abs(u_near) <= self.closure_velocity) & ~releasing[indices]
        closed = np.zeros(self._n, dtype=bool)
        if candidates.any():
            rows = np.flatnonzero(candidates)
            D = terms.delassus()[np.ix_(rows, rows)]
            solution = self._checked(
                self.acceleration_solver,
                self.acceleration_solver.solve(D, terms.acceleration_bias()[rows]),
            )
            solutions.append(solution)
            closed[indices[rows[solution.velocity <= self.closure_acceleration]]] = True
        if (closed & (self.constraints.friction > 0.0)).any():
            raise IntegrationError(
                self.name,
                time,
                f"constraints {self._names(closed & (self.constraints.friction > 0.0))} with "
                "friction stay at contact: event_driven applies frictional impact laws but has "
                "no sliding or sticking phases between impacts (use moreau_jean)",
            )
        if closed.any() or self._bilateral:
            q, v = self._project(q, v, closed, time)
        return _Settled(
            q,
            v,
            closed,
            impulse,
            self._max_step(terms, u_near, closed[indices]),
            solutions,
            impacts,
        )

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
            start = time.perf_counter()
            result = law.solve_contact_space(terms.delassus(), u_minus)
            elapsed = time.perf_counter() - start
            return ContactSolution(result.impulse, result.u, "solved", result.steps, 0.0, elapsed)
        bounces = (u_minus < 0.0) & (-restitution * u_minus >= self.zeno_velocity)
        e = np.where(bounces, restitution, 0.0)
        return self.impact_solver.solve(terms.delassus(), (1.0 + e) * u_minus)

    def _frictional_impact(
        self, v: Vector, terms: ConstraintTerms, u_minus: Vector, indices: NDArray[np.intp]
    ) -> tuple[ContactSolution, Vector]:
        """Impulse and velocity jump of an impact at one constraint with Coulomb friction.

        Darboux–Keller integration (:func:`frictional_impact`) with the constraint's law; the
        pinocchio data hold the configuration of ``terms``.

        Several constraints at contact together take the LZB law with planar friction
        (:func:`lzb_impact_with_friction`) when every law among them is the energetic one.

        Raises:
            InvalidParameterError: Several constraints at contact together, one with friction,
                and not all energetic, or with two tangents (3D friction: not provided).
        """
        if indices.size > 1:
            return self._lzb_frictional_impact(v, terms, u_minus, indices)
        index = int(indices[0])
        dynamics = self._dynamics
        rows, _ = self.constraints.tangent_rows(dynamics.data, indices)
        Minv_rows = np.column_stack(
            [pin.cholesky.solve(dynamics.model, dynamics.data, row) for row in rows]
        )
        pad = terms.Minv_Jt.shape[0] - Minv_rows.shape[0]  # motor coordinates: untouched
        Minv_Ht = np.hstack((terms.Minv_Jt, np.vstack((Minv_rows, np.zeros((pad, rows.shape[0]))))))
        H = np.vstack((terms.J[:, : rows.shape[1]], rows))
        W = np.zeros((3, 3))
        W[: H.shape[0], : H.shape[0]] = H @ Minv_Ht[: H.shape[1]]
        u = np.zeros(3)
        u[: H.shape[0]] = np.concatenate((u_minus, rows @ v[: rows.shape[1]]))
        e = float(self.constraints.restitution[index])
        law = str(self.restitution_law[index])
        if -e * u_minus[0] < self.zeno_velocity:  # an accumulation: plastic
            e = 0.0
        start = time.perf_counter()
        result = frictional_impact(
            W,
            u,
            friction=float(self.constraints.friction[index]),
            restitution=e,
            law=law,
            tangential_restitution=self.tangential_restitution if law == "newton" else None,
        )
        elapsed = time.perf_counter() - start
        solution = ContactSolution(result.impulse[:1], result.u[:1], "solved", 1, 0.0, elapsed)
        return solution, Minv_Ht @ result.impulse[: H.shape[0]]

    def _lzb_frictional_impact(
        self, v: Vector, terms: ConstraintTerms, u_minus: Vector, indices: NDArray[np.intp]
    ) -> tuple[ContactSolution, Vector]:
        """Simultaneous impacts with friction: the LZB law with one tangent per contact."""
        names = self._names(np.isin(np.arange(self._n), indices))
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
        start = time.perf_counter()
        result = lzb_impact_with_friction(
            law, M, terms.J[:, :nv], J_t, v[:nv], self.constraints.friction[indices]
        )
        elapsed = time.perf_counter() - start
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
        start = time.perf_counter()
        result = frictional_impact(W, [u_minus[0], 0.0, 0.0], friction=0.0, restitution=e, law=law)
        elapsed = time.perf_counter() - start
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

    def _project(self, q: Vector, v: Vector, closed: Mask, time: float) -> tuple[Vector, Vector]:
        r"""Project (q, v) onto the closed and bilateral constraints in the metric of M.

        Gauss–Newton steps :math:`q \leftarrow q \ominus M^{-1} J^T D^+ r` on the stacked
        residuals r (closed gaps, then :math:`h(q)`), then :math:`v \leftarrow v - M^{-1} J^T
        D^+ (J v + \partial g/\partial t)`, at the absolute ``time`` [s].
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
        if terms.velocity.size:
            v = v - terms.Minv_Jt @ _solve(terms.delassus(), terms.velocity)
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
        duration: float,
        max_step: float,
        start: float,
        t_start: float,
    ) -> _Segment:
        """Integrate with the closed set fixed until ``duration`` [s] or the first event.

        ``start + t_start`` is the absolute time in [s] of the segment's start (``start`` that
        of the step).

        The gap event of an open constraint resting on its surface (g and u within the
        closure tolerances: it just released, or its acceleration barely opened it) fires at
        g = -closure_gap rather than at g = 0, which it starts on: it marks the constraint
        coming back, not its start. The next active-set solve and projection then close it.
        """
        dynamics, nv = self._dynamics, self._dynamics.nv
        closed_indices = np.flatnonzero(closed)
        open_indices = np.flatnonzero(~closed)
        m = closed_indices.size
        origin = start + t_start  # [s]
        gap0, u0 = dynamics.kinematics(q0, v0, origin)
        resting = (gap0 <= self.closure_gap) & (np.abs(u0) <= self.closure_velocity)
        offsets = np.where(resting, self.closure_gap, 0.0)[open_indices]  # [m] or [rad]
        cache: dict[str, Any] = {"key": None}

        def evaluate(t: float, y: Vector) -> tuple[Vector, Vector]:
            key = (t, y.tobytes())
            if cache["key"] != key:
                dq, v = y[:nv], y[nv : 2 * nv]
                q = dynamics.configuration(q0, dq)
                if m or self._bilateral:
                    terms = dynamics.constraint_terms(q, v, tau, closed_indices, t=origin + t)
                    multipliers = (
                        _solve(terms.delassus(), -terms.acceleration_bias()) if m else np.zeros(0)
                    )
                    acceleration = terms.a_free + terms.Minv_Jt @ multipliers
                    gap = terms.gap
                else:
                    multipliers = np.zeros(0)
                    gap, _ = dynamics.kinematics(q, v, origin + t)
                    acceleration = dynamics.free_acceleration(q, v, tau)
                rate = np.concatenate((dynamics.chart_rate(q0, dq, v), acceleration, multipliers))
                cache["key"] = key
                cache["value"] = (
                    rate,
                    np.concatenate((gap[open_indices] + offsets, multipliers)),
                )
            value: tuple[Vector, Vector] = cache["value"]
            return value

        y0 = np.concatenate((np.zeros(nv), v0, np.zeros(m)))
        watched = np.concatenate(
            (
                np.ones(open_indices.size, dtype=bool),
                evaluate(0.0, y0)[1][open_indices.size :] > self.release_force,
            )
        )
        events = [_event(evaluate, int(k)) for k in np.flatnonzero(watched)]
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
        fired = np.zeros(open_indices.size + m, dtype=bool)
        if solution.status == 1:
            watched_indices = np.flatnonzero(watched)
            for k, times in enumerate(solution.t_events):
                fired[watched_indices[k]] = times.size > 0
        closing = np.zeros(self._n, dtype=bool)
        releasing = np.zeros(self._n, dtype=bool)
        closing[open_indices[fired[: open_indices.size]]] = True
        releasing[closed_indices[fired[open_indices.size :]]] = True
        return _Segment(
            q=dynamics.configuration(q0, y[:nv]),
            v=y[nv : 2 * nv].copy(),
            impulse=y[2 * nv :].copy(),
            duration=float(solution.t[-1]),
            closing=closing,
            releasing=releasing,
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
