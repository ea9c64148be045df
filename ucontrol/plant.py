"""What every integrator shares: the plant's evaluation at a state, the outcome of a step.

An integrator (Moreau–Jean, event-driven, compliant) is used the same way by the closed loop
(:func:`ucontrol.simulate`): :meth:`Integrator.evaluate` at :math:`(q_k, v_k)` gives the
gaps, normal velocities and energies the controller and the log need, then
:meth:`Integrator.step` advances under the generalized forces held over the step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.solvers.contact_solution import ContactSolution

if TYPE_CHECKING:
    from ucontrol.contact.compiled_rows import ConstraintRows

Vector = NDArray[np.float64]


class PlantEvaluation(NamedTuple):
    """Everything the plant knows at the start of a step, at (q_k, v_k).

    Attributes:
        q: Configuration, shape (nq,) (nq + nf with flexible joints: motors last).
        v: Velocity, shape (nv,) (nv + nf with flexible joints).
        gap: Constraint gaps, shape (n,).
        normal_velocity: Constraint velocities ``J v``, shape (n,).
        kinetic_energy: In [J], motors included.
        potential_energy: Gravitational plus the joint springs' elastic energy, in [J].
        t: Time of the evaluation in [s], or None when it was not given (constraints that do
            not depend on time).
        normal_rows: The constraints' normal Jacobian rows J at q, shape (n, nv), when they
            were computed with the gaps (:class:`~ucontrol.contact.compiled_rows.ConstraintRows`),
            else None.
    """

    q: Vector
    v: Vector
    gap: Vector
    normal_velocity: Vector
    kinetic_energy: float
    potential_energy: float
    t: float | None = None
    normal_rows: Vector | None = None


def evaluate_plant(
    data: pin.Data,
    constraints: ConstraintSet,
    flexible: FlexibleJoints | None,
    q: Vector,
    v: Vector,
    *,
    frames: bool = True,
    t: float | None = None,
    rows: ConstraintRows | None = None,
) -> PlantEvaluation:
    """All dynamics terms, constraint gaps, normal velocities and energies at (q, v).

    Runs ``pin.computeAllTerms`` (and the frame placements when ``frames``) on ``data`` at the
    links' state; with flexible joints (q, v) are the extended state and the energies include
    the motors and the springs. ``t`` [s] is required when the constraints depend on time
    (moving surfaces: :attr:`ConstraintSet.time_dependent`). With ``rows`` (the compiled
    constraints of ``constraints``) the gaps, normal velocities and normal rows come from one
    compiled call instead of the frame placements.
    """
    model = constraints.robot.model
    if flexible is None and rows is not None:
        return evaluate_rigid_rows(model, data, rows, q, v, t)
    if flexible is None:
        q1, v1 = q, v
    else:  # the links' state, and the motors'
        q1, v1, q2, v2 = flexible.split(q, v)
    pin.computeAllTerms(model, data, q1, v1)
    normal_rows = None
    if rows is not None:
        gap, normal_velocity, normal_rows = rows(q1, v1)
    else:
        if frames:
            pin.updateFramePlacements(model, data)
        gap, normal_velocity = constraints.evaluate(data, q1, v1, t)
    kinetic, potential = data.kinetic_energy, data.potential_energy
    if flexible is not None:  # the motors' kinetic and the springs' elastic energy
        kinetic += flexible.motor_kinetic_energy(v2)
        potential += flexible.spring_energy(q1, q2)
    return PlantEvaluation(q, v, gap, normal_velocity, kinetic, potential, t, normal_rows)


def evaluate_rigid_rows(
    model: pin.Model, data: pin.Data, rows: ConstraintRows, q: Vector, v: Vector, t: float | None
) -> PlantEvaluation:
    """:func:`evaluate_plant` of a rigid robot whose constraints are compiled ``rows``.

    Its shortest path, for the closed loop: ``pin.computeAllTerms`` and one compiled call, or
    the compiled call alone when the rows carry the dynamics
    (:meth:`~ucontrol.contact.compiled_rows.ConstraintRows.bind_dynamics` to ``data``: then
    ``data`` holds M and h only).
    """
    if rows.dynamics:
        gap, normal_velocity, normal_rows = rows(q, v)
        kinetic, potential = rows.energies()
    else:
        pin.computeAllTerms(model, data, q, v)
        gap, normal_velocity, normal_rows = rows(q, v)
        kinetic, potential = data.kinetic_energy, data.potential_energy
    return PlantEvaluation(q, v, gap, normal_velocity, kinetic, potential, t, normal_rows)


class StepOutcome(NamedTuple):
    """The result of one step from a :class:`PlantEvaluation`.

    Attributes:
        q: Configuration at the end of the step, shape (nq,) (nq + nf with flexible joints).
        v: Velocity at the end of the step, shape (nv,) (nv + nf with flexible joints).
        impulse: Normal impulse of each constraint over the step in [N s], shape (n,).
        active: Which constraints were in the active set, shape (n,).
        solution: The contact solve, or None when the active set was empty.
        plastic: Whether Newton's law was replaced by a plastic one (e = 0) in this step,
            because the restitution impulses would have added energy.
        events: Events located within the step (impacts, contact closures and releases) by
            event-driven integrators; 0 for time-stepping, which locates none.
        friction_impulse: Friction impulse of each constraint over the step in world
            coordinates, in [N s], shape (n, 3) (on the first sphere of a sphere–sphere
            contact, the opposite on the second), or None when the constraints have no
            friction.
        impacts: The step's impacts as (constraint index, time in [s]) pairs, in the order
            found: the located impact times of event-driven integration (within the step), the
            contact onsets of compliant integration, and the step's start time t_k for a
            constraint that a Moreau–Jean step closes with an impulse (time-stepping locates no
            impact: its resolution is the step h). Times count from the evaluation's ``t``
            (0 when it has none); empty (the shared ``()``) for a step without impacts.
    """

    q: Vector
    v: Vector
    impulse: Vector
    active: NDArray[np.bool_]
    solution: ContactSolution | None
    events: int = 0
    plastic: bool = False
    friction_impulse: Vector | None = None
    impacts: tuple[tuple[int, float], ...] = ()


class Integrator(Protocol):
    """How time advances: the interface the closed loop relies on.

    Attributes:
        name: The integrator's name in logs and scene files.
        dt: Step (or sampling period) h in [s].
        theta: θ of the position update (1/2 where the integrator has none), used to
            measure the energy a step's impulses add.
        constraints: The unilateral constraints it enforces.
    """

    name: str
    dt: float
    theta: float
    constraints: ConstraintSet

    def evaluate(self, q: Vector, v: Vector, t: float | None = None) -> PlantEvaluation:
        """Dynamics, kinematics and constraint gaps at (q, v) and time t; prepares :meth:`step`.

        ``t`` [s] is required when the constraints depend on time (the closed loop passes it
        then), and may be omitted otherwise.
        """
        ...

    def step(self, state: PlantEvaluation, tau: Vector) -> StepOutcome:
        """Advance one step from ``state`` under generalized forces ``tau``, shape (nv,)."""
        ...
