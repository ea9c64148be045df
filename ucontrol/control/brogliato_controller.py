r"""Tracking control through free, transition, constrained and takeoff phases (Brogliato ch. 8).

Task coordinates :math:`X = \phi(q)` with the constraints :math:`X_1 \ge 0`
(:class:`TaskCoordinates`), errors :math:`\tilde X = X - X_d`,
:math:`s = \dot{\tilde X} + \gamma_2 \tilde X`, :math:`\dot X_r = \dot X_d - \gamma_2 \tilde X`.
The law is written in joint space with the reference velocity
:math:`\dot q_r = J^+ \dot X_r + N \xi` (:math:`J^+ = J^T (J J^T)^{-1}`, :math:`N = I - J^+ J`,
posture velocity :math:`\xi = -\gamma_p (q \ominus q_p)`) and :math:`s_q = \dot q - \dot q_r`:

.. math::

    \tau = M \ddot q_r + C(q, \dot q) \dot q_r + g(q) - \gamma_1 J^T s
           - \gamma_N N^T M N s_q
           + J_c^T \big(-\lambda_d + K_f (\lambda - \lambda_d)\big).

For a square task (m = nv, the two-link arm) :math:`N = 0`, :math:`s_q = J^{-1} s` and this is
exactly the task-space Slotine–Li law
:math:`\tau = J^T(\bar M \ddot X_r + \bar C \dot X_r + \bar g - \gamma_1 s)` of the book with
:math:`\bar M = J^{-T} M J^{-1}`; for a redundant arm the null space tracks the posture. The
Lyapunov function is :math:`V = V_1 + \gamma_1 \gamma_2 \tilde X^T \tilde X`,
:math:`V_1 = \tfrac12 s_q^T M s_q` (:math:`= \tfrac12 s^T \bar M s` when square), with
:math:`\dot V = -\gamma_1(\|\dot{\tilde X}\|^2 + \gamma_2^2\|\tilde X\|^2) - \gamma_N
\|N s_q\|_M^2` in free motion. The last term acts in the constrained phase only, on the
contacts :math:`c` held there; λ is the measured contact *force*, the impulse of the last step
divided by its length.

The law is written once, as a casadi Function with named inputs and outputs
(:func:`_rigid_law_function`): compiled to C where a compiler is found, run by casadi's
virtual machine otherwise or with ``UCONTROL_NO_COMPILE=1`` (the reference the compiled path
is checked against, tests/test_paths_agree.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.control.controller import ContactState, Vector
from ucontrol.control.desired_cycle import DesiredCycle
from ucontrol.control.phase import Phase
from ucontrol.control.phase_machine import DesiredState, PhaseMachine
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.model.compile_cache import definition_key
from ucontrol.model.compiled_function import CompiledFunction
from ucontrol.model.robot_model import RobotModel, inertia_parameters

if TYPE_CHECKING:
    import casadi as ca

    from ucontrol.log import Log


@dataclass(frozen=True, kw_only=True)
class BrogliatoGains:
    r"""Gains of :class:`BrogliatoController`.

    Attributes:
        gamma1: :math:`\gamma_1` in [N s/m], > 0: damping of the sliding variable s.
        gamma2: :math:`\gamma_2` in [1/s], > 0: bandwidth of :math:`s = 0`.
        force_gain: :math:`K_f` in [0, 1): feedback on the contact force error. The force
            measured is that of the previous step, so the loop
            :math:`\lambda_k - \lambda_d = r - K_f(\lambda_{k-1} - \lambda_d)` (r: model
            residual) is stable only for :math:`K_f < 1`; it divides the error by
            :math:`1 + K_f`.
        posture_gain: :math:`\gamma_p` in [1/s], > 0: posture velocity in the null space.
        null_space_gain: :math:`\gamma_N` in [1/s], > 0: damping of the null-space motion.
    """

    gamma1: float
    gamma2: float
    force_gain: float = 0.5
    posture_gain: float = 2.0
    null_space_gain: float = 10.0

    def __post_init__(self) -> None:
        for name in ("gamma1", "gamma2", "posture_gain", "null_space_gain"):
            object.__setattr__(self, name, as_positive(name, getattr(self, name)))
        force_gain = float(self.force_gain)
        if not 0.0 <= force_gain < 1.0:
            raise InvalidParameterError("force_gain", self.force_gain, "in [0, 1)")
        object.__setattr__(self, "force_gain", force_gain)


#: Pinocchio joints whose configuration space is a vector space (q ⊖ q0 = q - q0).
_VECTOR_SPACE_JOINTS = frozenset(
    f"JointModel{name}"
    for name in (
        *("RX", "RY", "RZ", "RevoluteUnaligned", "PX", "PY", "PZ", "PrismaticUnaligned"),
        "Translation",
    )
)

#: A contact closing faster than this at the start of a step is impacting, in [m/s]: the
#: impulse of that step is not used as a force measurement.
IMPACT_SPEED = 1e-6

#: Outputs of the law's casadi Function, by name (:func:`_rigid_law_function`): the torque
#: (nv,), V1 and V on the reference [J], the task coordinates X (m,).
LAW_OUTPUTS = ("tau", "V1", "V", "X")
#: The modules whose code writes the law (part of its definition key).
_GENERATED_BY = (
    "ucontrol.control.brogliato_controller",
    "ucontrol.model.symbolic_model",
    "ucontrol.model.compiled_function",
)

#: Per-sample fields written to the log (name: shape, with m task coordinates and n contacts).
LOG_FIELDS = {
    "phase": "()",
    "contact_phase": "(n,)",
    "events": "(n,)",
    "V": "()",
    "V1": "()",
    "virtual_depth": "(n,)",
    "task_position": "(m,)",
    "task_desired": "(m,)",
    "task_target": "(m,)",
    "lambda_d": "(n,)",
    "contact_force": "(n,)",
}


class BrogliatoController:
    """Phase-machine tracking controller for a robot under unilateral constraints.

    Call it as ``controller(t, q, v, contacts)`` (see :class:`ucontrol.control.Controller`)
    with non-decreasing times; it is stateful (call :meth:`reset` before reusing it). Its
    contact names must be those of the plant's constraints.

    Args:
        robot: The controller's model of the robot (may differ from the plant's, see
            :meth:`RobotModel.with_scaled_inertia`); fully actuated.
        task: Task coordinates: the contact frame, its constraints and tangential directions.
        cycle: The desired cycle (nominal path, contact phases, transition design).
        gains: γ1, γ2, K_f and the null-space gains.
        posture: Posture :math:`q_p` of the null-space task, shape (nq,); default the neutral
            configuration (unused when the task is square).

    Raises:
        InvalidParameterError: The robot is not fully actuated.
        NotFoundError: The cycle names a contact that is not a task constraint.
        PathThroughSurfaceError: The nominal path crosses an obstacle outside its contact
            phases.
    """

    #: Number of time derivatives of the desired trajectory the law uses.
    _order = 2

    def __init__(
        self,
        robot: RobotModel,
        task: TaskCoordinates,
        cycle: DesiredCycle,
        gains: BrogliatoGains,
        *,
        posture: Vector | None = None,
    ) -> None:
        if robot.nu != robot.nv:
            raise InvalidParameterError("robot", robot.name, "a fully actuated robot (nu = nv)")
        self.robot = robot
        self.task = task
        self.cycle = cycle
        self.gains = gains
        self.posture = robot.check_configuration(
            "posture", robot.neutral() if posture is None else posture
        )
        self.machine = PhaseMachine(task, cycle, order=self._order)
        self._model = robot.model
        self._data = pin.Data(robot.model)
        self._redundant = task.m < robot.nv
        # With only vector-space joints, q ⊖ q_p is q - q_p: Pinocchio's difference is that
        # subtraction there (its VectorSpaceOperation), without the call.
        self._posture_by_subtraction = self._redundant and all(
            joint.shortname() in _VECTOR_SPACE_JOINTS for joint in robot.model.joints[1:]
        )
        self._pass_data = self._data  # the data the law reads (use_plant_data)
        self._plant_terms = False  # whether M and h come from the plant's evaluation
        # The rigid law (subclasses bring their own): one casadi Function, compiled or run by
        # casadi's virtual machine (UCONTROL_NO_COMPILE=1, no C compiler).
        self._rigid_law: CompiledFunction | None = None
        self._inertia_input: NDArray[np.float64] | None = None  # the law's, if it has one
        # λ_d applied on the task rows (the state profile's output), or None: the time
        # profile's, ``desired.force``.
        self._lambda_d_output: Vector | None = None
        # With the state profile, the law's inputs that λ_d is designed from and the position
        # of each declared contact in them (see _write_state_force_inputs); else None.
        self._state_force_inputs: tuple[tuple[Vector, ...], NDArray[np.int64]] | None = None
        if type(self)._order == 2:
            self._build_rigid_law()
        self._log_fields: tuple[Log, tuple[NDArray[Any], ...]] | None = None
        self.reset()

    def _build_rigid_law(self) -> None:
        """Build the law of :func:`_rigid_law_function` and bind its inputs by name."""
        robot, task, gains = self.robot, self.task, self.gains
        model, joint = robot.model, robot.model.frames[task.frame_id].parentJoint
        support = [  # the velocity coordinates that move the task frame
            int(i)
            for j in model.supports[joint][1:]
            for i in range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)
        ]
        state_force = self.cycle.force_profile == "state"
        self._clipped_reference = clipped = self.cycle.reference_after_impact == "clipped"
        arguments = (robot.nv, task.m, self._redundant, support)

        def build() -> ca.Function:
            kinematics = _symbolic_kinematics(robot, task.frame)
            return _rigid_law_function(
                *arguments, kinematics, state_force=state_force, clipped_reference=clipped
            )

        # What the law is built from (the model's kinematics for the symbolic ones; its
        # inertias are an input): a later build of an equal law, e.g. for another draw of the
        # masses, loads its library without casadi's graph.
        definition = definition_key(
            [*arguments, _without_inertias(model), task.frame, state_force, clipped],
            _GENERATED_BY,
        )
        name = _law_name(state_force)
        law = self._rigid_law = CompiledFunction.cached(name, definition, build)
        names = law.names_in()
        inputs = {name: law.input_view(law.index_in(name)) for name in names}
        # The configuration input of a law with its own kinematics, or None.
        self._configuration_input = inputs.get("q")
        self._law_index = {name: law.index_in(name) for name in names}
        self._run_law = law.runner()
        inputs["parameters"][:] = _law_parameters(task, gains)  # constant per controller
        # The model's inertias (e.g. mass-scaled) where the law has them as an input: written
        # with the data's bindings, per model (use_inertias).
        self._inertia_input = inputs.get("inertia")
        self._bind_model()
        # The other inputs are written in place at each call: v, q ⊖ q_p, the force term, and
        # the columns of the target (X_d, dX_d, ddX_d) and of the reference (X_d, dX_d),
        # each (m,).
        self._velocity_input, self._posture_input = inputs["v"], inputs["posture_error"]
        # The force term (time profile), or what the law designs λ_d from (state profile).
        self._force_input = inputs.get("force")
        if state_force:
            self._state_force_inputs = (
                tuple(inputs[name] for name in _STATE_FORCE_INPUTS),
                self.machine.coordinates,
            )
        target, reference = inputs["target"], inputs["reference"]
        self._law_columns = (*target.T, *reference.T)
        # The target at once from the machine's stacked samples, and the reference from the
        # target's first two columns where nothing is clipped.
        self._target_buffer = law.input_buffer(law.index_in("target"))
        self._reference_buffer = law.input_buffer(law.index_in("reference"))
        self._target_head = self._target_buffer[: self._reference_buffer.size]
        outputs = {name: law.output_buffer(law.index_out(name)) for name in LAW_OUTPUTS}
        self._V1_output, self._V_output = outputs["V1"], outputs["V"]
        self._X_output = outputs["X"]
        self._tau_output = outputs["tau"]
        if state_force:
            self._lambda_d_output = law.output_buffer(law.index_out("lambda_d"))

    def _bind_model(self) -> None:
        """Bind the law to the controller's own data and write its model's inertias."""
        self._bind_data(self._data)
        if self._inertia_input is not None:
            self._inertia_input[:] = inertia_parameters(self._model)

    def use_inertias(self, robot: RobotModel) -> bool:
        """Take the masses, centres of mass and rotational inertias of ``robot``.

        ``robot`` is this controller's :attr:`robot` with other inertias, e.g. another draw of
        a campaign's believed masses (:func:`~ucontrol.model.model_uncertainty.perturbed_robot`,
        :meth:`RobotModel.with_scaled_inertia`). From then on each call is that of a
        controller built with ``robot``, without building its law again: :attr:`robot` is
        ``robot``, M and h come from a new Pinocchio data of its model, and the law's
        ``inertia`` input (the symbolic kinematics, :func:`_symbolic_kinematics`) holds its
        inertias. What the controller derived from its robot when it was built is kinematic and
        is kept: the law itself (its definition excludes the inertias), the task coordinates
        (frame, A, b), the phase machine and its cycle, the posture, whether the task is
        redundant. The plant's data (:meth:`use_plant_data`) is given up for the controller's
        own, as a new controller has it; the state of the run (phases, events, measurements) is
        kept: :meth:`reset` starts a new run.

        Args:
            robot: The controller's new model: the kinematics (joints, their placements and
                limits, frames, armature, gravity) and the actuation of :attr:`robot`.

        Returns:
            Whether the inertias were taken. False, with nothing changed, for a robot of other
            kinematics or actuation, or for a subclass with a law of its own (the flexible
            joints' law, :class:`~ucontrol.control.FlexibleBrogliatoController`).
        """
        if self._rigid_law is None or robot.nu != self.robot.nu:
            return False
        if _with_inertias(robot.model, self._model.inertias) != self._model:
            return False  # Pinocchio's equality: every field but the inertias
        self.robot, self._model, self._data = robot, robot.model, pin.Data(robot.model)
        self._plant_terms = False
        self._bind_model()
        return True

    def use_plant_data(self, data: pin.Data | None) -> bool:
        """Read M(q) and h(q, v) from the plant's evaluation instead of computing them.

        For the closed loop (:func:`ucontrol.simulate`), when the controller sees the plant's
        own state and model: ``data`` is the plant's Pinocchio data of this controller's
        model, filled by ``pin.computeAllTerms`` at the very (q, v) of each following call.
        The law then runs only its Coriolis pass (C, the joint Jacobians and their time
        variation, which leaves M, h and the energies as they are) and the frame placement
        on it, or nothing for a robot whose law has the symbolic kinematics
        (:func:`_symbolic_kinematics`): two Pinocchio calls fewer, the same law to round-off
        (M and h from the plant's evaluation rather than ``crba`` and
        ``nonLinearEffects``). None goes back to the controller's own data.

        Returns:
            Whether the plant's data is used (by the rigid law; a subclass with a law of its
            own does not).
        """
        if self._rigid_law is None:
            return False
        self._bind_data(self._data if data is None else data)
        self._plant_terms = data is not None
        return self._plant_terms

    def _bind_data(self, data: pin.Data) -> None:
        """Bind the law's kinematic and dynamic inputs, by name, to ``data``'s buffers."""
        law, index, task = self._rigid_law, self._law_index, self.task
        assert law is not None
        joint = self._model.frames[task.frame_id].parentJoint
        buffers = {
            "M": data.M,
            "C": data.C,
            "nle": data.nle,
            "J": data.J,
            "dJ": data.dJ,
            "p": data.oMf[task.frame_id].translation,  # views
            "joint_velocity": data.ov[joint].vector,
        }
        for name, buffer in buffers.items():
            if name in index:  # the symbolic kinematics need M and h only
                law.bind_input(index[name], buffer)
        self._pass_data = data

    def reset(self) -> None:
        """Forget the run: phases back to free, events and measurements cleared."""
        self.machine.reset()
        n, m = len(self.machine.contacts), self.task.m
        self._plant_index: list[int] | None = None
        self._last_t = -np.inf
        self.V = self.V1 = 0.0
        self.X = np.zeros(m)
        self.desired = DesiredState.zeros(m, n, self._order)
        # Measurements of the last call, written in place by _measure.
        self.contact_force = np.zeros(n)
        self._force_written = True  # the law's force input may be non-zero
        # A read-only ``constrained`` of the machine (kept alive, so that the same object is
        # the same flags) and the (contact, task row) of its held contacts.
        self._held_rows: tuple[NDArray[np.bool_], list[tuple[int, int]]] | None = None
        self._closed = np.zeros(n, dtype=bool)
        self._settled = np.zeros(n, dtype=bool)
        self._persistent = np.zeros(n, dtype=bool)

    @property
    def phase(self) -> Phase:
        """Phase of the cycle at the last call."""
        return self.machine.phase

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Torques, shape (nu,), in [N m] (or [N] for prismatic joints)."""
        closed = self._measure(t, contacts)
        model, data = self._model, self._pass_data
        configuration = self._configuration_input
        if configuration is not None:  # C and the frame's kinematics inside the law
            configuration[...] = q
        else:
            pin.computeCoriolisMatrix(model, data, q, v)  # C, the joint Jacobians, ...
        if not self._plant_terms:  # bound inputs (M and h: the plant's evaluation's)
            pin.crba(model, data, q)  # M, upper triangle (the law reads it)
            pin.nonLinearEffects(model, data, q, v)
        if configuration is None:
            pin.updateFramePlacement(model, data, self.task.frame_id)
        self._velocity_input[...] = v
        if self._posture_by_subtraction:  # pin.difference on vector-space joints
            np.subtract(q, self.posture, out=self._posture_input)
        elif self._redundant:
            self._posture_input[...] = pin.difference(model, self.posture, q)
        machine = self.machine
        desired = machine.desired(t)
        self._evaluate_law(desired)
        if machine.update(t, closed, self._V1_output.item(), desired):
            desired = machine.desired(t)
            self._evaluate_law(desired)
        self.desired = desired
        self.V1, self.V = self._V1_output.item(), self._V_output.item()
        self.X[...] = self._X_output
        return self._tau_output.copy()  # fully actuated: u = tau

    def prepare_log(self, log: Log) -> None:
        """Declare the fields of :data:`LOG_FIELDS` and the contact names (metadata)."""
        n, m = len(self.machine.contacts), self.task.m
        shapes = {"()": (), "(n,)": (n,), "(m,)": (m,)}
        for name, shape in LOG_FIELDS.items():
            dtype = np.int64 if name in ("phase", "contact_phase", "events") else float
            log.add_field(name, shapes[shape], dtype)
        log.metadata["controller"] = "brogliato"
        log.metadata["controller_contacts"] = list(self.machine.contacts)
        log.metadata["gamma1"] = self.gains.gamma1
        log.metadata["gamma2"] = self.gains.gamma2
        log.metadata["period"] = self.cycle.period

    def record(self, log: Log) -> None:
        """Write the values of the last call into the current row (events only once)."""
        machine, desired = self.machine, self.desired
        if self._log_fields is None or self._log_fields[0] is not log:
            self._log_fields = (log, log.extra_fields(list(LOG_FIELDS)))
        k = log.size  # len(log)
        (
            phase,
            contact_phase,
            events,
            V,
            V1,
            virtual_depth,
            task_position,
            task_desired,
            task_target,
            lambda_d,
            contact_force,
        ) = self._log_fields[1]  # in the order of LOG_FIELDS
        phase[k] = machine.phase_value
        contact_phase[k] = machine.phase_values
        if machine.events_pending:
            events[k] = machine.events
            machine.events.fill(0)  # events are logged once
            machine.events_pending = False
        else:  # machine.events is 0
            events[k] = 0
        V[k] = self.V
        V1[k] = self.V1
        virtual_depth[k] = machine.depth
        task_position[k] = self.X
        task_desired[k] = desired.reference[0]
        task_target[k] = desired.target[0]
        applied = self._lambda_d_output
        lambda_d[k] = desired.force if applied is None else applied[machine.coordinates]
        contact_force[k] = self.contact_force

    def _measure(self, t: float, contacts: ContactState) -> NDArray[np.bool_]:
        """Check the time, read the contact forces; return which declared contacts closed.

        Writes ``contact_force`` (their :attr:`ContactState.force`) and the flags in place,
        one declared contact at a time (a handful: Python scalars cost less than array
        operations).
        """
        if t < self._last_t:
            raise InvalidParameterError(
                "t", t, f">= {self._last_t} (the controller is stateful: reset() it per run)"
            )
        self._last_t = t
        if self._plant_index is None:
            self._plant_index = self._find_contacts(contacts.names)
        impulse, speed = contacts.impulse.tolist(), None  # speeds read once a contact closed
        dt = contacts.dt  # [s]
        force, closed, settled, persistent = (
            self.contact_force,
            self._closed,
            self._settled,
            self._persistent,
        )
        for i, j in enumerate(self._plant_index):
            force_i = impulse[j] / dt  # [N]
            # The impulse / dt of a step is a contact force only if the contact stayed closed
            # over it without impact: feeding an impact back would push the robot off the
            # surface.
            closed_i = force_i > 0.0
            force[i], closed[i] = force_i, closed_i
            persistent[i] = closed_i and settled[i]
            if not closed_i:
                settled[i] = False
                continue
            if speed is None:
                speed = contacts.normal_velocity.tolist()
            settled[i] = speed[j] >= -IMPACT_SPEED
        return closed

    def _find_contacts(self, names: list[str]) -> list[int]:
        missing = [name for name in self.machine.contacts if name not in names]
        if missing:
            raise NotFoundError("plant contact", missing[0], names)
        return [names.index(name) for name in self.machine.contacts]

    def _evaluate_law(self, desired: DesiredState) -> None:
        """Run the law on ``desired``; its outputs (tau, V1, V, X) hold the values.

        The state's inputs are those :meth:`__call__` wrote in place or bound; the outputs
        are the law's buffers, rewritten by its next run.
        """
        rows = self._held_contacts(desired.constrained)
        force = self._force_input
        if force is None:  # λ_d designed in the law (state profile)
            self._write_state_force_inputs(desired, rows)
        elif rows:
            force.fill(0.0)
            self._force_written = True
            terms = self._force_terms(desired, rows)[1]
            for i, j in rows:
                force[j] = terms[i]
        elif self._force_written:  # no contact held: no force term
            force.fill(0.0)
            self._force_written = False
        target, reference, stacked = desired.target, desired.reference, desired.stacked
        if stacked is not None and stacked.size == self._target_buffer.size:
            self._target_buffer[...] = stacked  # the columns X_d, dX_d, ddX_d at once
        else:
            X_d, dX_d, ddX_d = self._law_columns[:3]
            X_d[...], dX_d[...], ddX_d[...] = target
        if reference[0] is target[0] and reference[1] is target[1]:  # nothing clipped
            self._reference_buffer[...] = self._target_head
        else:
            X_ref, dX_ref = self._law_columns[3:5]
            X_ref[...], dX_ref[...] = reference
            if self._clipped_reference:  # the clipped rows at rest, the others the target's
                ddX_ref = self._law_columns[5]
                ddX_ref[...] = target[2]
                ddX_ref[(reference[0] != target[0]) | (reference[1] != target[1])] = 0.0
        self._run_law()

    def _write_state_force_inputs(self, desired: DesiredState, rows: list[tuple[int, int]]) -> None:
        r"""Write the inputs of the state-based λ_d (:func:`_state_force`) in place.

        The inputs (``_state_force_inputs``) are the 1-D arrays held, active, the time profile
        :math:`\lambda_t` and each of its derivatives in ``desired.force_derivatives`` (none
        for the rigid law, two for the flexible one), measured and λ; declared contact i sits
        at one position of each (its task row in the rigid law, i in the flexible one). Held
        contacts (``rows``, :meth:`_held_contacts`) get the profile, and the measured force
        where it is valid; active ones are the held and those closed over the last step.
        Nothing is written while no contact is held and the inputs are still zeros.
        """
        assert self._state_force_inputs is not None
        inputs, positions = self._state_force_inputs
        if not rows and not self._force_written:
            return
        for values in inputs:
            values.fill(0.0)
        self._force_written = bool(rows)
        held, active, *profile, measured, lambda_measured = inputs
        active[positions[self._closed]] = 1.0
        samples = (desired.force, *desired.force_derivatives)  # [N], [N/s^k]
        held_before = self.desired.constrained  # at the last call
        for i, _ in rows:
            k = positions[i]
            held[k] = active[k] = 1.0
            for values, sample in zip(profile, samples, strict=True):
                values[k] = sample[i]
            if self._persistent[i] and held_before[i]:  # a force of this law
                measured[k], lambda_measured[k] = 1.0, self.contact_force[i]

    def _force_terms(
        self, desired: DesiredState, rows: list[tuple[int, int]]
    ) -> tuple[list[float], list[float]]:
        r"""The force λ used and the force term :math:`-\lambda_d + K_f(\lambda - \lambda_d)`.

        Per declared contact, in [N], on Python scalars (n is a handful): λ is the measured
        force of a held contact (``rows``, :meth:`_held_contacts`) where it is a valid
        measurement, else :math:`\lambda_d` (0 off the constrained phase, so the term is 0).
        """
        force_gain = self.gains.force_gain
        lambda_d = desired.force.tolist()
        used = lambda_d.copy()
        measured, persistent = self.contact_force.tolist(), self._persistent.tolist()
        for i, _ in rows:
            if persistent[i]:
                used[i] = measured[i]
        terms = [-d + force_gain * (m - d) for d, m in zip(lambda_d, used, strict=True)]
        return used, terms

    def _held_contacts(self, held: NDArray[np.bool_]) -> list[tuple[int, int]]:
        """(contact, task row) of each declared contact that ``held`` flags; [] for none.

        Kept while ``held`` is the same read-only object (the machine's flags, shared while
        the phases hold).
        """
        if held is self.machine.none_constrained:
            return []
        cached = self._held_rows
        if cached is not None and cached[0] is held:
            return cached[1]
        coordinates = self.machine.coordinates.tolist()
        rows = [(i, coordinates[i]) for i, is_held in enumerate(held.tolist()) if is_held]
        self._held_rows = None if held.flags.writeable else (held, rows)
        return rows


