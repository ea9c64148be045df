r"""Brogliato–Ortega–Lozano passivity-based tracking of flexible-joint robots, in the phase machine.

Plant (Spong, :class:`ucontrol.model.FlexibleJoints`, no damper), link coordinates
:math:`q_1`, motor coordinates :math:`q_2`, S the selection of the flexible joints:

.. math::

    M(q_1)\ddot q_1 + C(q_1, \dot q_1)\dot q_1 + g(q_1) = S^T K (q_2 - S q_1) + S_r^T u_r
        + J_c^T \lambda, \qquad B \ddot q_2 + K (q_2 - S q_1) = u_f,

with :math:`u_r` the torques of the rigid actuated joints (selection :math:`S_r`,
:math:`S^T S + S_r^T S_r = I`). Link reference :math:`q_{1d}(t)`:
:math:`\tilde q_1 = q_1 - q_{1d}`, :math:`s_1 = \dot{\tilde q}_1 + \gamma_2 \tilde q_1`,
:math:`\dot q_{1r} = \dot q_{1d} - \gamma_2 \tilde q_1`. The rigid law of the current phase is

.. math::

    U_R = M \ddot q_{1r} + C \dot q_{1r} + g - \gamma_1 s_1
          + J_c^T\big(-\lambda_d + K_f (\lambda - \lambda_d)\big)

(force term on the contacts held in their constrained phase, as in
:class:`BrogliatoController`). The motor reference
:math:`q_{2d} = S q_{1d} + K^{-1} S U_R` gives :math:`\tilde q_2 = q_2 - q_{2d}`,
:math:`s_2 = \dot{\tilde q}_2 + \gamma_2 \tilde q_2`, and the inputs are

.. math::

    u_f = B \ddot q_{2r} + K (q_{2d} - S q_{1d}) - \gamma_1 s_2, \qquad u_r = S_r U_R.

Closed loop (free motion): the link receives :math:`S^T K(q_2 - S q_1) + S_r^T S_r U_R
= U_R + S^T K (\tilde q_2 - S \tilde q_1)`, so with :math:`e = S \tilde q_1 - \tilde q_2`

.. math::

    M \dot s_1 + C s_1 + \gamma_1 s_1 = -S^T K e, \qquad B \dot s_2 + \gamma_1 s_2 = K e.

With :math:`V = \tfrac12 s_1^T M s_1 + \tfrac12 s_2^T B s_2
+ \gamma_1\gamma_2 (\tilde q_1^T \tilde q_1 + \tilde q_2^T \tilde q_2) + \tfrac12 e^T K e`,
:math:`\dot M - 2C` skew-symmetric and :math:`S s_1 - s_2 = \dot e + \gamma_2 e`:
:math:`\dot V = -\gamma_1 (|s_1|^2 + |s_2|^2) - (\dot e + \gamma_2 e)^T K e
+ 2\gamma_1\gamma_2(\tilde q_1^T \dot{\tilde q}_1 + \tilde q_2^T \dot{\tilde q}_2)
+ e^T K \dot e`, and since :math:`|s|^2 = |\dot{\tilde q}|^2 + \gamma_2^2 |\tilde q|^2
+ 2\gamma_2 \tilde q^T \dot{\tilde q}`,

.. math::

    \dot V = -\gamma_1 \big(|\dot{\tilde q}_1|^2 + \gamma_2^2 |\tilde q_1|^2
             + |\dot{\tilde q}_2|^2 + \gamma_2^2 |\tilde q_2|^2\big) - \gamma_2\, e^T K e \le 0.

With every actuated joint flexible (S a permutation) this is the law of Brogliato, Ortega and
Lozano; a rigid actuated joint simply receives its :math:`U_R` entry.

Exact derivatives. :math:`\dot q_{2d}` and :math:`\ddot q_{2d}` need :math:`\dot U_R` and
:math:`\ddot U_R`, hence :math:`q_{1d}` up to order 4, :math:`\lambda_d` up to order 2 and the
link's :math:`\ddot q_1` and :math:`\dddot q_1`, which are not measured: they come from the
model above, :math:`\ddot q_1 = M^{-1}(S^T K(q_2 - S q_1) + S_r^T S_r U_R - C\dot q_1 - g
+ J_c^T \lambda)`, and its time derivative (which holds :math:`\dot q_2`). Everything is one
casadi expression differentiated by automatic differentiation (the total time derivative is
:math:`\sum_y \partial_y(\cdot)\,\dot y` over the state, the references and the forces). The
measured force λ cannot be differentiated: its value is used and its derivatives are taken as
those of :math:`\lambda_d`, which the force loop tracks (so the force term
:math:`-\lambda_d + K_f(\lambda - \lambda_d)` has the derivatives of :math:`-\lambda_d`).
Holding λ constant instead leaves the link jerk of the model short of
:math:`M^{-1} J_c^T \dot\lambda_d` while :math:`\lambda_d` falls, and V rises by a model error
that does not vanish with the step (7.6e-7 and 6.8e-7 J in the flexible one-constraint case
at h = 1 and 2 ms, against 1.6e-8 and 6.2e-8 J, O(h²), this way). Where it is not a valid
measurement (the contact is held but was not closed without impact over the last step)
:math:`\lambda_d` replaces it; the forces of contacts outside their constrained phase are not
in the model (0).

Link reference (square task, m = nv): :math:`q_{1d} = \phi^{-1}(X_d^*)` by Newton's method
from the previous :math:`q_{1d}` (first call: the measured :math:`q_1`), and its derivatives
from :math:`\frac{d^k}{dt^k}\phi(q_{1d}(t)) = X_d^{*(k)}`, linear in :math:`q_{1d}^{(k)}`
with matrix :math:`J_X`: :math:`q_{1d}^{(k)} = J_X^{-1}(X_d^{*(k)} - R_k)`, the remainder
:math:`R_k` by automatic differentiation. The phase machine of order 4 joins the segments of
the desired task trajectory :math:`C^4` (:mod:`ucontrol.control.trajectory_segment`), so
:math:`q_{1d}` is :math:`C^4` and neither V (which holds :math:`q_{1d}'''` through
:math:`\dot q_{2d}`) nor the motor torque (:math:`q_{1d}''''` through :math:`\ddot q_{2d}`)
jumps at the switches; only the gap target steps, from the virtual target to the surface at
:math:`t_f`, and the force term switches on there (both back at an opening before the fall
under the takeoff rule, :mod:`ucontrol.control.phase_machine`).

V and V1 are built on the tracked target :math:`X_d^*` (the virtual target during
transitions), unlike the rigid controller which clips the reference at the surface: a motor
reference of the clipped trajectory would need derivatives it does not have. V1 is the
kinetic-like part :math:`\tfrac12 s_1^T M s_1 + \tfrac12 s_2^T B s_2`, which scales the
virtual depth at :math:`\tau_0`.

Joint dampers D are refused: the link would receive :math:`D(\dot q_2 - S\dot q_1)`, and
keeping the closed loop above would need :math:`K(q_{2d} - S q_{1d}) + D(\dot q_{2d} - S
\dot q_{1d}) = S U_R`, a differential equation in :math:`q_{2d}` (a controller state), or the
motor acceleration, which holds the input itself.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from ucontrol.control.brogliato_controller import (
    _STATE_FORCE_INPUTS,
    BrogliatoController,
    BrogliatoGains,
    _reference_terms,
    _state_force,
)
from ucontrol.control.controller import ContactState, Vector
from ucontrol.control.desired_cycle import DesiredCycle
from ucontrol.control.phase_machine import DesiredState
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.exceptions import InvalidParameterError, SolverError
from ucontrol.model.compiled_function import CompiledFunction
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.robot_model import RobotModel
from ucontrol.model.symbolic_model import SymbolicModel

if TYPE_CHECKING:
    from ucontrol.log import Log

#: Newton's method for :math:`q_{1d}` stops once its step is below this, in [rad] (or [m]).
NEWTON_TOLERANCE = 1e-10
#: ... or fails after this many iterations.
NEWTON_ITERATIONS = 30
#: Distinct steps whose Taylor coefficients of Newton's start are kept.
TAYLOR_CACHE_SIZE = 64

#: Per-sample fields written to the log besides those of the rigid controller
#: (:data:`ucontrol.control.brogliato_controller.LOG_FIELDS`), with nv links and nf motors.
FLEXIBLE_LOG_FIELDS = {
    "motor_desired": "(nf,)",
    "link_desired": "(nv,)",
}


class FlexibleBrogliatoController(BrogliatoController):
    r"""Phase-machine tracking controller for a robot with flexible joints.

    Called like :class:`BrogliatoController` with the extended state of the plant:
    ``controller(t, q, v, contacts)`` with q = (q1, q2) of shape (nq + nf,) and
    v = (dq1, dq2) of shape (nv + nf,); it returns u of shape (nu,), the motor torque on a
    flexible joint. Phases, events and log fields are those of :class:`BrogliatoController`
    (V and V1 are the flexible ones), plus :data:`FLEXIBLE_LOG_FIELDS`.

    Args:
        robot: The controller's model of the links (rigid robot); fully actuated, fixed base,
            revolute and prismatic joints only.
        flexible: Which joints are flexible, K and B (no damper).
        task: Square task coordinates (m = nv).
        cycle: The desired cycle.
        gains: γ1, γ2 and K_f (the null-space gains are unused).
        posture: As for :class:`BrogliatoController`; unused (the task is square).

    Attributes:
        link_desired: :math:`q_{1d}` and its first 4 time derivatives at the last call,
            each shape (nv,).
        motor_desired: :math:`q_{2d}, \dot q_{2d}, \ddot q_{2d}` at the last call, each (nf,).

    Raises:
        InvalidParameterError: The task is redundant, ``flexible`` belongs to another robot
            or has dampers, a joint is not revolute or prismatic, the robot is not fully
            actuated, or the cycle's ``reference_after_impact`` is not ``"virtual"``.
        FrameNotFoundError: The task frame is not in the robot.
    """

    _order = 4

    def __init__(
        self,
        robot: RobotModel,
        flexible: FlexibleJoints,
        task: TaskCoordinates,
        cycle: DesiredCycle,
        gains: BrogliatoGains,
        *,
        posture: Vector | None = None,
    ) -> None:
        if (flexible.nq, flexible.nv) != (robot.nq, robot.nv):
            raise InvalidParameterError(
                "flexible",
                flexible.joints,
                f"flexible joints of a robot with nq = {robot.nq} and nv = {robot.nv}, "
                f"not {flexible.nq} and {flexible.nv}",
            )
        if task.m != robot.nv:
            raise InvalidParameterError(
                "task",
                task.names,
                f"a square task of m = nv = {robot.nv} coordinates (the flexible law inverts "
                "the task map; redundant tasks are not supported)",
            )
        if cycle.reference_after_impact != "virtual":
            raise InvalidParameterError(
                "reference_after_impact",
                cycle.reference_after_impact,
                '"virtual" for the flexible-joint law (its motor reference needs the '
                "derivatives of one target)",
            )
        if np.any(flexible.damping != 0.0):
            raise InvalidParameterError(
                "damping",
                flexible.damping.tolist(),
                "0 on every flexible joint (the law cannot cancel a transmission damper)",
            )
        model = SymbolicModel(robot)
        self.flexible = flexible
        super().__init__(robot, task, cycle, gains, posture=posture)
        position = model.frame_position(task.frame)
        q, X_d = ca.SX.sym("q", robot.nv), ca.SX.sym("X_d", task.m)
        X = ca.DM(task.A) @ position(q) - ca.DM(task.b)
        error = X - X_d  # [m]
        self._newton_step = CompiledFunction(
            ca.Function(
                "newton_step",
                [q, X_d],
                [ca.solve(ca.jacobian(X, q), error), error],
                ["q", "X_d"],
                ["step", "error"],
            )
        )
        self._reference_derivatives = CompiledFunction(_reference_derivatives(q, X))
        state_force = cycle.force_profile == "state"
        law = self._law = CompiledFunction(
            _law_function(model, flexible, self.machine.coordinates, X, q, state_force=state_force)
        )
        function = law.function
        inputs = {name: law.input_view(function.index_in(name)) for name in function.name_in()}
        # Parameters: constant per controller.
        inputs["gamma1"][...], inputs["gamma2"][...] = gains.gamma1, gains.gamma2
        if state_force:
            inputs["force_gain"][...] = gains.force_gain
        inputs["stiffness"][...] = flexible.stiffness
        inputs["motor_inertia"][...] = flexible.motor_inertia
        # The inputs written in place before each call. The measured state q = (q1, q2) and
        # v = (dq1, dq2), each (nv + nf,), as the plant orders them, and views of q1, dq1
        # (nv,), q2, dq2 (nf,).
        nv, nf = robot.nv, flexible.nf
        self._q_input, self._v_input = inputs["q"], inputs["v"]
        self._state_input = (
            self._q_input[:nv], self._v_input[:nv], self._q_input[nv:], self._v_input[nv:]
        )  # fmt: skip
        # The link reference: q1d and its 4 derivatives (nv, 5), first holding X_d's
        # derivatives 1 to 4, which the derivatives of q1d then replace (Function
        # reference_derivatives, whose input is bound to it).
        self._reference_input = law.input_buffer(law.function.index_in("link_reference"))
        self._target_input = tuple(inputs["link_reference"][:, 1:].T)
        derivatives = self._reference_derivatives
        derivatives.bind_input(derivatives.function.index_in("reference"), self._reference_input)
        # The force term and its 2 derivatives (n, 3), then the model's contact force and its
        # derivative (n, 2): both bound to one array, written at once. With the state-based
        # λ_d, what the law designs it from, each (n,) (λ_t (n, 3) with its derivatives):
        # held, active, λ_t, λ_t', λ_t'', measured, λ bound to the rows of one array.
        n = len(self.machine.contacts)
        self._model_force_input = np.zeros(7 * n if state_force else 5 * n)
        if state_force:  # the rows, contact i at position i (_write_state_force_inputs)
            rows = tuple(self._model_force_input.reshape(7, n))
            self._state_force_inputs = (rows, np.arange(n))
        parts = (
            zip(_STATE_FORCE_INPUTS, (1, 1, 3, 1, 1))
            if state_force
            else (
                ("force", 3),
                ("model_force", 2),
            )
        )
        start = 0
        for name, size in parts:  # sizes in columns of n
            if n:
                part = self._model_force_input[start : start + size * n]
                law.bind_input(function.index_in(name), part)
            start += size * n
        # Views of the reference input: q1d, the targets' derivatives 1 to 4 (those of q1d
        # once solved), all 5 as rows.
        self._reference_q = self._reference_input[:nv]
        self._reference_tail = self._reference_input[nv:]
        self._reference_rows = self._reference_input.reshape(5, nv)
        # The law's outputs bound, by name, to the parts of one array (copied at once per
        # call), and a view of each part.
        self._law_output = np.zeros(sum(function.nnz_out(name) for name in function.name_out()))
        self._output_slices: dict[str, slice] = {}
        start = 0
        for name in function.name_out():
            end = start + law.function.nnz_out(name)
            self._output_slices[name] = slice(start, end)
            law.bind_output(law.function.index_out(name), self._law_output[start:end])
            start = end
        self._V1_output = self._law_output[self._output_slices["V1"]]
        # The three compiled calls on their inputs as written, and their output buffers.
        self._run_newton = self._newton_step.runner()
        newton = self._newton_step.function
        self._newton_output = self._newton_step.output_buffer(newton.index_out("step"))
        self._newton_error = self._newton_step.output_buffer(newton.index_out("error"))
        self._run_derivatives = derivatives.runner()
        self._derivatives_output = derivatives.output_buffer(0)
        self._run_flexible_law = law.runner()
        # Newton's iterate (updated in place) and target.
        self._newton_q = self._newton_step.input_buffer(newton.index_in("q"))
        self._newton_target = self._newton_step.input_buffer(newton.index_in("X_d"))
        # The coefficients [s^k / k!] of Newton's start by step dt [s] (see _taylor_start).
        self._taylor: dict[float, Vector] = {}
        self._nf = nf
        self._split_shapes = ((robot.nq + nf,), (nv + nf,))
        self._flexible_log_fields: tuple[Log, tuple[NDArray[np.float64], ...]] | None = None

    def reset(self) -> None:
        """Forget the run, including the last link reference (Newton's starting point)."""
        super().reset()
        nv, nf = self.robot.nv, self.flexible.nf
        self._reference_time: float | None = None
        self._link_rows = np.zeros((5, nv))  # q1d and its 4 derivatives, one per row
        # Read-only force derivatives of a held call (kept alive, so that the same object is
        # the same values: the plateau), their force-term rows and the first of them.
        self._force_rates: tuple[tuple[Vector, ...], list[float], list[float]] | None = None
        # The law's outputs of the last call (:data:`_LAW_OUTPUTS` (, ``lambda_d`` (n,)), as
        # ``_law_output``).
        state_force = self.cycle.force_profile == "state"
        n = len(self.machine.contacts) if state_force else 0
        self._outputs = np.zeros(2 * nv + 2 + 3 * nf + n)
        if state_force:
            self._lambda_d_output = np.zeros(self.task.m)

    @property
    def link_desired(self) -> tuple[Vector, ...]:
        """:math:`q_{1d}` and its first 4 time derivatives at the last call, each (nv,)."""
        return tuple(self._link_rows.copy())

    @property
    def motor_desired(self) -> tuple[Vector, ...]:
        r""":math:`q_{2d}, \dot q_{2d}, \ddot q_{2d}` at the last call, each (nf,)."""
        motor = self._outputs[self._output_slices["motor_reference"]]
        return tuple(motor.reshape(3, self.flexible.nf).copy())

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Actuator torques, shape (nu,), in [N m] (or [N]): motor torques on flexible joints."""
        q_shape, v_shape = self._split_shapes
        if q.shape != q_shape or v.shape != v_shape:
            self.flexible.split(q, v)  # raises the ShapeError
        q1 = q[: self.robot.nq]  # FlexibleJoints.split without its checks
        closed = self._measure(t, contacts)
        # The measured state: the same input for every evaluation, (q1, q2) and (dq1, dq2) as
        # the plant orders them.
        self._q_input[...], self._v_input[...] = q, v
        machine = self.machine
        desired = machine.desired(t)
        V1 = self._evaluate(t, q1, desired)
        if machine.update(t, closed, V1, desired):
            desired = machine.desired(t)
            self._evaluate(t, q1, desired)
        self.desired = desired
        # The law's input and output hold the last evaluation (that after the phase update).
        out = self._outputs = self._law_output.copy()  # fresh: the torque returned is kept
        part = self._output_slices
        self.V, self.V1 = out[part["V"]].item(), out[part["V1"]].item()
        self.X = out[part["X"]]
        if self._state_force_inputs is not None:  # λ_d applied, on the task rows (m,)
            assert self._lambda_d_output is not None
            self._lambda_d_output[machine.coordinates] = out[part["lambda_d"]]
        self._link_rows = self._reference_rows.copy()
        self._reference_time = t
        return out[part["u"]]

    def prepare_log(self, log: Log) -> None:
        """Declare the rigid controller's fields and :data:`FLEXIBLE_LOG_FIELDS`."""
        super().prepare_log(log)
        shapes = {"(nf,)": (self.flexible.nf,), "(nv,)": (self.robot.nv,)}
        for name, shape in FLEXIBLE_LOG_FIELDS.items():
            log.add_field(name, shapes[shape])
        log.metadata["controller"] = "flexible_brogliato"

    def record(self, log: Log) -> None:
        """Write the values of the last call into the current row (events only once)."""
        super().record(log)
        fields = self._flexible_log_fields
        if fields is None or fields[0] is not log:
            fields = self._flexible_log_fields = (
                log,
                log.extra_fields(list(FLEXIBLE_LOG_FIELDS)),
            )
        motor_desired, link_desired = fields[1]  # in the order of FLEXIBLE_LOG_FIELDS
        k = log.size  # len(log)
        motor_desired[k] = self._outputs[self._output_slices["motor_reference"]][: self._nf]
        link_desired[k] = self._link_rows[0]

    def _evaluate(self, t: float, q1: Vector, desired: DesiredState) -> float:
        """Evaluate the law at time ``t`` [s] on ``desired``; return its V1 [J].

        The measured state is the one :meth:`__call__` wrote into the law's input, ``q1`` its
        link configuration (nv,) (Newton's start on the first call). The law's input and
        output (``self._law_output``) hold this evaluation until the next one.
        """
        # The reference input: q1d, then X_d derivatives 1 to 4 (one copy from the machine's
        # stacked samples), which the derivatives of q1d replace.
        self._reference_q[...] = self._link_reference(t, desired.target[0], q1)
        stacked, tail = desired.stacked, self._reference_tail
        if stacked is not None and stacked.size == self._reference_input.size:
            tail[...] = stacked[stacked.size - tail.size :]
        else:
            X_1, X_2, X_3, X_4 = self._target_input
            X_1[...], X_2[...], X_3[...], X_4[...] = desired.target[1:]
        self._run_derivatives()  # reads the reference input in place
        derivatives = self._derivatives_output
        tail[...] = derivatives  # q1d derivatives 1 to 4
        held = self._held_contacts(desired.constrained)
        if self._state_force_inputs is not None:  # λ_d designed in the law from the state
            self._write_state_force_inputs(desired, held)
        elif held:
            # λ_d and its derivatives (3, n): 0 unless held; the force λ used and its
            # derivative (2, n): the measured value with the derivatives of λ_d, or λ_d where
            # there is no valid measurement. Force term -λ_d + K_f (λ - λ_d) (3, n), row by
            # row (λ - λ_d is λ_d' - λ_d' and λ_d'' - λ_d'' on the derivative rows), then λ:
            # on Python scalars (n is a handful).
            force_gain = self.gains.force_gain
            lambda_m, values = self._force_terms(desired, held)
            rates = desired.force_derivatives
            cached = self._force_rates
            if cached is None or cached[0] is not rates:  # else read-only values seen last call
                rows = [d.tolist() for d in rates]
                rate_terms = [-d + force_gain * (d - d) for row in rows for d in row]
                cached = (rates, rate_terms, rows[0])
                # Kept only for read-only values (the machine's plateau, shared between calls).
                frozen = not any(d.flags.writeable for d in rates)
                self._force_rates = cached if frozen else None
            self._model_force_input[...] = values + cached[1] + lambda_m + cached[2]
            self._force_written = True
        elif self._force_written:  # no contact held: no force in the model
            self._model_force_input.fill(0.0)
            self._force_written = False
        self._run_flexible_law()
        return self._V1_output.item()

    def _taylor_start(self, dt: float) -> None:
        r"""Newton's start: the last call's q1d expanded to ``dt`` [s] later, written in place.

        :math:`\sum_k q_{1d}^{(k)} dt^k / k!` as one product of the coefficients with the rows
        of the last call. The coefficients of each ``dt`` are kept (a run has a handful of
        distinct steps: the sample times' differences round to a few values).
        """
        cache = self._taylor
        taylor = cache.get(dt)
        if taylor is None:
            if len(cache) >= TAYLOR_CACHE_SIZE:  # a run with ever new steps: start again
                cache.clear()
            taylor = cache[dt] = np.array((1.0, dt, dt * dt / 2, dt**3 / 6, dt**4 / 24))
        np.dot(taylor, self._link_rows, out=self._newton_q)

    def _link_reference(self, t: float, X_d: Vector, q1: Vector) -> Vector:
        r""":math:`q_{1d} = \phi^{-1}(X_d)` at ``t`` [s] by Newton's method, shape (nv,).

        Newton starts from the Taylor expansion of the last call's :math:`q_{1d}` (first call:
        the measured link configuration ``q1``). The array returned is Newton's input buffer,
        rewritten by the next call.

        Raises:
            SolverError: Newton's method does not converge (target out of reach, singular
                task Jacobian).
        """
        q = self._newton_q  # a view of the input's first nv
        if self._reference_time is None:
            q[...] = q1
        else:
            self._taylor_start(t - self._reference_time)
        self._newton_target[...] = X_d
        run_newton, step = self._run_newton, self._newton_output
        for _ in range(NEWTON_ITERATIONS):
            run_newton()
            values = step.tolist()
            if not all(map(math.isfinite, values)):  # singular task Jacobian
                break
            q -= step
            if max(map(abs, values)) <= NEWTON_TOLERANCE:
                return q
        raise SolverError(
            "Newton's method for the link reference q1d = φ⁻¹(X_d)",
            f"no convergence to X_d = {X_d.tolist()} from q = {q.tolist()}",
            float(np.max(np.abs(self._newton_error))),
        )


def _time_derivative(expression: ca.SX, variables: list[ca.SX], rates: list[ca.SX]) -> ca.SX:
    r"""Total time derivative :math:`\sum_i \partial_{y_i} e\, \dot y_i` by casadi's AD."""
    return ca.jtimes(expression, ca.vertcat(*variables), ca.vertcat(*rates))


def _reference_derivatives(q: ca.SX, X: ca.SX) -> ca.Function:
    r"""Derivatives q', q'', q''', q'''' of the link reference as one casadi Function.

    Input ``reference`` (nv, 5): q and X', X'', X''', X'''' as columns; output
    ``derivatives`` (nv, 4): q' to q'''' as columns, along :math:`\phi(q(t)) = X(t)`
    (m = nv): :math:`q^{(k)} = J^{-1}(X^{(k)} - R_k)`, :math:`R_k` the k-th derivative of
    :math:`\phi(q(t))` with :math:`q^{(k)} = 0`.
    """
    nv = q.shape[0]
    rates = [q] + [ca.SX.sym(f"q_{k}", nv) for k in range(1, 5)]
    targets = [ca.SX.sym(f"X_{k}", nv) for k in range(1, 5)]
    J = ca.jacobian(X, q)
    derivative = X
    solved: list[ca.SX] = []
    for k in range(1, 5):
        derivative = _time_derivative(derivative, rates[:k], rates[1 : k + 1])
        remainder = ca.substitute(
            derivative, ca.vertcat(*rates[1 : k + 1]), ca.vertcat(*solved, ca.SX.zeros(nv))
        )
        solved.append(ca.solve(J, targets[k - 1] - remainder))
    return ca.Function(
        "reference_derivatives",
        [ca.horzcat(q, *targets)],
        [ca.horzcat(*solved)],
        ["reference"],
        ["derivatives"],
    )


#: Outputs of the flexible law, by name.
_LAW_OUTPUTS = ("u", "X", "V", "V1", "motor_reference")


def _law_function(
    model: SymbolicModel,
    flexible: FlexibleJoints,
    coordinates: NDArray[np.int64],
    X: ca.SX,
    q: ca.SX,
    *,
    state_force: bool = False,
) -> ca.Function:
    r"""The flexible law: its one definition, a casadi Function with named inputs and outputs.

    ``X`` is the task map of the symbol ``q``; ``coordinates`` are the task rows of the declared
    contacts (n of them). Inputs, in this order: ``q`` = (q1, q2) and ``v`` =
    (dq1, dq2) in the plant's order, each (nv + nf,); ``link_reference`` (nv, 5), q1d and its
    4 derivatives as columns; ``force`` (n, 3), the force term
    :math:`-\lambda_d + K_f(\lambda - \lambda_d)` and its 2 derivatives as columns;
    ``model_force`` (n, 2), the model's contact force and its derivative; and the parameters
    ``gamma1``, ``gamma2``, ``stiffness`` K (nf,) and ``motor_inertia`` B (nf,), so that one
    compiled library serves every gain and stiffness (sweeps do not recompile). Outputs
    (:data:`_LAW_OUTPUTS`): ``u`` (nu,), ``X`` the task coordinates of the links (m,), ``V``,
    ``V1``, ``motor_reference`` (nf, 3): q2d, dq2d, ddq2d as columns.

    With ``state_force`` (``force_profile = "state"``) the law designs :math:`\lambda_d` from
    the state (:func:`~ucontrol.control.brogliato_controller._state_force`, the rigid law's
    design applied to the links under the desired link torque :math:`U_R`, i.e. with the
    motors on their reference, e = 0): ``force`` and ``model_force`` are replaced by ``held``,
    ``active`` (n,), ``lambda_time`` (n, 3) the time profile :math:`\lambda_t` and its 2
    derivatives, ``measured`` and ``lambda_measured`` (n,), a parameter ``force_gain``
    :math:`K_f` is added, and an output ``lambda_d`` (n,). Its derivatives, which
    :math:`\dot U_R` and :math:`\ddot U_R` need, are those of this expression of the state
    (by AD, with the model's link acceleration and jerk), the measured force taking those of
    :math:`\lambda_d` as with the time profile.
    """
    nv, nf, n = model.nv, flexible.nf, len(coordinates)
    gamma1, gamma2 = ca.SX.sym("gamma1"), ca.SX.sym("gamma2")
    K, B = ca.SX.sym("stiffness", nf), ca.SX.sym("motor_inertia", nf)
    motors = [int(i) for i in flexible.v_index]
    rigid = [i for i in range(nv) if i not in motors]
    q1, dq1 = ca.SX.sym("q1", nv), ca.SX.sym("dq1", nv)
    q2, dq2 = ca.SX.sym("q2", nf), ca.SX.sym("dq2", nf)
    r = [ca.SX.sym(f"q1d_{k}", nv) for k in range(5)]
    link_X = ca.substitute(X, q, q1)
    J_c = ca.jacobian(link_X, q1)[[int(c) for c in coordinates], :]
    M, C, g = model.mass_matrix(q1), model.coriolis_matrix(q1, dq1), model.gravity(q1)
    q1_error, dq1_error, dq1_r, ddq1_r = _reference_terms(q1, dq1, (r[0], r[1], r[2]), gamma2)
    s1 = dq1_error + gamma2 * q1_error
    link_input = ca.SX.zeros(nv)
    link_input[motors] = K * (q2 - q1[motors])  # spring torque on the links
    force_inputs: dict[str, ca.SX] = {}
    if state_force:
        force_gain = ca.SX.sym("force_gain")
        force_inputs = {name: ca.SX.sym(name, n) for name in _STATE_FORCE_INPUTS}
        lambda_t = [ca.SX.sym(f"lambda_t_{k}", n) for k in range(3)]
        force_inputs["lambda_time"] = lambda_t[0]
        measured, lambda_m = force_inputs["measured"], force_inputs["lambda_measured"]
        drift = ca.jtimes(J_c @ dq1, q1, dq1)  # J̇_c q̇1 [m/s²]
        closed_loop = (M, J_c, drift, ddq1_r, C @ s1 + gamma1 * s1)
        force_term, lambda_d = _state_force(closed_loop, force_inputs, force_gain)
        used = lambda_d + measured * (lambda_m - lambda_d)  # the model's force [N]
        U_R = M @ ddq1_r + C @ dq1_r + g - gamma1 * s1 + J_c.T @ force_term  # [N m]
        link_input[rigid] = U_R[rigid]
        ddq1 = ca.solve(M, link_input - C @ dq1 - g + J_c.T @ used)  # [rad/s²]
        own = [q1, dq1, *r[:3], lambda_t[0]]
        lambda_d_rate = _time_derivative(lambda_d, own, [dq1, ddq1, *r[1:4], lambda_t[1]])
        variables = [q1, dq1, q2, *r[:4], lambda_t[0], lambda_t[1], lambda_m]
        rates = [dq1, ddq1, dq2, *r[1:], lambda_t[1], lambda_t[2], lambda_d_rate]
        force_inputs["lambda_time"] = ca.horzcat(*lambda_t)
        force_inputs["force_gain"] = force_gain
    else:  # the force term and its 2 derivatives, the model's force and its derivative
        f = [ca.SX.sym(f"f_{k}", n) for k in range(3)]
        lam = [ca.SX.sym(f"lambda_{k}", n) for k in range(2)]
        U_R = M @ ddq1_r + C @ dq1_r + g - gamma1 * s1 + J_c.T @ f[0]  # [N m]
        link_input[rigid] = U_R[rigid]
        ddq1 = ca.solve(M, link_input - C @ dq1 - g + J_c.T @ lam[0])  # [rad/s²]
        variables = [q1, dq1, q2, *r[:4], f[0], f[1], lam[0]]
        rates = [dq1, ddq1, dq2, *r[1:], f[1], f[2], lam[1]]
        force_inputs = {"force": ca.horzcat(*f), "model_force": ca.horzcat(*lam)}
    dU_R = _time_derivative(U_R, variables, rates)
    ddU_R = _time_derivative(dU_R, variables, rates)
    q2d = r[0][motors] + U_R[motors] / K
    dq2d = r[1][motors] + dU_R[motors] / K
    ddq2d = r[2][motors] + ddU_R[motors] / K
    q2_error, dq2_error = q2 - q2d, dq2 - dq2d
    s2 = dq2_error + gamma2 * q2_error
    ddq2_r = ddq2d - gamma2 * dq2_error
    u = ca.SX.zeros(nv)
    u[[int(i) for i in flexible.input_index]] = B * ddq2_r + K * (q2d - r[0][motors]) - gamma1 * s2
    u[rigid] = U_R[rigid]  # fixed base, fully actuated: input index = velocity index
    deflection_error = q1_error[motors] - q2_error
    V1 = 0.5 * ca.dot(s1, M @ s1) + 0.5 * ca.dot(s2, B * s2)  # [J]
    V = (
        V1
        + gamma1 * gamma2 * (ca.dot(q1_error, q1_error) + ca.dot(q2_error, q2_error))
        + 0.5 * ca.dot(deflection_error, K * deflection_error)
    )
    inputs = {"q": ca.vertcat(q1, q2), "v": ca.vertcat(dq1, dq2)}
    inputs |= {"link_reference": ca.horzcat(*r), **force_inputs}
    inputs |= {"gamma1": gamma1, "gamma2": gamma2, "stiffness": K, "motor_inertia": B}
    motor_reference = ca.horzcat(q2d, dq2d, ddq2d)
    outputs = dict(zip(_LAW_OUTPUTS, (u, link_X, V, V1, motor_reference), strict=True))
    if state_force:
        outputs["lambda_d"] = lambda_d
    return ca.Function(
        "flexible_brogliato_state_force_law" if state_force else "flexible_brogliato_law",
        list(inputs.values()),
        list(outputs.values()),
        list(inputs),
        list(outputs),
    )
