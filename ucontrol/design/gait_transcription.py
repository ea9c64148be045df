r"""Transcription of one walking step of a planar biped into a nonlinear program (casadi, IPOPT).

The step starts just after a heel strike with the stance foot on the ground at the origin and
ends at the next heel strike of the swing foot, one step length ahead. On a grid of :math:`N`
control intervals of :math:`h = T/N` (:math:`T` the free step time) with piecewise-constant
torques :math:`\tau_k` and :math:`S` classical Runge–Kutta (RK4) steps per interval (multiple
shooting, as :mod:`ucontrol.design.cycle_transcription`), on the casadi model of the robot
(:class:`ucontrol.model.symbolic_model.SymbolicModel`):

- stance (the stance foot :math:`p_s(q)` pinned, a holonomic constraint with its multiplier
  :math:`\lambda = (\lambda_t, \lambda_n)`):

  .. math::

      M(q)\dot v + h(q, v) = B\tau + J_s(q)^T\lambda, \qquad
      J_s(q)\dot v + \dot J_s(q, v)\, v = 0,

  index-reduced and started on :math:`p_s(q_0) = 0`, :math:`J_s v_0 = 0` (the second from the
  periodicity), with :math:`\lambda_n \ge \lambda_{\min}` and :math:`|\lambda_t| \le \mu
  \lambda_n` at every Runge–Kutta step;
- the swing foot :math:`p_w(q)` above the ground, :math:`z_w(q_k) \ge c\, 4 s_k (1 - s_k)`
  (:math:`s_k = k/N`, :math:`c` the clearance), coming down at the end, :math:`\dot z_w \le 0`;
- the heel strike at :math:`q^- = q_N`: a plastic impact at the swing foot, the old stance foot
  lifting off,

  .. math::

      M(q^-)(v^+ - v^-) = J_w(q^-)^T \Lambda, \qquad J_w(q^-) v^+ = 0, \qquad
      \Lambda_n \ge 0, \quad |\Lambda_t| \le \mu \Lambda_n, \qquad
      \big(J_s(q^-) v^+\big)_z \ge 0,

  with :math:`v^+` and the impulse :math:`\Lambda` decision variables;
- the relabelling :math:`R` (the legs' joints swapped, the base kept) and periodicity:
  :math:`R q^- = q_0 + L e_x`, :math:`R v^+ = v_0` (:math:`L` the step length). The swing foot
  then lands at :math:`(L, 0)` and the stance foot starts at rest, by the legs' symmetry.

The cost is the torque squared per distance, :math:`\frac1L \sum_k h\,|\tau_k|^2`
[N² m² s / m].
"""

from __future__ import annotations

import math
import time
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from ucontrol.design.designed_gait import DesignedGait
from ucontrol.design.gait_task import GaitTask
from ucontrol.exceptions import InfeasibleDesignError
from ucontrol.model.symbolic_model import SymbolicModel

Vector = NDArray[np.float64]
#: Cost scale [N² m² s / m]: the cost IPOPT sees is divided by it.
_COST_SCALE = 1e3
#: Smallest phase rate [rad/s] along the step: the phase must increase.
_MIN_PHASE_RATE = 0.05
#: Hip height of the warm start as a fraction of the leg's length.
_WARM_HEIGHT = 0.93