def _law_parameters(task: TaskCoordinates, gains: BrogliatoGains) -> Vector:
    """The parameter input of :func:`_rigid_law_function`: A, b, γ1, γ2, γp, γN, K_f."""
    return np.concatenate(
        [
            task.A.ravel(order="F"),
            task.b,
            [gains.gamma1, gains.gamma2, gains.posture_gain, gains.null_space_gain],
            [gains.force_gain],
        ]
    )


def _with_inertias(model: pin.Model, inertias: Sequence[pin.Inertia]) -> pin.Model:
    """A copy of ``model`` whose bodies have ``inertias`` (one per joint, the universe first)."""
    copy = pin.Model(model)
    for i, inertia in enumerate(inertias):
        copy.inertias[i] = inertia
    return copy


def _without_inertias(model: pin.Model) -> str:
    """``model``'s serialized form with every body's inertia zeroed (the law's input)."""
    zero = [pin.Inertia.Zero()] * model.njoints
    return str(_with_inertias(model, zero).saveToString())


def _law_name(state_force: bool) -> str:
    """The name of the law's Function (:func:`_rigid_law_function`)."""
    return "brogliato_state_force_law" if state_force else "brogliato_law"


def _symbolic_kinematics(robot: RobotModel, frame: str) -> ca.Function | None:
    r"""``(q, v, inertia) -> (C (nv, nv), p (3,), J (3, nv), dJ (3, nv))`` of ``frame``, or None.

    C(q, v) the Christoffel Coriolis matrix (Pinocchio's to round-off), p the frame's origin in
    the world, :math:`J = \partial p / \partial q` the linear part of its LOCAL_WORLD_ALIGNED
    Jacobian and :math:`\dot J = \partial (J v) / \partial q` (the Hessian of p is
    symmetric) its time variation, from :class:`~ucontrol.model.symbolic_model.SymbolicModel`
    with the bodies' inertias an input (``inertia``,
    :func:`~ucontrol.model.symbolic_model.inertia_parameters`: one library for every mass scale).
    None above :data:`~ucontrol.model.symbolic_model.SMALL_ROBOT_MAX_NV` joints (where
    Pinocchio's Coriolis pass is faster) or for joints it does not model
    (a free-flyer base, spherical or continuous joints). The second source of the law's
    kinematics beside Pinocchio's pass, kept because it saves more than 5 % of a closed-loop
    step of the two-link scenes (docs/controller.md, "One law, two paths").
    """
    import casadi as ca  # imported to build the law (a compile-cache miss)

    from ucontrol.model.symbolic_model import INERTIA_SIZE, SMALL_ROBOT_MAX_NV, SymbolicModel

    if robot.nv > SMALL_ROBOT_MAX_NV or robot.nq != robot.nv:
        return None
    try:
        model = SymbolicModel(robot, inertia_input=True)
    except InvalidParameterError:
        return None
    q, v = ca.SX.sym("q", robot.nv), ca.SX.sym("v", robot.nv)
    inertia = ca.SX.sym("inertia", INERTIA_SIZE * (robot.model.njoints - 1))
    p = model.frame_position(frame)(q)
    J = ca.jacobian(p, q)
    dJ = ca.jacobian(J @ v, q)
    C = model.coriolis_matrix(q, v, inertia)
    return ca.Function("frame_kinematics", [q, v, inertia], [C, p, J, dJ])


