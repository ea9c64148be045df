r"""Friction in the joints: viscous and Coulomb, per velocity coordinate.

Joint :math:`j` (velocity coordinate :math:`v_j`) opposes its motion with the torque

.. math:: \tau_{f,j} \in -D_j v_j - F_{c,j} \operatorname{Sgn}(v_j),

:math:`D_j \ge 0` the viscous coefficient in [N m s/rad] ([N s/m] for a prismatic joint),
:math:`F_{c,j} \ge 0` the Coulomb (dry) friction torque in [N m] ([N]) and
:math:`\operatorname{Sgn}` the set-valued sign (:math:`[-1, 1]` at 0: the joint sticks while
the torque holding it is below :math:`F_{c,j}`). The plant's integrators treat it as
``docs/friction.md`` ("Friction in joints") says; a controller's model of it
(:meth:`JointFriction.model_torque`) replaces the sign by a saturation.

Scenes declare it in a ``[joint_friction]`` table (:meth:`JointFriction.from_table`); with
flexible joints it acts on the link coordinates.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_positive, as_vector, check_keys
from ucontrol.exceptions import InvalidParameterError, SceneError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]

#: Keys of a ``[joint_friction]`` table (and of ``[controller.model] joint_friction``).
JOINT_FRICTION_KEYS = {"viscous", "coulomb", "velocity_band"}
#: Default half-width of the band of velocities [rad/s] or [m/s] over which a controller's
#: model of Coulomb friction goes linearly from :math:`-F_c` to :math:`F_c`.
VELOCITY_BAND = 1e-2


@dataclass(frozen=True, kw_only=True)
class JointFriction:
    r"""Viscous and Coulomb friction of each velocity coordinate of a robot.

    Attributes:
        viscous: :math:`D` of each velocity coordinate, >= 0, shape (nv,), in [N m s/rad]
            (revolute) or [N s/m] (prismatic).
        coulomb: :math:`F_c` of each velocity coordinate, >= 0, shape (nv,), in [N m] or [N].
        velocity_band: Half-width in [rad/s] or [m/s] of the band over which
            :meth:`model_torque` smooths the sign of Coulomb friction (a controller's model;
            the plant's friction is set-valued and does not use it).
    """

    viscous: Vector
    coulomb: Vector
    velocity_band: float = VELOCITY_BAND

    def __post_init__(self) -> None:
        viscous = as_vector("viscous", self.viscous)
        coulomb = as_vector("coulomb", self.coulomb, viscous.size)
        for name, values in (("viscous", viscous), ("coulomb", coulomb)):
            if np.any(values < 0.0):
                raise InvalidParameterError(name, values.tolist(), ">= 0 for every coordinate")
        object.__setattr__(self, "viscous", viscous)
        object.__setattr__(self, "coulomb", coulomb)
        object.__setattr__(self, "velocity_band", as_positive("velocity_band", self.velocity_band))

    @property
    def nv(self) -> int:
        """Number of velocity coordinates."""
        return int(self.viscous.size)

    @property
    def has_viscous(self) -> bool:
        """Whether some coordinate has viscous friction."""
        return bool(np.any(self.viscous > 0.0))

    @property
    def coulomb_index(self) -> NDArray[np.intp]:
        """Velocity coordinates with Coulomb friction (:math:`F_c > 0`), shape (m_j,)."""
        return np.flatnonzero(self.coulomb > 0.0)

    def model_torque(self, v: Vector, v_sign: Vector | None = None) -> Vector:
        r"""Friction torque a controller compensates: :math:`D v + F_c \,\mathrm{sat}(w/\epsilon)`.

        The opposite of the friction the joints exert, the sign smoothed:
        :math:`\mathrm{sat}` clips to [-1, 1] and :math:`\epsilon` is
        :attr:`velocity_band`.

        Args:
            v: Velocity of the viscous term, shape (nv,), in [rad/s] or [m/s].
            v_sign: Velocity w whose sign the Coulomb term takes, shape (nv,); default ``v``.

        Returns:
            Torques in [N m] or [N], shape (nv,).
        """
        w = v if v_sign is None else v_sign
        return self.viscous * v + self.coulomb * np.clip(w / self.velocity_band, -1.0, 1.0)

    def dissipation(self, v: Vector) -> float:
        r"""Power dissipated at ``v`` (nv,): :math:`\sum_j D_j v_j^2 + F_{c,j} |v_j|` in [W]."""
        return float(self.viscous @ (v * v) + self.coulomb @ np.abs(v))

    @classmethod
    def from_table(
        cls, robot: RobotModel, table: Any, section: str = "[joint_friction]"
    ) -> JointFriction:
        """The friction a ``[joint_friction]`` table declares for ``robot``.

        ``viscous`` and ``coulomb`` are each one number for every actuated joint (a free-flyer
        base has none) or a table of numbers by URDF joint name (the others get 0; a joint of
        several velocity coordinates gets the value on each); ``velocity_band`` [rad/s] is
        for controllers' models.

        Raises:
            SceneError: ``table`` is not a table, or declares neither ``viscous`` nor
                ``coulomb``.
            UnknownKeyError: A key other than ``viscous``, ``coulomb``, ``velocity_band``.
            NotFoundError: A joint name the robot does not have.
            InvalidParameterError: A value that is not a number >= 0.
        """
        if not isinstance(table, Mapping):
            raise SceneError(f"{section} must be a table, got {table!r}")
        check_keys(section, table, JOINT_FRICTION_KEYS)
        if "viscous" not in table and "coulomb" not in table:
            raise SceneError(f"{section} declares neither `viscous` nor `coulomb`")
        return cls(
            viscous=_per_coordinate(robot, table.get("viscous", 0.0), f"{section} viscous"),
            coulomb=_per_coordinate(robot, table.get("coulomb", 0.0), f"{section} coulomb"),
            velocity_band=table.get("velocity_band", VELOCITY_BAND),
        )


def _per_coordinate(robot: RobotModel, spec: Any, name: str) -> Vector:
    """One value per velocity coordinate from a number (actuated ones) or a table by joint."""
    values = np.zeros(robot.nv)
    if isinstance(spec, Mapping):
        model = robot.model
        for joint_name, value in spec.items():
            joint = model.joints[robot.joint_id(str(joint_name))]
            values[joint.idx_v : joint.idx_v + joint.nv] = _non_negative(
                f"{name} of {joint_name!r}", value
            )
    else:
        values[robot.actuated] = _non_negative(name, spec)
    return values


def _non_negative(name: str, value: Any) -> float:
    number = as_float(name, value)
    if number < 0.0:
        raise InvalidParameterError(name, value, ">= 0")
    return number
