r"""The robot's smooth dynamics between events, for integrators built on an ODE solver.

The event-driven and compliant integrators hand the motion to :func:`scipy.integrate.solve_ivp`,
which needs a state in a vector space. Over one integration segment starting at :math:`q_0` the
configuration is written :math:`q = q_0 \oplus \delta q` (``pin.integrate``) and the ODE state is
:math:`y = (\delta q, v)`, with

.. math:: \dot{\delta q} = \Big(\frac{\partial (q_0 \oplus \delta q)}{\partial \delta q}\Big)^{-1}v,
          \qquad M(q)\,\dot v = \tau - h(q, v) + J(q)^T \lambda,

the first being :math:`\dot{\delta q} = v` when every joint is a vector space (nq = nv).
:class:`SmoothDynamics` evaluates these terms on a private Pinocchio data buffer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.integrators.moreau_jean import PlantEvaluation
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]


@dataclass(frozen=True)
class ConstraintTerms:
    r"""Dynamics of the robot seen through a subset I of its constraints, at (q, v, τ).

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

    Args:
        robot: The robot.
        constraints: Its unilateral constraints.
    """

    def __init__(self, robot: RobotModel, constraints: ConstraintSet) -> None:
        self.robot = robot
        self.constraints = constraints
        self.model = robot.model
        self.data = robot.model.createData()
        self.nv = robot.nv
        self._euclidean = robot.nq == robot.nv
        self._zero_acceleration = np.zeros(robot.nv)

    def evaluate(self, q: Vector, v: Vector) -> PlantEvaluation:
        """Gaps, normal velocities and energies at (q (nq,), v (nv,)): the protocol's evaluate."""
        model, data = self.model, self.data
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        gap, normal_velocity = self.constraints.evaluate(data, q, v)
        return PlantEvaluation(
            q, v, gap, normal_velocity, data.kinetic_energy, data.potential_energy
        )

    def configuration(self, q0: Vector, dq: Vector) -> Vector:
        """The configuration ``q0 ⊕ dq``, shape (nq,), for a chart offset ``dq`` (nv,)."""
        return q0 + dq if self._euclidean else pin.integrate(self.model, q0, dq)

    def chart_rate(self, q0: Vector, dq: Vector, v: Vector) -> Vector:
        """Time derivative of the chart offset ``dq`` (nv,) at velocity ``v`` (nv,)."""
        if self._euclidean:
            return v
        return np.linalg.solve(pin.dIntegrate(self.model, q0, dq, pin.ARG1), v)

    def kinematics(self, q: Vector, v: Vector) -> tuple[Vector, Vector]:
        """Gaps and normal velocities of every constraint at (q, v), each of shape (n,)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v)
        pin.updateFramePlacements(model, data)
        return self.constraints.evaluate(data, q, v)

    def free_acceleration(self, q: Vector, v: Vector, tau: Vector) -> Vector:
        """Acceleration without constraint forces, ``M⁻¹ (τ - h)``, shape (nv,)."""
        return pin.aba(self.model, self.data, q, v, tau).copy()

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
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        gap, normal_velocity = self.constraints.evaluate(data, q, v)
        pin.cholesky.decompose(model, data)
        a_free = pin.cholesky.solve(model, data, tau - data.nle)
        J = self.constraints.jacobian(data, indices)
        if len(indices) == 1:  # M⁻¹ Jᵀ by one triangular solve instead of M⁻¹
            Minv_Jt = pin.cholesky.solve(model, data, J[0])[:, None]
        else:
            Minv_Jt = pin.cholesky.computeMinv(model, data) @ J.T
        drift = self._drift(q, v, indices) if with_drift else np.zeros(len(indices))
        return ConstraintTerms(gap, normal_velocity, a_free, J, Minv_Jt, drift)

    def _drift(self, q: Vector, v: Vector, indices: NDArray[np.intp]) -> Vector:
        """``J̇ v`` of the constraints ``indices``: zero for joint stops, shape (m,)."""
        if not np.any(np.asarray(indices) < self.constraints.n_contacts):
            return np.zeros(len(indices))
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, self._zero_acceleration)
        pin.updateFramePlacements(model, data)
        return self.constraints.normal_drift(data, indices)