def _rigid_law_function(
    nv: int,
    m: int,
    redundant: bool,
    support: list[int],
    kinematics: ca.Function | None = None,
    *,
    state_force: bool = False,
    clipped_reference: bool = False,
) -> ca.Function:
    r"""The rigid law of :class:`BrogliatoController`: its one definition, a casadi Function.

    :class:`~ucontrol.model.compiled_function.CompiledFunction` runs it compiled to C, or in
    casadi's virtual machine (the reference, ``UCONTROL_NO_COMPILE=1``). Inputs, by name:
    ``M`` (nv, nv) (upper triangle read), ``nle`` h(q, v) (nv,), ``v`` (nv,),
    ``posture_error`` :math:`q \ominus q_p` (nv,), ``target`` (m, 3) (position, velocity,
    acceleration as columns), ``reference`` (m, 2), ``force`` the force term
    :math:`-\lambda_d + K_f(\lambda - \lambda_d)` on the task rows (m,) (0 off the held
    contacts), ``parameters`` (:func:`_law_parameters`: the task map A (m, 3) column-major,
    b (m,), γ1, γ2, γp, γN, K_f), so that one compiled library serves every task geometry and
    every gain of a given robot (sweeps do not recompile). The kinematics come in one of two
    ways. Without ``kinematics``, from Pinocchio's pass: ``C`` C(q, v) (nv, nv), ``J`` and
    ``dJ`` the joint Jacobians and their time variation in the WORLD convention (6, nv)
    (``data.J``, ``data.dJ``), ``p`` the frame position (3,) and ``joint_velocity`` the
    spatial velocity of the frame's parent joint in the world (6,) (linear, angular;
    ``data.ov``); the frame's Jacobian and its time variation in LOCAL_WORLD_ALIGNED on the
    columns ``support`` are then those of ``pin.getFrameJacobian`` and
    ``pin.getFrameJacobianTimeVariation``, in their operations. With ``kinematics``
    (:func:`_symbolic_kinematics`), from ``q`` (nv,) and the bodies' ``inertia``
    (:func:`~ucontrol.model.symbolic_model.inertia_parameters`) inside the call. Outputs, by name
    (:data:`LAW_OUTPUTS`): ``tau`` (nv,), ``V1`` and ``V`` on the reference, ``X`` (m,).

    With ``clipped_reference`` (``reference_after_impact = "clipped"``, the book's law) the
    ``reference`` is (m, 3), with the clipped target's acceleration (0 on the clipped rows),
    and :math:`\dot q_r`, :math:`\ddot q_r` are built on it, :math:`\bar s` on ``target``;
    without it :math:`\dot q_r` is built on ``target`` too.

    With ``state_force`` (``force_profile = "state"``, :func:`_state_force`) the law designs
    :math:`\lambda_d` from the state itself: the input ``force`` is replaced by ``held``
    (1 on the task rows of the held contacts, else 0), ``active`` (1 on the rows of the held
    contacts and of those closed over the last step), ``lambda_time`` (the time profile on
    the held rows), ``measured`` (1 where the measured force is valid) and ``lambda_measured``
    (each (m,)), and a last output ``lambda_d`` (m,) gives the :math:`\lambda_d` applied.
    """
    import casadi as ca  # imported to build the law (a compile-cache miss)

    M_upper, C = ca.SX.sym("M", nv, nv), ca.SX.sym("C", nv, nv)
    nle, v = ca.SX.sym("nle", nv), ca.SX.sym("v", nv)
    J_world, dJ_world = ca.SX.sym("J", 6, nv), ca.SX.sym("dJ", 6, nv)
    p, posture_error = ca.SX.sym("p", 3), ca.SX.sym("posture_error", nv)
    joint_velocity = ca.SX.sym("joint_velocity", 6)
    target = ca.SX.sym("target", m, 3)
    reference = ca.SX.sym("reference", m, 3 if clipped_reference else 2)
    force = ca.SX.sym("force", m)
    parameters = ca.SX.sym("parameters", 3 * m + m + 5)
    A = ca.reshape(parameters[: 3 * m], m, 3)
    b = parameters[3 * m : 4 * m]
    gamma1, gamma2, posture_gain, null_space_gain, force_gain = ca.vertsplit(parameters[4 * m :], 1)
    M = ca.triu(M_upper) + ca.triu(M_upper, False).T
    # Frame Jacobian: v_p = v_O + ω × p; its time variation adds -(v_j + ω_j × p) × ω_col.
    J_lin, dJ_lin = ca.SX.zeros(3, nv), ca.SX.zeros(3, nv)
    shift = joint_velocity[:3] + _cross(joint_velocity[3:], p)  # [m/s]
    for j in support:
        J_lin[:, j] = J_world[:3, j] - _cross(p, J_world[3:, j])
        dJ_lin[:, j] = dJ_world[:3, j] - _cross(p, dJ_world[3:, j]) - _cross(shift, J_world[3:, j])
    inputs = {"M": M_upper, "nle": nle, "v": v, "posture_error": posture_error}
    inputs |= {"target": target, "reference": reference}
    if state_force:
        force_inputs = {name: ca.SX.sym(name, m) for name in _STATE_FORCE_INPUTS}
        inputs |= force_inputs
    else:
        inputs["force"] = force
    inputs["parameters"] = parameters
    if kinematics is None:  # C and the frame's kinematics from Pinocchio's pass
        inputs |= {"C": C, "J": J_world, "dJ": dJ_world, "p": p}
        inputs["joint_velocity"] = joint_velocity
    else:  # the same terms from the symbolic model
        q, inertia = ca.SX.sym("q", nv), ca.SX.sym("inertia", kinematics.numel_in(2))
        C, p, J_lin, dJ_lin = kinematics(q, v, inertia)
        inputs["q"], inputs["inertia"] = q, inertia
    J, dJ = A @ J_lin, A @ dJ_lin
    X = A @ p - b  # [m]
    dX = J @ v
    JJt = J @ J.T
    J_pinv = ca.solve(JJt, J).T
    dJ_pinv = -J_pinv @ dJ @ J_pinv
    if redundant:
        N = ca.SX.eye(nv) - J_pinv @ J
        dJ_pinv += N @ ca.solve(JJt, dJ).T
        dN = -(dJ_pinv @ J + J_pinv @ dJ)
        xi = -posture_gain * posture_error  # [rad/s]
        d_xi = -posture_gain * v
        N_xi, null_acceleration = N @ xi, dN @ xi + N @ d_xi
    else:
        N_xi = ca.SX.zeros(nv)

    def sliding(desired: tuple[ca.SX, ca.SX, ca.SX]) -> tuple[ca.SX, ...]:
        """s_q, X̃ [m], dX_r [m/s] and ddX_r [m/s²] for ``desired`` (X_d, dX_d, ddX_d)."""
        X_error, _, dX_r, ddX_r = _reference_terms(X, dX, desired, gamma2)
        return v - (J_pinv @ dX_r + N_xi), X_error, dX_r, ddX_r

    # V on the reference (its acceleration used by the book's q̇_r only).
    reference_acceleration = reference[:, 2] if clipped_reference else ca.SX.zeros(m)
    s_reference, X_error, dX_r_reference, ddX_r_reference = sliding(
        (reference[:, 0], reference[:, 1], reference_acceleration)
    )
    V1 = 0.5 * ca.dot(s_reference, M @ s_reference)  # [J]
    V = V1 + gamma1 * gamma2 * ca.dot(X_error, X_error)
    s_q, _, dX_r, ddX_r = sliding((target[:, 0], target[:, 1], target[:, 2]))
    s_coriolis = s_q  # C q̇_r = C v - C s_q: q̇_r on the target
    if clipped_reference:  # the book: q̇_r on the clipped target, s̄ on the virtual one
        dX_r, ddX_r, s_coriolis = dX_r_reference, ddX_r_reference, s_reference
    ddq_r = dJ_pinv @ dX_r + J_pinv @ ddX_r
    s = J @ s_q
    tau = M @ ddq_r + nle - C @ s_coriolis - gamma1 * (J.T @ s)
    dissipation = C @ s_q + gamma1 * (J.T @ s)  # [N m], of the closed loop (_state_force)
    if redundant:
        tau += M @ null_acceleration - null_space_gain * (N.T @ (M @ (N @ s_q)))
        dissipation += null_space_gain * (N.T @ (M @ (N @ s_q)))
        ddq_r += null_acceleration
    outputs = dict(zip(LAW_OUTPUTS, (tau, V1, V, X), strict=True))
    if state_force:
        closed_loop = (M, J, dJ @ v, ddq_r, dissipation)
        force, outputs["lambda_d"] = _state_force(closed_loop, force_inputs, force_gain)
    tau += J.T @ force
    outputs["tau"] = tau
    return ca.Function(
        _law_name(state_force),
        list(inputs.values()),
        list(outputs.values()),
        list(inputs),
        list(outputs),
    )


