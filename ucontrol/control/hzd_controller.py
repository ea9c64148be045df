r"""Virtual constraints for a planar biped: hybrid-zero-dynamics output tracking.

The robot (e.g. ``robots/rabbit.urdf``) walks in the x-z plane on a passive planar base, with
two legs of an actuated hip and knee each, ending in point feet. One foot is the **stance
foot**; which one is read from the contact state the controller gets (the gap and normal
velocity of each foot), never from the plant's impulses.

- **Phase variable**: the stance leg's angle from the vertical,
  :math:`\theta(q) = \operatorname{atan2}(x_h - x_f, z_h - z_f)` [rad] (hip h, stance foot
  f), increasing while the robot walks forward in +x; normalised to
  :math:`s = (\theta - \theta^+)/(\theta^- - \theta^+)`, 0 just after a heel strike and 1 at
  the next one.
- **Outputs**: :math:`y = q_a - h_d(s)`, :math:`q_a` = (stance hip, stance knee, swing hip,
  swing knee) in the URDF's relative angles, :math:`h_d` Bézier polynomials of degree M,
  :math:`h_d(s) = \sum_k \alpha_k \binom{M}{k} s^k (1 - s)^{M - k}`.
- **Torque**: input-output linearisation of the robot held at its stance foot. The dynamics
  :math:`M \dot v + h = B u + J_{st}^T \lambda`, the pinned foot
  :math:`J_{st} \dot v + \dot J_{st} v = 0` and the output law
  :math:`\ddot y = -K_p y - K_d \dot y` are solved together, one square linear system in
  :math:`(\dot v, u, \lambda)`; u is then clipped to the torque limit, if any.
- **Leg swap**: when the swing foot has touched down (gap at most ``contact_gap`` and normal
  velocity within :data:`AT_REST` of 0: stopped by the plastic impact) in the second half of
  the step (:math:`s \ge 1/2`: a swing foot grazing the ground early in the step does not
  swap the legs), it becomes the stance foot; :math:`q_a` is relabelled with it. Swapping
  on the approach instead (within ``contact_gap`` and moving down) put the new stance foot's
  law on the pre-impact velocity for one control period, in which the foot still moves at
  0.7 m/s: on ``rabbit_walk`` the torques jumped to the 150 N m limit at every step.

On the zero dynamics (:math:`y = \dot y = 0`) the gait is periodic when the impact maps the
end of a step onto the start of the next (docs/legged.md, "Walking").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_non_negative, as_positive
from ucontrol.control.controller import ContactState, Vector
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    NonFiniteValueError,
    ShapeError,
)

if TYPE_CHECKING:
    from ucontrol.log import Log
    from ucontrol.model.robot_model import RobotModel

#: Largest absolute normal velocity [m/s] of a swing foot that has touched down. After a plastic
#: Moreau–Jean impact the foot's normal velocity, evaluated at the new configuration, is
#: O(h) (0.9e-3 m/s on ``rabbit_walk`` at h = 1 ms); before it, the foot approaches at about
#: 0.7 m/s.
AT_REST = 1e-2
#: Number of outputs: stance hip, stance knee, swing hip, swing knee.
OUTPUTS = 4
_LWA = pin.LOCAL_WORLD_ALIGNED
_XZ = (0, 2)


def bezier(alpha: NDArray[np.float64], s: float) -> tuple[Vector, Vector, Vector]:
    r"""Bézier polynomials, their first and second derivatives in s at ``s``.

    :math:`h(s) = \sum_{k=0}^{M} \alpha_k b_k^M(s)`, :math:`b_k^M = \binom{M}{k} s^k (1-s)^{M-k}`;
    :math:`h' = M \sum_{k<M} (\alpha_{k+1} - \alpha_k) b_k^{M-1}` and
    :math:`h'' = M (M-1) \sum_{k<M-1} (\alpha_{k+2} - 2\alpha_{k+1} + \alpha_k) b_k^{M-2}`.

    Args:
        alpha: Coefficients, shape (n, M + 1) with M >= 2.
        s: The argument (any real; the gait uses [0, 1]).

    Returns:
        h(s), h'(s), h''(s), each of shape (n,).
    """
    degree = alpha.shape[1] - 1

    def basis(order: int) -> Vector:
        k = np.arange(order + 1)
        binomial = np.array([math.comb(order, int(i)) for i in k], dtype=float)
        return binomial * s**k * (1.0 - s) ** (order - k)

    value = alpha @ basis(degree)
    first = degree * np.diff(alpha, axis=1) @ basis(degree - 1)
    second = degree * (degree - 1) * np.diff(alpha, 2, axis=1) @ basis(degree - 2)
    return value, first, second


@dataclass(frozen=True, kw_only=True)
class HZDSettings:
    r"""The virtual constraints and the gains of :class:`HZDController`.

    Attributes:
        bezier: Coefficients :math:`\alpha` in [rad], shape (4, M + 1), M >= 2: rows stance hip,
            stance knee, swing hip, swing knee.
        theta_plus: :math:`\theta^+`, the phase variable at the start of a step in [rad].
        theta_minus: :math:`\theta^-`, at its end in [rad]; larger than ``theta_plus``.
        kp: Output stiffness :math:`K_p` in [1/s²].
        kd: Output damping :math:`K_d` in [1/s].
        contact_gap: Gap in [m] at or below which the swing foot counts as touching down.
        torque_limit: Largest absolute torque in [N m], or None for none.
    """

    bezier: NDArray[np.float64] = field(repr=False)
    theta_plus: float
    theta_minus: float
    kp: float
    kd: float
    contact_gap: float = 1e-3
    torque_limit: float | None = None

    def __post_init__(self) -> None:
        try:
            alpha = np.array(self.bezier, dtype=float)
        except (TypeError, ValueError) as error:
            raise InvalidParameterError(
                "bezier", self.bezier, "4 rows of M + 1 numbers [rad]"
            ) from error
        if alpha.ndim != 2 or alpha.shape[0] != OUTPUTS or alpha.shape[1] < 3:
            raise ShapeError("bezier", (OUTPUTS, -1), alpha.shape)
        bad = np.flatnonzero(~np.isfinite(alpha))
        if bad.size:
            raise NonFiniteValueError("bezier", self.bezier, bad.tolist())
        object.__setattr__(self, "bezier", alpha)
        for key in ("theta_plus", "theta_minus"):
            object.__setattr__(self, key, as_float(key, getattr(self, key)))
        if not self.theta_minus > self.theta_plus:
            raise InvalidParameterError(
                "theta_minus", self.theta_minus, f"larger than theta_plus = {self.theta_plus}"
            )
        object.__setattr__(self, "kp", as_positive("kp", self.kp))
        object.__setattr__(self, "kd", as_positive("kd", self.kd))
        object.__setattr__(self, "contact_gap", as_non_negative("contact_gap", self.contact_gap))
        if self.torque_limit is not None:
            object.__setattr__(self, "torque_limit", as_positive("torque_limit", self.torque_limit))

    @property
    def degree(self) -> int:
        """M, the degree of the Bézier polynomials."""
        return int(self.bezier.shape[1] - 1)

    def phase(self, theta: float) -> float:
        """The phase s of a phase variable θ [rad]."""
        return (theta - self.theta_plus) / (self.theta_minus - self.theta_plus)


@dataclass(frozen=True)
class Leg:
    """Where one leg sits in the model.

    Attributes:
        hip: Name of the hip joint.
        knee: Name of the knee joint.
        foot: Name of the foot frame.
        contact: Index of the foot's constraint in the contact state.
    """

    hip: str
    knee: str
    foot: str
    contact: int


class HZDController:
    """Hybrid-zero-dynamics output tracking of a planar biped (see the module's docstring).

    Args:
        robot: The biped; its actuated coordinates are exactly the two hips and two knees.
        legs: The two legs (hip, knee, foot, contact index).
        stance: The foot frame of the initial stance leg.
        settings: Virtual constraints and gains.

    Raises:
        InvalidParameterError: Not two legs, a joint that is not a one-coordinate actuated
            joint, other actuated joints, or ``stance`` that is no leg's foot.
        JointNotFoundError: A joint the robot lacks.
        FrameNotFoundError: A foot frame the robot lacks.
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        legs: tuple[Leg, Leg] | list[Leg],
        stance: str,
        settings: HZDSettings,
    ) -> None:
        if len(legs) != 2:
            raise InvalidParameterError("legs", list(legs), "two legs (hip, knee, foot)")
        model = robot.model
        actuated = [int(i) for i in robot.actuated]
        self._q: list[list[int]] = []
        self._v: list[list[int]] = []
        for leg in legs:
            q_index, v_index = [], []
            for name in (leg.hip, leg.knee):
                joint = model.joints[robot.joint_id(name)]
                if joint.nq != 1 or joint.nv != 1 or int(joint.idx_v) not in actuated:
                    kind = "passive" if joint.nq == 1 else f"nq = {joint.nq}"
                    raise InvalidParameterError(
                        f"joint {name!r}", kind, "an actuated one-coordinate joint"
                    )
                q_index.append(int(joint.idx_q))
                v_index.append(int(joint.idx_v))
            if leg.foot not in robot.frame_names:
                raise FrameNotFoundError(leg.foot, robot.frame_names)
            self._q.append(q_index)
            self._v.append(v_index)
        if robot.nu != OUTPUTS:
            raise InvalidParameterError(
                "robot",
                f"{robot.nu} actuated coordinates",
                "the two hips and two knees actuated, every other joint passive",
            )
        feet = [leg.foot for leg in legs]
        if stance not in feet:
            raise InvalidParameterError("stance", stance, f"one of the feet {feet}")
        self.robot = robot
        self.legs = tuple(legs)
        self.settings = settings
        #: Index (0 or 1) of the stance leg.
        self.stance = feet.index(stance)
        self._hip_frames = [robot.frame_id(leg.hip) for leg in legs]
        self._foot_frames = [robot.frame_id(leg.foot) for leg in legs]
        self._B = np.zeros((robot.nv, robot.nu))
        self._B[robot.actuated, np.arange(robot.nu)] = 1.0
        self._data = pin.Data(model)
        self._drift_data = pin.Data(model)
        self._s = 0.0
        self._y = np.zeros(OUTPUTS)

    def leg_of(self, contact: int) -> int:
        """The leg (0 or 1) whose foot is the constraint ``contact``.

        Raises:
            InvalidParameterError: No leg's foot is that constraint.
        """
        for i, leg in enumerate(self.legs):
            if leg.contact == contact:
                return i
        raise InvalidParameterError(
            "contact", contact, f"one of the feet's constraints {[g.contact for g in self.legs]}"
        )

    def output_indices(self, stance: int) -> tuple[list[int], list[int]]:
        """Configuration and velocity indices of q_a (4 each) with leg ``stance`` (0 or 1) down."""
        swing = 1 - stance
        return self._q[stance] + self._q[swing], self._v[stance] + self._v[swing]

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Hip and knee torques [N m] in the actuated order, shape (4,)."""
        swing = self.legs[1 - self.stance].contact
        theta = self.phase_variable(q, self.stance)[0]
        if (
            self.settings.phase(theta) >= 0.5
            and contacts.gap[swing] <= self.settings.contact_gap
            and abs(contacts.normal_velocity[swing]) <= AT_REST
        ):
            self.stance = 1 - self.stance
        return self.torque(q, v, self.legs[self.stance].contact)

    def phase_variable(self, q: Vector, stance: int, v: Vector | None = None) -> tuple[float, ...]:
        r"""θ [rad] with leg ``stance`` on the ground; with v also θ̇ [rad/s].

        Returns:
            (θ,) or (θ, θ̇).
        """
        model, data = self.robot.model, self._data
        if v is None:
            pin.framesForwardKinematics(model, data, q)
        else:
            pin.forwardKinematics(model, data, q, v)
            pin.updateFramePlacements(model, data)
        a, b = self._hip_minus_foot(data, stance)
        theta = math.atan2(a, b)
        if v is None:
            return (theta,)
        da, db = self._velocity_difference(data, stance)
        return theta, (b * da - a * db) / (a * a + b * b)

    def _hip_minus_foot(self, data: pin.Data, stance: int) -> tuple[float, float]:
        step = (
            data.oMf[self._hip_frames[stance]].translation
            - data.oMf[self._foot_frames[stance]].translation
        )
        return float(step[0]), float(step[2])

    def _velocity_difference(self, data: pin.Data, stance: int) -> tuple[float, float]:
        model = self.robot.model
        hip = pin.getFrameVelocity(model, data, self._hip_frames[stance], _LWA).linear
        foot = pin.getFrameVelocity(model, data, self._foot_frames[stance], _LWA).linear
        return float(hip[0] - foot[0]), float(hip[2] - foot[2])

    def outputs(self, q: Vector, v: Vector, contact: int) -> tuple[Vector, Vector]:
        """Outputs y [rad] and ẏ [rad/s], shape (4,) each, foot ``contact`` on the ground."""
        stance = self.leg_of(contact)
        s = self.settings
        theta, theta_dot = self.phase_variable(q, stance, v)
        h, dh, _ = bezier(s.bezier, s.phase(theta))
        scale = 1.0 / (s.theta_minus - s.theta_plus)  # ds/dθ [1/rad]
        q_index, v_index = self.output_indices(stance)
        return q[q_index] - h, v[v_index] - dh * scale * theta_dot

    def torque(self, q: Vector, v: Vector, contact: int) -> Vector:
        """The law at (q (nq,), v (nv,)) with the foot ``contact`` on the ground: shape (4,)."""
        return self.solve(q, v, contact)[1]

    def solve(self, q: Vector, v: Vector, contact: int) -> tuple[Vector, Vector, Vector]:
        r"""The linearising law's solution: :math:`\dot v` (nv,), u (4,), λ (2,) [N].

        λ holds the stance foot's x and z force components in the world frame. u is clipped to
        the torque limit after the solve (then :math:`\dot v` is the unclipped one's).
        """
        stance = self.leg_of(contact)
        settings = self.settings
        model, data, drift_data = self.robot.model, self._data, self._drift_data
        nv = model.nv
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        M = np.triu(data.M) + np.triu(data.M, 1).T
        pin.forwardKinematics(model, drift_data, q, v, np.zeros(nv))
        pin.updateFramePlacements(model, drift_data)
        hip, foot = self._hip_frames[stance], self._foot_frames[stance]
        J_foot = pin.getFrameJacobian(model, data, foot, _LWA)[:3][list(_XZ)]
        J_hip = pin.getFrameJacobian(model, data, hip, _LWA)[:3][list(_XZ)]
        drift_foot = pin.getFrameClassicalAcceleration(model, drift_data, foot, _LWA).linear[
            list(_XZ)
        ]
        drift_hip = pin.getFrameClassicalAcceleration(model, drift_data, hip, _LWA).linear[
            list(_XZ)
        ]
        # phase variable θ = atan2(a, b), (a, b) = hip - foot in (x, z)
        a, b = self._hip_minus_foot(data, stance)
        da, db = (J_hip - J_foot) @ v
        r2 = a * a + b * b  # [m²]
        theta = math.atan2(a, b)
        theta_dot = (b * da - a * db) / r2
        J_theta = (b * (J_hip[0] - J_foot[0]) - a * (J_hip[1] - J_foot[1])) / r2
        drift_relative = drift_hip - drift_foot
        theta_drift = (b * drift_relative[0] - a * drift_relative[1]) / r2
        theta_drift -= 2.0 * theta_dot * (a * da + b * db) / r2  # θ̈ = J_θ v̇ + this [rad/s²]
        scale = 1.0 / (settings.theta_minus - settings.theta_plus)  # [1/rad]
        h, dh, ddh = bezier(settings.bezier, (theta - settings.theta_plus) * scale)
        q_index, v_index = self.output_indices(stance)
        y = q[q_index] - h
        y_dot = v[v_index] - dh * scale * theta_dot
        # ÿ = H v̇ + drift
        H = -np.outer(dh * scale, J_theta)
        H[np.arange(OUTPUTS), v_index] += 1.0
        drift = -dh * scale * theta_drift - ddh * (scale * theta_dot) ** 2
        n_u = OUTPUTS
        system = np.zeros((nv + 2 + OUTPUTS, nv + n_u + 2))
        system[:nv, :nv] = M
        system[:nv, nv : nv + n_u] = -self._B
        system[:nv, nv + n_u :] = -J_foot.T
        system[nv : nv + 2, :nv] = J_foot
        system[nv + 2 :, :nv] = H
        rhs = np.concatenate(
            (-data.nle, -drift_foot, -drift - settings.kp * y - settings.kd * y_dot)
        )
        solution = np.linalg.solve(system, rhs)
        u = solution[nv : nv + n_u]
        if settings.torque_limit is not None:
            u = np.clip(u, -settings.torque_limit, settings.torque_limit)
        self._s = (theta - settings.theta_plus) * scale
        self._y = y
        return solution[:nv], u, solution[nv + n_u :]

    def prepare_log(self, log: Log) -> None:
        """Declare ``stance`` (leg index), ``phase_s`` (s) and ``outputs`` (y [rad], (4,))."""
        log.add_field("stance", ())
        log.add_field("phase_s", ())
        log.add_field("outputs", (OUTPUTS,))

    def record(self, log: Log) -> None:
        """Write the stance leg, s and y of the last call."""
        log.record_extra("stance", self.stance)
        log.record_extra("phase_s", self._s)
        log.record_extra("outputs", self._y)


def legs_from_names(names: Any, contacts: dict[str, int]) -> tuple[Leg, Leg]:
    """Two :class:`Leg` from ``[[hip, knee, foot], [hip, knee, foot]]``.

    Args:
        names: Two lists of three names.
        contacts: Constraint index of each foot frame that is a contact.

    Raises:
        InvalidParameterError: ``names`` is not two triples of names, or a foot is no
            contact's frame.
    """
    expected = "two lists [hip, knee, foot] of names"
    if (
        not isinstance(names, list | tuple)
        or len(names) != 2
        or any(not isinstance(leg, list | tuple) or len(leg) != 3 for leg in names)
        or any(not isinstance(name, str) for leg in names for name in leg)
    ):
        raise InvalidParameterError("legs", names, expected)
    legs = []
    for hip, knee, foot in names:
        if foot not in contacts:
            raise InvalidParameterError(
                "legs", foot, f"a foot frame with a contact, one of {sorted(contacts)}"
            )
        legs.append(Leg(hip=hip, knee=knee, foot=foot, contact=contacts[foot]))
    return legs[0], legs[1]
