r"""Raibert's three laws for a planar one-leg hopper: thrust, foot placement, attitude.

The robot (``robots/hopper.urdf``) has a planar base (x, z, pitch :math:`\theta`), a hip
(angle :math:`\varphi`) and a prismatic leg of length :math:`l`; the leg's angle to the
vertical is :math:`\psi = \theta + \varphi` and the foot sits at the hip plus
:math:`l(-\sin\psi, -\cos\psi)` in (x, z). One force on the leg joint is both the leg's spring,
:math:`k (l_0 - l)`, and its actuator. Whether the foot is on the ground is read from the
contact state the controller gets (the foot's gap at most ``contact_gap``), never from the
plant's impulses; the stance sub-phases from the leg's own rate and length.

- **Flight**: the leg spring with a damper, :math:`f = k(l_0 - l) - c\,\dot l`; the hip places
  the foot at :math:`x_f = \dot x T_s / 2 + k_{\dot x} (\dot x - \dot x_d)` ahead of the hip
  (the neutral point plus a speed correction), by a PD on :math:`\varphi` towards
  :math:`\psi_d - \theta` with :math:`\sin\psi_d = -x_f / l_0`.
- **Stance, compression** (:math:`\dot l \le 0`): the spring alone.
- **Stance, thrust** (:math:`\dot l > 0`, :math:`l < l_0`): the spring plus a thrust
  :math:`F = (E_d - E) / (l_0 - l)`, clipped to :math:`[-F_{max}, F_{max}]` (a negative
  thrust brakes a hop that is too high), with the vertical energy
  :math:`E = m g\, l\cos\psi + \tfrac12 m \dot z^2 + \tfrac12 k (l_0 - l)^2` of the mass m above
  the leg joint over the foot. Along a vertical stance :math:`\dot E = F \dot l` makes
  :math:`(E_d - E)/(l_0 - l)` constant: the thrust is constant, fixed by the bottom state,
  and the energy reaches :math:`E_d` at :math:`l = l_0`. The target
  :math:`E_d = m g z_0 + m g (h_d - z_0) \rho^2`, :math:`z_0 = l_0 \cos\psi`,
  :math:`\rho = (m + m_f)/m`, gives the hip the apex :math:`h_d` above the ground once the
  leg has pulled the foot (mass :math:`m_f`) off at the hip's speed (momentum shared).
- **Stance, extended** (:math:`l \ge l_0`, :math:`\dot l > 0`): the flight law's spring and
  damper, which pull the foot off the ground.
- **Stance, attitude**: the hip holds the body level,
  :math:`\tau = k_\theta \theta + d_\theta \dot\theta` (the hip's reaction on the body is
  :math:`-\tau`).

:math:`T_s` is a parameter (default :math:`\pi\sqrt{m/k}`, half the period of the mass on the
spring) instead of the last stance's measured duration: the law is then a function of the
measured state alone, and the apex-to-apex map of the closed loop is a map of the robot's
state (:func:`ucontrol.analysis.find_gait` with ``section="apex"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ucontrol._validation import as_float, as_non_negative, as_positive
from ucontrol.control.controller import ContactState, Vector
from ucontrol.exceptions import InvalidParameterError

if TYPE_CHECKING:
    from ucontrol.log import Log
    from ucontrol.model.robot_model import RobotModel

#: Phase codes written to the log's ``phase`` field.
FLIGHT, COMPRESSION, THRUST, EXTENDED = 0, 1, 2, 3
#: Largest absolute sine of the commanded leg angle (about 44 degrees).
_MAX_SIN_PSI = 0.7


@dataclass(frozen=True, kw_only=True)
class RaibertSettings:
    r"""What the hopper aims at and its gains.

    Attributes:
        apex: Commanded apex of the hip above the ground in [m].
        speed: Desired forward speed :math:`\dot x_d` in [m/s].
        leg_length: Rest length :math:`l_0` of the leg spring in [m].
        leg_stiffness: Spring stiffness k in [N/m].
        leg_damping: Flight damper c in [N s/m]; default critical for the foot,
            :math:`2\sqrt{k m_f}`.
        placement_gain: :math:`k_{\dot x}` of the foot placement in [s].
        stance_time: :math:`T_s` of the neutral point in [s]; default :math:`\pi\sqrt{m/k}`.
        hip_kp: Flight hip stiffness in [N m/rad].
        hip_kd: Flight hip damping in [N m s/rad].
        attitude_kp: Stance attitude stiffness in [N m/rad].
        attitude_kd: Stance attitude damping in [N m s/rad].
        max_thrust: Largest thrust :math:`|F|` in [N].
        contact_gap: Foot gap in [m] at or below which the foot counts as on the ground.
    """

    apex: float
    speed: float = 0.0
    leg_length: float = 0.5
    leg_stiffness: float = 3000.0
    leg_damping: float | None = None
    placement_gain: float = 0.03
    stance_time: float | None = None
    hip_kp: float = 60.0
    hip_kd: float = 6.0
    attitude_kp: float = 300.0
    attitude_kd: float = 30.0
    max_thrust: float = 2000.0
    contact_gap: float = 1e-3

    def __post_init__(self) -> None:
        object.__setattr__(self, "speed", as_float("speed", self.speed))
        for key in ("apex", "leg_length", "leg_stiffness", "max_thrust"):
            object.__setattr__(self, key, as_positive(key, getattr(self, key)))
        for key in ("placement_gain", "hip_kp", "hip_kd", "attitude_kp", "attitude_kd"):
            object.__setattr__(self, key, as_non_negative(key, getattr(self, key)))
        object.__setattr__(self, "contact_gap", as_non_negative("contact_gap", self.contact_gap))
        for key in ("leg_damping", "stance_time"):
            value = getattr(self, key)
            if value is not None:
                object.__setattr__(self, key, as_positive(key, value))
        if self.apex <= self.leg_length:
            raise InvalidParameterError(
                "apex", self.apex, f"above the leg's rest length {self.leg_length} m"
            )


class RaibertController:
    """Raibert's hopping laws on a planar one-leg hopper (see the module's docstring).

    Args:
        robot: The hopper: joints ``x``, ``z``, ``pitch`` (passive), ``hip``, ``leg``
            (actuated), one coordinate each.
        contact: Index of the foot's constraint in the contact state.
        settings: Targets and gains.
        joints: Names of the (x, z, pitch, hip, leg) joints in the robot.

    Raises:
        JointNotFoundError: A joint name the robot lacks.
        InvalidParameterError: The hip or the leg is not actuated, or a joint has more than
            one coordinate.
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        contact: int,
        settings: RaibertSettings,
        joints: tuple[str, str, str, str, str] = ("x", "z", "pitch", "hip", "leg"),
    ) -> None:
        model = robot.model
        q_index, v_index = [], []
        for name in joints:
            joint = model.joints[robot.joint_id(name)]
            if joint.nq != 1 or joint.nv != 1:
                raise InvalidParameterError(
                    f"joint {name!r}", f"nq = {joint.nq}", "a revolute or prismatic joint"
                )
            q_index.append(int(joint.idx_q))
            v_index.append(int(joint.idx_v))
        actuated = [int(i) for i in robot.actuated]
        for name, i in zip(joints[3:], v_index[3:], strict=True):
            if i not in actuated:
                raise InvalidParameterError(f"joint {name!r}", "passive", "an actuated joint")
        self._q = q_index
        self._v = v_index
        self._u = (actuated.index(v_index[3]), actuated.index(v_index[4]))
        self._nu = robot.nu
        data = pin.Data(model)
        pin.computeSubtreeMasses(model, data)
        #: Mass of the foot side of the leg joint in [kg].
        self.foot_mass = float(data.mass[robot.joint_id(joints[4])])
        #: Mass above the leg joint in [kg].
        self.mass = float(data.mass[0]) - self.foot_mass
        self.gravity = float(np.linalg.norm(robot.gravity))
        self.contact = contact
        self.settings = settings
        k = settings.leg_stiffness
        self.damping = (
            2.0 * math.sqrt(k * self.foot_mass)
            if settings.leg_damping is None
            else settings.leg_damping
        )
        self.stance_time = (
            math.pi * math.sqrt(self.mass / k)
            if settings.stance_time is None
            else settings.stance_time
        )
        self.phase = FLIGHT

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Hip torque [N m] and leg force [N] in the actuated order, shape (nu,)."""
        stance = bool(contacts.gap[self.contact] <= self.settings.contact_gap)
        return self.torque(q, v, stance)

    def stance_phase(self, q: Vector, v: Vector) -> int:
        """The stance sub-phase at (q, v): COMPRESSION, THRUST or EXTENDED."""
        l, l_dot = q[self._q[4]], v[self._v[4]]
        if l_dot <= 0.0:
            return COMPRESSION
        return THRUST if l < self.settings.leg_length else EXTENDED

    def torque(self, q: Vector, v: Vector, stance: bool) -> Vector:
        """The law at (q (nq,), v (nv,)) in flight or stance: shape (nu,)."""
        s = self.settings
        x_dot = v[self._v[0]]
        theta, theta_dot = q[self._q[2]], v[self._v[2]]
        phi, phi_dot = q[self._q[3]], v[self._v[3]]
        l, l_dot = q[self._q[4]], v[self._v[4]]
        spring = s.leg_stiffness * (s.leg_length - l)  # [N]
        if stance:
            self.phase = self.stance_phase(q, v)
            hip = s.attitude_kp * theta + s.attitude_kd * theta_dot
            if self.phase == COMPRESSION:
                leg = spring
            elif self.phase == THRUST:
                leg = spring + self.thrust(q, v)
            else:
                leg = spring - self.damping * l_dot
        else:
            self.phase = FLIGHT
            placement = x_dot * self.stance_time / 2.0 + s.placement_gain * (x_dot - s.speed)
            sin_psi = float(np.clip(-placement / s.leg_length, -_MAX_SIN_PSI, _MAX_SIN_PSI))
            phi_target = math.asin(sin_psi) - theta
            hip = s.hip_kp * (phi_target - phi) - s.hip_kd * phi_dot
            leg = spring - self.damping * l_dot
        u = np.zeros(self._nu)
        u[self._u[0]] = hip
        u[self._u[1]] = leg
        return u

    def thrust(self, q: Vector, v: Vector) -> float:
        """The thrust F in [N] at a stance state (q, v), before the leg's spring."""
        s, m, g = self.settings, self.mass, self.gravity
        l = q[self._q[4]]
        cos_psi = math.cos(q[self._q[2]] + q[self._q[3]])
        z_dot = v[self._v[1]]
        energy = m * g * l * cos_psi + 0.5 * m * z_dot**2
        energy += 0.5 * s.leg_stiffness * (s.leg_length - l) ** 2  # [J]
        z_off = s.leg_length * cos_psi  # hip height at full extension [m]
        rho = (m + self.foot_mass) / m
        target = m * g * z_off + m * g * (s.apex - z_off) * rho**2  # [J]
        return float(np.clip((target - energy) / (s.leg_length - l), -s.max_thrust, s.max_thrust))

    def prepare_log(self, log: Log) -> None:
        """Declare ``phase`` (0 flight, 1 compression, 2 thrust, 3 extended)."""
        log.add_field("phase", ())

    def record(self, log: Log) -> None:
        """Write the phase of the last call."""
        log.record_extra("phase", self.phase)
