r"""A periodic walking gait of RABBIT for the HZD controller, from its hybrid zero dynamics.

The gait is the Bézier coefficients :math:`\alpha` (4 rows, degree M) and the phase range
:math:`[\theta^+, \theta^-]` of ``[controller] type = "hzd"`` (ucontrol.control.HZDController).
On the zero dynamics (y = 0) the robot pinned at its stance foot has one degree of freedom,
θ; its angular momentum L about the stance foot obeys :math:`\dot L = m g (x_c - x_f)`
whatever the torques, and :math:`L = \kappa(\theta)\dot\theta`, so
:math:`\zeta = L^2/2` obeys :math:`d\zeta/d\theta = \kappa(\theta)\, m g\,(x_c - x_f)`:

.. math:: \zeta(\theta) = \zeta^+ - V(\theta), \qquad
          V(\theta) = -\int_{\theta^+}^{\theta} \kappa\, m g\, (x_c - x_f)\, d\vartheta .

The heel strike (plastic, sticking, :meth:`StanceFlow.heel_strike`) maps
:math:`L^- \mapsto L^+ = \delta L^-`; the step map of the zero dynamics is
:math:`\zeta^-_{k+1} = \delta^2 \zeta^-_k - V(\theta^-)`, with the fixed point
:math:`\zeta^{-*} = -V(\theta^-)/(1 - \delta^2)` and the multiplier :math:`\delta^2`
(Westervelt, Grizzle & Koditschek 2003). The constraints of the design make the zero dynamics
invariant under the impact:

- positions: :math:`\alpha_0 = R \alpha_M` (R swaps the legs' rows), the swing foot on the
  ground at :math:`\theta^-`, and :math:`\theta^+` the new stance leg's angle there;
- velocities: :math:`\alpha_1 = \alpha_0 + (\theta^- - \theta^+)/M \cdot \dot q_a^+/\dot\theta^+`
  from the post-impact velocity of a state on the zero dynamics.

Free: :math:`\alpha_2 \dots \alpha_M` and :math:`\theta^-`. SLSQP minimises the mean squared
torque per step subject to: a fixed point with :math:`\delta^2 < 1`, :math:`\zeta > 0` along the
step (the robot passes mid-stance), the swing foot's clearance, a positive normal force and
the force within a friction cone of 0.6 (the scene has μ = 0.8), a sticking plastic strike
that lifts the old foot, a mean speed of ``--speed``, knees bent (:math:`\alpha \ge 0`).

Run: ``python experiments/biped_gait_design.py`` (about a minute); prints the ``[controller]``
keys to paste into ``robots/rabbit_walk.toml``, with the predicted speed, period and δ².
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize

from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.control.hzd_controller import HZDController, HZDSettings, Leg, bezier
from ucontrol.model.robot_model import RobotModel
from ucontrol.scene import load_scene

#: The degree of the Bézier polynomials.
DEGREE = 5
#: Points of the grid in θ.
GRID = 41
#: Friction share the design's forces may use (the scene's μ is 0.8).
FRICTION = 0.6
#: Swing foot height at mid-step at least [m] (a sine bump in s).
CLEARANCE = 0.04
#: (q index, v index) of hip, knee of the left and right legs in robots/rabbit.urdf.
LEFT, RIGHT = (3, 4), (5, 6)
FEET = ("foot_left", "foot_right")


def momentum(robot: RobotModel, q: np.ndarray, v: np.ndarray, foot: str) -> float:
    """Angular momentum of the robot about a foot frame, about the y axis [kg m²/s]."""
    model = robot.model
    data = pin.Data(model)
    pin.computeCentroidalMomentum(model, data, q, v)
    com = pin.centerOfMass(model, data, q, v)
    r = com - robot.frame_position(q, foot)
    p = pin.computeTotalMass(model) * data.vcom[0]  # linear momentum [kg m/s]
    return float(data.hg.angular[1] + r[2] * p[0] - r[0] * p[2])


@dataclass
class Step:
    """The zero dynamics of one candidate gait, left foot in stance."""

    alpha: np.ndarray
    theta_plus: float
    theta_minus: float
    theta: np.ndarray
    q: np.ndarray  # (GRID, 7) on the zero dynamics
    sigma: np.ndarray  # (GRID, 7) dq/dθ
    kappa: np.ndarray  # (GRID,) L per unit θ̇ [kg m²]
    V: np.ndarray  # (GRID,) [J kg m²]
    delta: float
    impulse: np.ndarray
    old_foot_speed: float  # old stance foot's normal velocity after the strike per θ̇⁻
    foot_height: np.ndarray  # swing foot height (GRID,)
    step_length: float


class Design:
    """Zero dynamics of candidate gaits on RABBIT."""

    def __init__(self) -> None:
        self.scene = load_scene("rabbit_walk")  # its robot and feet
        self.robot = self.scene.robot
        self.flow = StanceFlow(self.scene.constraints)
        self.model = self.robot.model
        self.data = pin.Data(self.model)
        pin.computeSubtreeMasses(self.model, self.data)
        self.mass = float(self.data.mass[0])
        self.g = 9.81
        self.foot = [self.robot.frame_id("foot_left"), self.robot.frame_id("foot_right")]
        self.hip = [self.robot.frame_id("hip_left"), self.robot.frame_id("hip_right")]

    def configuration(self, alpha: np.ndarray, tp: float, tm: float, theta: float) -> np.ndarray:
        """The configuration on the zero dynamics at θ [rad], left foot at the origin, (7,)."""
        h = bezier(alpha, (theta - tp) / (tm - tp))[0]
        q = np.zeros(7)
        q[[LEFT[0], LEFT[1], RIGHT[0], RIGHT[1]]] = h
        pin.framesForwardKinematics(self.model, self.data, q)
        step = self.data.oMf[self.hip[0]].translation - self.data.oMf[self.foot[0]].translation
        q[2] = theta - math.atan2(step[0], step[2])  # pitch rotates the body about the hip
        pin.framesForwardKinematics(self.model, self.data, q)
        foot = self.data.oMf[self.foot[0]].translation
        q[0], q[1] = -foot[0], -foot[2]
        return q

    def momentum(self, q: np.ndarray, v: np.ndarray, foot: int) -> float:
        """Angular momentum about foot 0 (left) or 1 (right), y component [kg m²/s]."""
        return momentum(self.robot, q, v, FEET[foot])

    def step(self, alpha: np.ndarray, tp: float, tm: float) -> Step:
        """The zero dynamics of the gait (α, θ⁺, θ⁻) on a grid of θ, and its heel strike."""
        theta = np.linspace(tp, tm, GRID)
        eps = 1e-6
        qs, sigmas, kappas, torque_arm, heights = [], [], [], [], []
        for th in theta:
            q = self.configuration(alpha, tp, tm, th)
            sigma = (
                self.configuration(alpha, tp, tm, th + eps)
                - self.configuration(alpha, tp, tm, th - eps)
            ) / (2 * eps)
            kappa = self.momentum(q, sigma, 0)
            com = pin.centerOfMass(self.model, self.data, q)
            pin.framesForwardKinematics(self.model, self.data, q)
            qs.append(q)
            sigmas.append(sigma)
            kappas.append(kappa)
            torque_arm.append(com[0])  # stance foot at x = 0
            heights.append(self.data.oMf[self.foot[1]].translation[2])
        kappa_arr = np.array(kappas)
        rate = kappa_arr * self.mass * self.g * np.array(torque_arm)  # dζ/dθ
        V = -np.concatenate(([0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(theta))))
        q_minus, v_minus = qs[-1], sigmas[-1]
        v_plus, impulse = self.flow.heel_strike(q_minus, v_minus, 1)
        delta = self.momentum(q_minus, v_plus, 1) / kappa_arr[-1]
        J = self.scene.constraints.jacobian(self._data_at(q_minus, v_plus), [0])
        pin.framesForwardKinematics(self.model, self.data, q_minus)
        length = float(self.data.oMf[self.foot[1]].translation[0])
        return Step(
            alpha, tp, tm, theta, np.array(qs), np.array(sigmas), kappa_arr, V, delta,
            impulse, float((J @ v_plus)[0]), np.array(heights), length,
        )  # fmt: skip

    def _data_at(self, q: np.ndarray, v: np.ndarray) -> pin.Data:
        pin.computeAllTerms(self.model, self.data, q, v)
        pin.updateFramePlacements(self.model, self.data)
        return self.data

    def relabelled_rates(self, alpha: np.ndarray, tp: float, tm: float) -> tuple[float, np.ndarray]:
        """θ⁺ and q̇_a⁺/θ̇⁺ after the strike at θ⁻ (right foot the new stance)."""
        q = self.configuration(alpha, tp, tm, tm)
        eps = 1e-6
        sigma = (
            self.configuration(alpha, tp, tm, tm + eps)
            - self.configuration(alpha, tp, tm, tm - eps)
        ) / (2 * eps)
        v_plus, _ = self.flow.heel_strike(q, sigma, 1)
        pin.forwardKinematics(self.model, self.data, q, v_plus)
        pin.updateFramePlacements(self.model, self.data)
        step = self.data.oMf[self.hip[1]].translation - self.data.oMf[self.foot[1]].translation
        lwa = pin.LOCAL_WORLD_ALIGNED
        rel = (
            pin.getFrameVelocity(self.model, self.data, self.hip[1], lwa).linear
            - pin.getFrameVelocity(self.model, self.data, self.foot[1], lwa).linear
        )
        a, b = step[0], step[2]
        theta_plus = math.atan2(a, b)
        theta_dot = (b * rel[0] - a * rel[2]) / (a * a + b * b)
        rates = v_plus[[RIGHT[0], RIGHT[1], LEFT[0], LEFT[1]]] / theta_dot
        return theta_plus, rates


def swap(column: np.ndarray) -> np.ndarray:
    """R: the legs' rows exchanged."""
    return column[[2, 3, 0, 1]]


