r"""Elastic transmissions (Spong's flexible-joint model) on some joints of a robot.

A flexible joint j couples its link coordinate :math:`q_{1,j}` to a motor coordinate
:math:`q_{2,j}` through a spring of stiffness :math:`K_j` and a damper :math:`D_j`; the motor, of
inertia :math:`B_j`, receives the input:

.. math::

    M(q_1)\ddot q_1 + h(q_1, \dot q_1) + S^T\big(K (S q_1 - q_2) + D (S \dot q_1 - \dot q_2)\big)
        = J^T \lambda, \qquad
    B \ddot q_2 + K (q_2 - S q_1) + D (\dot q_2 - S \dot q_1) = u_f,

with S (nf, nv) the selection of the flexible joints' velocity coordinates. The plant's state
is then extended: :math:`q = (q_1, q_2)` of size nq + nf and :math:`v = (\dot q_1, \dot q_2)` of
size nv + nf, motors last in the order of :attr:`FlexibleJoints.joints`. The input keeps one
entry per actuated link coordinate: on a flexible joint it drives the motor, on a rigid one the
link. Motor coordinates exist only when a scene declares flexible joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]


@dataclass(frozen=True)
class FlexibleJoints:
    """Which joints of a robot are flexible, and their transmission parameters.

    Build with :meth:`from_robot`.

    Attributes:
        joints: Joint names, shape (nf,).
        q_index: Index of each joint's link coordinate in the robot's q, shape (nf,).
        v_index: Index of each joint's link coordinate in the robot's v, shape (nf,).
        stiffness: K in [N m/rad] (or [N/m] for prismatic joints), shape (nf,), > 0.
        motor_inertia: B in [kg m²] (or [kg]), shape (nf,), > 0.
        damping: D in [N m s/rad] (or [N s/m]), shape (nf,), >= 0.
        nq: Size of the robot's (link) configuration.
        nv: Size of the robot's (link) velocity.
        input_index: Position of each flexible joint in the input vector u, shape (nf,).
    """

    joints: tuple[str, ...]
    q_index: NDArray[np.intp]
    v_index: NDArray[np.intp]
    stiffness: Vector
    motor_inertia: Vector
    damping: Vector
    nq: int
    nv: int
    input_index: NDArray[np.intp]
    _extended_q: tuple[int] = field(init=False, repr=False, compare=False)
    _extended_v: tuple[int] = field(init=False, repr=False, compare=False)

    @classmethod
    def from_robot(
        cls,
        robot: RobotModel,
        joints: Sequence[str],
        *,
        stiffness: float | Sequence[float],
        motor_inertia: float | Sequence[float],
        damping: float | Sequence[float] = 0.0,
    ) -> FlexibleJoints:
        """Declare ``joints`` of ``robot`` flexible.

        Args:
            robot: The rigid robot (its link dynamics).
            joints: Names of actuated one-degree-of-freedom joints (revolute or prismatic).
            stiffness: K per joint, or one value for all, > 0.
            motor_inertia: B per joint, or one value for all, > 0.
            damping: D per joint, or one value for all, >= 0.

        Raises:
            JointNotFoundError: A joint is not in the robot.
            InvalidParameterError: A joint is listed twice, is not a one-degree-of-freedom
                actuated joint, or a parameter is out of range or non-finite.
            ShapeError: A per-joint list has the wrong length.
        """
        names = tuple(str(name) for name in joints)
        if not names:
            raise InvalidParameterError("flexible joints", list(names), "at least one joint")
        if len(set(names)) != len(names):
            raise InvalidParameterError("flexible joints", list(names), "distinct joint names")
        q_index, v_index = [], []
        for name in names:
            joint = robot.model.joints[robot.joint_id(name)]
            if (joint.nq, joint.nv) != (1, 1):  # revolute or prismatic, not continuous
                raise InvalidParameterError(
                    f"flexible joint {name!r}", joint.shortname(), "a revolute or prismatic joint"
                )
            if joint.idx_v not in robot.actuated:
                raise InvalidParameterError(f"flexible joint {name!r}", name, "an actuated joint")
            q_index.append(joint.idx_q)
            v_index.append(joint.idx_v)
        nf = len(names)
        actuated = list(robot.actuated)
        return cls(
            joints=names,
            q_index=np.array(q_index, dtype=np.intp),
            v_index=np.array(v_index, dtype=np.intp),
            stiffness=_per_joint("stiffness", stiffness, nf, positive=True),
            motor_inertia=_per_joint("motor_inertia", motor_inertia, nf, positive=True),
            damping=_per_joint("damping", damping, nf, positive=False),
            nq=robot.nq,
            nv=robot.nv,
            input_index=np.array([actuated.index(i) for i in v_index], dtype=np.intp),
        )

    def __post_init__(self) -> None:
        # The extended sizes, read at every step (split).
        object.__setattr__(self, "_extended_q", (self.nq + len(self.joints),))
        object.__setattr__(self, "_extended_v", (self.nv + len(self.joints),))

    @property
    def nf(self) -> int:
        """Number of flexible joints (motor coordinates)."""
        return len(self.joints)

    def input_coordinates(self, actuated: NDArray[np.intp]) -> NDArray[np.intp]:
        """Where each input acts in the extended velocity: motors for the flexible joints.

        Args:
            actuated: The robot's actuated link velocity indices, shape (nu,).

        Returns:
            Indices into (dq1, dq2), shape (nu,).
        """
        coordinates = np.array(actuated, dtype=np.intp)
        coordinates[self.input_index] = self.nv + np.arange(self.nf)
        return coordinates

    def rigid_limit(self, robot: RobotModel) -> RobotModel:
        """The robot these joints tend to as K grows: each motor's inertia added to its link's.

        Without impacts the flexible trajectories approach those of this rigid robot at the
        rate 1/K; an impact acts on the link inertia alone and leaves a fast spring oscillation
        whose energy does not vanish with 1/K (docs/flexible.md).
        """
        armature = np.zeros(robot.nv)
        armature[self.v_index] = self.motor_inertia
        return robot.with_armature(armature)

    def link_positions(self, q: Vector) -> Vector:
        """The flexible joints' link coordinates in a link configuration (nq,), shape (nf,)."""
        return q[self.q_index]

    def split(self, q: Vector, v: Vector) -> tuple[Vector, Vector, Vector, Vector]:
        """Link and motor parts of an extended state.

        Args:
            q: Extended configuration (q1, q2), shape (nq + nf,).
            v: Extended velocity (dq1, dq2), shape (nv + nf,).

        Returns:
            q1 (nq,), dq1 (nv,), q2 (nf,), dq2 (nf,) — views, not copies.
        """
        if q.shape != self._extended_q:
            raise ShapeError("extended configuration q", self._extended_q, q.shape)
        if v.shape != self._extended_v:
            raise ShapeError("extended velocity v", self._extended_v, v.shape)
        nq, nv = self.nq, self.nv
        return q[:nq], v[:nv], q[nq:], v[nv:]

    def deflection(self, q1: Vector, q2: Vector) -> Vector:
        """Spring deflection :math:`S q_1 - q_2` in [rad] (or [m]), shape (nf,)."""
        return q1[self.q_index] - q2

    def spring_torque(self, q1: Vector, dq1: Vector, q2: Vector, dq2: Vector) -> Vector:
        r"""Transmission torque on the motors, :math:`K (S q_1 - q_2) + D (S \dot q_1 - \dot q_2)`.

        In [N m] (or [N]), shape (nf,); the links receive its opposite.
        """
        return self.stiffness * self.deflection(q1, q2) + self.damping * (dq1[self.v_index] - dq2)

    def transmission_forces(self, q: Vector, v: Vector) -> Vector:
        r"""Generalized forces of the springs and dampers on the extended state.

        :math:`(-S^T f, f)` with f the :meth:`spring_torque`, in [N m] (or [N]), shape
        (nv + nf,), for the extended (q (nq + nf,), v (nv + nf,)).
        """
        q1, v1, q2, v2 = self.split(q, v)
        transmission = self.spring_torque(q1, v1, q2, v2)  # on the motors
        forces = np.zeros(self._extended_v)
        forces[self.v_index] = -transmission
        forces[self.nv :] = transmission
        return forces

    def spring_energy(self, q1: Vector, q2: Vector) -> float:
        """Elastic energy of the springs in [J]."""
        deflection = self.deflection(q1, q2)
        return float(0.5 * deflection @ (self.stiffness * deflection))

    def motor_kinetic_energy(self, dq2: Vector) -> float:
        """Kinetic energy of the motors in [J]."""
        return float(0.5 * dq2 @ (self.motor_inertia * dq2))

    def coupling_matrix(self, gains: Vector) -> Vector:
        r"""The matrix of the quadratic form :math:`\frac12 \delta^T G \delta`.

        With :math:`\delta = S \dot q_1 - \dot q_2` (or the deflection),

        it is :math:`\begin{pmatrix} S^T G S & -S^T G \\ -G S & G \end{pmatrix}` in the extended
        velocity coordinates, shape (nv + nf, nv + nf): with G = K it is the spring's stiffness
        matrix, with G = D the damper's.

        Args:
            gains: G per joint, shape (nf,).
        """
        n = self.nv + self.nf
        matrix = np.zeros((n, n))
        links = self.v_index
        motors = self.nv + np.arange(self.nf)
        matrix[links, links] = gains
        matrix[motors, motors] = gains
        matrix[links, motors] = -gains
        matrix[motors, links] = -gains
        return matrix


def _per_joint(name: str, value: float | Sequence[float], nf: int, *, positive: bool) -> Vector:
    """``value`` broadcast to shape (nf,), checked finite and > 0 (or >= 0)."""
    try:
        array = np.broadcast_to(np.asarray(value, dtype=float), (nf,)).copy()
    except ValueError as error:
        raise ShapeError(name, (nf,), np.shape(value)) from error
    except TypeError as error:
        raise InvalidParameterError(name, value, "a number or a list of numbers") from error
    bad = ~np.isfinite(array) | ((array <= 0.0) if positive else (array < 0.0))
    if bad.any():
        raise InvalidParameterError(
            name, float(array[bad.argmax()]), "finite and > 0" if positive else "finite and >= 0"
        )
    return array