#: Inputs of the law with the state-based desired force (:func:`_state_force`), each (m,).
_STATE_FORCE_INPUTS = ("held", "active", "lambda_time", "measured", "lambda_measured")


def _state_force(
    closed_loop: tuple[ca.SX, ...], inputs: dict[str, ca.SX], force_gain: ca.SX
) -> tuple[ca.SX, ca.SX]:
    r"""The force term and :math:`\lambda_d` designed from the state (book §8.1.4).

    In the constrained phase the closed loop of the law is
    :math:`M \dot s_q + D = (1 + K_f) J_c^T (\lambda - \lambda_d)`, D the law's
    dissipation :math:`C s_q + \gamma_1 J^T s (+ \gamma_N N^T M N s_q)`, and the held
    contacts keep :math:`J_c \dot v + \dot J_c v = 0`. Eliminating :math:`\dot v` gives the
    contact force the law produces,

    .. math::

        \lambda = \lambda_d + \frac{\Lambda_c \big(J_c M^{-1} D - J_c \ddot q_r
        - \dot J_c v\big)}{1 + K_f}, \qquad \Lambda_c = (J_c M^{-1} J_c^T)^{-1},

    and :math:`\lambda_d` is chosen so that it is the time profile :math:`\lambda_t > 0`:
    :math:`\lambda_d = \lambda_t - \Lambda_c(\cdots)/(1 + K_f)`; where the measured force
    is not valid (the law then uses :math:`\lambda_d` for it, without feedback) the factor
    is 1 instead of :math:`1 + K_f`. The rows c are those of
    the *active* contacts: the held ones and the others closed over the last step (a
    contact in its transition, whose force the law does not command but which holds its
    gap as well); inactive rows are decoupled (identity) and masked out, and
    :math:`\lambda_d` is 0 off the held rows.

    Args:
        closed_loop: M (nv, nv), the task Jacobian J (m, nv), :math:`\dot J v` (m,),
            :math:`\ddot q_r` (nv,) and D (nv,).
        inputs: The symbols of :data:`_STATE_FORCE_INPUTS`.
        force_gain: :math:`K_f`.

    Returns:
        The force term :math:`-\lambda_d + K_f(\lambda - \lambda_d)` and
        :math:`\lambda_d`, on the task rows (m,), in [N].
    """
    import casadi as ca  # imported to build the law (a compile-cache miss)

    M, J, dJ_v, ddq_r, dissipation = closed_loop
    held, active = inputs["held"], inputs["active"]
    J_active = ca.diag(active) @ J
    contact_inertia = J_active @ ca.solve(M, J_active.T) + ca.diag(1.0 - active)  # [1/kg]
    residual = active * (J_active @ ca.solve(M, dissipation) - J @ ddq_r - dJ_v)  # [m/s²]
    total = ca.solve(contact_inertia, residual)  # force on the active rows [N]
    measured = inputs["measured"]
    lambda_d = held * (inputs["lambda_time"] - total / (1.0 + force_gain * measured))
    used = lambda_d + measured * (inputs["lambda_measured"] - lambda_d)  # λ where valid [N]
    return -lambda_d + force_gain * (used - lambda_d), lambda_d


