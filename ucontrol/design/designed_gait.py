"""A designed walking step: the optimal-control solution, its solver figures and its checks.

The checks (:meth:`DesignedGait.residuals`) recompute the step's constraints with Pinocchio,
independently of the casadi model the step was designed on.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]
#: ``((hip, knee, foot), (hip, knee, foot))``: joint and frame names of a biped's legs.
Legs = tuple[tuple[str, str, str], tuple[str, str, str]]


@dataclass(frozen=True, kw_only=True)
class DesignedGait:
    r"""One designed step of a planar biped, from just after a heel strike to the next one.

    Attributes:
        robot: The biped (planar base x, z, pitch first).
        legs: ``((hip, knee, foot), (hip, knee, foot))`` of the legs.
        stance: Stance foot of the step.
        t: Grid times in [s], shape (N + 1,), from 0 to the step time.
        q: Configurations at the grid points, shape (N + 1, nv).
        v: Velocities at the grid points in [m/s] or [rad/s], shape (N + 1, nv); ``v[-1]`` is
            the velocity just before the heel strike.
        tau: Piecewise-constant torques of the actuated joints in [N m], shape (N, nu).
        force: Stance-foot force (tangential x, normal z) in [N] at the grid points, shape
            (N + 1, 2) (the last with the last interval's torques).
        v_plus: Velocity just after the heel strike (before the relabelling), shape (nv,).
        impulse: Heel-strike impulse on the new stance foot (x, z) in [N s], shape (2,).
        step_length: Distance between the two stance feet in [m].
        substeps: RK4 steps per control interval of the design.
        cost: Torque squared per distance in [N² m² s / m].
        status: IPOPT's return status.
        success: IPOPT converged.
        iterations: IPOPT iterations.
        cpu_time: Processor time of the solve in [s].
        max_violation: Largest constraint violation of the program at the solution.
        stationarity: :math:`\|\nabla f + J_g^T\lambda\|_\infty` of the scaled program at the
            solution, from casadi's Jacobians and IPOPT's multipliers (KKT stationarity).
    """

    robot: RobotModel
    legs: Legs
    stance: str
    t: Vector
    q: Vector
    v: Vector
    tau: Vector
    force: Vector
    v_plus: Vector
    impulse: Vector
    step_length: float
    substeps: int
    cost: float
    status: str
    success: bool
    iterations: int
    cpu_time: float
    max_violation: float
    stationarity: float

    @property
    def step_time(self) -> float:
        """Duration of the step in [s]."""
        return float(self.t[-1])

    @property
    def speed(self) -> float:
        """Average walking speed in [m/s]."""
        return self.step_length / self.step_time

    @property
    def swing(self) -> str:
        """Swing foot of the step."""
        return next(leg[2] for leg in self.legs if leg[2] != self.stance)

    def relabelling(self) -> Vector:
        """The matrix (nv, nv) swapping the legs' joints (the base rows the identity)."""
        return relabelling_matrix(self.robot, self.legs)

    @property
    def actuated_indices(self) -> NDArray[np.intp]:
        """Indices in v of q_a = (stance hip, stance knee, swing hip, swing knee), shape (4,)."""
        return output_indices(self.robot, self.legs, self.stance)

    def residuals(self, friction: float) -> dict[str, float]:
        r"""The step's constraints recomputed with Pinocchio.

        Args:
            friction: Coulomb coefficient the step was designed with.

        Returns:
            ``pinned_foot``: largest distance of the stance foot from its start at the grid
            points [m]; ``stance_start``: its distance from the origin at t = 0 [m];
            ``impact_momentum``: :math:`|M(v^+ - v^-) - J_w^T\Lambda|_\infty` [N s];
            ``impact_velocity``: :math:`|J_w v^+|_\infty` [m/s]; ``liftoff_velocity``: the old
            stance foot's normal velocity after the strike [m/s], >= 0 expected;
            ``periodic_q``, ``periodic_v``: :math:`|R q^- - q_0 - L e_x|_\infty`,
            :math:`|R v^+ - v_0|_\infty`; ``landing``: distance of the swing foot at the strike
            from (L, 0) [m]; ``friction_margin``: largest :math:`|\lambda_t| - \mu\lambda_n`
            over the grid and the impulse, <= 0 expected [N]; ``min_normal_force`` [N];
            ``min_swing_height``: over the inner grid points [m].
        """
        robot = self.robot
        stance = robot.frame_path(self.q, self.stance)[:, [0, 2]]
        swing = robot.frame_path(self.q, self.swing)[:, [0, 2]]
        q_minus, v_minus = self.q[-1], self.v[-1]
        M = pin.crba(robot.model, pin.Data(robot.model), q_minus)
        M = np.triu(M) + np.triu(M, 1).T
        J_w = robot.frame_jacobian(q_minus, self.swing)[[0, 2]]
        J_s = robot.frame_jacobian(q_minus, self.stance)[[0, 2]]
        R = self.relabelling()
        shift = np.zeros(robot.nv)
        shift[0] = self.step_length
        margins = np.concatenate(
            (
                np.abs(self.force[:, 0]) - friction * self.force[:, 1],
                [abs(self.impulse[0]) - friction * self.impulse[1]],
            )
        )
        return {
            "pinned_foot": float(np.max(np.linalg.norm(stance - stance[0], axis=1))),
            "stance_start": float(np.linalg.norm(stance[0])),
            "impact_momentum": float(
                np.max(np.abs(M @ (self.v_plus - v_minus) - J_w.T @ self.impulse))
            ),
            "impact_velocity": float(np.max(np.abs(J_w @ self.v_plus))),
            "liftoff_velocity": float((J_s @ self.v_plus)[1]),
            "periodic_q": float(np.max(np.abs(R @ q_minus - self.q[0] - shift))),
            "periodic_v": float(np.max(np.abs(R @ self.v_plus - self.v[0]))),
            "landing": float(np.linalg.norm(swing[-1] - np.array([self.step_length, 0.0]))),
            "friction_margin": float(np.max(margins)),
            "min_normal_force": float(np.min(self.force[:, 1])),
            "min_swing_height": float(np.min(swing[1:-1, 1])),
        }

    def summary(self, friction: float) -> dict[str, object]:
        """Solver figures, the step's figures and its residuals (JSON-ready)."""
        return {
            "status": self.status,
            "success": self.success,
            "iterations": self.iterations,
            "cpu_time_s": self.cpu_time,
            "cost_N2m2s_per_m": self.cost,
            "step_length_m": self.step_length,
            "step_time_s": self.step_time,
            "speed_m_s": self.speed,
            "impulse_N_s": self.impulse.tolist(),
            "max_violation": self.max_violation,
            "stationarity": self.stationarity,
            "residuals": self.residuals(friction),
        }

    def save(self, directory: str | Path, friction: float) -> None:
        """Write ``gait.npz`` (the arrays) and ``gait.json`` (:meth:`summary`) to ``directory``."""
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        np.savez(
            directory / "gait.npz",
            t=self.t,
            q=self.q,
            v=self.v,
            tau=self.tau,
            force=self.force,
            v_plus=self.v_plus,
            impulse=self.impulse,
        )
        text = json.dumps(self.summary(friction), indent=2)
        (directory / "gait.json").write_text(text + "\n")


def relabelling_matrix(robot: RobotModel, legs: Legs) -> Vector:
    """The matrix R (nv, nv) swapping the legs' hips and knees; the base rows the identity."""
    R = np.eye(robot.nv)
    for a, b in zip(legs[0][:2], legs[1][:2], strict=True):
        i, j = (robot.model.joints[robot.joint_id(name)].idx_v for name in (a, b))
        R[[i, j]] = R[[j, i]]
    return R


def output_indices(robot: RobotModel, legs: Legs, stance: str) -> NDArray[np.intp]:
    """Indices in v of q_a = (stance hip, stance knee, swing hip, swing knee), shape (4,)."""
    stance_leg = next(leg for leg in legs if leg[2] == stance)
    swing_leg = next(leg for leg in legs if leg[2] != stance)
    names = (*stance_leg[:2], *swing_leg[:2])
    return np.array([robot.model.joints[robot.joint_id(name)].idx_v for name in names])
