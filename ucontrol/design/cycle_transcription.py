r"""Transcription of one cycle into a nonlinear program (casadi Opti, IPOPT).

The cycle starts at takeoff and runs through the phases

.. code-block:: text

    flight --impact--> [bounce --impact-->] x bounces   contact   (--> flight: periodicity)

Each phase :math:`p` has a free duration :math:`T_p` (time scaling: :math:`N_p` control
intervals of :math:`h_p = T_p / N_p`), piecewise-constant torques and multiple shooting with
:math:`S` classical Runge–Kutta (RK4) steps per interval, on the casadi model of the robot
(:class:`ucontrol.model.symbolic_model.SymbolicModel`):

- flight and bounces: :math:`M(q)\dot v + h(q, v) = \tau`, gap :math:`g(q) \ge 0`;
- contact: :math:`M\dot v + h = \tau + W^T\lambda`, :math:`J_n \dot v + \dot J_n v = 0`
  (index-reduced, started on :math:`g = 0`, :math:`J_n v = 0`), with
  :math:`W = J_n - \mu\,J_t` for a contact sliding along its tangent :math:`t` (Coulomb,
  :math:`\lambda_t = -\mu\lambda`), :math:`W = J_n` without friction;
- impact at a landing (:math:`g = 0`): :math:`M(v^+ - v^-) = J_n^T P`, Newton's law
  :math:`J_n v^+ = -e J_n v^-` for a bounce, and a final plastic impact
  :math:`J_n v^+ = 0`, which for :math:`e > 0` is the plant's: an impact rebounding slower than
  ``zeno_velocity`` is plastic (:class:`ucontrol.integrators.EventDriven`), so its landing speed
  is bounded by half of ``zeno_velocity / e``.

The torques and the contact multipliers are those of the plant between events, so the torques
replayed open-loop with a zero-order hold in the event-driven integrator reproduce the states
up to the RK4 error (:func:`ucontrol.design.replay_open_loop`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from ucontrol.design.compiled_nlp import solve_compiled
from ucontrol.design.design_report import DesignReport
from ucontrol.design.design_task import DesignTask
from ucontrol.design.designed_cycle import CyclePhase, DesignedCycle
from ucontrol.design.dop853_tableau import dop853_tableau
from ucontrol.design.warm_start import WarmStart, hand_made_warm_start
from ucontrol.exceptions import DesignError, InfeasibleDesignError
from ucontrol.model.compiled_function import compilation_possible
from ucontrol.model.symbolic_model import SymbolicModel

Vector = NDArray[np.float64]
#: A progress callback: (iteration, objective, primal infeasibility, dual infeasibility).
Progress = Callable[[int, float, float, float], None]

#: Kinds of limits the elastic (feasibility) problem may relax; the others stay hard.
_SOFT_KINDS = ("torque", "joint", "impact", "takeoff", "clearance")
#: Models with at most this many joints have their Runge–Kutta stages inlined (casadi SX).
INLINE_JOINTS = 4
#: Slack above this, in the constraint's units, names a limit as binding.
_BINDING_SLACK = 1e-6


@dataclass
class _Group:
    """A named block of constraints: ``lb <= expr <= ub``."""

    name: str
    kind: str
    expr: Any
    lb: Vector
    ub: Vector
    slack: Any = None
    scale: float = 1.0


@dataclass(frozen=True)
class _PhaseVars:
    name: str
    kind: str  # "flight", "bounce" or "contact"
    X: Any  # (2 nv, N + 1)
    U: Any  # (nv, N)
    T: Any  # duration [s]
    N: int


class CycleTranscription:
    """The nonlinear program of a task's cycle.

    Args:
        task: The design task.
        compiled: Solve with the program's derivatives compiled to C and cached across runs
            (:mod:`ucontrol.design.compiled_nlp`; for models with more than
            :data:`INLINE_JOINTS` joints the library is built in the background by the first
            run, which solves in casadi's virtual machine, and loaded by later runs);
            default: where a C compiler is present and ``UCONTROL_NO_COMPILE`` is not set.
            False: casadi's virtual machine, the same optimum.

    Attributes:
        task: The task.
        nv: Joint coordinates.
        compiled: Whether the solve runs compiled derivatives (else, or when their build
            fails or still runs in the background, casadi's virtual machine).
        functions: The casadi Functions of the model: ``gap``, ``normal_velocity``,
            ``position`` (tracked frame), ``free`` and ``contact`` RK4 intervals, ``impact``,
            ``contact_force``, ``normal_acceleration``.
    """

    def __init__(self, task: DesignTask, *, compiled: bool | None = None) -> None:
        self.task = task
        robot = task.scene.robot
        self.nv = nv = robot.nv
        self.joint_names = robot.joint_names
        contact = task.contact
        self.restitution = float(contact.restitution)
        self.friction = float(contact.friction)
        model = SymbolicModel(robot)
        phase = task.contact_phase
        tangent = None
        if self.friction > 0.0 or (phase.landing is not None and phase.takeoff is not None):
            tangent = self._sliding_tangent(contact.surface.normal)
        # kinematics and M, h as SX; the solves inlined (SX) for a small model, called as
        # linear solves (MX) for a larger one, whose symbolic solves outgrow memory
        qs, vs = ca.SX.sym("q", nv), ca.SX.sym("v", nv)
        p_s = model.frame_position(contact.frame)(qs)
        normal = ca.DM(contact.surface.normal)
        gap_s = ca.dot(normal, p_s - ca.DM(contact.surface.point)) - contact.radius
        J_n_s = ca.jacobian(gap_s, qs)  # (1, nv)
        J_t_s = (
            ca.jacobian(ca.dot(ca.DM(tangent), p_s), qs) if tangent is not None else ca.SX(1, nv)
        )
        drift_s = ca.jacobian(J_n_s @ vs, qs) @ vs  # J̇_n v [m/s²]
        self.inline = nv <= INLINE_JOINTS
        if compiled is None:
            compiled = compilation_possible()
        self.compiled = compiled
        sym: Any = ca.SX if self.inline else ca.MX
        q: Any
        v: Any
        tau: Any
        # M and h by the recursive Newton–Euler algorithm (~1e3 nodes for the Panda, where
        # SymbolicModel's C v has ~1e5)
        if self.inline:
            q, v, tau = qs, vs, ca.SX.sym("tau", nv)
            M, h = model.mass_matrix(qs), model.nonlinear_effects(qs, vs)
            gap, J_n, J_t, drift = gap_s, J_n_s, J_t_s, drift_s
        else:
            q, v, tau = ca.MX.sym("q", nv), ca.MX.sym("v", nv), ca.MX.sym("tau", nv)
            kinematics = ca.Function("kinematics", [qs], [gap_s, J_n_s, J_t_s])
            dynamics = ca.Function("dynamics", [qs, vs], [drift_s, model.nonlinear_effects(qs, vs)])
            gap, J_n, J_t = kinematics(q)
            drift, h = dynamics(q, v)
            M = model.mass_matrix(q)
        u_n = J_n @ v
        a_free = ca.solve(M, tau - h)
        W = J_n
        if self.friction > 0.0:
            W = J_n - self.friction * J_t
        Minv_Wt = ca.solve(M, W.T)
        force = -(J_n @ a_free + drift) / (J_n @ Minv_Wt)  # λ [N]
        a_contact = a_free + Minv_Wt @ force
        P = sym.sym("P")
        v_plus = v + ca.solve(M, J_n.T) * P
        position = model.frame_position(task.frame)(q)
        x = ca.vertcat(q, v)
        f = {}
        f["gap"] = ca.Function("gap", [q], [gap])
        f["normal_velocity"] = ca.Function("u_n", [q, v], [u_n])
        f["position"] = ca.Function("p", [q], [position])
        f["velocity"] = ca.Function("dp", [q, v], [ca.jacobian(position, q) @ v])
        f["contact_force"] = ca.Function("lambda", [x, tau], [force])
        f["normal_acceleration"] = ca.Function("a_n", [x, tau], [J_n @ a_free + drift])
        f["impact"] = ca.Function("impact", [q, v, P], [v_plus])
        rate_free = ca.Function("rate_free", [x, tau], [ca.vertcat(v, a_free)])
        rate_contact = ca.Function("rate_contact", [x, tau], [ca.vertcat(v, a_contact)])
        f["gravity"] = ca.Function("g", [q], [model.gravity(q)])
        if tangent is not None:
            f["sliding_velocity"] = ca.Function("u_t", [q, v], [J_t @ v])
        S, scheme = task.grid.substeps, task.grid.scheme
        f["free"] = _rk_interval(
            "free",
            rate_free,
            f["gap"],
            S,
            nv,
            scheme=scheme,
            normal=(f["normal_velocity"], f["normal_acceleration"]),
            called=self.compiled,
        )
        f["contact"] = _rk_interval(
            "contact",
            rate_contact,
            None,
            S,
            nv,
            f["contact_force"],
            scheme=scheme,
            called=self.compiled,
        )
        self.functions = f

    def _sliding_tangent(self, normal: Vector) -> Vector:
        """Direction of sliding: from the landing to the takeoff point, in the surface."""
        phase = self.task.contact_phase
        if phase.landing is None or phase.takeoff is None:
            raise DesignError(
                f"contact {phase.contact!r} has friction (mu = {self.friction}): the task must "
                "give `landing` and `takeoff` so that the sliding direction is known"
            )
        direction = phase.takeoff - phase.landing
        direction = direction - (direction @ normal) * normal
        norm = float(np.linalg.norm(direction))
        if norm < 1e-9:
            raise DesignError(
                "with friction, `landing` and `takeoff` must differ along the surface"
            )
        return np.asarray(direction / norm)

    # ------------------------------------------------------------------ the program

    def _phase_layout(self) -> list[tuple[str, str, int]]:
        grid = self.task.grid
        layout = [("flight", "flight", grid.flight_intervals)]
        layout += [
            (f"bounce_{k + 1}", "bounce", grid.bounce_intervals) for k in range(self.task.bounces)
        ]
        layout.append(("contact", "contact", grid.contact_intervals))
        return layout

    def build(self, warm: WarmStart, *, elastic: bool = False) -> tuple[ca.Opti, dict[str, Any]]:
        """The Opti problem, warm-started; ``elastic`` relaxes the limits with penalised slacks.

        Returns:
            The problem and its handles (phase variables, impulses, cost terms, groups).
        """
        task, f, nv = self.task, self.functions, self.nv
        opti = ca.Opti()
        groups: list[_Group] = []

        def constrain(name: str, kind: str, expr: Any, lb: Any, ub: Any) -> None:
            expr = ca.vec(expr)
            n = expr.shape[0]
            lb = np.broadcast_to(np.asarray(lb, dtype=float), (n,)).copy()
            ub = np.broadcast_to(np.asarray(ub, dtype=float), (n,)).copy()
            group = _Group(name, kind, expr, lb, ub)
            equal = np.flatnonzero(lb == ub)
            lower = np.flatnonzero(np.isfinite(lb) & (lb != ub))
            upper = np.flatnonzero(np.isfinite(ub) & (lb != ub))
            low = high = expr
            if elastic and kind in _SOFT_KINDS and (lower.size or upper.size):
                finite = np.abs(np.concatenate((lb[np.isfinite(lb)], ub[np.isfinite(ub)])))
                group.scale = max(float(np.max(finite, initial=0.0)), 1e-3)
                group.slack = opti.variable()  # relative violation of the whole group
                opti.subject_to(group.slack >= 0)
                opti.set_initial(group.slack, 1.0)
                low, high = expr + group.scale * group.slack, expr - group.scale * group.slack
            if equal.size:
                opti.subject_to(expr[equal.tolist()] == lb[equal])
            if lower.size:
                opti.subject_to(low[lower.tolist()] >= lb[lower])
            if upper.size:
                opti.subject_to(high[upper.tolist()] <= ub[upper])
            groups.append(group)

        phases: list[_PhaseVars] = []
        for name, kind, N in self._phase_layout():
            X = opti.variable(2 * nv, N + 1)
            U = opti.variable(nv, N)
            T = opti.variable()
            phases.append(_PhaseVars(name, kind, X, U, T, N))
        impulses = [opti.variable() for _ in range(len(phases) - 1)]

        effort: Any = 0
        dynamic: Any = 0
        impulse_cost: Any = 0
        force_cost: Any = 0
        smooth: Any = 0
        contact_spec = task.contact_phase
        for i, ph in enumerate(phases):
            dt = ph.T / ph.N
            interval = f["contact" if ph.kind == "contact" else "free"]
            path_values, path_interior = [], []
            for k in range(ph.N):
                x_next, values, interior = interval(ph.X[:, k], ph.U[:, k], dt)
                opti.subject_to(ph.X[:, k + 1] == x_next)
                path_values.append(values)
                path_interior.append(interior)
                effort += dt * ca.sumsqr(ph.U[:, k])
                dynamic += dt * ca.sumsqr(ph.U[:, k] - f["gravity"](ph.X[:nv, k]))
                if k > 0:
                    smooth += ca.sumsqr(ph.U[:, k] - ph.U[:, k - 1]) / dt
            values = ca.horzcat(*path_values)  # (S + 1, N): substep starts + interval end
            if ph.kind == "contact":
                S = task.grid.substeps
                n_fall = max(2, ph.N // 5)
                fall = np.minimum(1.0, (ph.N - 1 - np.arange(ph.N)) / n_fall)
                starts = values[:S, :]
                lower = np.tile(contact_spec.force_min * fall, (S, 1))  # (S, N) [N]
                constrain(
                    "contact force >= force_min", "force", ca.vec(starts), lower.T.ravel(), np.inf
                )
                constrain(
                    "contact force <= force_max",
                    "force",
                    ca.vec(starts),
                    -np.inf,
                    contact_spec.force_max,
                )
                constrain(
                    "contact force = 0 at takeoff", "takeoff_force", values[S, ph.N - 1], 0.0, 0.0
                )
                force_cost += dt * ca.sumsqr(starts - contact_spec.force) / S
                if "sliding_velocity" in f:
                    u_t = ca.horzcat(
                        *[f["sliding_velocity"](ph.X[:nv, k], ph.X[nv:, k]) for k in range(1, ph.N)]
                    )
                    constrain("sliding direction", "contact", u_t, 0.0, np.inf)
            else:
                S = task.grid.substeps
                gaps = ca.vec(values[:S, :])[1:]  # the phase's first point is on the surface
                constrain(f"gap >= 0 in {ph.name}", "gap", gaps, 0.0, np.inf)
                if task.grid.landing_interior:
                    constrain(
                        f"gap >= 0 between the points of the landing of {ph.name}",
                        "gap",
                        path_interior[-1],  # the dip of a soft landing, between its last points
                        0.0,
                        np.inf,
                    )
            # the phase's end on the surface (the landings), phase durations
            if ph.kind != "contact":
                constrain(
                    f"landing gap ({ph.name})", "landing", f["gap"](ph.X[:nv, ph.N]), 0.0, 0.0
                )
            spec = contact_spec if ph.kind == "contact" else task.flight
            if ph.kind == "bounce":
                constrain(
                    f"duration of {ph.name}", "duration", ph.T, 1e-3, task.flight.duration_max
                )
            else:
                constrain(
                    f"duration of {ph.name}", "duration", ph.T, spec.duration_min, spec.duration_max
                )
            if task.joint_limits is not None:
                q_all = ph.X[:nv, :]
                for j in range(nv):
                    constrain(
                        f"joint limit of {self.joint_names[j]!r} "
                        f"([{task.joint_limits[0, j]:.4g}, {task.joint_limits[1, j]:.4g}] rad)",
                        "joint",
                        q_all[j, :].T,
                        task.joint_limits[0, j],
                        task.joint_limits[1, j],
                    )
            for j in range(nv):
                limit = task.torque_limit[j]
                constrain(
                    f"torque limit of joint {self.joint_names[j]!r} (|tau| <= {limit:.4g} N m)",
                    "torque",
                    ph.U[j, :].T,
                    -limit,
                    limit,
                )
            if i + 1 < len(phases):
                nxt = phases[i + 1]
                q_minus, v_minus = ph.X[:nv, ph.N], ph.X[nv:, ph.N]
                P = impulses[i]
                opti.subject_to(nxt.X[:nv, 0] == q_minus)
                opti.subject_to(nxt.X[nv:, 0] == f["impact"](q_minus, v_minus, P))
                u_minus = f["normal_velocity"](q_minus, v_minus)
                u_plus = f["normal_velocity"](q_minus, nxt.X[nv:, 0])
                final = nxt.kind == "contact"
                if final:
                    constrain(f"plastic impact ({ph.name})", "impact_law", u_plus, 0.0, 0.0)
                    if self.restitution > 0.0:
                        threshold = 0.5 * task.zeno_velocity / self.restitution
                        constrain(
                            f"landing speed <= {threshold:.3g} m/s (plastic below the plant's "
                            "zeno_velocity)",
                            "landing",
                            -u_minus,
                            -np.inf,
                            threshold,
                        )
                else:
                    constrain(
                        f"Newton's law (impact after {ph.name})",
                        "impact_law",
                        u_plus + self.restitution * u_minus,
                        0.0,
                        0.0,
                    )
                    bounce = 1.5 * task.zeno_velocity / self.restitution
                    constrain(
                        f"bouncing impact after {ph.name}", "landing", -u_minus, bounce, np.inf
                    )
                if math.isfinite(task.impact_velocity):
                    constrain(
                        f"impact velocity after {ph.name} (<= {task.impact_velocity:.4g} m/s)",
                        "impact",
                        -u_minus,
                        -np.inf,
                        task.impact_velocity,
                    )
                constrain(f"impulse >= 0 ({ph.name})", "impact_law", P, 0.0, np.inf)
                if math.isfinite(task.impact_impulse):
                    constrain(
                        f"impact impulse after {ph.name} (<= {task.impact_impulse:.4g} N s)",
                        "impact",
                        P,
                        -np.inf,
                        task.impact_impulse,
                    )
                impulse_cost += P**2
        # takeoff, periodicity, mid-flight clearance, landing and takeoff points
        flight, contact = phases[0], phases[-1]
        opti.subject_to(flight.X[:, 0] == contact.X[:, contact.N])
        constrain(
            f"takeoff acceleration (>= {contact_spec.takeoff_acceleration:.4g} m/s^2)",
            "takeoff",
            f["normal_acceleration"](flight.X[:, 0], flight.U[:, 0]),
            contact_spec.takeoff_acceleration,
            np.inf,
        )
        if task.flight.clearance > 0.0:
            fraction = np.arange(1, flight.N) / flight.N
            gaps = ca.horzcat(*[f["gap"](flight.X[:nv, k]) for k in range(1, flight.N)])
            constrain(
                f"clearance along the flight (>= {task.flight.clearance:.4g} m at mid-flight)",
                "clearance",
                gaps.T,
                task.flight.clearance * 4.0 * fraction * (1.0 - fraction),
                np.inf,
            )
        if contact_spec.landing is not None:
            first_landing = phases[0].X[:nv, phases[0].N]
            constrain(
                "landing point",
                "point",
                f["position"](first_landing),
                contact_spec.landing,
                contact_spec.landing,
            )
        if contact_spec.takeoff is not None:
            constrain(
                "takeoff point",
                "point",
                f["position"](flight.X[:nv, 0]),
                contact_spec.takeoff,
                contact_spec.takeoff,
            )
        period = sum(ph.T for ph in phases)
        if task.period is not None:
            constrain("period", "period", period, task.period, task.period)
        else:
            constrain("period bounds", "period", period, task.period_min, task.period_max)

        weights = task.cost
        cost = (
            weights.effort * effort
            + weights.dynamic_effort * dynamic
            + weights.impulse * impulse_cost
            + weights.time * period
            + weights.force * force_cost
            + weights.smoothness * smooth
        )
        handles: dict[str, Any] = {
            "phases": phases,
            "impulses": impulses,
            "cost": cost,
            "terms": {
                "effort": effort,
                "dynamic_effort": dynamic,
                "impulse": impulse_cost,
                "time": period,
                "force": force_cost,
                "smoothness": smooth,
            },
            "groups": groups,
        }
        self._set_initial(opti, phases, impulses, warm)
        scale = max(abs(float(_evaluate_initial(opti, cost))), 1e-3)
        if elastic:
            penalty = sum(g.slack for g in groups if g.slack is not None)
            opti.minimize(penalty + 1e-6 * cost / scale)
        else:
            opti.minimize(cost / scale)
        handles["scale"] = scale
        return opti, handles

    def _set_initial(
        self, opti: ca.Opti, phases: list[_PhaseVars], impulses: list[Any], warm: WarmStart
    ) -> None:
        for ph in phases:
            guess = warm.phases[ph.kind if ph.kind != "bounce" else "bounce"]
            opti.set_initial(ph.X, _resample(guess.x, ph.N + 1).T)
            opti.set_initial(ph.U, _resample(guess.tau, ph.N).T)
            opti.set_initial(ph.T, guess.duration)
        for P in impulses:
            opti.set_initial(P, 0.0)

    # ------------------------------------------------------------------ solve

    def solve(
        self, warm: WarmStart | None = None, *, progress: Progress | None = None
    ) -> tuple[DesignedCycle, DesignReport]:
        """Solve the program; on failure, solve the elastic one to name the binding limits.

        Raises:
            InfeasibleDesignError: IPOPT found no feasible cycle; names the binding limits
                and holds the best iterate.
        """
        warm = warm if warm is not None else hand_made_warm_start(self.task, self._phase_layout())
        opti, handles = self.build(warm)
        report, cycle = self._run(opti, handles, progress, compiled=self.compiled)
        if report.success:
            return cycle, report
        elastic, elastic_handles = self.build(warm, elastic=True)
        # the elastic program's slacks start at an arbitrary 1: its start pushed inside; a
        # diagnosis, solved once: not worth a compile
        elastic_report, best = self._run(elastic, elastic_handles, progress, warm_start=False)
        binding = []
        for group in elastic_handles["groups"]:
            if group.slack is None:
                continue
            slack = group.scale * float(elastic.debug.value(group.slack))
            if slack > _BINDING_SLACK:
                binding.append((group.name, slack))
        if not elastic_report.success or not binding:
            binding = [(name, value) for name, value in report.violations.items() if value > 1e-6]
        binding.sort(key=lambda item: -item[1])
        raise InfeasibleDesignError(binding, best=best, report=report)

    def _run(
        self,
        opti: ca.Opti,
        handles: dict[str, Any],
        progress: Progress | None,
        *,
        warm_start: bool = True,
        compiled: bool = False,
    ) -> tuple[DesignReport, DesignedCycle]:
        task = self.task
        every = task.solver.progress_every

        def on_iteration(iteration: int, stats: Callable[[], dict[str, Any]]) -> None:
            if progress is None or iteration % every:
                return
            so_far = stats()["iterations"]
            progress(
                iteration,
                float(so_far["obj"][-1]),
                float(so_far["inf_pr"][-1]),
                float(so_far["inf_du"][-1]),
            )

        options: dict[str, Any] = {"print_time": False, "error_on_fail": False}
        ipopt: dict[str, Any] = {
            "max_iter": task.solver.max_iter,
            "tol": task.solver.tol,
            "print_level": task.solver.print_level,
            "sb": "yes",
            "mu_strategy": "adaptive",
            "warm_start_init_point": "yes" if warm_start and task.solver.warm_start else "no",
            "hessian_approximation": task.solver.hessian,
        }
        start = time.process_time()
        solved = (
            solve_compiled(opti, options, ipopt, on_iteration, background=not self.inline)
            if compiled
            else None
        )
        if solved is not None:
            value, stats = solved
        else:
            if progress is not None:
                opti.callback(lambda iteration: on_iteration(iteration, opti.debug.stats))
            opti.solver("ipopt", options, ipopt)
            try:
                solution = opti.solve()
                value = solution.value
                stats = solution.stats()
            except RuntimeError:  # pragma: no cover - casadi raises on some failures anyway
                value = opti.debug.value
                stats = opti.debug.stats()
        seconds = time.process_time() - start  # [s] CPU
        cycle = self._cycle(value, handles)
        report = self._report(opti, value, stats, handles, seconds)
        return report, cycle

    def _cycle(self, value: Callable[[Any], Any], handles: dict[str, Any]) -> DesignedCycle:
        f, nv, S = self.functions, self.nv, self.task.grid.substeps
        phases, t0 = [], 0.0
        for ph in handles["phases"]:
            X = np.asarray(value(ph.X), dtype=float).reshape(2 * nv, ph.N + 1)
            U = np.asarray(value(ph.U), dtype=float).reshape(nv, ph.N)
            T = float(value(ph.T))
            t = t0 + np.linspace(0.0, T, ph.N + 1)
            q, v = X[:nv].T, X[nv:].T
            position = np.array([np.asarray(f["position"](qk)).ravel() for qk in q])
            velocity = np.array(
                [np.asarray(f["velocity"](qk, vk)).ravel() for qk, vk in zip(q, v, strict=True)]
            )
            if ph.kind == "contact":
                force = np.array(
                    [
                        float(f["contact_force"](X[:, k], U[:, min(k, ph.N - 1)]))
                        for k in range(ph.N + 1)
                    ]
                )
            else:
                force = np.zeros(ph.N + 1)
            phases.append(
                CyclePhase(
                    name=ph.name,
                    kind=ph.kind,
                    t=t,
                    q=q,
                    v=v,
                    tau=U.T,
                    force=force,
                    position=position,
                    velocity=velocity,
                )
            )
            t0 += T
        impulses = np.array([float(value(P)) for P in handles["impulses"]])
        task = self.task
        return DesignedCycle(
            phases=tuple(phases),
            impulses=impulses,
            frame=task.frame,
            contact=task.contact_phase.contact,
            force=task.contact_phase.force,
            restitution=self.restitution,
            friction=self.friction,
            substeps=S,
            scheme=task.grid.scheme,
            scene=str(task.scene.source) if task.scene.source is not None else "",
        )

    def _report(
        self,
        opti: ca.Opti,
        value: Callable[[Any], Any],
        stats: dict[str, Any],
        handles: dict[str, Any],
        seconds: float,
    ) -> DesignReport:
        violations: dict[str, float] = {}
        for group in handles["groups"]:
            g = np.atleast_1d(np.asarray(value(group.expr), dtype=float).ravel())
            worst = float(np.max(np.maximum(group.lb - g, g - group.ub), initial=0.0))
            violations[group.name] = max(violations.get(group.name, 0.0), max(worst, 0.0))
        g_all = np.atleast_1d(np.asarray(value(opti.g), dtype=float).ravel())
        lbg = np.atleast_1d(np.asarray(value(opti.lbg), dtype=float).ravel())
        ubg = np.atleast_1d(np.asarray(value(opti.ubg), dtype=float).ravel())
        max_violation = float(np.max(np.maximum(lbg - g_all, g_all - ubg), initial=0.0))
        # KKT stationarity of the scaled problem, from the Jacobians (independent of IPOPT)
        x, lam = opti.x, opti.lam_g
        gradient = ca.gradient(opti.f, x) + ca.jacobian(opti.g, x).T @ lam
        stationarity = float(np.max(np.abs(np.asarray(value(gradient), dtype=float))))
        lam_value = np.atleast_1d(np.asarray(value(lam), dtype=float).ravel())
        # complementarity: multiplier times the slack of its nearer bound
        slack = np.minimum(np.abs(g_all - lbg), np.abs(ubg - g_all))
        equality = lbg == ubg
        complementarity = float(
            np.max(np.abs(lam_value[~equality] * slack[~equality]), initial=0.0)
        )
        sign_error = float(
            np.max(
                np.concatenate(
                    (
                        np.maximum(-lam_value, 0.0)[
                            (np.abs(ubg - g_all) < np.abs(g_all - lbg)) & ~equality
                        ],
                        np.maximum(lam_value, 0.0)[
                            (np.abs(ubg - g_all) >= np.abs(g_all - lbg)) & ~equality
                        ],
                    )
                ),
                initial=0.0,
            )
        )
        iterations = stats.get("iterations", {})
        phases = handles["phases"]
        return DesignReport(
            status=str(stats.get("return_status", "unknown")),
            success=bool(stats.get("success", False)),
            iterations=int(stats.get("iter_count", 0)),
            cost=float(value(handles["cost"])),
            cost_terms={name: float(value(term)) for name, term in handles["terms"].items()},
            durations={ph.name: float(value(ph.T)) for ph in phases},
            impulses=[float(value(P)) for P in handles["impulses"]],
            max_violation=max_violation,
            violations=violations,
            inf_pr=float(iterations["inf_pr"][-1]) if iterations else math.nan,
            inf_du=float(iterations["inf_du"][-1]) if iterations else math.nan,
            stationarity=stationarity * 1.0,
            complementarity=complementarity,
            multiplier_sign_error=sign_error,
            cost_scale=float(handles["scale"]),
            cpu_seconds=_cpu_split(stats, seconds),
            hessian_calls=int(stats.get("n_call_nlp_hess_l", 0)),
        )


def _cpu_split(stats: dict[str, Any], seconds: float) -> dict[str, float]:
    """CPU seconds of the solve by part, from casadi's timers (see ``DesignReport``)."""
    hessian = float(stats.get("t_proc_nlp_hess_l", 0.0))
    jacobian = float(stats.get("t_proc_nlp_jac_g", 0.0))
    functions = sum(float(stats.get(f"t_proc_nlp_{name}", 0.0)) for name in ("f", "g", "grad_f"))
    return {
        "solve": seconds,
        "hessian": hessian,
        "jacobian": jacobian,
        "functions": functions,
        "rest": max(seconds - hessian - jacobian - functions, 0.0),
    }


def design_cycle(
    task: DesignTask,
    *,
    warm: WarmStart | None = None,
    progress: Progress | None = None,
    compiled: bool | None = None,
) -> tuple[DesignedCycle, DesignReport]:
    """Design the cycle of ``task``: transcribe, warm-start from the hand-made cycle, solve.

    Args:
        task: The design task.
        warm: Initial guess; default the scene's hand-made cycle.
        progress: Called every ``task.solver.progress_every`` IPOPT iterations.
        compiled: Whether IPOPT runs the program's derivatives compiled to C, cached across
            runs (see :class:`CycleTranscription`); default where a C compiler is present.

    Returns:
        The designed cycle and the solver's report.

    Raises:
        InfeasibleDesignError: No feasible cycle; names the binding limits, keeps the best
            iterate.
    """
    return CycleTranscription(task, compiled=compiled).solve(warm, progress=progress)


def _tableau(scheme: str) -> tuple[Vector, Vector]:
    """Butcher matrix A (s, s) and weights b (s,) of an explicit Runge–Kutta scheme."""
    if scheme == "rk4":
        A = np.zeros((4, 4))
        A[1, 0], A[2, 1], A[3, 2] = 0.5, 0.5, 1.0
        return A, np.array([1.0, 2.0, 2.0, 1.0]) / 6.0
    # DOP853's order-8 propagation stages (Hairer, Nørsett and Wanner), written in our module
    A, b, _ = dop853_tableau()
    return A, b


#: Fractions of a substep where the gap's interpolant is checked, and the quintic Hermite
#: basis there: weights of (g0, δ u0, δ² a0, δ² a1, δ u1, g1).
_INTERIOR = np.array([0.25, 0.5, 0.75])
_HERMITE5 = np.array(
    [
        [
            1 - 10 * s**3 + 15 * s**4 - 6 * s**5,
            s - 6 * s**3 + 8 * s**4 - 3 * s**5,
            0.5 * s**2 - 1.5 * s**3 + 1.5 * s**4 - 0.5 * s**5,
            0.5 * s**3 - s**4 + 0.5 * s**5,
            -4 * s**3 + 7 * s**4 - 3 * s**5,
            10 * s**3 - 15 * s**4 + 6 * s**5,
        ]
        for s in _INTERIOR
    ]
)


def _rk_interval(
    name: str,
    rate: ca.Function,
    gap: ca.Function | None,
    substeps: int,
    nv: int,
    force: ca.Function | None = None,
    scheme: str = "rk4",
    normal: tuple[ca.Function, ca.Function] | None = None,
    *,
    called: bool = False,
) -> ca.Function:
    r"""``(x0, tau, h) -> (x_end, values, interior)``: ``substeps`` Runge–Kutta steps.

    ``values`` (substeps + 1,): the gap (or contact force) at each substep start, then at the
    end with the same torque. ``interior`` (3 substeps,): with ``normal`` (the normal velocity
    :math:`u = J_n v` and acceleration :math:`a = J_n \dot v + \dot J_n v` Functions), the
    gap's quintic Hermite interpolant from :math:`(g, u, a)` at both ends of each substep, at
    a quarter, half and three quarters of it (error :math:`O(\delta^6)`), so that a flight
    cannot dip through the surface between two points unnoticed; else zeros.

    With ``called`` (a small model, whose stages are SX), one substep and its probes are an SX
    Function ``<name>_substep`` (the end's probes ``<name>_probe``) that the interval calls
    ``substeps`` times in MX: the same operations, whose C code (:mod:`.compiled_nlp`) then
    holds each derivative of a substep once instead of ``substeps`` times unrolled.
    """
    A, b = _tableau(scheme)
    # small models: the stages inlined (SX, fastest); larger ones: the rate Function called
    # (MX), whose inlined stages and their Hessian outgrow memory (the 9-joint Panda: > 9 GB)
    sym: Any = ca.SX if nv <= INLINE_JOINTS else ca.MX
    tau = sym.sym("tau", nv)
    h = sym.sym("h")

    def probe(state: Any) -> list[Any]:
        """The gap (or force) at ``state``, and with ``normal`` the speed and acceleration."""
        rates = [] if normal is None else [normal[0](state[:nv], state[nv:]), normal[1](state, tau)]
        value = force(state, tau) if force is not None else gap(state[:nv])  # type: ignore[misc]
        return [value, *rates]

    def advance(x: Any, step: Any) -> Any:
        k: list[Any] = []
        for i in range(A.shape[0]):
            increment = sum((A[i, j] * k[j] for j in range(i) if A[i, j] != 0.0), sym.zeros(2 * nv))
            k.append(rate(x + step * increment, tau))
        return x + step * sum(
            (b[i] * k[i] for i in range(len(k)) if b[i] != 0.0), sym.zeros(2 * nv)
        )

    x0, inputs = sym.sym("x0", 2 * nv), [tau, h]
    step_of: Callable[[Any], tuple[Any, list[Any]]]
    probe_of: Callable[[Any], list[Any]]
    if called and sym is ca.SX:
        x_s, step_s = ca.SX.sym("x", 2 * nv), ca.SX.sym("step")
        # derivatives one direction at a time: C code of a 7-direction forward-over-reverse
        # is 7 times as long, and the compiler's time grows faster than the code
        one = {"max_num_dir": 1}
        sub = ca.Function(
            f"{name}_substep", [x_s, tau, step_s], ca.cse([advance(x_s, step_s), *probe(x_s)]), one
        )
        end = ca.Function(f"{name}_probe", [x_s, tau], ca.cse(probe(x_s)), one)
        x0, tau_m, h = ca.MX.sym("x0", 2 * nv), ca.MX.sym("tau", nv), ca.MX.sym("h")
        inputs = [tau_m, h]
        step = h / substeps

        def step_of(x: Any) -> tuple[Any, list[Any]]:
            x_next, *probes = sub.call([x, tau_m, step])
            return x_next, probes

        def probe_of(x: Any) -> list[Any]:
            return list(end.call([x, tau_m]))

        zeros: Any = ca.MX.zeros
    else:
        step = h / substeps

        def step_of(x: Any) -> tuple[Any, list[Any]]:
            probes = probe(x)
            return advance(x, step), probes

        probe_of, zeros = probe, sym.zeros
    x = x0
    points = []  # per point: [value] or [value, speed, acceleration]
    for _ in range(substeps):
        x, probes = step_of(x)
        points.append(probes)
    points.append(probe_of(x))
    values = [point[0] for point in points]
    interior = []
    for i in range(substeps):
        ends = (
            ca.vertcat(
                values[i],
                step * points[i][1],
                step**2 * points[i][2],
                step**2 * points[i + 1][2],
                step * points[i + 1][1],
                values[i + 1],
            )
            if normal is not None
            else zeros(6)
        )
        interior.append(ca.mtimes(ca.DM(_HERMITE5), ends))
    outputs = [x, ca.vertcat(*values), ca.vertcat(*interior)]
    if isinstance(x, ca.SX):
        # the probes repeat the first stage's dynamics and the contact rate its solves:
        # shared once, the interval and its derivatives, which the solve spends its time in,
        # shrink by an eighth (flight) to a quarter (contact)
        outputs = ca.cse(outputs)
    return ca.Function(name, [x0, *inputs], outputs)


def _resample(samples: Vector, n: int) -> Vector:
    """Linear resampling of ``samples`` (m, d) to (n, d) over the same normalised time."""
    samples = np.atleast_2d(samples)
    s_old = np.linspace(0.0, 1.0, samples.shape[0])
    s_new = np.linspace(0.0, 1.0, n)
    return np.column_stack(
        [np.interp(s_new, s_old, samples[:, j]) for j in range(samples.shape[1])]
    )


def _evaluate_initial(opti: ca.Opti, expr: Any) -> float:
    """Value of ``expr`` at the initial guess."""
    return float(opti.debug.value(expr, opti.initial()))
