r"""Moreau–Jean time-stepping (event-capturing θ-scheme), frictionless.

One step from :math:`(q_k, v_k)` with step :math:`h` and :math:`\theta \in [1/2, 1]`:

1. free velocity :math:`v_\text{free} = v_k + h M^{-1}(\tau - h(q_k, v_k))`;
2. active set by prediction: :math:`a \in I` iff :math:`g_a + \gamma h u_a \le 0`
   (:math:`\gamma = 1/2`);
3. Signorini–Newton at velocity level on :math:`I`:
   :math:`0 \le u_a(v_{k+1}) + e_a u_a(v_k) \perp P_a \ge 0`, solved as a QP in the impulses,
   :math:`v_{k+1} = v_\text{free} + M^{-1} J_I^T P`;
4. :math:`q_{k+1} = q_k \oplus h((1-\theta) v_k + \theta v_{k+1})`.

Every matrix is evaluated at step k. The scheme is of order one, captures impacts without
locating them, and enforces Newton's law exactly at every impact.

Newton's law uses :math:`e_a` for closing constraints only (:math:`u_a < -u_\text{th}`, the
``restitution_threshold``, 0 by default); separating or persistent ones get :math:`e_a = 0`.
With unequal restitutions on simultaneous impacts the generalized Newton law can add kinetic
energy (the impulses' work :math:`\tfrac12 P^T(u_\text{free} + u^+)` turns positive, e.g. near
singular configurations where constraint rows are almost dependent); such a step is redone with
the plastic law (e = 0), which never adds energy, and flagged in :attr:`StepOutcome.plastic`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_in_interval, as_positive
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import InvalidParameterError, SolverError
from ucontrol.model.robot_model import RobotModel
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

Vector = NDArray[np.float64]

#: Kinetic energy the restitution impulses of a step may add, relative to 1 + the kinetic
#: energy in [J], before the step is redone with a plastic law (e = 0).
ENERGY_GAIN_TOLERANCE = 1e-12


class PlantEvaluation(NamedTuple):
    """Everything the plant knows at the start of a step, at (q_k, v_k).

    Attributes:
        q: Configuration, shape (nq,).
        v: Velocity, shape (nv,).
        gap: Constraint gaps, shape (n,).
        normal_velocity: Constraint velocities ``J v``, shape (n,).
        kinetic_energy: In [J].
        potential_energy: Gravitational, in [J].
    """

    q: Vector
    v: Vector
    gap: Vector
    normal_velocity: Vector
    kinetic_energy: float
    potential_energy: float


class StepOutcome(NamedTuple):
    """The result of one step from a :class:`PlantEvaluation`.

    Attributes:
        q: Configuration at the end of the step, shape (nq,).
        v: Velocity at the end of the step, shape (nv,).
        impulse: Normal impulse of each constraint over the step in [N s], shape (n,).
        active: Which constraints were in the active set, shape (n,).
        solution: The contact solve, or None when the active set was empty.
        plastic: Whether Newton's law was replaced by a plastic one (e = 0) in this step,
            because the restitution impulses would have added kinetic energy.
        events: Events located within the step (impacts, contact closures and releases) by
            event-driven integrators; 0 for time-stepping, which locates none.
    """

    q: Vector
    v: Vector
    impulse: Vector
    active: NDArray[np.bool_]
    solution: ContactSolution | None
    events: int = 0
    plastic: bool = False


class MoreauJean:
    """Moreau–Jean integrator of a robot under unilateral constraints.

    The plant owns a private Pinocchio data buffer, so controllers may use the robot freely.
    Use :meth:`evaluate` at (q_k, v_k), then :meth:`step` with the generalized forces.

    Args:
        robot: The robot.
        constraints: Its unilateral constraints.
        dt: Time step h in [s].
        theta: θ of the position update, in [1/2, 1].
        solver: Contact LCP solver; default a :class:`ProxsuiteLCPSolver`.
        restitution_threshold: Closing speed in [m/s] (or [rad/s]) below which a contact is
            treated as persistent and gets e = 0; separating contacts always get e = 0.
            0 applies Newton's law to every closing contact.
    """

    name = "moreau_jean"
    gamma = 0.5  # active-set prediction horizon, in steps

    def __init__(
        self,
        robot: RobotModel,
        constraints: ConstraintSet,
        *,
        dt: float,
        theta: float = 0.5,
        solver: ProxsuiteLCPSolver | None = None,
        restitution_threshold: float = 0.0,
    ) -> None:
        self.robot = robot
        self.constraints = constraints
        self.dt = as_positive("dt", dt)
        self.theta = as_in_interval("theta", theta, 0.5, 1.0)
        self.solver = solver if solver is not None else ProxsuiteLCPSolver()
        self.restitution_threshold = as_float("restitution_threshold", restitution_threshold)
        if self.restitution_threshold < 0.0:
            raise InvalidParameterError("restitution_threshold", restitution_threshold, ">= 0")
        self._model = robot.model
        self._data = robot.model.createData()
        self._has_contacts = constraints.n_contacts > 0

    def evaluate(self, q: Vector, v: Vector) -> PlantEvaluation:
        """Dynamics, kinematics and constraint gaps at (q, v); prepares :meth:`step`."""
        model, data = self._model, self._data
        pin.computeAllTerms(model, data, q, v)
        if self._has_contacts:
            pin.updateFramePlacements(model, data)
        gap, normal_velocity = self.constraints.evaluate(data, q, v)
        return PlantEvaluation(
            q, v, gap, normal_velocity, data.kinetic_energy, data.potential_energy
        )

    def step(self, state: PlantEvaluation, tau: Vector) -> StepOutcome:
        """Advance one step from ``state`` (the last :meth:`evaluate`) under forces ``tau``.

        Args:
            state: The evaluation at the start of the step.
            tau: Generalized forces (actuation plus external), shape (nv,), in [N m] or [N].
        """
        model, data, h = self._model, self._data, self.dt
        pin.cholesky.decompose(model, data)
        v_free = state.v + h * pin.cholesky.solve(model, data, tau - data.nle)
        active = state.gap + (self.gamma * h) * state.normal_velocity <= 0.0
        indices = active.nonzero()[0]
        impulse = np.zeros(self.constraints.size)
        solution = None
        plastic = False
        if indices.size:
            J = self.constraints.jacobian(data, indices)
            if indices.size == 1:  # M⁻¹ Jᵀ by one triangular solve instead of M⁻¹
                Minv_Jt = pin.cholesky.solve(model, data, J[0])[:, None]
            else:
                Minv_Jt = pin.cholesky.computeMinv(model, data) @ J.T
            D = J.dot(Minv_Jt)
            u_free = J.dot(v_free)
            u_minus = state.normal_velocity[indices]
            restitution = self.constraints.restitution[indices]
            rebound = np.where(u_minus < -self.restitution_threshold, restitution * u_minus, 0.0)
            solution = self._solve(D, u_free + rebound)
            if rebound.any():
                # Kinetic energy given by the impulses, ½ Pᵀ(u_free + u⁺) [J]: never positive
                # for a plastic law or equal restitutions, it can be with unequal ones.
                u_plus = solution.velocity - rebound
                gain = 0.5 * solution.impulses.dot(u_free + u_plus)
                if gain > ENERGY_GAIN_TOLERANCE * (1.0 + state.kinetic_energy):
                    solution = self._solve(D, u_free)
                    plastic = True
            impulse[indices] = solution.impulses
            v_next = v_free + Minv_Jt.dot(solution.impulses)
        else:
            v_next = v_free
        q_next = pin.integrate(
            model, state.q, h * ((1.0 - self.theta) * state.v + self.theta * v_next)
        )
        return StepOutcome(q_next, v_next, impulse, active, solution, plastic=plastic)

    def _solve(self, D: Vector, b: Vector) -> ContactSolution:
        """The contact LCP (D, b), or :class:`SolverError` when it is not solved."""
        solution = self.solver.solve(D, b)
        if solution.status != "solved":
            raise SolverError(self.solver.name, solution.status, solution.residual)
        return solution