def _reference_terms(
    x: ca.SX, dx: ca.SX, desired: tuple[ca.SX, ca.SX, ca.SX], gamma2: ca.SX
) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    r"""Slotine–Li's errors and reference, shared by the rigid and the flexible law.

    For coordinates x (task coordinates, or the links of the flexible law) and their rate
    dx, each (k,), and the desired :math:`(x_d, \dot x_d, \ddot x_d)`: the errors
    :math:`\tilde x = x - x_d`, :math:`\dot{\tilde x}`, the reference velocity
    :math:`\dot x_r = \dot x_d - \gamma_2 \tilde x` and its derivative
    :math:`\ddot x_r = \ddot x_d - \gamma_2 \dot{\tilde x}`
    (so that :math:`s = \dot x - \dot x_r = \dot{\tilde x} + \gamma_2 \tilde x`).
    """
    x_d, dx_d, ddx_d = desired
    error, rate_error = x - x_d, dx - dx_d
    return error, rate_error, dx_d - gamma2 * error, ddx_d - gamma2 * rate_error


def _cross(a: ca.SX, b: ca.SX) -> ca.SX:
    """Cross product of 3-vectors in the operations of Eigen's ``cross``."""
    import casadi as ca  # imported to build the law (a compile-cache miss)

    return ca.vertcat(
        a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]
    )
