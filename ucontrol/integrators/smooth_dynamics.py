r"""The robot's smooth dynamics between events, for integrators built on an ODE solver.

The event-driven and compliant integrators hand the motion to :func:`scipy.integrate.solve_ivp`,
which needs a state in a vector space. Over one integration segment starting at :math:`q_0` the
configuration is written :math:`q = q_0 \oplus \delta q` (``pin.integrate``) and the ODE state is
:math:`y = (\delta q, v)`, with

.. math:: \dot{\delta q} = \Big(\frac{\partial (q_0 \oplus \delta q)}{\partial \delta q}\Big)^{-1}v,
          \qquad M(q)\,\dot v = \tau - h(q, v) + J(q)^T \lambda,

the first being :math:`\dot{\delta q} = v` when every joint is a vector space (nq = nv).

**Bilateral constraints.** With :attr:`~ucontrol.contact.ConstraintSet.bilateral` (rows
:math:`J_b`, drift :math:`\dot J_b v`) every term is that of the robot *held by them* at
acceleration level (index reduction): with :math:`D_b = J_b M^{-1} J_b^T` and its
pseudo-inverse (dependent rows: a planar point closure, a closure declared twice),

.. math:: a_\text{free} = a_0 - M^{-1} J_b^T D_b^+ (J_b a_0 + \dot J_b v), \qquad
          P = M^{-1} - M^{-1} J_b^T D_b^+ J_b M^{-1},

:math:`a_0 = M^{-1}(\tau - h)`, and the unilateral rows see :math:`P J^T` in place of
:math:`M^{-1} J^T` (``Minv_Jt``), so their Delassus matrix is :math:`J P J^T`. Since
:math:`J_b P = 0`, unilateral impulses and forces never move the bilateral rows.

**Moving surfaces.** Gaps and normal velocities are relative to the surfaces at time t,
:math:`u = J v + \partial g / \partial t` (``rate``), and a point contact's constraint
acceleration gains the surface's, :math:`-n \cdot \ddot x(t)`, in ``drift``.

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

**Viscous joint friction.** With a :class:`~ucontrol.model.joint_friction.JointFriction`
whose Coulomb part is zero, :math:`-D \dot q_1` joins the links' generalized force
(:math:`\tau_1 - D \dot q_1`, link coordinates only, as Moreau–Jean's), integrated like any
other smooth force. Coulomb joint friction is set-valued and is not a smooth force: it is
refused (Moreau–Jean treats it).

:class:`SmoothDynamics` evaluates these terms on a private Pinocchio data buffer.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.joint_friction import JointFriction
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
        drift: :math:`\dot J_I v` (minus :math:`n \cdot \ddot x(t)` against a moving surface),
            the constraint accelerations at zero joint acceleration, in [m/s²] or [rad/s²],
            shape (m,).
        rate: :math:`\partial g_I / \partial t` in [m/s] (zero against fixed surfaces), shape
            (m,).
        T: Tangential rows of the constraints asked for (``tangents``), shape (k, nv); empty
            when none were.
        Minv_Tt: :math:`M^{-1} T^T` (held by the bilateral rows), shape (nv, k).
        drift_t: :math:`\dot T v` in [m/s²] (zero without ``with_drift``), shape (k,).

    With bilateral constraints ``a_free`` and ``Minv_Jt`` are those of the robot held by
    them (module docstring).
    """

    gap: Vector
    normal_velocity: Vector
    a_free: Vector
    J: Vector
    Minv_Jt: Vector
    drift: Vector
    rate: Vector
    T: Vector = field(default_factory=lambda: np.zeros((0, 0)))
    Minv_Tt: Vector = field(default_factory=lambda: np.zeros((0, 0)))
    drift_t: Vector = field(default_factory=lambda: np.zeros(0))

    def velocity(self, v: Vector) -> Vector:
        r"""Normal velocities :math:`J_I v + \partial g_I/\partial t` of I at ``v`` (nv,)."""
        return self.J @ v + self.rate

    def delassus(self) -> Vector:
        r"""Delassus matrix :math:`D = J_I M^{-1} J_I^T`, shape (m, m)."""
        return self.J @ self.Minv_Jt

    def acceleration_bias(self) -> Vector:
        r"""Constraint accelerations without constraint forces, shape (m,).

        :math:`J_I a_\text{free} + \dot J_I v`, in [m/s²] or [rad/s²].
        """
        return self.J @ self.a_free + self.drift


