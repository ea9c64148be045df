r"""Juggling a ball with a 1-DoF paddle: impact-to-impact replanning of the paddle's motion.

The ball (unactuated) flies ballistically between hits; the paddle (a prismatic joint) is
driven by a computed-force tracking law on a desired motion that is replanned at every hit
(Brogliato 2016, §8.5.2, after Zavala-Río & Brogliato's tracking approach: the paddle's
desired motion is a designed trajectory through the next impact; here the design is one cubic
per flight, a discrete-time feedback on the ball's post-impact state).

At a hit (and at the start) the controller predicts the ball's next arrival at the hit height
:math:`z_h` (contact gap 0 with the paddle there), at time :math:`t_h` with velocity
:math:`v_b^-`, and the ball's take-off speed that reaches the commanded apex :math:`H` (height
of the ball's centre), :math:`V = \sqrt{2 g (H - z_h - d)}` (d: distance of the centres at
contact). Newton's law with the ball/paddle mass ratio :math:`\mu = m_b / m_p` and momentum
conservation give the paddle velocity at the hit,

.. math::

    v_p^- = \frac{(1 + \mu) V - (\mu - e)\, v_b^-}{1 + e},

and the paddle follows the cubic from its present state to :math:`(z_h, v_p^-)` at
:math:`t_h`, then holds :math:`z_h` if the ball does not come. With an exact model the apex
error is removed in one hit (dead-beat); the closed loop's Floquet multipliers
(:mod:`ucontrol.analysis.poincare`) are near 0.

The paddle force is :math:`u = m_p(\ddot z_r + k_d (\dot z_r - \dot z) + k_p (z_r - z)) + g_p(q)`
with :math:`g_p` the paddle's gravity force; the ball's generalized force is 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import (
    as_bool,
    as_float,
    as_in_interval,
    as_positive,
)
from ucontrol.control.controller import ContactState
from ucontrol.exceptions import InvalidParameterError

if TYPE_CHECKING:
    from ucontrol.log import Log
    from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class JugglingSettings:
    """What the juggler aims at and how it tracks.

    Attributes:
        apex: Commanded apex of the ball's centre in [m].
        hit_height: Paddle height at the hits in [m].
        restitution: Ball/paddle restitution e the controller assumes, in [0, 1).
        kp: Position gain in [1/s²].
        kd: Velocity gain in [1/s].
        max_paddle_speed: Largest paddle speed at a hit in [m/s]; an apex needing more is
            out of reach.
        estimate_restitution: Replace the assumed e after every hit by the one measured
            there, ``-(v_b+ - v_p)/(v_b- - v_p)`` (ball velocity extrapolated back to the
            planned hit time): removes the apex offset a wrong e leaves.
    """

    apex: float
    hit_height: float = 0.0
    restitution: float = 0.8
    kp: float = 900.0
    kd: float = 60.0
    max_paddle_speed: float = 10.0
    estimate_restitution: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "apex", as_float("apex", self.apex))
        object.__setattr__(self, "hit_height", as_float("hit_height", self.hit_height))
        e = as_in_interval("restitution", self.restitution, 0.0, 1.0)
        if e >= 1.0:
            raise InvalidParameterError("restitution", e, "in [0, 1) (e = 1 needs no juggler)")
        object.__setattr__(self, "restitution", e)
        for key in ("kp", "kd", "max_paddle_speed"):
            object.__setattr__(self, key, as_positive(key, getattr(self, key)))
        object.__setattr__(
            self, "estimate_restitution", as_bool("estimate_restitution", self.estimate_restitution)
        )


@dataclass(frozen=True)
class Hit:
    """One planned hit.

    Attributes:
        time: Time of the plan (just after the previous hit) in [s].
        hit_time: Predicted time of the hit in [s].
        ball_velocity: Predicted ball velocity at the hit in [m/s].
        paddle_velocity: Paddle velocity planned at the hit in [m/s].
    """

    time: float
    hit_time: float
    ball_velocity: float
    paddle_velocity: float


class JugglingController:
    """Paddle juggling with one cubic per flight, replanned at every hit.

    Args:
        robot: The robot holding the paddle's and the ball's prismatic joints (vertical).
        paddle_joint: Name of the paddle's joint.
        ball_joint: Name of the ball's joint.
        contact: Index of the ball/paddle constraint in the scene's constraints.
        distance: Distance between the joint coordinates at contact, z_ball - z_paddle, in [m].
        settings: Apex, hit height, restitution and gains.
        gravity: g in [m/s²] (the magnitude of the robot's gravity).
        q_hit: Configuration near the hits, shape (nq,), where a subclass evaluates the
            paddle's effective mass for the reach check (default the neutral one).

    Raises:
        InvalidParameterError: The apex is out of the paddle's reach.
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        paddle_joint: str | None,
        ball_joint: str,
        contact: int,
        distance: float,
        settings: JugglingSettings,
        gravity: float | None = None,
        q_hit: Vector | None = None,
    ) -> None:
        self.robot = robot
        model = robot.model
        self.ball = int(model.joints[robot.joint_id(ball_joint)].idx_v)
        self.contact = int(contact)
        self.distance = float(distance)
        self.settings = settings
        self.g = float(np.linalg.norm(robot.gravity)) if gravity is None else float(gravity)
        M = robot.mass_matrix(robot.neutral())
        self.ball_mass = float(M[self.ball, self.ball])  # [kg]
        if paddle_joint is not None:
            self.paddle = int(model.joints[robot.joint_id(paddle_joint)].idx_v)
            self.paddle_mass = float(M[self.paddle, self.paddle])  # [kg]
            self.mass_ratio = self.ball_mass / self.paddle_mass
        self._update_mass_ratio(robot.neutral() if q_hit is None else q_hit)
        self.restitution = settings.restitution  # assumed, or measured at the last hit
        rise = settings.apex - settings.hit_height - self.distance  # [m]
        if rise <= 0.0:
            raise InvalidParameterError(
                "apex",
                settings.apex,
                f"> {settings.hit_height + self.distance:g} m (hit height + contact distance)",
            )
        self.takeoff_speed = math.sqrt(2.0 * self.g * rise)  # [m/s]
        needed = self._paddle_velocity(-self.takeoff_speed)
        if abs(needed) > settings.max_paddle_speed:
            raise InvalidParameterError(
                "apex",
                settings.apex,
                f"reachable with a paddle speed <= {settings.max_paddle_speed:g} m/s "
                f"(needs {needed:.3g} m/s)",
            )
        self.hits: list[Hit] = []
        self._plan: tuple[float, float, Vector] | None = None  # t0, T, cubic coefficients
        self._last: dict[str, float] = {"z_ref": math.nan, "hit_time": math.nan}

    def _paddle_velocity(self, ball_velocity: float) -> float:
        """Paddle velocity at the hit sending the ball up at the take-off speed, in [m/s]."""
        e, mu = self.restitution, self.mass_ratio
        return ((1.0 + mu) * self.takeoff_speed - (mu - e) * ball_velocity) / (1.0 + e)

    def _measure_restitution(self, t: float, v: Vector) -> None:
        """Measure the restitution of the last hit from its planned approach and the take-off."""
        hit = self.hits[-1]
        ball_out = float(v[self.ball]) + self.g * (t - hit.hit_time)  # back to the hit [m/s]
        approach = hit.ball_velocity - hit.paddle_velocity  # [m/s], < 0
        # paddle after the hit by momentum conservation (its velocity now is already changed
        # by its own force since the hit)
        paddle_out = hit.paddle_velocity + self.mass_ratio * (hit.ball_velocity - ball_out)
        measured = -(ball_out - paddle_out) / approach
        if 0.0 <= measured < 1.0:
            self.restitution = measured

    def _paddle_state(self, q: Vector, v: Vector) -> tuple[float, float]:
        """Paddle height [m] and vertical velocity [m/s]."""
        return float(q[self.paddle]), float(v[self.paddle])

    def _update_mass_ratio(self, q: Vector) -> None:
        """Ball mass over the paddle's effective mass at q (constant for a prismatic paddle)."""

    def _torque(self, q: Vector, v: Vector, z_r: float, dz_r: float, ddz_r: float) -> Vector:
        """Generalized forces tracking the reference, shape (nv,)."""
        s = self.settings
        acceleration = ddz_r + s.kd * (dz_r - v[self.paddle]) + s.kp * (z_r - q[self.paddle])
        tau = np.zeros(self.robot.nv)
        tau[self.paddle] = (
            self.paddle_mass * acceleration + self.robot.gravity_torque(q)[self.paddle]
        )
        return tau

    def _replan(self, t: float, q: Vector, v: Vector) -> None:
        if self.settings.estimate_restitution and self.hits:
            self._measure_restitution(t, v)
        self._update_mass_ratio(q)
        z_b, v_b = float(q[self.ball]), float(v[self.ball])
        target = self.settings.hit_height + self.distance  # ball height at the hit [m]
        # z_b + v_b s - g s²/2 = target, the later root
        disc = v_b * v_b + 2.0 * self.g * (z_b - target)
        if disc < 0.0:  # the ball will not come down to the hit height: hold
            self._plan = None
            return
        s = (v_b + math.sqrt(disc)) / self.g  # [s]
        ball_in = v_b - self.g * s
        paddle_in = self._paddle_velocity(ball_in)
        z0, v0 = self._paddle_state(q, v)
        z1 = self.settings.hit_height
        T = max(s, 1e-6)
        a2 = (3.0 * (z1 - z0) - (2.0 * v0 + paddle_in) * T) / T**2
        a3 = (2.0 * (z0 - z1) + (v0 + paddle_in) * T) / T**3
        self._plan = (t, T, np.array([z0, v0, a2, a3]))
        self.hits.append(Hit(t, t + s, ball_in, paddle_in))

    def reference(self, t: float) -> tuple[float, float, float]:
        """Desired paddle (position [m], velocity [m/s], acceleration [m/s²]) at t."""
        if self._plan is None:
            return self.settings.hit_height, 0.0, 0.0
        t0, T, c = self._plan
        s = t - t0
        if s > T:
            return self.settings.hit_height, 0.0, 0.0
        return (
            c[0] + c[1] * s + c[2] * s**2 + c[3] * s**3,
            c[1] + 2.0 * c[2] * s + 3.0 * c[3] * s**2,
            2.0 * c[2] + 6.0 * c[3] * s,
        )

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Paddle force (ball force 0), shape (nu,)."""
        hit = contacts.impulse[self.contact] > 0.0
        if (self._plan is None and not self.hits) or hit:
            self._replan(t, q, v)
        z_r, dz_r, ddz_r = self.reference(t)
        tau = self._torque(q, v, z_r, dz_r, ddz_r)
        self._last = {"z_ref": z_r, "hit_time": self.hits[-1].hit_time if self.hits else math.nan}
        return tau[self.robot.actuated]

    def prepare_log(self, log: Log) -> None:
        """Declare ``paddle_reference`` [m] and ``planned_hit_time`` [s]."""
        log.add_field("paddle_reference", ())
        log.add_field("planned_hit_time", ())

    def record(self, log: Log) -> None:
        """Write the current reference and planned hit time."""
        log.record_extra("paddle_reference", self._last["z_ref"])
        log.record_extra("planned_hit_time", self._last["hit_time"])


class ArmJugglingController(JugglingController):
    r"""Juggling with the tip of an arm: the same plan, tracked in task space.

    The tip (a frame) follows the cubic along the vertical axis and holds the ball's
    horizontal coordinate; the joint torques are the computed torque
    :math:`\tau = M J^{-1}(\ddot p_\text{cmd} - \dot J \dot q) + h` of the arm's joints (J the
    tip's in-plane position rows, square). The paddle mass of the plan is the arm's effective mass
    along the vertical at the present configuration, :math:`1/(J_v M^{-1} J_v^T)`, re-evaluated
    at every hit.

    Args:
        robot: The arm plus the ball's prismatic joint along the vertical axis.
        frame: The tip frame (the ball's contact partner).
        arm_joints: Names of the arm's joints (as many as the plane's two axes).
        ball_joint: Name of the ball's joint.
        contact: Index of the ball/tip constraint.
        distance: Ball centre above the tip at contact, in [m].
        settings: Apex and hit height (of the tip along the vertical), restitution, gains.
        hit_x: Horizontal coordinate of the hits (the ball's line), in [m].
        axes: Indices (horizontal, vertical) of the plane's axes in world coordinates.
        q_hit: A configuration near the hits for the reach check, shape (nq,).
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        frame: str,
        arm_joints: tuple[str, ...],
        ball_joint: str,
        contact: int,
        distance: float,
        settings: JugglingSettings,
        hit_x: float,
        axes: tuple[int, int] = (0, 1),
        q_hit: Vector | None = None,
    ) -> None:
        import pinocchio as pin  # the arm's kinematics; pinocchio is the model layer's backend

        self._pin = pin
        self._data = pin.Data(robot.model)
        self._frame = robot.frame_id(frame)
        self.arm = np.array(
            [int(robot.model.joints[robot.joint_id(name)].idx_v) for name in arm_joints]
        )
        if self.arm.size != 2:
            raise InvalidParameterError("arm_joints", arm_joints, "two joints of a planar arm")
        self.axes = axes
        self.hit_x = float(hit_x)
        self.robot = robot
        super().__init__(
            robot,
            paddle_joint=None,
            ball_joint=ball_joint,
            contact=contact,
            distance=distance,
            settings=settings,
            q_hit=q_hit,
        )

    def _kinematics(self, q: Vector, v: Vector) -> tuple[Vector, Vector, Vector, Vector]:
        """Tip position (3,), velocity (3,), J̇ q̇ (3,) and Jacobian rows (3, nv), world."""
        pin, model, data = self._pin, self.robot.model, self._data
        pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        J = pin.getFrameJacobian(model, data, self._frame, frame)[:3]
        bias = pin.getFrameClassicalAcceleration(model, data, self._frame, frame).linear
        return data.oMf[self._frame].translation.copy(), J @ v, np.asarray(bias), J

    def _paddle_state(self, q: Vector, v: Vector) -> tuple[float, float]:
        p, dp, _, _ = self._kinematics(q, v)
        return float(p[self.axes[1]]), float(dp[self.axes[1]])

    def _update_mass_ratio(self, q: Vector) -> None:
        _, _, _, J = self._kinematics(q, np.zeros(self.robot.nv))
        M = self.robot.mass_matrix(q)[np.ix_(self.arm, self.arm)]
        Jv = J[self.axes[1], self.arm]
        self.paddle_mass = 1.0 / float(Jv @ np.linalg.solve(M, Jv))  # effective mass [kg]
        self.mass_ratio = self.ball_mass / self.paddle_mass

    def _torque(self, q: Vector, v: Vector, z_r: float, dz_r: float, ddz_r: float) -> Vector:
        s, (h_axis, v_axis) = self.settings, self.axes
        p, dp, bias, J = self._kinematics(q, v)
        command = np.array(
            [
                s.kp * (self.hit_x - p[h_axis]) - s.kd * dp[h_axis],
                ddz_r + s.kd * (dz_r - dp[v_axis]) + s.kp * (z_r - p[v_axis]),
            ]
        )  # [m/s²]
        plane = np.array([h_axis, v_axis])
        rows = J[np.ix_(plane, self.arm)]
        ddq = np.linalg.solve(rows, command - bias[plane])
        M = self.robot.mass_matrix(q)
        h = self.robot.nonlinear_effects(q, v)
        tau = np.zeros(self.robot.nv)
        tau[self.arm] = M[np.ix_(self.arm, self.arm)] @ ddq + h[self.arm]
        return tau
