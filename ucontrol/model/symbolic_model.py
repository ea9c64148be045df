r"""Casadi expressions of a fixed-base robot's kinematics and dynamics, from its Pinocchio model.

The one symbolic source of the rigid dynamics, Pinocchio's the reference it is checked against
(``tests/model/test_symbolic_model.py``): the compiled constraint rows of small robots, the
Brogliato laws and the design of cycles (:mod:`ucontrol.design`) build on it. Laws that need
exact time derivatives of model terms (the flexible-joint law needs the third derivative of
the link configuration) differentiate these expressions with casadi's automatic
differentiation. The model is rebuilt from ``model.parents``, ``model.jointPlacements``,
``model.inertias``, ``model.frames`` and ``model.gravity``:

- joint i placed at :math:`{}^0M_i = {}^0M_{\lambda(i)}\, {}^{\lambda(i)}M_i\, M_J(q_i)`, with
  :math:`M_J` a rotation about (revolute) or a translation along (prismatic) the joint axis;
- the joint torques :math:`\tau(q, v, \dot v) = M(q)\dot v + h(q, v)` by the recursive
  Newton–Euler algorithm (Featherstone, *Rigid Body Dynamics Algorithms*, Springer 2008, ch. 5;
  Pinocchio's ``rnea``), :math:`O(n)` operations:

  .. math::

      v_i = {}^iX_{\lambda(i)} v_{\lambda(i)} + S_i \dot q_i, \quad
      a_i = {}^iX_{\lambda(i)} a_{\lambda(i)} + S_i \ddot q_i + v_i \times S_i \dot q_i, \quad
      f_i = I_i a_i + v_i \times^* I_i v_i,

  with :math:`a_0 = -g_0` (gravity), then :math:`\tau_i = S_i^T f_i` and
  :math:`f_{\lambda(i)} \mathrel{+}= {}^{\lambda(i)}X_i^* f_i` from the leaves to the root
  (spatial vectors as (linear, angular) pairs of 3-vectors at each joint frame's origin, in
  that frame); :math:`h(q, v) = \tau(q, v, 0)`, :math:`g(q) = \tau(q, 0, 0)`, and the columns
  of :math:`M(q)` are :math:`\tau(q, 0, e_j)` without gravity, plus the model's armature a on
  the diagonal (as ``crba``);
- the Christoffel Coriolis matrix
  :math:`C(q, v) = \tfrac12\big(\dot M + \partial_q(M v) - \partial_q(M v)^T\big)`, i.e.
  :math:`C_{kj} = \sum_i \tfrac12 (\partial_i M_{kj} + \partial_j M_{ki} - \partial_k M_{ij})
  v_i`, so that :math:`C v` holds the Coriolis and centrifugal terms and
  :math:`\dot M - 2C = \partial_q(Mv)^T - \partial_q(Mv)` is skew-symmetric.

Every joint must have one degree of freedom (nq = nv): Pinocchio's RX, RY, RZ,
RevoluteUnaligned, PX, PY, PZ and PrismaticUnaligned joints.

The bodies' inertias are constants of the expressions, or (``inertia_input=True``) a last input
``inertia`` of every dynamics Function, :data:`INERTIA_SIZE` numbers per body
(:func:`inertia_parameters`): then the code generated from them serves every mass and inertia
of the robot (a Monte Carlo over the model's masses compiles it once).
"""

from __future__ import annotations

import functools
from typing import Any

import casadi as ca
import numpy as np
import pinocchio as pin

from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import SMALL_ROBOT_MAX_NV as SMALL_ROBOT_MAX_NV  # its home before
from ucontrol.model.robot_model import RobotModel
from ucontrol.model.robot_model import inertia_parameters as inertia_parameters  # its home before

#: Numbers per body in the ``inertia`` input (:func:`inertia_parameters`): the mass in [kg], the
#: centre of mass in the joint frame (3,) in [m], the rotational inertia about it in [kg m²] as
#: (xx, xy, xz, yy, yz, zz).
INERTIA_SIZE = 10

#: Supported Pinocchio joint types: (kind, axis in the joint frame; None: read it from the joint).
_JOINT_TYPES: dict[str, tuple[str, tuple[float, float, float] | None]] = {
    "JointModelRX": ("revolute", (1.0, 0.0, 0.0)),
    "JointModelRY": ("revolute", (0.0, 1.0, 0.0)),
    "JointModelRZ": ("revolute", (0.0, 0.0, 1.0)),
    "JointModelRevoluteUnaligned": ("revolute", None),
    "JointModelPX": ("prismatic", (1.0, 0.0, 0.0)),
    "JointModelPY": ("prismatic", (0.0, 1.0, 0.0)),
    "JointModelPZ": ("prismatic", (0.0, 0.0, 1.0)),
    "JointModelPrismaticUnaligned": ("prismatic", None),
}