@dataclass
class Candidate:
    """A gait on its fixed point of the zero dynamics: the figures the design constrains."""

    alpha: np.ndarray
    theta_plus: float
    theta_minus: float
    step: Step
    delta2: float
    zeta: np.ndarray  # L²/2 along the step [kg² m⁴/s²]
    duration: float  # [s]
    speed: float  # [m/s]
    torques: np.ndarray  # (GRID, 4) [N m]
    forces: np.ndarray  # (GRID, 2) stance foot's (x, z) force [N]
    cost: float  # mean squared torque / 1000 [N² m²]


class Problem:
    """The free coefficients -> a gait obeying the invariance conditions."""

    def __init__(self, design: Design, speed: float) -> None:
        self.design = design
        self.speed = speed
        self._cache: dict[bytes, Candidate] = {}

    def alpha(self, x: np.ndarray) -> tuple[np.ndarray, float, float]:
        """α (4, M + 1), θ⁺ and θ⁻ of the free variables x = (α_2..α_M, θ⁻)."""
        free = x[:-1].reshape(4, DEGREE - 1)
        tm = float(x[-1])
        alpha = np.zeros((4, DEGREE + 1))
        alpha[:, 2:] = free
        alpha[:, 0] = swap(alpha[:, -1])
        # θ⁺ from the configuration at the strike (it depends on α_M and θ⁻ only)
        tp = -tm
        for _ in range(3):  # θ⁺ enters q(θ) only through s; α_M at s = 1 fixes it
            tp, rates = self.design.relabelled_rates(alpha, tp, tm)
        alpha[:, 1] = alpha[:, 0] + (tm - tp) / DEGREE * rates
        return alpha, tp, tm

    def evaluate(self, x: np.ndarray) -> Candidate:
        """The candidate gait of the free variables x (cached)."""
        key = np.asarray(x, dtype=float).tobytes()
        if key in self._cache:
            return self._cache[key]
        alpha, tp, tm = self.alpha(x)
        step = self.design.step(alpha, tp, tm)
        d2 = step.delta**2
        zeta_minus = -step.V[-1] / max(1.0 - d2, 1e-3)
        zeta = d2 * zeta_minus - step.V  # along the step
        zeta_safe = np.maximum(zeta, 1e-6)
        theta_dot = np.sqrt(2.0 * zeta_safe) / step.kappa
        duration = float(
            np.sum(np.diff(step.theta) * 0.5 * (1 / theta_dot[1:] + 1 / theta_dot[:-1]))
        )
        settings = HZDSettings(bezier=alpha, theta_plus=tp, theta_minus=tm, kp=1.0, kd=1.0)
        law = HZDController(
            self.design.robot,
            legs=(
                Leg("hip_left", "knee_left", "foot_left", 0),
                Leg("hip_right", "knee_right", "foot_right", 1),
            ),
            stance="foot_left",
            settings=settings,
        )
        torques, forces = [], []
        for q, sigma, rate in zip(step.q, step.sigma, theta_dot, strict=True):
            _, u, lam = law.solve(q, sigma * rate, 0)
            torques.append(u)
            forces.append(lam)
        torques_arr, forces_arr = np.array(torques), np.array(forces)
        result = Candidate(
            alpha, tp, tm, step, d2, zeta, duration, step.step_length / duration,
            torques_arr, forces_arr, float(np.mean(np.sum(torques_arr**2, axis=1))) / 1e3,
        )  # fmt: skip
        self._cache[key] = result
        return result

    def constraints(self, x: np.ndarray) -> np.ndarray:
        """The inequalities (>= 0) of the design at x (module docstring)."""
        r = self.evaluate(x)
        step, forces, alpha = r.step, r.forces, r.alpha
        s = np.linspace(0.0, 1.0, GRID)
        inner = slice(1, -1)
        return np.concatenate(
            (
                [0.9 - r.delta2],
                [float(np.min(r.zeta)) - 0.5],
                step.foot_height[inner] - CLEARANCE * np.sin(np.pi * s[inner]),
                forces[:, 1] / (self.design.mass * 9.81) - 0.2,
                FRICTION * forces[:, 1] - np.abs(forces[:, 0]),
                [step.impulse[0], FRICTION * step.impulse[0] - abs(step.impulse[1])],
                [step.old_foot_speed],
                [step.step_length - 0.1],
                alpha[[1, 3]].ravel() - 0.05,
            )
        )

    def equalities(self, x: np.ndarray) -> np.ndarray:
        """The equalities (= 0): the swing foot down at θ⁻, the mean speed."""
        r = self.evaluate(x)
        return np.array([r.step.foot_height[-1], r.speed - self.speed])


