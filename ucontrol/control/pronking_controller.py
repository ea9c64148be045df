r"""Landing and pronking of a floating-base robot on point feet: a stance/thrust/flight machine.

The controller sees the configuration, the velocity and the feet's gaps (a foot is *in contact*
when its gap is at most ``contact_gap``); it never reads the plant's impulses. Heights are those
of the centre of mass above the level of the feet's centres on the ground,
:math:`h = c \cdot n_\uparrow - \overline{(p_i \cdot n_\uparrow - g_i)}` (mean over the feet, g_i
their gaps, :math:`n_\uparrow = -\hat g` the upward direction).

**Stance** (at least one foot in contact). A desired rate of change of the centroidal momentum,

.. math::

    F = m\,(\ddot h_d\, n_\uparrow + a_{xy} - g), \qquad
    a_{xy} = -k_{xy}(c - c_0)_{xy} - d_{xy}\,\dot c_{xy}, \qquad
    T = I_c\,\big(-k_R \log(R R_d^T)^\vee - d_R\, \omega\big),

(:math:`c_0` the centre of mass at the first call: the robot hops in place) is distributed over
the feet in contact by a small QP (proxsuite) in the feet's forces
:math:`f_i` with friction pyramids of coefficient :math:`\mu_c`,

.. math::

    \min_f \Big\| \sum_i \begin{bmatrix} f_i \\ (p_i - c) \times f_i \end{bmatrix}
      - \begin{bmatrix} F \\ T \end{bmatrix} \Big\|^2 + \epsilon \|f\|^2
    \quad \text{s.t.} \quad |f_i \cdot t_{ij}| \le \mu_c\, f_i \cdot n_i,\;
    0 \le f_i \cdot n_i \le f_\text{max},

(its unconstrained optimum :math:`A^T (A A^T + \epsilon I)^{-1} w` when that lies in the
pyramids: it is then the QP's solution) and produced by the joints of each stance leg statically,
:math:`\tau_\text{leg} = g_\text{leg}(q) - J_{i,\text{leg}}^T f_i` (g the generalized gravity,
J_i the foot's linear Jacobian): gravity compensation distributed over the feet plus a
virtual spring-damper on the centre of mass. A leg whose foot is in the air, and every leg in
flight, holds the touchdown posture by a joint PD,
:math:`\tau = K_p (q_\text{td} - q) - K_d \dot q` (plus its gravity when some foot carries the
robot; none in free fall).

**Height law.** Landing and standing (phase CONSTRAINED): :math:`\ddot h_d = k_h (h_s - h) -
d_h \dot h` toward the standing height :math:`h_s`. Thrust (phase TAKEOFF), from the bottom of
the compression (:math:`\dot h \ge 0`) while hops remain: the constant acceleration that reaches
the take-off speed :math:`v_\text{to}` at the touchdown height :math:`h_\text{td}` (the height
with the legs at the touchdown posture),

.. math::

    \ddot h_d = \frac{v_\text{to}^2 - \dot h^2}{2\,(h_\text{td} - h)}, \qquad
    v_\text{to}^2 = 2 g (H - h_\text{td}) + \delta_k,

with H the commanded apex; the thrust ends at :math:`h \ge h_\text{td}` (phase FREE, flight).
After each flight the measured apex :math:`H_k` corrects the energy of the next thrust,
:math:`\delta_{k+1} = \delta_k + 2 g\, k_a (H - H_k)` (``apex_gain`` :math:`k_a`; 0 disables).
Touchdown (phase CONSTRAINED again): a foot in contact while :math:`\dot h < 0`.

**Paths.** The law is written once (:mod:`~ucontrol.control.pronking_law`) and evaluated on numpy
arrays, its readable reference (``compiled=False``), or built on casadi expressions and compiled
to C where a C compiler is found; compiled, in the closed loop it reads the plant's evaluation
(:meth:`PronkingController.use_plant_data`). The phase machine and the QP beyond the pyramids
are shared by both paths.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_int, as_non_negative, as_positive, as_vector
from ucontrol.contact.tangent_basis import tangent_basis
from ucontrol.control.controller import ContactState, Vector
from ucontrol.control.phase import Phase
from ucontrol.control.pronking_law import (
    NUMPY_LAW_OPS,
    distribute_forces,
    height_acceleration,
    joint_torques,
    law_measures,
    stance_wrench,
)
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.compiled_function import compilation_possible
from ucontrol.solvers.proxsuite_qp import INFINITY, WarmStartedQP

if TYPE_CHECKING:
    from ucontrol.log import Log
    from ucontrol.model.compiled_function import CompiledFunction
    from ucontrol.model.robot_model import RobotModel

Mask = NDArray[np.bool_]
Index = NDArray[np.int64]

_REGULARIZATION = 1e-4  # ε of the force QP: the weight of ||f||² [N²] beside the wrench's residual
_MIN_STROKE = 1e-9  # [m] guards the thrust law against a zero distance to the touchdown height
#: The settings the law's input ``gains`` holds, in its order.
_LAW_GAINS = (
    "horizontal_stiffness",
    "horizontal_damping",
    "attitude_stiffness",
    "attitude_damping",
    "height_stiffness",
    "height_damping",
)


@dataclass(frozen=True, kw_only=True)
class PronkSettings:
    """Targets and gains of :class:`PronkingController`.

    Attributes:
        stand_height: Height h_s of the centre of mass in stance, in [m].
        apex: Commanded apex H of the centre of mass in the hops, in [m].
        hops: Number of hops; then the robot stands.
        kp: Joint stiffness of the legs in the air, in [N m/rad].
        kd: Joint damping of the legs in the air, in [N m s/rad].
        height_stiffness: k_h in [1/s²].
        height_damping: d_h in [1/s].
        horizontal_stiffness: k_xy in [1/s²].
        horizontal_damping: d_xy in [1/s].
        attitude_stiffness: k_R in [1/s²].
        attitude_damping: d_R in [1/s].
        friction: Coefficient μ_c of the pyramids the commanded forces keep in (>= 0).
        max_normal_force: f_max per foot in [N].
        contact_gap: A foot with a gap at most this is in contact, in [m].
        apex_gain: k_a of the apex correction (0: none).
    """

    stand_height: float
    apex: float
    hops: int = 0
    kp: float = 20.0
    kd: float = 0.5
    height_stiffness: float = 150.0
    height_damping: float = 18.0
    horizontal_stiffness: float = 50.0
    horizontal_damping: float = 14.0
    attitude_stiffness: float = 150.0
    attitude_damping: float = 25.0
    friction: float = 0.5
    max_normal_force: float = INFINITY
    contact_gap: float = 1e-3
    apex_gain: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "stand_height", as_positive("stand_height", self.stand_height))
        object.__setattr__(self, "apex", as_float("apex", self.apex))
        object.__setattr__(self, "hops", as_int("hops", self.hops, 0))
        for key in (
            "kp",
            "kd",
            "height_stiffness",
            "height_damping",
            "horizontal_stiffness",
            "horizontal_damping",
            "attitude_stiffness",
            "attitude_damping",
            "friction",
            "apex_gain",
        ):
            object.__setattr__(self, key, as_non_negative(key, getattr(self, key)))
        for key in ("max_normal_force", "contact_gap"):
            object.__setattr__(self, key, as_positive(key, getattr(self, key)))


class PronkingController:
    """Land, pronk ``hops`` times to a commanded apex, then stand (module docstring: the law).

    Args:
        robot: A robot on a free-flyer base (the controller keeps its own Pinocchio data).
        feet: Names of the feet's frames (point contacts).
        contacts: Index of each foot's constraint in the :class:`ContactState` arrays.
        normals: Each foot's ground normal (world), shape (n_feet, 3).
        posture: Touchdown posture, shape (nq,): the legs' joints hold it in the air, its base
            orientation is the attitude R_d held in stance.
        settings: Heights, hops and gains.
        compiled: Run the law compiled to C (:mod:`~ucontrol.control.pronking_law`); False
            runs it on numpy arrays (the reference); None (default) compiles where a C
            compiler is found and ``UCONTROL_NO_COMPILE`` is not set.

    Attributes:
        compiled: Whether the calls run the compiled law.

    Raises:
        InvalidParameterError: A robot without a free-flyer base, feet and contacts of
            different lengths, a foot on no leg, or heights out of order
            (``stand_height < h_td < apex`` when hopping, h_td the posture's height).
        FrameNotFoundError: A foot frame the robot does not have.
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        feet: Sequence[str],
        contacts: Sequence[int],
        normals: Vector,
        posture: Vector,
        settings: PronkSettings,
        compiled: bool | None = None,
    ) -> None:
        model = robot.model
        if model.njoints < 2 or model.joints[1].shortname() != "JointModelFreeFlyer":
            raise InvalidParameterError("robot", robot.name, "a robot on a free-flyer base")
        if len(feet) != len(contacts) or not feet:
            raise InvalidParameterError(
                "contacts", list(contacts), f"one constraint index per foot ({len(feet)} feet)"
            )
        self.robot = robot
        self.settings = settings
        self._model, self._data = model, pin.Data(model)
        self._frames = [robot.frame_id(name) for name in feet]
        self.feet = tuple(str(name) for name in feet)
        self._contacts = np.array(contacts, dtype=np.int64)
        normals = np.asarray(normals, dtype=float).reshape(len(feet), 3)
        self._normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        self._tangents = tangent_basis(self._normals)  # (n_feet, 2, 3)
        self.posture = as_vector("posture", posture, robot.nq)
        self._actuated = robot.actuated
        self._legs = [self._leg(frame, name) for frame, name in zip(self._frames, feet)]
        in_legs = np.concatenate(self._legs)
        self._others = np.setdiff1d(self._actuated, in_legs)
        q_of_v = _configuration_index(model)
        if np.any(q_of_v[self._actuated] < 0):
            raise InvalidParameterError(
                "robot",
                robot.name,
                "actuated joints with one configuration coordinate per velocity (revolute, "
                "prismatic) for the pronking controller",
            )
        #: The legs, the actuated joints on no leg and the configuration index of each velocity.
        self._structure = (self._legs, self._others, q_of_v)
        self.g = float(np.linalg.norm(robot.gravity))
        self.up = -robot.gravity / self.g
        self.mass = float(pin.computeTotalMass(model))  # [kg]
        self.touchdown_height = self._posture_height()
        self._check_heights()
        self._R_d = pin.Quaternion(self.posture[3:7]).normalized().matrix()
        self._qp = WarmStartedQP(eps_abs=1e-8)
        self._build_constraints()
        self.phase: Phase | None = None  # set by the first call, from the feet's gaps
        self.hops_done = 0
        self.apexes: list[float] = []
        self._energy_correction = 0.0  # δ_k [m²/s²]
        self._flight_apex = -math.inf
        self._c0: Vector | None = None
        self._forces = np.zeros((len(feet), 3))
        self._height = math.nan
        self.compiled = compilation_possible() if compiled is None else bool(compiled)
        if self.compiled:
            self._build_law()

    def _leg(self, frame: int, name: str) -> Index:
        """Actuated velocity indices of the joints between the base and a foot."""
        model = self._model
        actuated = set(self._actuated.tolist())
        leg = np.array(
            [
                index
                for j in model.supports[model.frames[frame].parentJoint]
                if j > 1  # neither the universe nor the free-flyer
                for index in range(
                    model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv
                )
                if index in actuated
            ],
            dtype=np.int64,
        )
        if leg.size == 0:
            raise InvalidParameterError("feet", name, "a frame below some actuated joint")
        return leg

    def _posture_height(self) -> float:
        """Height h_td of the centre of mass above the lowest foot at the posture, in [m]."""
        model, data, q = self._model, self._data, self.posture
        c = pin.centerOfMass(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        lowest = min(float(data.oMf[f].translation @ self.up) for f in self._frames)
        return float(c @ self.up) - lowest

    def _check_heights(self) -> None:
        s = self.settings
        if s.stand_height >= self.touchdown_height:
            raise InvalidParameterError(
                "stand_height",
                s.stand_height,
                f"< {self.touchdown_height:.4g} m, the height at the touchdown posture",
            )
        if s.hops > 0 and s.apex <= self.touchdown_height:
            raise InvalidParameterError(
                "apex", s.apex, f"> {self.touchdown_height:.4g} m, the touchdown height"
            )

    def _build_constraints(self) -> None:
        """The friction pyramids and normal bounds of the force QP, rows (5 n_feet, 3 n_feet)."""
        n, mu = len(self._frames), self.settings.friction
        C = np.zeros((5 * n, 3 * n))
        upper = np.zeros(5 * n)
        for i in range(n):
            normal, (t1, t2) = self._normals[i], self._tangents[i]
            cols = slice(3 * i, 3 * i + 3)
            C[5 * i + 0, cols] = t1 - mu * normal
            C[5 * i + 1, cols] = -t1 - mu * normal
            C[5 * i + 2, cols] = t2 - mu * normal
            C[5 * i + 3, cols] = -t2 - mu * normal
            C[5 * i + 4, cols] = normal
            upper[5 * i + 4] = self.settings.max_normal_force
        self._C = C
        self._pyramids = np.zeros((5, 3 * n))  # foot i's five rows on its three columns
        for i in range(n):
            self._pyramids[:, 3 * i : 3 * i + 3] = C[5 * i : 5 * i + 5, 3 * i : 3 * i + 3]
        self._A = np.zeros((6, 3 * n))  # the wrench matrix of the last stance call
        self._lower = np.full(5 * n, -INFINITY)
        self._lower[4::5] = 0.0
        self._upper = upper

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Joint torques, shape (nu,)."""
        if self.compiled:
            return self._compiled_call(q, v, contacts)
        ops, data = NUMPY_LAW_OPS, self._data
        self._evaluate(data, q, v)
        c, momentum = data.com[0], data.hg.linear
        feet = [data.oMf[f].translation for f in self._frames]  # [m]
        gaps = contacts.gap[self._contacts]
        constants = self._law_constants()
        h, h_dot, touching = law_measures(ops, c, momentum, gaps, feet, self.up, constants)
        if self._c0 is None:
            self._c0 = c.copy()
        self._update_phase(h, h_dot, bool(touching.any()))
        self._height = h
        supported = self.phase != Phase.FREE
        self._forces = np.zeros((len(feet), 3))
        if supported and touching.any():
            state = self._law_state_values()
            R = data.oMi[1].rotation
            wrench = stance_wrench(
                ops, self._height_acceleration(h, h_dot), c, momentum, data.Ag, R, v, state,
                self._law_gains(), constants, self.up, self._R_d,
            )  # fmt: skip
            self._A, f, feasible = distribute_forces(
                ops, wrench, c, feet, touching, self._pyramids, self._lower, self._upper,
                constants,
            )  # fmt: skip
            columns = np.repeat(touching, 3)
            self._forces = (
                f.reshape(-1, 3) if feasible else self._constrained_forces(self._A, wrench, columns)
            )
        s = self.settings
        tau = joint_torques(
            ops, self._forces.ravel(), data.J, data.g, q, v, gaps, float(supported),
            (s.kp, s.kd, s.contact_gap), self.posture, feet, self._structure,
        )  # fmt: skip
        return tau[self._actuated]

    def _evaluate(self, data: pin.Data, q: Vector, v: Vector) -> None:
        """Pinocchio's passes the law reads: centroidal terms, Jacobians, feet, gravity."""
        model = self._model
        pin.ccrba(model, data, q, v)  # centre of mass, centroidal momentum and its matrix
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        pin.computeGeneralizedGravity(model, data, q)

    def _law_state_values(self) -> Vector:
        """The law's input ``state``: c_0 [m], 1 in thrust else 0, v_to [m/s], shape (5,)."""
        assert self._c0 is not None
        return np.array([*self._c0, self.phase == Phase.TAKEOFF, self.takeoff_speed()])

    def _height_acceleration(self, h: float, h_dot: float) -> float:
        """The desired vertical acceleration of the centre of mass in this phase, in [m/s²]."""
        takeoff, v_to = float(self.phase == Phase.TAKEOFF), self.takeoff_speed()
        gains, constants = self._law_gains(), self._law_constants()
        return float(height_acceleration(NUMPY_LAW_OPS, h, h_dot, takeoff, v_to, gains, constants))

    def _law_gains(self) -> list[float]:
        """The law's input ``gains``: k_xy, d_xy, k_R, d_R, k_h, d_h."""
        return [getattr(self.settings, name) for name in _LAW_GAINS]

    def _law_constants(self) -> list[float]:
        """The law's input ``constants``: m, |g|, h_s, h_td, ε, the least stroke, contact_gap."""
        s = self.settings
        h_s, h_td, gap = s.stand_height, self.touchdown_height, s.contact_gap  # [m]
        return [self.mass, self.g, h_s, h_td, _REGULARIZATION, _MIN_STROKE, gap]

    def _build_law(self) -> None:
        """Build the compiled law (:mod:`~ucontrol.control.pronking_law`), bind it by name."""
        from ucontrol.control import pronking_law
        from ucontrol.model.compiled_function import CompiledFunction

        model, s, n = self._model, self.settings, len(self._frames)
        forces = pronking_law.force_law_function(n, model.nv)
        torques = pronking_law.torque_function(model.nq, model.nv, *self._structure, self._actuated)
        law, torque_law = CompiledFunction(forces), CompiledFunction(torques)
        self._laws: tuple[CompiledFunction, CompiledFunction] = (law, torque_law)
        self._law_index = (forces.index_in, torques.index_in)
        law_in = {name: law.input_view(forces.index_in(name)) for name in forces.name_in()}
        torque_in = {
            name: torque_law.input_view(torques.index_in(name)) for name in torques.name_in()
        }
        # The state both read (copied in at each call), and the forces from one to the other.
        self._q_in, self._v_in = np.zeros(model.nq), np.zeros(model.nv)
        self._gaps_in = np.zeros(n)
        for function, compiled in ((forces, law), (torques, torque_law)):
            compiled.bind_input(function.index_in("v"), self._v_in)
            compiled.bind_input(function.index_in("gaps"), self._gaps_in)
        torque_law.bind_input(torques.index_in("q"), self._q_in)
        force_out = law.output_buffer(forces.index_out("forces"))
        torque_law.bind_input(torques.index_in("forces"), force_out)
        self._force_out = force_out
        self._forces_view = force_out.reshape(n, 3)  # the feet's forces, rows [N]
        self._A = law.output_buffer(forces.index_out("A")).reshape((6, 3 * n), order="F")
        self._wrench_out = law.output_buffer(forces.index_out("wrench"))
        self._measures_out = law.output_buffer(forces.index_out("measures"))
        self._feasible_out = law.output_buffer(forces.index_out("feasible"))
        self._tau_out = torque_law.output_buffer(torques.index_out("tau"))
        # Constant inputs.
        law_in["gains"][:] = self._law_gains()
        law_in["constants"][:] = self._law_constants()
        law_in["up"][:] = self.up
        law_in["attitude"][...] = self._R_d
        law_in["pyramids"][...] = self._pyramids
        law_in["lower"][:], law_in["upper"][:] = self._lower, self._upper
        torque_in["gains"][:] = [s.kp, s.kd, s.contact_gap]
        torque_in["posture"][:] = self.posture
        # Inputs written at each call.
        self._state_in, self._supported_in = law_in["state"], torque_in["supported"]
        self._run_law, self._run_torques = law.runner(), torque_law.runner()
        self._law_state: tuple[Phase | None, float] | None = None
        self._plant_data = False
        self._bind_data(self._data)

    def _bind_data(self, data: pin.Data) -> None:
        """Bind the compiled law's kinematic and dynamic inputs, by name, to ``data``'s views."""
        law, torque_law = self._laws
        law_index, torque_index = self._law_index
        law.bind_input(law_index("com"), data.com[0])
        law.bind_input(law_index("momentum"), data.hg.linear)
        law.bind_input(law_index("rotation"), data.oMi[1].rotation)
        law.bind_input(law_index("Ag"), data.Ag)
        torque_law.bind_input(torque_index("J"), data.J)
        torque_law.bind_input(torque_index("g"), data.g)
        for i, frame in enumerate(self._frames):
            name = f"foot_{i}"
            law.bind_input(law_index(name), data.oMf[frame].translation)
            torque_law.bind_input(torque_index(name), data.oMf[frame].translation)
        self._law_data = data

    def use_plant_data(self, data: pin.Data | None) -> bool:
        """Read the plant's evaluation instead of running Pinocchio's passes (compiled law).

        For the closed loop (:func:`ucontrol.simulate`), when the controller sees the plant's
        own state and model: ``data`` is the plant's Pinocchio data of this controller's
        model, filled by ``pin.computeAllTerms`` at the very (q, v) of each following call,
        which holds the centre of mass, the centroidal momentum and its matrix, the joints'
        Jacobians and the generalized gravity the law reads. Each call then runs only the
        frame placements on it (the feet's positions): four Pinocchio passes fewer, the same
        law to round-off (the gravity and the momentum of ``computeAllTerms`` rather than of
        ``computeGeneralizedGravity`` and ``ccrba``, about 1e-15 apart). None goes back to
        the controller's own data.

        Returns:
            Whether the plant's data is used (not by the numpy reference, ``compiled=False``).
        """
        if not self.compiled:
            return False
        self._bind_data(self._data if data is None else data)
        self._plant_data = data is not None
        return self._plant_data

    def _compiled_call(self, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """:meth:`__call__` by the compiled law: the same law as the reference, to round-off."""
        data = self._law_data
        if self._plant_data:
            pin.updateFramePlacements(self._model, data)
        else:
            self._evaluate(data, q, v)
        self._q_in[:] = q
        self._v_in[:] = v
        self._gaps_in[:] = contacts.gap[self._contacts]
        if self._c0 is None:
            self._c0 = data.com[0].copy()
        self._write_law_state()
        self._run_law()
        h, h_dot, touching = self._measures_out.tolist()  # [m], [m/s], number of feet
        self._update_phase(h, h_dot, touching > 0.0)
        if self._write_law_state():  # a new phase, or thrust's energy: the law again
            self._run_law()
        self._height = h
        supported = self.phase != Phase.FREE
        if supported and touching > 0.0:
            if self._feasible_out[0] < 0.5:
                columns = np.repeat(self._gaps_in <= self.settings.contact_gap, 3)
                forces = self._constrained_forces(self._A, self._wrench_out, columns)
                self._force_out[:] = forces.ravel()
        else:
            self._force_out[:] = 0.0
        self._forces = self._forces_view
        self._supported_in[0] = supported
        self._run_torques()
        return self._tau_out.copy()

    def _write_law_state(self) -> bool:
        """Write c_0, the thrust flag and v_to into the law's ``state``; whether they changed."""
        key = (self.phase, self._energy_correction)
        if key == self._law_state:
            return False
        self._law_state = key
        self._state_in[:] = self._law_state_values()
        return True

    def _update_phase(self, h: float, h_dot: float, touching: bool) -> None:
        s = self.settings
        if self.phase is None:
            self.phase = Phase.CONSTRAINED if touching else Phase.FREE
        if self.phase == Phase.FREE:
            self._flight_apex = max(self._flight_apex, h)
            if touching and h_dot < 0.0:  # touchdown
                self.phase = Phase.CONSTRAINED
                if math.isfinite(self._flight_apex) and self.hops_done > 0:
                    self.apexes.append(self._flight_apex)
                    error = s.apex - self._flight_apex  # [m]
                    self._energy_correction += 2.0 * self.g * s.apex_gain * error
        elif self.phase == Phase.CONSTRAINED:
            if self.hops_done < s.hops and h_dot >= 0.0 and touching:  # bottom of the stroke
                self.phase = Phase.TAKEOFF
        elif h >= self.touchdown_height or not touching:  # thrust ends: take-off
            self.phase = Phase.FREE
            self.hops_done += 1
            self._flight_apex = h

    @property
    def forces(self) -> Vector:
        """The feet's forces (world) the last call commanded, in [N], shape (n_feet, 3)."""
        return self._forces.copy()

    def takeoff_speed(self) -> float:
        """The take-off speed v_to the next thrust aims at, in [m/s]."""
        s = self.settings
        energy = 2.0 * self.g * (s.apex - self.touchdown_height) + self._energy_correction
        return math.sqrt(max(energy, 0.0))

    def _constrained_forces(self, A: Vector, wrench: Vector, columns: Mask) -> Vector:
        """The force QP's solution by proxsuite (its optimum is outside the pyramids), (n_feet, 3).

        Args:
            A: The wrench matrix of all the feet, shape (6, 3 n_feet).
            wrench: The desired wrench (F [N], T [N m]), shape (6,).
            columns: The force columns of the feet in contact, shape (3 n_feet,).
        """
        H = A.T @ A
        H.flat[:: H.shape[0] + 1] += _REGULARIZATION
        box = np.where(columns, INFINITY, 0.0)
        result = self._qp.solve(H, -A.T @ wrench, self._C, self._lower, self._upper, -box, box)
        return np.array(result.x).reshape(-1, 3)

    def prepare_log(self, log: Log) -> None:
        """Declare ``phase``, ``hops``, ``com_height`` [m] and ``foot_force_command`` [N]."""
        log.add_field("phase", (), dtype=np.int64)
        log.add_field("hops", (), dtype=np.int64)
        log.add_field("com_height", ())
        log.add_field("foot_force_command", (len(self._frames), 3))
        log.metadata["controller"] = "pronk"
        log.metadata["feet"] = list(self.feet)

    def record(self, log: Log) -> None:
        """Write the current phase, hop count, height and commanded forces."""
        log.record_extra("phase", int(Phase.FREE if self.phase is None else self.phase))
        log.record_extra("hops", self.hops_done)
        log.record_extra("com_height", self._height)
        log.record_extra("foot_force_command", self._forces)


def _configuration_index(model: pin.Model) -> Index:
    """Configuration index of each velocity index of a one-coordinate joint, shape (nv,)."""
    index = np.full(model.nv, -1, dtype=np.int64)
    for joint in model.joints[1:]:
        if joint.nq == joint.nv:
            index[joint.idx_v : joint.idx_v + joint.nv] = np.arange(
                joint.idx_q, joint.idx_q + joint.nq
            )
    return index
