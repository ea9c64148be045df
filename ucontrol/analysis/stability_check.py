r"""The a-priori weak-stability check of a Brogliato tracking cycle (book ch. 8, Lemma 8.1).

Before a run, :func:`check_scene` evaluates, for the scene's desired cycle and gains and for
each declared contact, the conditions under which the transition phase of the cycle ends as the
book's stability framework needs (docs/stability_check.md gives the derivation):

- ``jump_bound``: the jumps of V over the accumulation of impacts are bounded; the bound
  :math:`J = \tfrac12 \|s_q^+\|_M^2` is that of the first impact (approach velocity
  :math:`v_0`, restitution e), the later ones being :math:`-\tfrac12 (1 - e^2) m_n v_k^2 \le 0`;
- ``finite_accumulation``: along the contact normal the closed loop is
  :math:`\ddot x + c\dot x + kx = -g(t)`; its flights are followed exactly until the
  target rests at -d, after which the pull kd > 0 and the restitution e bound the remaining
  flights, so that the impacts accumulate within a computed :math:`t_\infty - t_0`;
- ``held_contacts_stay_closed`` (when another contact is in its constrained phase at this
  one's first impact): the impulse it takes and its force just after are positive;
- ``accumulation_before_takeoff``: :math:`t_0` + that bound + the rest time ends before the
  takeoff :math:`t_d`;
- ``positive_force``: the designed :math:`\lambda_d > 0` on the constrained phase
  :math:`[t_f, t_d)`.

The bounds are computed for the cycle tracked exactly up to :math:`\tau_0`
(:math:`V(\tau_0) = 0`, the depth of :math:`V_1(\tau_0)` given), along the contact normal with
the effective mass :math:`m_n = (J_n M^{-1} J_n^T)^{-1}` at the landing configuration. What
cannot be bounded a priori is listed in :attr:`StabilityCheck.not_computed`; after a run,
:func:`compare_with_run` sets the measured quantities
(:func:`~ucontrol.analysis.weak_stability.weak_stability`) beside the bounds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ucontrol.analysis.cycles import CYCLE_FIELDS, finite_or_none
from ucontrol.analysis.weak_stability import weak_stability
from ucontrol.control.desired_cycle import DesiredCycle
from ucontrol.control.path_reach import check_reach
from ucontrol.control.phase_machine import PhaseMachine
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.exceptions import InvalidParameterError
from ucontrol.log import Log

if TYPE_CHECKING:
    from ucontrol.contact.point_contact import PointContact
    from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]

#: Samples of the desired trajectory per second of the approach and the transition.
SAMPLES_PER_SECOND = 20000
#: Exit status of ``ucontrol check`` when a condition fails (2 is kept for bad input).
EXIT_CONDITION_FAILS = 1

#: What the check does not bound a priori (written with every check).
NOT_COMPUTED = (
    "the rise of V between the impacts of the transition (V is built on the target clipped "
    "at the surface while the law pulls towards the virtual target): measured after a run "
    "as transition_rise",
    "the departure of the contact force from lambda_d in the constrained phase, which "
    "depends on the tracking error left at t_f and, in discrete time, on how the controller "
    "measures the force over impact steps: measured after a run as min_constrained_force",
    "the jumps for V(tau0) > 0: the bounds are those of the cycle tracked exactly up to tau0",
)


class _Gains(Protocol):
    gamma1: float
    gamma2: float
    force_gain: float


class _Controller(Protocol):
    """What the check reads of a :class:`ucontrol.control.BrogliatoController`."""

    robot: RobotModel
    task: TaskCoordinates
    cycle: DesiredCycle
    gains: _Gains


class _Scene(Protocol):
    """What :func:`check_scene` reads of a :class:`ucontrol.scene.Scene` (read-only)."""

    @property
    def name(self) -> str: ...

    @property
    def robot(self) -> RobotModel: ...

    @property
    def contacts(self) -> tuple[PointContact, ...]: ...

    @property
    def controller(self) -> Mapping[str, Any]: ...

    @property
    def flexible(self) -> Any: ...

    @property
    def q0(self) -> Vector: ...

    def build_controller(self) -> Any: ...


@dataclass(frozen=True)
class Condition:
    """One condition of the check.

    Attributes:
        name: ``jump_bound``, ``finite_accumulation``, ``held_contacts_stay_closed`` (when
            other contacts are in their constrained phase at this one's first impact),
            ``accumulation_before_takeoff`` or ``positive_force``.
        holds: Whether it holds.
        value: The computed quantity (unit in ``statement``).
        limit: What it is compared with.
        statement: The condition in words, with its numbers.
        gains: The gains and cycle settings it depends on, by their scene keys.
    """

    name: str
    holds: bool
    value: float
    limit: float
    statement: str
    gains: dict[str, float]


@dataclass(frozen=True)
class ContactCheck:
    r"""The computed quantities of one declared contact (times in [s] from the run's start).

    Attributes:
        contact: Contact name.
        restitution: e of the contact.
        depth: Virtual depth d in [m] for the given :math:`V_1(\tau_0)`.
        tau0: :math:`\tau_0` of the first cycle.
        first_impact: :math:`t_0`, when the approach target crosses the surface.
        approach_velocity: :math:`v_0 < 0`, the target's normal velocity there, in [m/s].
        effective_mass: :math:`m_n` at the landing configuration in [kg].
        pull_min: Smallest pull towards the surface in [m/s²] of the tail bound: kd once
            the target rests, or :math:`g_{min}` over the remaining samples when the impacts
            accumulate before.
        pull_max: Largest one in [m/s²] (kd, or :math:`g_{max}`).
        rebound_ratio: Bound on the ratio of successive rebound velocities in the tail
            (e, or :math:`e\rho`).
        jump_bound: J in [J], bound on the sum of the jumps of V over the accumulation.
        accumulation_time_bound: Bound on :math:`t_\infty - t_0` in [s] (inf if none).
        takeoff: :math:`t_d` of the first cycle.
        min_desired_force: Smallest :math:`\lambda_d` on :math:`[t_f, t_d)` in [N].
        conditions: The conditions of this contact.
        held_impulses: Impulse [N s] of each contact held in its constrained phase at this
            contact's first impact (empty when none is held).
    """

    contact: str
    restitution: float
    depth: float
    tau0: float
    first_impact: float
    approach_velocity: float
    effective_mass: float
    pull_min: float
    pull_max: float
    rebound_ratio: float
    jump_bound: float
    accumulation_time_bound: float
    takeoff: float
    min_desired_force: float
    conditions: list[Condition]
    held_impulses: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class StabilityCheck:
    r"""The result of :func:`check_scene`.

    Attributes:
        scene: Scene name.
        gains: :math:`\gamma_1, \gamma_2, K_f` and the cycle settings used.
        V1_tau0: :math:`V_1(\tau_0)` in [J] that set the virtual depth.
        contacts: One record per declared contact.
        not_computed: What is not bounded a priori.
    """

    scene: str
    gains: dict[str, float]
    V1_tau0: float
    contacts: list[ContactCheck]
    not_computed: tuple[str, ...] = field(default=NOT_COMPUTED)

    @property
    def conditions(self) -> list[Condition]:
        """Every condition, contact after contact."""
        return [condition for contact in self.contacts for condition in contact.conditions]

    @property
    def holds(self) -> bool:
        """Whether every condition holds."""
        return all(condition.holds for condition in self.conditions)

    @property
    def failures(self) -> list[Condition]:
        """The conditions that fail."""
        return [condition for condition in self.conditions if not condition.holds]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (non-finite numbers as None)."""
        return {
            "scene": self.scene,
            "holds": self.holds,
            "gains": self.gains,
            "V1_tau0": self.V1_tau0,
            "contacts": [
                {
                    **{
                        key: _json(value)
                        for key, value in vars(contact).items()
                        if key != "conditions"
                    },
                    "conditions": [
                        {key: _json(value) for key, value in vars(c).items()}
                        for c in contact.conditions
                    ],
                }
                for contact in self.contacts
            ],
            "not_computed": list(self.not_computed),
        }

    def report(self) -> str:
        """Lines for a terminal: each condition, holds or FAILS, with its numbers."""
        lines = [
            f"{self.scene}: weak-stability check (book ch. 8, Lemma 8.1) with "
            + ", ".join(f"{key} = {value:g}" for key, value in self.gains.items())
        ]
        for contact in self.contacts:
            lines.append(
                f"  {contact.contact}: e = {contact.restitution:g}, d = {contact.depth:.4g} m, "
                f"t0 = {contact.first_impact:.4g} s, v0 = {contact.approach_velocity:.4g} m/s, "
                f"m_n = {contact.effective_mass:.4g} kg, t_d = {contact.takeoff:.4g} s"
            )
            for condition in contact.conditions:
                verdict = "holds" if condition.holds else "FAILS"
                gains = ", ".join(f"{key} = {value:g}" for key, value in condition.gains.items())
                lines.append(f"    {condition.name}: {verdict}: {condition.statement} [{gains}]")
        lines.append("  not bounded a priori (measured after a run):")
        lines.extend(f"    - {item}" for item in self.not_computed)
        return "\n".join(lines)


def check_scene(scene: _Scene, *, V1_tau0: float = 0.0) -> StabilityCheck:
    r"""Check the weak-stability conditions of a scene's Brogliato cycle before running it.

    Args:
        scene: A scene (:class:`ucontrol.scene.Scene`) whose controller is a rigid-joint
            ``brogliato`` one.
        V1_tau0: :math:`V_1(\tau_0)` in [J], >= 0, that sets the virtual depth (0: the cycle
            tracked exactly).

    Raises:
        InvalidParameterError: The scene's controller is not a rigid-joint Brogliato
            controller, or ``V1_tau0`` is negative or not finite.
        PathOutOfReachError: The landing point is out of the robot's reach.
    """
    kind = dict(scene.controller).get("type", "zero")
    if kind != "brogliato":
        raise InvalidParameterError(
            "[controller] type", kind, "'brogliato' (the check is that of its cycle)"
        )
    if scene.flexible is not None:
        raise InvalidParameterError(
            "[flexible]", "declared", "absent: the check covers the rigid-joint law only"
        )
    controller = scene.build_controller()
    restitutions = {contact.name: contact.restitution for contact in scene.contacts}
    return check_stability(
        controller, scene.robot, restitutions, scene.q0, name=scene.name, V1_tau0=V1_tau0
    )


def check_stability(
    controller: _Controller,
    plant: RobotModel,
    restitutions: Mapping[str, float],
    q_start: Vector,
    *,
    name: str = "",
    V1_tau0: float = 0.0,
) -> StabilityCheck:
    r"""The check of :func:`check_scene` on a controller and the plant it runs against.

    Args:
        controller: A :class:`ucontrol.control.BrogliatoController` (its robot, task, cycle
            and gains are read).
        plant: The plant's robot (its inertia sets the impacts).
        restitutions: Restitution coefficient of each declared contact, by contact name.
        q_start: Configuration from which the landing configuration is searched, (nq,).
        name: Scene name for the report.
        V1_tau0: :math:`V_1(\tau_0)` in [J], >= 0.

    Raises:
        InvalidParameterError: ``V1_tau0`` is negative or not finite.
    """
    V1_tau0 = float(V1_tau0)
    if not (math.isfinite(V1_tau0) and V1_tau0 >= 0.0):
        raise InvalidParameterError("V1_tau0", V1_tau0, "a finite value >= 0 in [J]")
    gains, cycle = controller.gains, controller.cycle
    settings = {
        "gamma1": float(gains.gamma1),
        "gamma2": float(gains.gamma2),
        "force_gain": float(gains.force_gain),
        "approach_time": cycle.approach_time,
        "depth_min": cycle.depth_min,
        "rest_time": cycle.rest_time,
    }
    contacts: dict[int, ContactCheck] = {}
    held: list[tuple[float, float, int, int]] = []  # (t_f bound, t_d, task row, contact)
    machine = PhaseMachine(controller.task, cycle)
    for i in sorted(range(len(cycle.contact_phases)), key=machine.approach_time):
        restitution = restitutions[cycle.contact_phases[i].contact]
        result = _check_contact(controller, plant, restitution, i, q_start, V1_tau0, held)
        contacts[i] = result
        t_f = result.first_impact + result.accumulation_time_bound + cycle.rest_time
        held.append((t_f, result.takeoff, int(machine.coordinates[i]), i))
    ordered = [contacts[i] for i in range(len(contacts))]
    return StabilityCheck(scene=name, gains=settings, V1_tau0=V1_tau0, contacts=ordered)


def _check_contact(
    controller: _Controller,
    plant: RobotModel,
    restitution: float,
    i: int,
    q_start: Vector,
    V1_tau0: float,
    held: Sequence[tuple[float, float, int, int]] = (),
) -> ContactCheck:
    """The quantities and conditions of declared contact ``i`` in the first cycle.

    ``held`` lists the (t_f bound, t_d, task row, contact) of the contacts checked before: those in
    their constrained phase at this contact's first impact stay closed through its impacts.
    """
    task, cycle, gains = controller.task, controller.cycle, controller.gains
    gamma1, gamma2, e = float(gains.gamma1), float(gains.gamma2), float(restitution)
    machine = PhaseMachine(task, cycle)
    j = int(machine.coordinates[i])
    tau0, t_d = machine.approach_time(i), machine.takeoff_time(i)
    closed = np.zeros(len(machine.contacts), dtype=bool)
    machine.update(tau0, closed, V1_tau0, machine.desired(tau0))
    depth = float(machine.depth[i])
    t, samples = _samples(machine, tau0, t_d)
    x_d = samples[:, 0, j]
    crossing = np.flatnonzero(x_d <= 0.0)
    contact = cycle.contact_phases[i].contact
    used = {"gamma1": gamma1, "gamma2": gamma2, "depth": depth, "restitution": e}
    if crossing.size == 0:  # the approach never reaches the surface
        condition = Condition(
            "jump_bound",
            False,
            float(x_d.min()),
            0.0,
            f"the approach target never reaches the surface before t_d = {t_d:.4g} s "
            f"(lowest gap {x_d.min():.3g} m)",
            {"approach_time": cycle.approach_time, "depth": depth},
        )
        return ContactCheck(
            contact, e, depth, tau0, math.nan, math.nan, math.nan, math.nan, math.nan,
            math.nan, math.inf, math.inf, t_d, math.nan, [condition],
        )  # fmt: skip
    k0 = int(crossing[0])
    t0, X0, v0 = float(t[k0]), samples[k0, 0].copy(), float(samples[k0, 1, j])
    X0[j] = 0.0
    q_land = _landing_configuration(controller, plant, X0, t0, q_start)
    kept = [(contact, row) for t_f, t_off, row, contact in held if t_f < t0 < t_off]
    rows = [row for _, row in kept]
    m_n, jump, held_impulses, s_jump, J = _impact(controller, plant, q_land, j, v0, e, rows)
    reduced = _ReducedNormal(gamma1 / m_n, gamma2, e, t[k0:], samples[k0:, :, j])
    bound, g_min, g_max, ratio = reduced.accumulation_bound(t0, v0, tau0 + cycle.approach_time)
    conditions = [
        Condition(
            "jump_bound",
            math.isfinite(jump),
            jump,
            math.inf,
            f"sum of the jumps of V over the accumulation <= J = {jump:.4g} J (first impact at "
            f"v0 = {v0:.4g} m/s; each later one -(1 - e²) m_n v_k²/2 <= 0)",
            {"gamma1": gamma1, "gamma2": gamma2, "restitution": e},
        ),
        Condition(
            "finite_accumulation",
            math.isfinite(bound),
            bound,
            math.inf,
            (
                f"the impacts accumulate within t_inf - t0 <= {bound:.4g} s (flights followed "
                f"exactly, then a pull towards the surface >= {g_min:.4g} m/s² and a rebound "
                f"ratio <= {ratio:.4g} bound the rest)"
                if math.isfinite(bound)
                else "no finite accumulation is guaranteed: the pull towards the surface "
                f"falls to {g_min:.4g} m/s² and a rebound does not land before t_d "
                f"(rebound ratio {ratio:.4g}); raise gamma1, gamma2 or the virtual depth"
            ),
            used,
        ),
    ]
    if rows:
        forces = _held_forces(controller, plant, q_land, J, rows, s_jump, t0, kept)
        names = ", ".join(task.names[row] for row in rows)
        stays_closed = bool(held_impulses.min() >= 0.0 and forces.min() > 0.0)
        conditions.append(
            Condition(
                "held_contacts_stay_closed",
                stays_closed,
                float(forces.min()),
                0.0,
                f"the first impact keeps {names} (in its constrained phase) closed: impulse "
                f"{', '.join(f'{p:.4g}' for p in held_impulses)} N s >= 0 and force just after "
                f"it {', '.join(f'{f:.4g}' for f in forces)} N > 0"
                + ("" if stays_closed else "; it opens, and the bounds above assume it does not"),
                {"gamma1": gamma1, "force_gain": float(gains.force_gain), "restitution": e},
            )
        )
    t_f = t0 + bound + cycle.rest_time
    conditions.append(
        Condition(
            "accumulation_before_takeoff",
            t_f < t_d,
            t_f,
            t_d,
            f"t_f <= t0 + {bound:.4g} s + rest_time = {t_f:.4g} s < t_d = {t_d:.4g} s",
            {**used, "rest_time": cycle.rest_time},
        )
    )
    min_force = _min_desired_force(cycle, i, t_f, t_d)
    conditions.append(
        Condition(
            "positive_force",
            min_force > 0.0,
            min_force,
            0.0,
            f"designed lambda_d > 0 on [t_f, t_d): smallest {min_force:.4g} N"
            if t_f < t_d
            else "no constrained phase is guaranteed (t_f is not bounded before t_d)",
            {"force": cycle.contact_phases[i].force, "force_fall_time": cycle.force_fall_time},
        )
    )
    return ContactCheck(
        contact, e, depth, tau0, t0, v0, m_n, g_min, g_max, ratio, jump, bound, t_d,
        min_force, conditions, held_impulses.tolist(),
    )  # fmt: skip


def _samples(machine: PhaseMachine, start: float, stop: float) -> tuple[Vector, Vector]:
    """Times (N,) and desired position, velocity, acceleration (N, 3, m) on [start, stop)."""
    t = np.arange(start, stop, 1.0 / SAMPLES_PER_SECOND)
    return t, np.array([machine.desired(float(time)).target for time in t])


def _landing_configuration(
    controller: _Controller, plant: RobotModel, X: Vector, t0: float, q_start: Vector
) -> Vector:
    """A configuration whose task coordinates are ``X`` (m,): the landing, by inverse kinematics.

    The world point is the nominal one at ``t0`` moved along the task directions to ``X``.
    """
    task = controller.task
    nominal = controller.cycle.path(t0)[0]
    point = nominal + np.linalg.pinv(task.A) @ (X + task.b - task.A @ nominal)  # [m]
    return check_reach(_Point(point), plant, task.frame, q_start, samples=1)[0]


@dataclass(frozen=True)
class _Point:
    """A constant path at ``point`` (3,), for :func:`check_reach`."""

    point: Vector
    period: float = 1.0

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        zero = np.zeros(3)
        return self.point, zero, zero

    def derivatives(self, t: float, order: int) -> tuple[Vector, ...]:
        return (self.point, *([np.zeros(3)] * order))


def _held_forces(
    controller: _Controller,
    plant: RobotModel,
    q: Vector,
    J: Vector,
    rows: Sequence[int],
    s_jump: Vector,
    t0: float,
    kept: Sequence[tuple[int, int]],
) -> Vector:
    r"""Contact forces [N] of the held rows just after another contact's first impact, (h,).

    On the held rows s = 0 and :math:`\dot s = 0`, so the closed loop
    :math:`\bar M\dot s + \bar C s + \gamma_1 s = (1 + K_f)(\lambda - \lambda_d)` gives
    :math:`\lambda_h = \lambda_{d,h} - \bar M_{hF}\bar M_{FF}^{-1}\gamma_1 s_F / (1 + K_f)`
    with F the other rows, where s is the jump of the impact (C̄ s neglected) and
    :math:`\bar M = (J M^{-1} J^T)^{-1}`.
    """
    gains, cycle = controller.gains, controller.cycle
    M_task = np.linalg.inv(J @ np.linalg.solve(plant.mass_matrix(q), J.T))  # [kg]
    free = [row for row in range(J.shape[0]) if row not in rows]
    s_dot = -np.linalg.solve(M_task[np.ix_(free, free)], float(gains.gamma1) * s_jump[free])
    push = M_task[np.ix_(list(rows), free)] @ s_dot / (1.0 + float(gains.force_gain))  # [N]
    machine = PhaseMachine(controller.task, cycle)
    desired = np.array(
        [cycle.desired_force(cycle.contact_phases[i], t0, machine.takeoff_time(i)) for i, _ in kept]
    )
    return desired + push


def _impact(
    controller: _Controller,
    plant: RobotModel,
    q: Vector,
    j: int,
    v0: float,
    e: float,
    held: Sequence[int] = (),
) -> tuple[float, float, Vector, Vector, Vector]:
    r"""Effective mass, V after the first impact, held impulses, jump of s, task Jacobian.

    Returns :math:`m_n` [kg], V [J], the held rows' impulses [N s] (h,), the jump
    :math:`J\Delta\dot q` of the task velocity, so of s on the (unclipped) target [m/s] (m,),
    and J (m, nv) at ``q``.

    Before it the robot tracks the target exactly; after it V is built on the reference
    clipped at the surface: :math:`s_q^+ = J^+ e_j v_0 + \Delta\dot q`,
    :math:`\Delta\dot q = -(1 + e) W J_n^T m_n v_0` (Newton's law on the plant), with
    :math:`m_n = (J_n W J_n^T)^{-1}` and W the plant's inverse inertia :math:`M^{-1}`, or, with
    the task rows ``held`` closed through the impact, :math:`M^{-1}` restricted to their
    tangent space: :math:`W = M^{-1} - M^{-1} J_h^T (J_h M^{-1} J_h^T)^{-1} J_h M^{-1}`; the
    impulses the held rows then take, :math:`P_h = -(J_h M^{-1} J_h^T)^{-1} J_h M^{-1} J_n^T P_n`
    (shape (h,)), must be >= 0 for them to stay closed.
    """
    task = controller.task
    J = task.A @ plant.frame_jacobian(q, task.frame)[:3]  # (m, nv)
    J_n = J[j]
    W = np.linalg.inv(plant.mass_matrix(q))  # [1/kg], mixed units
    held_impulses = np.zeros(0)
    if held:
        J_h = J[list(held)]
        W_Jt = W @ J_h.T
        coupling = np.linalg.solve(J_h @ W_Jt, W_Jt.T)  # (J_h W J_h^T)^-1 J_h W, (h, nv)
        W = W - W_Jt @ coupling
    m_n = 1.0 / float(J_n @ W @ J_n)  # [kg]
    impulse = -(1.0 + e) * m_n * v0  # P_n > 0 [N s]
    if held:  # what the held rows must take for their velocity to stay 0: -(...)^-1 J_h W J_n^T P_n
        held_impulses = -(coupling @ J_n) * impulse  # [N s]
    jump_velocity = (W @ J_n) * impulse  # [rad/s]
    J_pinv = np.linalg.solve(J @ J.T, J).T
    s_q = J_pinv[:, j] * v0 + jump_velocity
    M = controller.robot.mass_matrix(q)
    return m_n, float(0.5 * s_q @ M @ s_q), held_impulses, J @ jump_velocity, J


class _ReducedNormal:
    r"""The closed loop along the contact normal: :math:`\ddot x + c\dot x + kx = -g(t)`.

    With :math:`a = \gamma_1/m_n`, :math:`c = a + \gamma_2`, :math:`k = a\gamma_2` and the
    pull :math:`g = -(\ddot x_d + c\dot x_d + k x_d)` of the target :math:`x_d`; Newton's law
    :math:`\dot x^+ = -e\dot x^-` at x = 0. Between impacts :math:`\tilde x = x - x_d` is
    explicit: :math:`s = \dot{\tilde x} + \gamma_2\tilde x = s_0 e^{-a\tau}` and
    :math:`\tilde x = \tilde x_0 e^{-\gamma_2\tau} + s_0 (e^{-a\tau} - e^{-\gamma_2\tau})
    /(\gamma_2 - a)`.

    Args:
        a: :math:`\gamma_1/m_n` in [1/s].
        gamma2: :math:`\gamma_2` in [1/s].
        e: Restitution.
        t: Sample times from the first impact to the takeoff, (N,) [s].
        target: :math:`x_d` and its two derivatives there, (N, 3).
    """

    def __init__(self, a: float, gamma2: float, e: float, t: Vector, target: Vector) -> None:
        self.a, self.gamma2, self.e = a, gamma2, e
        self.c, self.k = a + gamma2, a * gamma2
        self.t, self.target = t, target
        self.pull = -(target[:, 2] + self.c * target[:, 1] + self.k * target[:, 0])  # [m/s²]

    def accumulation_bound(self, t0: float, v0: float, t_rest: float) -> tuple[float, ...]:
        r"""Bound on :math:`t_\infty - t_0` [s], the pull's extremes [m/s²], the rebound ratio.

        The flights are followed exactly (on the samples) up to the first impact after
        ``t_rest``, when the target is at rest at -d; from there the rebound velocities fall
        at least by e per impact (:math:`\tfrac12\dot x^2 + \tfrac12 k (x + d)^2` does not
        increase in flight) under a pull >= kd, and :meth:`_tail` bounds the rest. Impacts
        that accumulate before ``t_rest`` are bounded the same way with the pull's extremes
        over the remaining samples. inf when a flight does not end before the last sample.
        """
        t, x_d = self.t, self.target[:, 0]
        time, u, index = t0, self.e * abs(v0), 0
        while time < t_rest:
            landing = self._landing(index, u)
            if landing is None:  # the contact leaves for the rest of the window
                return math.inf, float(self.pull.min()), float(self.pull.max()), math.inf
            next_index, velocity = landing
            if next_index - index < 3:  # accumulated between two samples: bound the rest
                return self._bounded_tail(time, index, u)
            index, time, u = next_index, float(t[next_index]), self.e * abs(velocity)
        g = self.k * -float(x_d[-1])  # kd [m/s²]
        if not g > 0.0:
            return math.inf, g, g, self.e
        return time - t0 + _tail(u, g, self.c, self.e), g, g, self.e

    def _bounded_tail(self, time: float, index: int, u: float) -> tuple[float, ...]:
        r"""The bound once the impacts accumulate at sample ``index``, before the target rests.

        Over a window of W seconds the pull lies in :math:`[g_{min}, g_{max}]`; if the flights
        bounded with those values (rebound ratio :math:`e\sqrt{(g_{max} + kH)/g_{min}}`) end
        within W, every one of them starts and ends in the window, so the bound holds. W
        doubles from 1 ms until it does, or the samples run out (inf).
        """
        window, rate = 1e-3, 1.0 / float(self.t[1] - self.t[0])  # [s], samples per [s]
        g_min = g_max = ratio = math.nan
        while True:
            stop = index + int(window * rate) + 1
            pull = self.pull[index:stop]
            g_min, g_max = float(pull.min()), float(pull.max())
            if g_min > 0.0:
                height = u**2 / (2.0 * g_min)  # [m]
                ratio = self.e * math.sqrt((g_max + self.k * height) / g_min)
                if ratio < 1.0:
                    tail = _tail(u, g_min, self.c, ratio)
                    if tail <= window:
                        return time - float(self.t[0]) + tail, g_min, g_max, ratio
            if stop >= self.pull.size:
                return math.inf, g_min, g_max, ratio
            window *= 2.0

    def _landing(self, index: int, u: float) -> tuple[int, float] | None:
        """Sample and velocity [m/s] of the landing of a flight launched at ``u`` [m/s].

        The flight starts from sample ``index``; None if it does not land by the last sample.
        """
        t, (x_d, v_d) = self.t, (self.target[:, 0], self.target[:, 1])
        tau = t[index:] - t[index]  # [s]
        x0, s0 = -x_d[index], u - v_d[index] - self.gamma2 * x_d[index]  # x̃ and s at launch
        a, g2 = self.a, self.gamma2
        decay_s, decay_x = np.exp(-a * tau), np.exp(-g2 * tau)
        if abs(g2 - a) > 1e-9 * max(a, g2):
            mix = (decay_s - decay_x) / (g2 - a)
        else:
            mix = tau * decay_x
        x_tilde = x0 * decay_x + s0 * mix
        x = x_d[index:] + x_tilde
        below = np.flatnonzero(x[1:] <= 0.0)
        if below.size == 0:
            return None
        k = int(below[0]) + 1
        velocity = v_d[index + k] - g2 * x_tilde[k] + s0 * decay_s[k]
        return index + k, float(velocity)


def _tail(u: float, g: float, c: float, ratio: float) -> float:
    r"""Bound in [s] on the flights launched at :math:`u\,r^n`, n >= 0 (:math:`r` = ``ratio``).

    Each flight under a pull >= g and damping c lasts at most :func:`_flight_time`; below
    :math:`10^{-12} u` the flights are bounded by :math:`T_s(u) = u/g + t^*(u^2/2g)`, whose
    ratio to u does not decrease with u, so their sum by :math:`T_s(u_N)/(1 - r)`.
    """
    total, speed = 0.0, u
    while speed > 1e-12 * u:
        total += _flight_time(speed, g, c)
        speed *= ratio
    return total + _flight_time(speed, g, c, damped_rise=False) / (1.0 - ratio)


def _flight_time(u: float, g: float, c: float, *, damped_rise: bool = True) -> float:
    r"""Bound in [s] on a flight launched at ``u`` [m/s] under a pull >= g [m/s²], damping c [1/s].

    The rise lasts at most :math:`\tau_r = \ln(1 + cu/g)/c` to at most
    :math:`H = (u - g\tau_r)/c` (:math:`\ddot x \le -g - c\dot x`); the descent covers at
    least :math:`D(t) = \frac{g}{c}(t - \frac{1 - e^{-ct}}{c})` in t, so it lasts at most the
    root of :math:`D(t) = H`. Without ``damped_rise``: at most u/g to :math:`u^2/2g`.
    """
    if u <= 0.0:
        return 0.0
    if damped_rise:
        y = c * u / g
        rise = math.log1p(y) / c  # [s]
        height = g / c**2 * _minus_log1p(y)  # (u - g rise) / c [m]
    else:
        rise, height = u / g, u**2 / (2.0 * g)

    def covered(time: float) -> float:
        return g / c**2 * _plus_expm1(c * time)  # [m]

    low, high = 0.0, max(math.sqrt(2.0 * height / g), 1e-300)
    while covered(high) < height:
        high *= 2.0
    for _ in range(100):  # bisection to the float resolution of the root
        mid = 0.5 * (low + high)
        low, high = (mid, high) if covered(mid) < height else (low, mid)
    return rise + high


def _minus_log1p(y: float) -> float:
    r""":math:`y - \ln(1 + y)` for y >= 0, by its series where it cancels."""
    if y < 1e-3:
        return y**2 / 2 - y**3 / 3 + y**4 / 4 - y**5 / 5
    return y - math.log1p(y)


def _plus_expm1(x: float) -> float:
    """:math:`x + e^{-x} - 1` for x >= 0, by its series where it cancels."""
    if x < 1e-3:
        return x**2 / 2 - x**3 / 6 + x**4 / 24 - x**5 / 120
    return x + math.expm1(-x)


def _min_desired_force(cycle: DesiredCycle, i: int, t_f: float, t_d: float) -> float:
    r"""Smallest designed :math:`\lambda_d` [N] on :math:`[t_f, t_d)` (sampled), NaN if empty."""
    if not t_f < t_d:
        return math.nan
    phase = cycle.contact_phases[i]
    t = np.arange(t_f, t_d, 1.0 / SAMPLES_PER_SECOND)
    return min(cycle.desired_force(phase, float(time), t_d) for time in t)


def compare_with_run(check: StabilityCheck, log: Log) -> dict[str, Any]:
    """The check's bounds beside the quantities measured on a run, cycle by cycle.

    Args:
        check: The check of the scene that ran.
        log: The run's log (a Brogliato controller's, same declared contacts).

    Returns:
        :meth:`StabilityCheck.to_dict` with, under ``measured``, for each contact the bounds
        and per cycle the measured values of :func:`weak_stability` and whether each bound held
        (JSON-ready; ``ucontrol check SCENE --run DIR`` writes it under ``stability_check`` in
        ``DIR/summary.json``).

    Raises:
        InvalidParameterError: The log is not that of a Brogliato controller with the
            check's contacts.
    """
    names = [contact.contact for contact in check.contacts]
    logged = log.metadata.get("controller_contacts")
    if not CYCLE_FIELDS <= set(log.fields) or logged != names:
        raise InvalidParameterError(
            "log", f"a run with contacts {logged}", f"a run of a Brogliato controller on {names}"
        )
    report = weak_stability(log)
    contacts = []
    for i, contact in enumerate(check.contacts):
        cycles = []
        for cycle in report.cycles:
            measured = {
                "impact_jumps": cycle.contact_impact_jumps[i],
                "accumulation_time": cycle.accumulation_time[i],
                "first_impact_velocity": cycle.first_impact_velocity[i],
                "min_constrained_force": cycle.min_constrained_force[i],
            }
            cycles.append(
                {
                    "index": cycle.index,
                    "V_tau0": cycle.V_tau0,
                    **{key: _json(value) for key, value in measured.items()},
                    "jump_bound_holds": cycle.contact_impact_jumps[i] <= contact.jump_bound,
                    "accumulation_bound_holds": _at_most(
                        measured["accumulation_time"], contact.accumulation_time_bound
                    ),
                    "force_positive": _positive(measured["min_constrained_force"]),
                }
            )
        contacts.append(
            {
                "contact": contact.contact,
                "jump_bound": _json(contact.jump_bound),
                "accumulation_time_bound": _json(contact.accumulation_time_bound),
                "approach_velocity": _json(contact.approach_velocity),
                "min_desired_force": _json(contact.min_desired_force),
                "cycles": cycles,
            }
        )
    return {**check.to_dict(), "measured": contacts}


def _at_most(value: float, bound: float) -> bool | None:
    return None if math.isnan(value) else value <= bound


def _positive(value: float) -> bool | None:
    return None if math.isnan(value) else value > 0.0


def _json(value: Any) -> Any:
    if isinstance(value, float):
        return finite_or_none(value)
    if isinstance(value, Sequence) and not isinstance(value, str):
        return [_json(item) for item in value]
    if isinstance(value, dict):
        return {key: _json(item) for key, item in value.items()}
    return value
