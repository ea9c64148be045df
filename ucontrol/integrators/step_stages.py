r"""The rules of a Moreau–Jean step that every path of it applies, each written once.

A step (:mod:`ucontrol.integrators.moreau_jean`) is a list of named stages: free velocity,
active set, impact law (the offsets of the contact problem), contact problem, energy guard,
position update. This module holds the memory a step passes to the next
(:class:`StepMemory`) and the stages' rules as pure functions. The rules that the compiled
fast path (:mod:`ucontrol.integrators.compiled_free_step`) also applies, the impact law and
the energy guard, are written over an array namespace (:class:`ArrayOps`): numpy for the
readable reference, casadi's symbols for the generated code, so that both run the same
definition.

**Active set** (:func:`active_set`, :func:`is_active`). Constraint a is in the active set when
its predicted gap :math:`g_a + \gamma h u_a` is at most its entry of
:attr:`StepMemory.activation`: 0, or the
release gap :math:`\varepsilon_p + h u_p` (:func:`release_gap`) for a constraint that carried
an impulse in the last step (:func:`next_memory`). At the first step of a run, a constraint
closed at the start (gap at most :data:`START_GAP_TOLERANCE`) counts as held.

**Impacts** (:func:`is_impact`). A constraint has an impact in a step when it gets an impulse
and closes at the step's start faster than :data:`IMPACT_VELOCITY_THRESHOLD`, or faster than
:data:`HELD_IMPACT_VELOCITY` when the last step held it: the step's
:attr:`~ucontrol.plant.StepOutcome.impacts` and the logs'
:func:`~ucontrol.analysis.impacts.impact_mask` apply this one rule.

**Impact law** (:func:`newton_offsets`). Newton's restitution :math:`e_a u_a^-` on the closing
rows (:math:`u_a^- < -u_\text{th}`; every row with the ``"siconos"`` law), and the closure
:math:`g_a / h` of a held row still open (which gets no restitution).

**Energy guard** (:func:`impulse_energy_gain`, :func:`gains_energy`). The energy the impulses
add to the scheme's discrete energy over the step,
:math:`G = P^T\big(\tfrac12(u_\text{free} + u^+) - \theta(u_\text{free} - u_k)\big)`; a step
with restitution whose :math:`G` exceeds :data:`ENERGY_GAIN_TOLERANCE` :math:`(1 + T)` is
redone plastic (module docstring of :mod:`~ucontrol.integrators.moreau_jean`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

Vector = NDArray[np.float64]

#: Energy the restitution impulses of a step may add, relative to 1 + the kinetic energy in
#: [J], before the step is redone with a plastic law (e = 0).
ENERGY_GAIN_TOLERANCE = 1e-12
#: Gap in [m] (or [rad]) up to which a constraint counts as closed at the first step of a run.
START_GAP_TOLERANCE = 1e-9
#: A constraint closing faster than this at the start of a step, with an impulse in the step and
#: none in the last, has an impact, in [m/s] (or [rad/s] for stops); slower ones are persistent
#: contact.
IMPACT_VELOCITY_THRESHOLD = 1e-6
#: A constraint held by the last step has an impact only when it closes faster than this, in
#: [m/s] (or [rad/s]): a pressed foot pushed into the ground. A held contact otherwise closes
#: only its drift, at O(h) speeds (mm/s).
HELD_IMPACT_VELOCITY = 0.1
#: The active set's row as one number, where a step has one active row, else these (the
#: compiled free step's :meth:`~ucontrol.integrators.compiled_free_step.CompiledFreeStep.run`).
NO_ACTIVE_ROW, SEVERAL_ACTIVE_ROWS = -1.0, -2.0


class StepMemory(NamedTuple):
    """What one step leaves to the next, as one object.

    Attributes:
        activation: Largest predicted gap of each constraint in the active set, in [m] (or
            [rad]), shape (n,): the release gap (:func:`release_gap`) for those that carried
            an impulse in the last step, else 0.
        first: Whether the next step is the first of a run.
    """

    activation: Vector
    first: bool


def fresh_memory(n: int) -> StepMemory:
    """The memory at the start of a run of ``n`` constraints: nothing held, first step."""
    return StepMemory(np.zeros(n), True)


class ArrayOps(NamedTuple):
    """The elementwise operations the shared rules use, for one kind of array.

    Attributes:
        where: ``where(condition, x, y)``.
        logical_and: Elementwise and of two conditions.
        logical_or: Elementwise or of two conditions.
        dot: Inner product of two vectors.
    """

    where: Callable[[Any, Any, Any], Any]
    logical_and: Callable[[Any, Any], Any]
    logical_or: Callable[[Any, Any], Any]
    dot: Callable[[Any, Any], Any]


#: The rules on numpy arrays (the reference step).
NUMPY_OPS = ArrayOps(np.where, np.logical_and, np.logical_or, np.dot)


def predicted_gaps(gap: Any, normal_velocity: Any, horizon: Any) -> Any:
    r"""Gaps predicted ``horizon`` = γh [s] ahead, :math:`g + \gamma h u`, in [m] (or [rad])."""
    return gap + horizon * normal_velocity


def theta_displacement(v: Any, v_next: Any, h: Any, theta: Any) -> Any:
    r""":math:`\mathrm{h}\big((1 - \theta) v_k + \theta v_{k+1}\big)`, the step's displacement.

    The tangent vector the position update adds to :math:`q_k` (:math:`q_k \oplus` it), in the
    units of v times [s].
    """
    return h * ((1.0 - theta) * v + theta * v_next)


def release_gap(persistence_tolerance: float, persistence_speed: float, h: float) -> float:
    r"""Predicted gap :math:`\varepsilon_p + h u_p` up to which a held constraint stays active.

    A contact pressed through a step leaves it with a gap of the order of the step's drift,
    :math:`h^2 \dot q^T \nabla^2 g\, \dot q` (the velocity is constrained with :math:`J(q_k)`,
    the position follows the curved surface of constraint): 1.7 µm at h = 1 ms on the rimless
    wheel's stance spoke, 27 µm at 4 ms. The band :math:`h u_p` holds it while the normal
    velocity this drift amounts to, :math:`h \dot q^T \nabla^2 g\, \dot q`, is below
    :math:`u_p` (module docstring of :mod:`~ucontrol.integrators.moreau_jean`).

    Args:
        persistence_tolerance: :math:`\varepsilon_p` in [m] (or [rad]).
        persistence_speed: :math:`u_p` in [m/s] (or [rad/s]).
        h: Step in [s].

    Returns:
        The release gap in [m] (or [rad]); 0 when both are 0 (no persistence).
    """
    return persistence_tolerance + h * persistence_speed


def is_impact(impulse: Any, activation: Any, u_minus: Any) -> Any:
    r"""Whether a constraint has an impact in a step (elementwise on arrays).

    Args:
        impulse: Its normal impulse in the step in [N s] (or [N m s]).
        activation: Its entry of the last step's :attr:`StepMemory.activation` (> 0: held).
        u_minus: Its normal velocity at the start of the step in [m/s] (or [rad/s]).

    Returns:
        :math:`P_a > 0` and :math:`u_a^- < -`:data:`IMPACT_VELOCITY_THRESHOLD` (not held) or
        :math:`u_a^- < -`:data:`HELD_IMPACT_VELOCITY` (held): non-zero (true) where it holds.
        The conditions are combined by products (and) and sums (or), which numpy's booleans,
        Python's and casadi's symbols (the compiled step's) all have.
    """
    closing = (activation <= 0.0) * (u_minus < -IMPACT_VELOCITY_THRESHOLD)
    return (impulse > 0.0) * (closing + (u_minus < -HELD_IMPACT_VELOCITY))


def is_active(predicted: Any, activation: Any) -> Any:
    r"""Whether constraints are in a step's active set (elementwise), past the first step.

    Args:
        predicted: Predicted gaps :math:`g + \gamma h u` in [m] (or [rad]), shape (n,).
        activation: The last step's :attr:`StepMemory.activation`, shape (n,).
    """
    return predicted <= activation


def active_set(
    memory: StepMemory, gap: Vector, predicted: Vector, release: float
) -> tuple[NDArray[np.bool_], Vector]:
    r"""The active set of a step, and the activation thresholds it used.

    Args:
        memory: The memory of the last step.
        gap: Gaps at step k, shape (n,).
        predicted: Predicted gaps :math:`g + \gamma h u`, shape (n,).
        release: Predicted gap up to which a held constraint stays active
            (:func:`release_gap`).

    Returns:
        Which constraints are active, shape (n,), and the thresholds, shape (n,) (those of
        ``memory``, with the constraints closed at the start held at the first step).
    """
    activation = memory.activation
    if memory.first:
        closed = (gap <= START_GAP_TOLERANCE) & (predicted > activation)
        activation = activation.copy()
        activation[closed] = max(release, START_GAP_TOLERANCE)
    return is_active(predicted, activation), activation


def next_memory(
    impulse: Vector, rows: Sequence[int] | NDArray[np.intp], release: float
) -> StepMemory:
    """The memory after a step with normal ``impulse`` (n,): those with one are held.

    ``rows`` are the constraints of the step's active set, the only ones with an impulse (a
    few: a loop over them costs less than a pass over every constraint); ``release`` is the
    release gap (:func:`release_gap`) in [m] (or [rad]).
    """
    activation = np.zeros(impulse.size)
    for i in rows:
        if impulse[i] > 0.0:
            activation[i] = release
    return StepMemory(activation, False)


def newton_offsets(
    ops: ArrayOps,
    gap: Any,
    u_minus: Any,
    restitution: Any,
    held: Any,
    h: Any,
    threshold: float,
    siconos: bool,
    plastic: bool = False,
) -> tuple[Any, Any]:
    r"""Newton's restitution terms and the closures of a step's normal rows.

    Args:
        ops: The array operations (:data:`NUMPY_OPS`, or casadi's).
        gap: Gaps :math:`g_a` in [m], shape (m,).
        u_minus: Normal velocities :math:`u_a^-` at step k in [m/s], shape (m,).
        restitution: Newton's coefficients :math:`e_a`, shape (m,).
        held: Which rows carried an impulse in the last step (activation > 0), shape (m,).
        h: Step in [s].
        threshold: Closing speed below which no restitution applies, in [m/s].
        siconos: Restitution on every row (Siconos' convention), not only closing ones.
        plastic: Every ``restitution`` is 0 (known when the step is built): no rebound to
            compute.

    Returns:
        :math:`e_a u_a^-` on the closing rows not held open (0 elsewhere), and the closure
        :math:`g_a / h` on the held rows with a positive gap (0 elsewhere), in [m/s].
    """
    held_open = ops.logical_and(held, gap > 0.0)
    closure = ops.where(held_open, gap / h, 0.0)
    if plastic:  # e = 0 on every row: e u⁻ = 0
        return 0.0 * u_minus, closure
    no_rebound = held_open if siconos else ops.logical_or(held_open, u_minus >= -threshold)
    rebound = ops.where(no_rebound, 0.0, restitution * u_minus)
    return rebound, closure


def impulse_energy_gain(
    ops: ArrayOps, impulses: Any, u_free: Any, u_plus: Any, u_k: Any, theta: Any
) -> Any:
    r"""Energy :math:`G` in [J] that ``impulses`` add to :math:`T + V` over the step.

    :math:`G = P^T\big(\tfrac12(u_\text{free} + u^+) - \theta(u_\text{free} - u_k)\big)`: the
    kinetic part and the work of the step's smooth forces over the displacement the impulses
    cause; all velocities of the same rows in [m/s], impulses in [N s].
    """
    return ops.dot(impulses, 0.5 * (u_free + u_plus) - theta * (u_free - u_k))


def gains_energy(gain: Any, kinetic_energy: Any) -> Any:
    """Whether a step's impulses gain more than :data:`ENERGY_GAIN_TOLERANCE` (1 + T) [J]."""
    return gain > ENERGY_GAIN_TOLERANCE * (1.0 + kinetic_energy)