@dataclass(frozen=True)
class ManifoldTerms:
    r"""The closed unilateral rows I and the bilateral rows stacked (I first), at (q, v, t).

    Attributes:
        residual: Gaps of I then :math:`h(q)`, shape (m + m_b,), in [m] or [rad].
        velocity: Their rates (:math:`u_I`, then :math:`J_b v`), shape (m + m_b,).
        J: Their Jacobian rows, shape (m + m_b, nv).
        Minv_Jt: :math:`M^{-1} J^T`, shape (nv, m + m_b).
    """

    residual: Vector
    velocity: Vector
    J: Vector
    Minv_Jt: Vector

    def delassus(self) -> Vector:
        r"""Delassus matrix :math:`J M^{-1} J^T`, shape (m + m_b, m + m_b)."""
        return self.J @ self.Minv_Jt


class SmoothDynamics:
    """Smooth dynamics and constraint kinematics of a robot on a private data buffer.

    States and forces are the plant's: (q (nq,), v (nv,), τ (nv,)) of the robot, extended by
    the motor coordinates with flexible joints (module docstring).

    Args:
        robot: The robot.
        constraints: Its unilateral constraints.
        flexible: Flexible joints of the robot: the state then holds their motor coordinates.
        joint_friction: Viscous friction of the link coordinates (no Coulomb part), or None.
        integrator: Name of the integrator, for the errors.

    Attributes:
        nv: Size of the plant's velocity: the robot's nv, plus nf with flexible joints.

    Raises:
        InvalidParameterError: ``joint_friction`` has a Coulomb part or not the robot's nv.
    """

    def __init__(
        self,
        robot: RobotModel,
        constraints: ConstraintSet,
        flexible: FlexibleJoints | None = None,
        joint_friction: JointFriction | None = None,
        integrator: str = "smooth dynamics",
    ) -> None:
        self.robot = robot
        self.constraints = constraints
        self.flexible = flexible
        #: D of the link coordinates [N m s/rad] or [N s/m], shape (nv,), or None.
        self.viscous: Vector | None = None
        if joint_friction is not None:
            if joint_friction.nv != robot.nv:
                raise InvalidParameterError(
                    "joint_friction",
                    f"{joint_friction.nv} coordinates",
                    f"{robot.nv} (the robot's nv)",
                )
            if joint_friction.coulomb_index.size:
                raise InvalidParameterError(
                    "joint_friction",
                    f"Coulomb friction on coordinates {joint_friction.coulomb_index.tolist()}",
                    f"viscous friction only with {integrator} (Coulomb joint friction is "
                    "set-valued: use moreau_jean)",
                )
            if joint_friction.has_viscous:
                self.viscous = joint_friction.viscous
        self.model = robot.model
        self.data = pin.Data(robot.model)
        self.nv = robot.nv + (0 if flexible is None else flexible.nf)
        self._link_nq = robot.nq
        self._link_nv = robot.nv
        self._euclidean = robot.nq == robot.nv
        self._zero_acceleration = np.zeros(robot.nv)
        self.bilateral = constraints.bilateral
        #: Point contacts against moving surfaces: (index, motion, normal).
        self._moving = [
            (i, contact.surface.motion, np.asarray(contact.surface.normal, dtype=float))
            for i, contact in enumerate(constraints.contacts)
            if contact.surface.motion is not None
        ]

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

    def kinematics(self, q: Vector, v: Vector, t: float | None = None) -> tuple[Vector, Vector]:
        """Gaps and normal velocities of every constraint at (q, v), each of shape (n,).

        Relative to the moving surfaces at t [s] (required when some surface moves).
        """
        model, data = self.model, self.data
        q1, v1 = q[: self._link_nq], v[: self._link_nv]
        pin.forwardKinematics(model, data, q1, v1)
        pin.updateFramePlacements(model, data)
        return self.constraints.evaluate(data, q1, v1, t)

    def free_acceleration(self, q: Vector, v: Vector, tau: Vector) -> Vector:
        """Acceleration without constraint forces, ``M⁻¹ (τ - h)``, shape (nv,).

        Without bilateral constraints only (with them use :meth:`constraint_terms`).
        """
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
        t: float | None = None,
        tangents: NDArray[np.intp] | None = None,
    ) -> ConstraintTerms:
        """Everything the constraints ``indices`` (m,) need at (q, v) under forces ``tau``.

        Args:
            q: Configuration, shape (nq,).
            v: Velocity, shape (nv,).
            tau: Generalized forces, shape (nv,).
            indices: Constraint indices, shape (m,).
            with_drift: Compute ``J̇ v``; without it ``drift`` is zero (and, with bilateral
                constraints, their own drift is left out of ``a_free``).
            t: Time in [s]; required when some surface moves.
            tangents: Constraints whose tangential row (one each, those of
                :meth:`~ucontrol.contact.ConstraintSet.sustains_friction`) and its drift are
                wanted too, shape (k,); None: none.
        """
        model, data = self.model, self.data
        q1, v1, link_force, motor_acceleration = self._split_forces(q, v, tau)
        pin.computeAllTerms(model, data, q1, v1)
        pin.updateFramePlacements(model, data)
        gap, normal_velocity = self.constraints.evaluate(data, q1, v1, t)
        pin.cholesky.decompose(model, data)
        a_free = pin.cholesky.solve(model, data, link_force - data.nle)
        J = self.constraints.jacobian(data, indices)
        k = 0
        if tangents is not None and tangents.size:  # stacked under the normal rows
            T = self.constraints.tangent_rows(data, tangents)[0]
            k = T.shape[0]
            J = np.vstack((J, T))
        bilateral = self.bilateral
        J_b = bilateral.jacobian(data) if bilateral is not None else None
        if J_b is None and J.shape[0] == 1:  # M⁻¹ Jᵀ by one triangular solve, not M⁻¹
            Minv_Jt = pin.cholesky.solve(model, data, J[0])[:, None]
            Minv = None
        else:
            Minv = pin.cholesky.computeMinv(model, data)
            Minv_Jt = Minv @ J.T
        drift, drift_b = (
            self._drift(q1, v1, indices, t, tangents if k else None)
            if with_drift
            else (np.zeros(len(indices) + k), np.zeros(0 if J_b is None else J_b.shape[0]))
        )
        if J_b is not None and Minv is not None:  # held by the bilateral rows
            Minv_Jbt = Minv @ J_b.T
            gain = Minv_Jbt @ _pseudo_inverse(J_b @ Minv_Jbt)  # M⁻¹ J_bᵀ D_b⁺, (nv, m_b)
            a_free = a_free - gain @ (J_b @ a_free + drift_b)
            Minv_Jt = Minv_Jt - gain @ (Minv_Jbt.T @ J.T)  # P Jᵀ
        rate = (
            self.constraints.normal_rate(indices, t)
            if self.constraints.time_dependent and t is not None  # (evaluate raised without t)
            else np.zeros(len(indices))
        )
        if motor_acceleration is not None:  # the constraints act on the links only
            motors = motor_acceleration.size
            a_free = np.concatenate((a_free, motor_acceleration))
            J = np.hstack((J, np.zeros((J.shape[0], motors))))
            Minv_Jt = np.vstack((Minv_Jt, np.zeros((motors, Minv_Jt.shape[1]))))
        if not k:
            return ConstraintTerms(gap, normal_velocity, a_free, J, Minv_Jt, drift, rate)
        m = len(indices)
        return ConstraintTerms(
            gap,
            normal_velocity,
            a_free,
            J[:m],
            Minv_Jt[:, :m],
            drift[:m],
            rate,
            J[m:],
            Minv_Jt[:, m:],
            drift[m:],
        )

    def manifold_terms(
        self, q: Vector, v: Vector, indices: NDArray[np.intp], t: float | None = None
    ) -> ManifoldTerms:
        """Residuals, rates and rows of the closed constraints ``indices`` and the bilateral ones.

        Args:
            q: Configuration, shape (nq,).
            v: Velocity, shape (nv,).
            indices: Closed unilateral constraints, shape (m,).
            t: Time in [s]; required when some surface moves.
        """
        model, data = self.model, self.data
        q1, v1 = q[: self._link_nq], v[: self._link_nv]
        pin.computeAllTerms(model, data, q1, v1)
        pin.updateFramePlacements(model, data)
        gap, normal_velocity = self.constraints.evaluate(data, q1, v1, t)
        J = self.constraints.jacobian(data, indices)
        residual, velocity = gap[indices], normal_velocity[indices]
        if self.bilateral is not None:
            J_b = self.bilateral.jacobian(data)
            residual = np.concatenate((residual, self.bilateral.residual(data, q1)))
            velocity = np.concatenate((velocity, J_b @ v1))
            J = np.vstack((J, J_b))
        pin.cholesky.decompose(model, data)
        Minv_Jt = pin.cholesky.computeMinv(model, data) @ J.T
        if self.flexible is not None:  # the constraints act on the links only
            motors = self.nv - self._link_nv
            J = np.hstack((J, np.zeros((J.shape[0], motors))))
            Minv_Jt = np.vstack((Minv_Jt, np.zeros((motors, Minv_Jt.shape[1]))))
        return ManifoldTerms(residual, velocity, J, Minv_Jt)

    def _split_forces(
        self, q: Vector, v: Vector, tau: Vector
    ) -> tuple[Vector, Vector, Vector, Vector | None]:
        """Link state, the links' generalized force and the motors' acceleration.

        Returns:
            q1 (nq,), dq1 (nv,) and τ1 - Sᵀ f - D dq1 (nv,) of the links, and (τ2 + f) / B
            (nf,) in [rad/s²] (or [m/s²]), None without flexible joints (then τ1 = τ - D v).
        """
        flexible = self.flexible
        if flexible is None:
            if self.viscous is not None:
                tau = tau - self.viscous * v  # [N m]
            return q, v, tau, None
        nq, nv = self._link_nq, self._link_nv
        force = tau + flexible.transmission_forces(q, v)
        link_force = force[:nv]
        if self.viscous is not None:
            link_force = link_force - self.viscous * v[:nv]  # [N m]
        return q[:nq], v[:nv], link_force, force[nv:] / flexible.motor_inertia

    def _drift(
        self,
        q: Vector,
        v: Vector,
        indices: NDArray[np.intp],
        t: float | None,
        tangents: NDArray[np.intp] | None = None,
    ) -> tuple[Vector, Vector]:
        r"""``J̇ v`` at the link state (q, v) of the constraints ``indices`` and bilateral rows.

        Zero for stops and couplings; a contact against a moving surface adds
        :math:`-n \cdot \ddot x(t)`. Returns shapes (m,) and (m_b,); with ``tangents``
        (k,), the drift of their tangential rows follows the normal ones, shape (m + k,).
        """
        bilateral = self.bilateral
        drift = np.zeros(len(indices))
        drift_b = np.zeros(0 if bilateral is None else bilateral.size)
        if bilateral is not None or tangents is not None or self.constraints.has_drift(indices):
            model, data = self.model, self.data
            pin.forwardKinematics(model, data, q, v, self._zero_acceleration)
            pin.updateFramePlacements(model, data)
            drift = self.constraints.normal_drift(data, indices, q=q, v=v, t=t)
            if tangents is not None:
                drift = np.concatenate((drift, self.constraints.tangent_drift(data, tangents, v)))
            if bilateral is not None:
                drift_b = bilateral.drift(data)
        if t is not None:  # (moving surfaces need t: constraints.evaluate raised without it)
            for i, motion, normal in self._moving:  # (collision rows: in normal_drift)
                rows = np.flatnonzero(np.asarray(indices) == i)
                if rows.size:
                    drift[rows] -= normal.dot(motion(t)[2])
        return drift, drift_b


def _pseudo_inverse(D: Vector) -> Vector:
    """Pseudo-inverse of a symmetric positive semi-definite D (m, m): dependent rows allowed."""
    return np.asarray(np.linalg.pinv(D, rcond=1e-12, hermitian=True), dtype=np.float64)
