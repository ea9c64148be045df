r"""The robot's smooth dynamics between events, for integrators built on an ODE solver.

The event-driven and compliant integrators hand the motion to :func:`scipy.integrate.solve_ivp`,
which needs a state in a vector space. Over one integration segment starting at :math:`q_0` the
configuration is written :math:`q = q_0 \oplus \delta q` (``pin.integrate``) and the ODE state is
:math:`y = (\delta q, v)`, with

.. math:: \dot{\delta q} = \Big(\frac{\partial (q_0 \oplus \delta q)}{\partial \delta q}\Big)^{-1}v,
          \qquad M(q)\,\dot v = \tau - h(q, v) + J(q)^T \lambda,

the first being :math:`\dot{\delta q} = v` when every joint is a vector space (nq = nv).

**Flexible joints.** With :class:`~ucontrol.model.FlexibleJoints` the plant's state is the
extended one, :math:`q = (q_1, q_2)` and :math:`v = (\dot q_1, \dot q_2)` (motors last), and so
are :math:`\delta q` and τ (the motor torques last). The transmission torque
:math:`f = K (S q_1 - q_2) + D (S \dot q_1 - \dot q_2)` enters the links' generalized force,

.. math:: M(q_1)\,\ddot q_1 = \tau_1 - S^T f - h(q_1, \dot q_1) + J^T \lambda, \qquad
          B\,\ddot q_2 = \tau_2 + f,

and the constraints act on the links only: their Jacobian rows have zero motor columns, so
:math:`M^{-1} J^T` (M the block-diagonal inertia of links and motors) has zero motor rows and
neither impulses nor projections in the metric of M change the motors. The energy adds the
motors' kinetic energy and the springs' elastic energy. The springs are integrated like any
other force: stiff ones need a stiff solver (compliant's Radau), not an explicit Runge–Kutta.

:class:`SmoothDynamics` evaluates these terms on a private Pinocchio data buffer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.robot_model import RobotModel
from ucontrol.plant import PlantEvaluation, evaluate_plant

Vector = NDArray[np.float64]


@dataclass(frozen=True)
class ConstraintTerms:
    r"""Dynamics of the robot seen through a subset I of its constraints, at (q, v, τ).

    Sizes are those of the plant's velocity: nv, or nv + nf with flexible joints (the motor
    columns of ``J`` and rows of ``Minv_Jt`` are then zero).

    Attributes:
        gap: Gaps of every constraint in [m] or [rad], shape (n,).
        normal_velocity: ``J v`` of every constraint in [m/s] or [rad/s], shape (n,).
        a_free: Unconstrained acceleration :math:`M^{-1}(\tau - h)`, shape (nv,).
        J: Normal Jacobian rows of I, shape (m, nv).
        Minv_Jt: :math:`M^{-1} J_I^T`, shape (nv, m).
        drift: :math:`\dot J_I v`, the constraint accelerations at zero joint acceleration, in
            [m/s²] or [rad/s²], shape (m,).
    """

    gap: Vector
    normal_velocity: Vector
    a_free: Vector
    J: Vector
    Minv_Jt: Vector
    drift: Vector

    def delassus(self) -> Vector:
        r"""Delassus matrix :math:`D = J_I M^{-1} J_I^T`, shape (m, m)."""
        return self.J @ self.Minv_Jt

    def acceleration_bias(self) -> Vector:
        r"""Constraint accelerations without constraint forces, shape (m,).

        :math:`J_I a_\text{free} + \dot J_I v`, in [m/s²] or [rad/s²].
        """
        return self.J @ self.a_free + self.drift


class SmoothDynamics:
    """Smooth dynamics and constraint kinematics of a robot on a private data buffer.

    States and forces are the plant's: (q (nq,), v (nv,), τ (nv,)) of the robot, extended by
    the motor coordinates with flexible joints (module docstring).

    Args:
        robot: The robot.
        constraints: Its unilateral constraints.
        flexible: Flexible joints of the robot: the state then holds their motor coordinates.

    Attributes:
        nv: Size of the plant's velocity: the robot's nv, plus nf with flexible joints.
    """

    def __init__(
        self,
        robot: RobotModel,
        constraints: ConstraintSet,
        flexible: FlexibleJoints | None = None,
    ) -> None:
        self.robot = robot
        self.constraints = constraints
        self.flexible = flexible
        self.model = robot.model
        self.data = robot.model.createData()
        self.nv = robot.nv + (0 if flexible is None else flexible.nf)
        self._link_nq = robot.nq
        self._link_nv = robot.nv
        self._euclidean = robot.nq == robot.nv
        self._zero_acceleration = np.zeros(robot.nv)

    def evaluate(self, q: Vector, v: Vector, t: float | None = None) -> PlantEvaluation:
        """Gaps, normal velocities and energies at (q, v): the protocol's evaluate.

        The energies include the motors' kinetic and the springs' elastic energy; ``t`` [s]
        is passed to constraints that depend on time.
        """
        return evaluate_plant(self.data, self.constraints, self.flexible, q, v, t=t)

    def configuration(self, q0: Vector, dq: Vector) -> Vector:
        """The configuration ``q0 ⊕ dq``, shape (nq,), for a chart offset ``dq`` (nv,)."""
        if self._euclidean:
            return q0 + dq
        nq, nv = self._link_nq, self._link_nv
        links = pin.integrate(self.model, q0[:nq], dq[:nv])
        if self.flexible is None:
            return links
        return np.concatenate((links, q0[nq:] + dq[nv:]))

    def chart_rate(self, q0: Vector, dq: Vector, v: Vector) -> Vector:
        """Time derivative of the chart offset ``dq`` (nv,) at velocity ``v`` (nv,)."""
        if self._euclidean:
            return v
        nq, nv = self._link_nq, self._link_nv
        jacobian = pin.dIntegrate(self.model, q0[:nq], dq[:nv], pin.ARG1)
        links = np.linalg.solve(jacobian, v[:nv])
        if self.flexible is None:
            return links
        return np.concatenate((links, v[nv:]))

    def kinematics(self, q: Vector, v: Vector) -> tuple[Vector, Vector]:
        """Gaps and normal velocities of every constraint at (q, v), each of shape (n,)."""
        model, data = self.model, self.data
        q1, v1 = q[: self._link_nq], v[: self._link_nv]
        pin.forwardKinematics(model, data, q1, v1)
        pin.updateFramePlacements(model, data)
        return self.constraints.evaluate(data, q1, v1)

    def free_acceleration(self, q: Vector, v: Vector, tau: Vector) -> Vector:
        """Acceleration without constraint forces, ``M⁻¹ (τ - h)``, shape (nv,)."""
        q1, v1, link_force, motor_acceleration = self._split_forces(q, v, tau)
        acceleration = pin.aba(self.model, self.data, q1, v1, link_force).copy()
        if motor_acceleration is None:
            return acceleration
        return np.concatenate((acceleration, motor_acceleration))

    def constraint_terms(
        self,
        q: Vector,
        v: Vector,
        tau: Vector,
        indices: NDArray[np.intp],
        *,
        with_drift: bool = True,
    ) -> ConstraintTerms:
        """Everything the constraints ``indices`` (m,) need at (q, v) under forces ``tau``.

        Args:
            q: Configuration, shape (nq,).
            v: Velocity, shape (nv,).
            tau: Generalized forces, shape (nv,).
            indices: Constraint indices, shape (m,).
            with_drift: Compute ``J̇ v``; without it ``drift`` is zero.
        """
        model, data = self.model, self.data
        q1, v1, link_force, motor_acceleration = self._split_forces(q, v, tau)
        pin.computeAllTerms(model, data, q1, v1)
        pin.updateFramePlacements(model, data)
        gap, normal_velocity = self.constraints.evaluate(data, q1, v1)
        pin.cholesky.decompose(model, data)
        a_free = pin.cholesky.solve(model, data, link_force - data.nle)
        J = self.constraints.jacobian(data, indices)
        if len(indices) == 1:  # M⁻¹ Jᵀ by one triangular solve instead of M⁻¹
            Minv_Jt = pin.cholesky.solve(model, data, J[0])[:, None]
        else:
            Minv_Jt = pin.cholesky.computeMinv(model, data) @ J.T
        drift = self._drift(q1, v1, indices) if with_drift else np.zeros(len(indices))
        if motor_acceleration is not None:  # the constraints act on the links only
            motors = motor_acceleration.size
            a_free = np.concatenate((a_free, motor_acceleration))
            J = np.hstack((J, np.zeros((J.shape[0], motors))))
            Minv_Jt = np.vstack((Minv_Jt, np.zeros((motors, Minv_Jt.shape[1]))))
        return ConstraintTerms(gap, normal_velocity, a_free, J, Minv_Jt, drift)

    def _split_forces(
        self, q: Vector, v: Vector, tau: Vector
    ) -> tuple[Vector, Vector, Vector, Vector | None]:
        """Link state, the links' generalized force and the motors' acceleration.

        Returns:
            q1 (nq,), dq1 (nv,) and τ1 - Sᵀ f (nv,) of the links, and (τ2 + f) / B (nf,) in
            [rad/s²] (or [m/s²]), None without flexible joints (then τ1 = τ).
        """
        flexible = self.flexible
        if flexible is None:
            return q, v, tau, None
        nq, nv = self._link_nq, self._link_nv
        force = tau + flexible.transmission_forces(q, v)
        return q[:nq], v[:nv], force[:nv], force[nv:] / flexible.motor_inertia

    def _drift(self, q: Vector, v: Vector, indices: NDArray[np.intp]) -> Vector:
        """``J̇ v`` at the link state (q, v) of the constraints ``indices``: zero for stops."""
        if not np.any(np.asarray(indices) < self.constraints.n_contacts):
            return np.zeros(len(indices))
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, self._zero_acceleration)
        pin.updateFramePlacements(model, data)
        return self.constraints.normal_drift(data, indices)