class SymbolicModel:
    r"""Frame positions, M(q), C(q, v) and g(q) of a fixed-base robot as casadi Functions.

    The Functions take and return casadi matrices (call them with numbers for values, with
    ``casadi.SX`` symbols to build larger expressions).

    Args:
        robot: A fixed-base robot whose joints are all revolute or prismatic.
        inertia_input: Make the bodies' inertias a last input ``inertia``
            (:func:`inertia_parameters`, shape (10 (njoints - 1),)) of the dynamics Functions
            (M, h, C, g, V) instead of constants.

    Attributes:
        nv: Number of joint coordinates (nq = nv).
        inertia: The symbol of the ``inertia`` input, or None (constants).
        mass_matrix: ``(q (nv,)) -> M (nv, nv)`` in [kg m²] (mixed units).
        nonlinear_effects: ``(q (nv,), v (nv,)) -> h (nv,)``, :math:`C(q, v) v + g(q)` in
            [N m] (or [N]).
        coriolis_matrix: ``(q (nv,), v (nv,)) -> C (nv, nv)`` with :math:`\dot M - 2C`
            skew-symmetric, in [kg m²/s].
        gravity: ``(q (nv,)) -> g (nv,)``, the generalized gravity forces in [N m] (or [N]).
        potential_energy: ``(q (nv,)) -> V``, the gravitational potential energy in [J].

    Raises:
        InvalidParameterError: A joint is not one of the supported types (e.g. a free-flyer
            base, a spherical or a continuous joint).
    """

    def __init__(self, robot: RobotModel, *, inertia_input: bool = False) -> None:
        model = robot.model
        self._robot = robot
        self.nv = model.nv
        q = ca.SX.sym("q", self.nv)
        self._q, self._v = q, ca.SX.sym("v", self.nv)
        bodies = model.njoints - 1
        self.inertia = ca.SX.sym("inertia", INERTIA_SIZE * bodies) if inertia_input else None
        # Each body's (mass, centre of mass (3,), rotational inertia (3, 3)): symbols or values.
        self._bodies = [self._body_inertia(i) for i in range(1, model.njoints)]
        rotations: list[ca.SX] = [ca.SX.eye(3)]
        positions: list[ca.SX] = [ca.SX.zeros(3)]
        # Each joint's (kind, axis, index, rotation, translation) from its parent's frame.
        self._joints: list[tuple[str, ca.DM, int, ca.SX, ca.SX]] = []
        for i in range(1, model.njoints):
            kind, axis = _joint_axis(model, i)
            placement = model.jointPlacements[i]
            parent = model.parents[i]
            rotation = rotations[parent] @ ca.DM(placement.rotation)
            position = positions[parent] + rotations[parent] @ ca.DM(placement.translation)
            angle_or_offset = q[model.joints[i].idx_q]
            local_rotation: Any = ca.DM(placement.rotation)
            local_translation: Any = ca.DM(placement.translation)
            if kind == "revolute":
                rotation = rotation @ _rotation(axis, angle_or_offset)
                local_rotation = local_rotation @ _rotation(axis, angle_or_offset)
            else:
                position = position + rotation @ (ca.DM(axis) * angle_or_offset)
                local_translation = local_translation + local_rotation @ (
                    ca.DM(axis) * angle_or_offset
                )
            rotations.append(rotation)
            positions.append(position)
            index = model.joints[i].idx_v
            self._joints.append((kind, ca.DM(axis), index, local_rotation, local_translation))
        self._rotations, self._positions = rotations, positions

    @property
    def mass_matrix(self) -> ca.Function:
        """``(q (nv,)) -> M (nv, nv)`` in [kg m²] (mixed units), built on first use."""
        return self._dynamics[0]

    @property
    def coriolis_matrix(self) -> ca.Function:
        r"""``(q (nv,), v (nv,)) -> C (nv, nv)``, :math:`\dot M - 2C` skew, built on first use."""
        return self._dynamics[1]

    @functools.cached_property
    def nonlinear_effects(self) -> ca.Function:
        r"""``(q (nv,), v (nv,)) -> h (nv,)``, :math:`C(q, v) v + g(q)`, built on first use."""
        h = self._rnea(self._v, ca.SX.zeros(self.nv), gravity=True)
        return self._function("h", [self._q, self._v], h, ["q", "v"])

    @property
    def gravity(self) -> ca.Function:
        """``(q (nv,)) -> g (nv,)`` in [N m] (or [N]), built on first use."""
        return self._dynamics[2]

    @property
    def potential_energy(self) -> ca.Function:
        r"""``(q (nv,)) -> V`` in [J]: :math:`-\sum_i m_i g_0 \cdot c_i(q)`, as Pinocchio's."""
        return self._dynamics[3]

    @functools.cached_property
    def _dynamics(self) -> tuple[ca.Function, ca.Function, ca.Function, ca.Function]:
        """The Functions M(q), C(q, v), g(q) and V(q) (module docstring)."""
        model, q, nv = self._robot.model, self._q, self.nv
        v, zero = self._v, ca.SX.zeros(nv)
        columns = [self._rnea(None, ca.SX(ca.DM.eye(nv)[:, j]), gravity=False) for j in range(nv)]
        M = ca.horzcat(*columns)
        armature = np.asarray(model.armature, dtype=float)
        if armature.any():  # rotor inertias on the diagonal, as crba
            M += ca.diag(ca.DM(armature))
        gravity = ca.DM(np.asarray(model.gravity.linear))
        potential = ca.SX.zeros(1)
        for i in range(1, model.njoints):
            mass, lever, _ = self._bodies[i - 1]
            centre = self._positions[i] + self._rotations[i] @ lever  # [m]
            potential -= mass * ca.dot(gravity, centre)
        M_v = M @ v
        dM_v = ca.jacobian(M_v, q)
        M_dot = ca.reshape(ca.jacobian(ca.vec(M), q) @ v, nv, nv)
        C = 0.5 * (M_dot + dM_v - dM_v.T)
        return (
            self._function("M", [q], M, ["q"]),
            self._function("C", [q, v], C, ["q", "v"]),
            self._function("g", [q], self._rnea(None, zero, gravity=True), ["q"]),
            self._function("V", [q], potential, ["q"]),
        )

    def _function(self, name: str, inputs: list[ca.SX], output: ca.SX, names: list[str]) -> Any:
        """``ca.Function`` ``name`` of ``inputs`` (and of :attr:`inertia` if it is an input)."""
        if self.inertia is not None:
            inputs, names = [*inputs, self.inertia], [*names, "inertia"]
        return ca.Function(name, inputs, [output], names, [name])

    def _body_inertia(self, joint: int) -> tuple[Any, Any, Any]:
        """Mass, centre of mass (3,) and rotational inertia (3, 3) of body ``joint``.

        Values (a float and ``casadi.DM``) or, with :attr:`inertia`, its entries in the order
        of :func:`inertia_parameters`.
        """
        if self.inertia is None:
            inertia = self._robot.model.inertias[joint]
            return inertia.mass, ca.DM(inertia.lever), ca.DM(inertia.inertia)
        x = self.inertia[INERTIA_SIZE * (joint - 1) : INERTIA_SIZE * joint]
        xx, xy, xz, yy, yz, zz = (x[k] for k in range(4, 10))
        rotational = ca.vertcat(
            ca.horzcat(xx, xy, xz), ca.horzcat(xy, yy, yz), ca.horzcat(xz, yz, zz)
        )
        return x[0], x[1:4], rotational

    def _rnea(self, v: ca.SX | None, a: ca.SX, *, gravity: bool) -> ca.SX:
        """Joint torques at velocities ``v`` and accelerations ``a`` (expressions, (nv,)).

        Without the armature's torques; with gravity's when ``gravity`` (module docstring).
        ``v`` None: at rest (the velocity terms, zero, not built).
        """
        model = self._robot.model
        n = model.njoints
        gravity_linear = ca.DM(np.asarray(model.gravity.linear)) if gravity else ca.DM.zeros(3)
        velocity: list[tuple[ca.SX, ca.SX]] = [(ca.SX.zeros(3), ca.SX.zeros(3))]
        acceleration: list[tuple[Any, Any]] = [(-gravity_linear, ca.SX.zeros(3))]
        forces: list[list[ca.SX]] = [[ca.SX.zeros(3), ca.SX.zeros(3)] for _ in range(n)]
        for i in range(1, n):
            kind, axis, index, R, p = self._joints[i - 1]
            parent = model.parents[i]
            acc_lin_p, acc_ang_p = acceleration[parent]
            acc_lin = R.T @ (acc_lin_p + ca.cross(acc_ang_p, p))
            acc_ang = R.T @ acc_ang_p
            s_lin, s_ang = (ca.DM.zeros(3), axis) if kind == "revolute" else (axis, ca.DM.zeros(3))
            qdd = a[index]
            acc_lin, acc_ang = acc_lin + s_lin * qdd, acc_ang + s_ang * qdd
            if v is not None:
                # motion from the parent's frame into joint i's: R^T (v + ω × p), R^T ω
                lin_p, ang_p = velocity[parent]
                lin = R.T @ (lin_p + ca.cross(ang_p, p))
                ang = R.T @ ang_p
                qd = v[index]
                lin, ang = lin + s_lin * qd, ang + s_ang * qd
                # a += v × S q̇, (v, ω) × (m_v, m_ω) = (ω × m_v + v × m_ω, ω × m_ω)
                acc_lin = acc_lin + ca.cross(ang, s_lin * qd) + ca.cross(lin, s_ang * qd)
                acc_ang = acc_ang + ca.cross(ang, s_ang * qd)
                velocity.append((lin, ang))
            acceleration.append((acc_lin, acc_ang))
            mass, c, I_c = self._bodies[i - 1]  # [kg], [m], [kg m²] about the centre of mass
            # I a and I v: linear m (a_v + a_ω × c), angular I_c a_ω + c × linear
            f_lin = mass * (acc_lin + ca.cross(acc_ang, c))
            f_ang = I_c @ acc_ang + ca.cross(c, f_lin)
            forces[i][0] = forces[i][0] + f_lin
            forces[i][1] = forces[i][1] + f_ang
            if v is not None:
                h_lin = mass * (lin + ca.cross(ang, c))
                h_ang = I_c @ ang + ca.cross(c, h_lin)
                # v ×* (h_lin, h_ang) = (ω × h_lin, ω × h_ang + v × h_lin)
                forces[i][0] = forces[i][0] + ca.cross(ang, h_lin)
                forces[i][1] = forces[i][1] + ca.cross(ang, h_ang) + ca.cross(lin, h_lin)
        tau = [ca.SX(0)] * self.nv
        for i in range(n - 1, 0, -1):
            kind, axis, index, R, p = self._joints[i - 1]
            f_lin, f_ang = forces[i]
            tau[index] = ca.dot(axis, f_ang if kind == "revolute" else f_lin)
            parent = model.parents[i]
            # force into the parent's frame: R f, R n + p × R f
            parent_lin = R @ f_lin
            forces[parent][0] = forces[parent][0] + parent_lin
            forces[parent][1] = forces[parent][1] + R @ f_ang + ca.cross(p, parent_lin)
        return ca.vertcat(*tau)

    def frame_position(self, frame: str) -> ca.Function:
        """``(q (nv,)) -> p (3,)``: position of the origin of ``frame`` in the world in [m].

        Raises:
            FrameNotFoundError: ``frame`` is not in the robot model.
        """
        model = self._robot.model
        placement = model.frames[self._robot.frame_id(frame)]
        joint = placement.parentJoint
        p = self._positions[joint] + self._rotations[joint] @ ca.DM(placement.placement.translation)
        return ca.Function(f"p_{frame}", [self._q], [p], ["q"], ["p"])


def _joint_axis(model: pin.Model, i: int) -> tuple[str, np.ndarray]:
    """Kind ("revolute" or "prismatic") and unit axis of joint ``i`` in its own frame."""
    joint = model.joints[i]
    kind_axis = _JOINT_TYPES.get(joint.shortname())
    if kind_axis is None:
        raise InvalidParameterError(
            f"joint {model.names[i]!r}",
            joint.shortname(),
            f"one of the joint types {', '.join(_JOINT_TYPES)} (a fixed-base tree of "
            "revolute and prismatic joints)",
        )
    kind, fixed_axis = kind_axis
    axis = np.asarray(joint.extract().axis if fixed_axis is None else fixed_axis, dtype=float)
    return kind, axis / np.linalg.norm(axis)


def _rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    r"""Rotation by ``angle`` about the unit ``axis`` (Rodrigues' formula).

    :math:`R = I + \sin\theta\,[a]_\times + (1 - \cos\theta)[a]_\times^2`.
    """
    skew = ca.DM([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return ca.DM.eye(3) + ca.sin(angle) * skew + (1.0 - ca.cos(angle)) * (skew @ skew)