class GaitTranscription:
    """The nonlinear program of a task's walking step.

    Args:
        task: The gait task.

    Attributes:
        task: The task.
        nv: Velocity coordinates (nq = nv).
        functions: casadi Functions: ``interval`` (RK4 over one control interval: end state
            and the stance force at each substep start), ``force`` (stance multiplier),
            ``stance``, ``swing`` (feet in the x–z plane), ``J_stance``, ``J_swing``, ``M``.
    """

    def __init__(self, task: GaitTask) -> None:
        self.task = task
        robot = task.robot
        self.nv = nv = robot.nv
        nu = robot.nu
        model = SymbolicModel(robot)
        q, v, tau = ca.SX.sym("q", nv), ca.SX.sym("v", nv), ca.SX.sym("tau", nu)
        B = np.zeros((nv, nu))
        B[robot.actuated, np.arange(nu)] = 1.0
        p_s = model.frame_position(task.stance)(q)[[0, 2]]  # (x, z) [m]
        p_w = model.frame_position(task.swing)(q)[[0, 2]]
        J_s, J_w = ca.jacobian(p_s, q), ca.jacobian(p_w, q)  # (2, nv)
        drift = ca.jacobian(J_s @ v, q) @ v  # J̇_s v [m/s²]
        M = model.mass_matrix(q)
        h = model.nonlinear_effects(q, v)
        solved = ca.solve(M, ca.horzcat(ca.mtimes(ca.DM(B), tau) - h, J_s.T))  # (nv, 3)
        a_free, Minv_Jt = solved[:, 0], solved[:, 1:]
        force = -ca.solve(J_s @ Minv_Jt, J_s @ a_free + drift)  # λ = (λ_t, λ_n) [N]
        x = ca.vertcat(q, v)
        rate = ca.Function("rate", [x, tau], [ca.vertcat(v, a_free + Minv_Jt @ force)])
        f: dict[str, ca.Function] = {
            "force": ca.Function("force", [x, tau], [force]),
            "stance": ca.Function("p_s", [q], [p_s]),
            "swing": ca.Function("p_w", [q], [p_w]),
            "J_stance": ca.Function("J_s", [q], [J_s]),
            "J_swing": ca.Function("J_w", [q], [J_w]),
            "M": ca.Function("M", [q], [M]),
        }
        f["interval"] = _rk4_interval(rate, f["force"], task.substeps, nv, nu)
        p_hip = model.frame_position(task.stance_leg[0])(q)[[0, 2]]
        theta = ca.atan2(p_hip[0] - p_s[0], p_hip[1] - p_s[1])  # phase θ [rad]
        f["hip_height"] = ca.Function("hip_z", [q], [p_hip[1]])
        f["theta"] = ca.Function("theta", [q], [theta])
        f["theta_rate"] = ca.Function("theta_dot", [q, v], [ca.jacobian(theta, q) @ v])
        self.functions = f

    def build(self) -> tuple[ca.Opti, dict[str, Any]]:
        """The Opti problem, warm-started; returns it and the handles of its variables."""
        task, f, nv = self.task, self.functions, self.nv
        N, mu, L = task.intervals, task.friction, task.step_length
        nu = task.robot.nu
        opti = ca.Opti()
        X = opti.variable(2 * nv, N + 1)
        U = opti.variable(nu, N)
        T = opti.variable()
        v_plus = opti.variable(nv)
        P = opti.variable(2)  # heel-strike impulse (tangential, normal) [N s]
        dt = T / N
        effort: Any = 0
        for k in range(N):
            x_next, forces = f["interval"](X[:, k], U[:, k], dt)  # forces (2, S)
            opti.subject_to(X[:, k + 1] == x_next)
            if k == N - 1:  # and at the step's end, with the last interval's torques
                forces = ca.horzcat(forces, f["force"](X[:, N], U[:, k]))
            opti.subject_to(forces[1, :] >= task.force_min)
            opti.subject_to(forces[0, :] - mu * forces[1, :] <= 0)
            opti.subject_to(-forces[0, :] - mu * forces[1, :] <= 0)
            effort += dt * ca.sumsqr(U[:, k])
            if k > 0:
                s = k / N
                opti.subject_to(f["swing"](X[:nv, k])[1] >= task.clearance * 4 * s * (1 - s))
        opti.subject_to(ca.vec(U) <= task.torque_limit)
        opti.subject_to(ca.vec(U) >= -task.torque_limit)
        # the base's third coordinate is the torso's pitch (GaitTask checks the base)
        bounded = [(2, task.pitch_bounds)]
        for leg in task.legs:
            for joint, bounds in zip(leg[:2], (task.hip_bounds, task.knee_bounds), strict=True):
                bounded.append((task.robot.model.joints[task.robot.joint_id(joint)].idx_v, bounds))
        for index, (lower, upper) in bounded:
            opti.subject_to(opti.bounded(lower, X[index, :], upper))
        hip_z = ca.horzcat(*[f["hip_height"](X[:nv, k]) for k in range(N + 1)])
        opti.subject_to(hip_z >= task.hip_height_min)
        q0, v0 = X[:nv, 0], X[nv:, 0]
        q_minus, v_minus = X[:nv, N], X[nv:, N]
        opti.subject_to(f["stance"](q0) == 0)
        # heel strike: plastic at the swing foot, the old stance foot lifting off
        J_w = f["J_swing"](q_minus)
        opti.subject_to(f["M"](q_minus) @ (v_plus - v_minus) == J_w.T @ P)
        opti.subject_to(J_w @ v_plus == 0)
        opti.subject_to(P[1] >= 0)
        opti.subject_to(P[1] <= task.impact_impulse)
        opti.subject_to(P[0] - mu * P[1] <= 0)
        opti.subject_to(-P[0] - mu * P[1] <= 0)
        opti.subject_to((f["J_stance"](q_minus) @ v_plus)[1] >= 0)
        opti.subject_to((J_w @ v_minus)[1] <= 0)
        # relabelling and periodicity, x shifted by the step length
        R = ca.DM(task.relabelling())
        shift = np.zeros(nv)
        shift[0] = L
        opti.subject_to(R @ q_minus - q0 == shift)
        opti.subject_to(R @ v_plus - v0 == 0)
        if task.speed is not None:
            opti.subject_to(T == L / task.speed)
        else:
            opti.subject_to(opti.bounded(task.step_time_min, T, task.step_time_max))
        cost = effort / L  # [N² m² s / m]
        fit = self._virtual_constraints(opti, X, v_plus)
        opti.minimize((cost + task.fit_weight * fit) / _COST_SCALE)
        self._warm_start(opti, X, U, T, v_plus, P)
        return opti, {"X": X, "U": U, "T": T, "v_plus": v_plus, "P": P, "cost": cost, "fit": fit}

    def _virtual_constraints(self, opti: ca.Opti, X: Any, v_plus: Any) -> Any:
        r"""Mean squared distance [rad²] of the step's :math:`q_a` from a Bézier :math:`h_d(s)`.

        The coefficients :math:`\alpha` are variables, their four endpoint columns set by the
        heel strike as :func:`ucontrol.design.hzd_fit.fit_bezier` sets them; the phase must
        increase (:math:`\dot\theta > 0` at every grid point).
        """
        task, f, nv, N = self.task, self.functions, self.nv, self.task.intervals
        M, a = task.degree, task.actuated_indices.tolist()
        R = ca.DM(task.relabelling())
        theta = ca.horzcat(*[f["theta"](X[:nv, k]) for k in range(N + 1)])
        rates = ca.horzcat(*[f["theta_rate"](X[:nv, k], X[nv:, k]) for k in range(N + 1)])
        opti.subject_to(rates >= _MIN_PHASE_RATE)
        q_plus, v_next = R @ X[:nv, N], R @ v_plus
        span = theta[N] - theta[0]
        alpha = opti.variable(4, M + 1)
        opti.subject_to(alpha[:, M] == X[a, N])
        v_minus = X[[nv + i for i in a], N]
        opti.subject_to(alpha[:, M - 1] == alpha[:, M] - span / M * v_minus / rates[N])
        opti.subject_to(alpha[:, 0] == q_plus[a])
        opti.subject_to(
            alpha[:, 1] == alpha[:, 0] + span / M * v_next[a] / f["theta_rate"](q_plus, v_next)
        )
        misfit: Any = 0
        for k in range(N + 1):
            s = (theta[k] - theta[0]) / span
            h_d = sum(
                math.comb(M, i) * s**i * (1 - s) ** (M - i) * alpha[:, i] for i in range(M + 1)
            )
            misfit += ca.sumsqr(X[a, k] - h_d)
        opti.set_initial(alpha, 0.0)
        return misfit / (4 * (N + 1))

    def _warm_start(self, opti: ca.Opti, X: Any, U: Any, T: Any, v_plus: Any, P: Any) -> None:
        """A hand-made step: hip at constant height, swing foot on a parabola, torques zero."""
        task, N = self.task, self.task.intervals
        L = task.step_length
        T_guess = (
            L / task.speed
            if task.speed is not None
            else 0.5 * (task.step_time_min + task.step_time_max)
        )
        q = np.array([self._warm_configuration(k / N) for k in range(N + 1)])
        v = np.gradient(q, T_guess / N, axis=0)
        opti.set_initial(X, np.hstack((q, v)).T)
        opti.set_initial(U, np.zeros((task.robot.nu, N)))
        opti.set_initial(T, T_guess)
        opti.set_initial(v_plus, task.relabelling() @ v[0])
        opti.set_initial(P, np.array([0.0, 1.0]))

    def _warm_configuration(self, s: float) -> Vector:
        """The warm start's configuration at the fraction ``s`` of the step."""
        task = self.task
        robot = task.robot
        L, nv = task.step_length, self.nv
        q = np.zeros(nv)
        # leg lengths from the neutral configuration (legs straight down)
        hip_s, knee_s, foot_s = task.stance_leg
        hip_z = robot.frame_position(robot.neutral(), hip_s)[2]
        knee_z = robot.frame_position(robot.neutral(), knee_s)[2]
        foot_z = robot.frame_position(robot.neutral(), foot_s)[2]
        thigh, shank = hip_z - knee_z, knee_z - foot_z
        height = _WARM_HEIGHT * (thigh + shank)
        hip = np.array([-L / 2 + s * L, height])
        q[0], q[1] = hip[0], height - (hip_z - robot.neutral()[1])
        swing = np.array([-L + 2 * L * s, 1.5 * task.clearance * 4 * s * (1 - s)])
        for leg, foot in ((task.stance_leg, np.zeros(2)), (task.swing_leg, swing)):
            d = foot - hip
            reach = min(float(np.hypot(*d)), 0.999 * (thigh + shank))
            cos_knee = (reach**2 - thigh**2 - shank**2) / (2 * thigh * shank)
            knee = math.acos(max(-1.0, min(1.0, cos_knee)))
            # absolute angle of the hip-to-foot line about +y (0 straight down, + foot behind)
            direction = math.atan2(-d[0], -d[1])
            inner = math.atan2(shank * math.sin(knee), thigh + shank * math.cos(knee))
            q[robot.model.joints[robot.joint_id(leg[0])].idx_v] = direction - inner
            q[robot.model.joints[robot.joint_id(leg[1])].idx_v] = knee
        return q

    def solve(self) -> DesignedGait:
        """Solve the program with IPOPT.

        Raises:
            InfeasibleDesignError: IPOPT found no feasible step; names its status and keeps
                the last iterate in ``best``.
        """
        task, f, nv = self.task, self.functions, self.nv
        opti, handles = self.build()
        opti.solver(
            "ipopt",
            {"print_time": False, "error_on_fail": False},
            {
                "max_iter": task.max_iter,
                "tol": task.tol,
                "print_level": task.print_level,
                "sb": "yes",
                "mu_strategy": "adaptive",
            },
        )
        start = time.process_time()
        value: Any
        try:
            solution = opti.solve_limited()  # a failed solve is reported below, not raised
            value, stats = solution.value, solution.stats()
        except RuntimeError:  # casadi raises on some failures anyway (infeasible, restoration)
            value, stats = opti.debug.value, opti.debug.stats()
        cpu = time.process_time() - start
        N, S = task.intervals, task.substeps
        X = np.asarray(value(handles["X"]), dtype=float).reshape(2 * nv, N + 1)
        U = np.asarray(value(handles["U"]), dtype=float).reshape(task.robot.nu, N)
        T = float(value(handles["T"]))
        forces = np.array(
            [
                np.asarray(f["force"](X[:, k], U[:, min(k, N - 1)]), dtype=float).ravel()
                for k in range(N + 1)
            ]
        )
        g = np.atleast_1d(np.asarray(value(opti.g), dtype=float).ravel())
        lbg = np.atleast_1d(np.asarray(value(opti.lbg), dtype=float).ravel())
        ubg = np.atleast_1d(np.asarray(value(opti.ubg), dtype=float).ravel())
        violation = float(np.max(np.maximum(lbg - g, g - ubg), initial=0.0))
        # KKT stationarity of the scaled program from casadi's Jacobians and IPOPT's multipliers
        gradient = ca.gradient(opti.f, opti.x) + ca.jacobian(opti.g, opti.x).T @ opti.lam_g
        stationarity = float(np.max(np.abs(np.asarray(value(gradient), dtype=float))))
        gait = DesignedGait(
            robot=task.robot,
            legs=task.legs,
            stance=task.stance,
            t=np.linspace(0.0, T, N + 1),
            q=X[:nv].T.copy(),
            v=X[nv:].T.copy(),
            tau=U.T.copy(),
            force=forces,
            v_plus=np.asarray(value(handles["v_plus"]), dtype=float).ravel(),
            impulse=np.asarray(value(handles["P"]), dtype=float).ravel(),
            step_length=task.step_length,
            substeps=S,
            cost=float(value(handles["cost"])),
            status=str(stats.get("return_status", "unknown")),
            success=bool(stats.get("success", False)),
            iterations=int(stats.get("iter_count", 0)),
            cpu_time=cpu,
            max_violation=violation,
            stationarity=stationarity,
        )
        if not gait.success:
            binding = [(f"the step (IPOPT: {gait.status})", violation)]
            raise InfeasibleDesignError(binding, best=gait)
        return gait


def design_gait(task: GaitTask) -> DesignedGait:
    """Design the walking step of ``task``: transcribe, warm-start, solve with IPOPT.

    Raises:
        InfeasibleDesignError: No feasible step; the last iterate is kept in ``best``.
    """
    return GaitTranscription(task).solve()


def _rk4_interval(
    rate: ca.Function, force: ca.Function, substeps: int, nv: int, nu: int
) -> ca.Function:
    """``(x0, tau, h) -> (x_end, forces (2, substeps))``: ``substeps`` RK4 steps of ``rate``."""
    x0, tau, h = ca.SX.sym("x0", 2 * nv), ca.SX.sym("tau", nu), ca.SX.sym("h")
    step = h / substeps
    x, forces = x0, []
    for _ in range(substeps):
        forces.append(force(x, tau))
        k1 = rate(x, tau)
        k2 = rate(x + step / 2 * k1, tau)
        k3 = rate(x + step / 2 * k2, tau)
        k4 = rate(x + step * k3, tau)
        x = x + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("interval", [x0, tau, h], [x, ca.horzcat(*forces)])