def first_guess(theta_minus: float = 0.2, pitch: float = 0.1, knee: float = 0.2) -> np.ndarray:
    """Hips linear in s, stance knee constant, swing knee bent mid-step (leg angle p+φ+κ/2)."""
    end = np.array(
        [
            theta_minus - pitch - knee / 2,
            knee,
            -theta_minus - pitch - knee / 2,
            knee,
        ]
    )
    start = swap(end)
    k = np.arange(DEGREE + 1) / DEGREE
    alpha = start[:, None] * (1 - k) + end[:, None] * k
    alpha[3] += 0.8 * np.sin(np.pi * k) ** 2
    return np.concatenate((alpha[:, 2:].ravel(), [theta_minus]))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=0.6, help="mean speed [m/s]")
    parser.add_argument("--iterations", type=int, default=150, help="SLSQP iterations at most")
    args = parser.parse_args(argv)
    problem = Problem(Design(), args.speed)
    x0 = first_guess()
    r0 = problem.evaluate(x0)
    print(f"first guess: delta^2 {r0.delta2:.4f}, speed {r0.speed:.4f} m/s")
    solution = minimize(
        lambda x: problem.evaluate(x).cost,
        x0,
        method="SLSQP",
        constraints=[
            {"type": "ineq", "fun": problem.constraints},
            {"type": "eq", "fun": problem.equalities},
        ],
        options={"maxiter": args.iterations, "ftol": 1e-8},
    )
    r = problem.evaluate(solution.x)
    print(f"{solution.message}: mean squared torque {1e3 * r.cost:.1f} N^2 m^2")
    print(
        f"smallest inequality {np.min(problem.constraints(solution.x)):.2e}, "
        f"equalities {problem.equalities(solution.x)}"
    )
    print(f"speed {r.speed:.4f} m/s, period {r.duration:.4f} s, delta^2 {r.delta2:.6f}")
    print(
        f"step length {r.step.step_length:.4f} m, largest |u| {np.max(np.abs(r.torques)):.1f} N m"
    )
    print(f"theta_plus = {r.theta_plus!r}\ntheta_minus = {r.theta_minus!r}\nbezier = [")
    for row in r.alpha:
        print("  [" + ", ".join(f"{float(value)!r}" for value in row) + "],")
    print("]")
    print("q+ =", [float(value) for value in r.step.q[0]])


if __name__ == "__main__":
    main()
