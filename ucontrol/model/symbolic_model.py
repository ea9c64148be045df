r"""Casadi expressions of a fixed-base robot's kinematics and dynamics, from its Pinocchio model.

Laws that need exact time derivatives of model terms (the flexible-joint law needs the third
derivative of the link configuration) differentiate these expressions with casadi's automatic
differentiation. The model is rebuilt from ``model.parents``, ``model.jointPlacements``,
``model.inertias``, ``model.frames`` and ``model.gravity``:

- joint i placed at :math:`{}^0M_i = {}^0M_{\lambda(i)}\, {}^{\lambda(i)}M_i\, M_J(q_i)`, with
  :math:`M_J` a rotation about (revolute) or a translation along (prismatic) the joint axis;
- :math:`M(q) = \sum_i m_i J_{c,i}^T J_{c,i} + J_{\omega,i}^T R_i I_i R_i^T J_{\omega,i}
  + \mathrm{diag}(a)` (linear Jacobian of the centre of mass, angular Jacobian from the world
  axes of the revolute joints supporting body i, rotational inertia :math:`I_i` about the
  centre of mass, the model's armature a);
- :math:`g(q) = -\sum_i m_i J_{c,i}^T g_0` (:math:`g_0` the gravity acceleration);
- the Christoffel Coriolis matrix
  :math:`C(q, v) = \tfrac12\big(\dot M + \partial_q(M v) - \partial_q(M v)^T\big)`, i.e.
  :math:`C_{kj} = \sum_i \tfrac12 (\partial_i M_{kj} + \partial_j M_{ki} - \partial_k M_{ij})
  v_i`, so that :math:`C v` holds the Coriolis and centrifugal terms and
  :math:`\dot M - 2C = \partial_q(Mv)^T - \partial_q(Mv)` is skew-symmetric.

Every joint must have one degree of freedom (nq = nv): Pinocchio's RX, RY, RZ,
RevoluteUnaligned, PX, PY, PZ and PrismaticUnaligned joints.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import pinocchio as pin

from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

#: Largest nv for which the compiled symbolic terms (M, C, h, a frame's kinematics) beat
#: Pinocchio's recursive algorithms: measured faster at nv = 2 and slower at nv = 7, where the
#: Christoffel terms, which grow as nv³ in the C code, dominate (docs/benchmarks.md, sixth
#: round).
SMALL_ROBOT_MAX_NV = 3

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

    Attributes:
        nv: Number of joint coordinates (nq = nv).
        mass_matrix: ``(q (nv,)) -> M (nv, nv)`` in [kg m²] (mixed units).
        coriolis_matrix: ``(q (nv,), v (nv,)) -> C (nv, nv)`` with :math:`\dot M - 2C`
            skew-symmetric, in [kg m²/s].
        gravity: ``(q (nv,)) -> g (nv,)``, the generalized gravity forces in [N m] (or [N]).
        potential_energy: ``(q (nv,)) -> V``, the gravitational potential energy in [J].

    Raises:
        InvalidParameterError: A joint is not one of the supported types (e.g. a free-flyer
            base, a spherical or a continuous joint).
    """

    def __init__(self, robot: RobotModel) -> None:
        model = robot.model
        self._robot = robot
        self.nv = model.nv
        q = ca.SX.sym("q", self.nv)
        self._q = q
        rotations: list[ca.SX] = [ca.SX.eye(3)]
        positions: list[ca.SX] = [ca.SX.zeros(3)]
        world_axes: list[ca.SX | None] = [None]  # world axis of each revolute joint
        for i in range(1, model.njoints):
            kind, axis = _joint_axis(model, i)
            placement = model.jointPlacements[i]
            parent = model.parents[i]
            rotation = rotations[parent] @ ca.DM(placement.rotation)
            position = positions[parent] + rotations[parent] @ ca.DM(placement.translation)
            angle_or_offset = q[model.joints[i].idx_q]
            if kind == "revolute":
                world_axes.append(rotation @ ca.DM(axis))
                rotation = rotation @ _rotation(axis, angle_or_offset)
            else:
                world_axes.append(None)
                position = position + rotation @ (ca.DM(axis) * angle_or_offset)
            rotations.append(rotation)
            positions.append(position)
        self._rotations, self._positions = rotations, positions
        self._world_axes = world_axes

    @property
    def mass_matrix(self) -> ca.Function:
        """``(q (nv,)) -> M (nv, nv)`` in [kg m²] (mixed units), built on first use."""
        return self._dynamics[0]

    @property
    def coriolis_matrix(self) -> ca.Function:
        r"""``(q (nv,), v (nv,)) -> C (nv, nv)``, :math:`\dot M - 2C` skew, built on first use."""
        return self._dynamics[1]

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
        model, q = self._robot.model, self._q
        v = ca.SX.sym("v", self.nv)
        rotations, positions, world_axes = self._rotations, self._positions, self._world_axes
        M = ca.SX.zeros(self.nv, self.nv)
        g = ca.SX.zeros(self.nv)
        potential = ca.SX.zeros(1)
        gravity = ca.DM(np.asarray(model.gravity.linear))
        for i in range(1, model.njoints):
            inertia = model.inertias[i]
            centre = positions[i] + rotations[i] @ ca.DM(inertia.lever)  # [m]
            J_centre = ca.jacobian(centre, q)
            J_angular = ca.SX.zeros(3, self.nv)
            for j in model.supports[i][1:]:
                if world_axes[j] is not None:
                    J_angular[:, model.joints[j].idx_v] = world_axes[j]
            I_world = rotations[i] @ ca.DM(inertia.inertia) @ rotations[i].T  # [kg m²]
            M += inertia.mass * (J_centre.T @ J_centre) + J_angular.T @ I_world @ J_angular
            g -= inertia.mass * (J_centre.T @ gravity)
            potential -= inertia.mass * ca.dot(gravity, centre)
        M += ca.diag(ca.DM(np.asarray(model.armature, dtype=float)))  # rotor inertias, as crba
        M_v = M @ v
        dM_v = ca.jacobian(M_v, q)
        M_dot = ca.reshape(ca.jacobian(ca.vec(M), q) @ v, self.nv, self.nv)
        C = 0.5 * (M_dot + dM_v - dM_v.T)
        return (
            ca.Function("M", [q], [M], ["q"], ["M"]),
            ca.Function("C", [q, v], [C], ["q", "v"], ["C"]),
            ca.Function("g", [q], [g], ["q"], ["g"]),
            ca.Function("V", [q], [potential], ["q"], ["V"]),
        )

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
