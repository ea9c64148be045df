r"""Consistency of design model and plant: the designed torques replayed open-loop.

The torques of a :class:`~ucontrol.design.DesignedCycle` are held over each control interval
(zero-order hold, as in the design) in the event-driven integrator
(:class:`ucontrol.integrators.EventDriven`: solve_ivp between events, gap and release events,
Newton's impact law, the plastic threshold ``zeno_velocity``) from the cycle's initial state,
and the plant's states at the control nodes are compared with the design's. The design's
states differ from the plant's by the RK4 error of the design grid (order 4 in the substep)
and the plant's integration tolerances.

An impact time of the plant is found from its state at the start of the step holding it: the
free motion under the held torque is integrated (``solve_ivp``, DOP853, on Pinocchio's
dynamics) to the root of the gap. A landing at a speed :math:`|u^-|` fixes its time only to
:math:`\delta t \approx \delta g / |u^-|` for a gap error :math:`\delta g`: soft landings
(the plastic ones of a contact with e > 0) have ill-conditioned times by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol.design.design_task import DesignTask
from ucontrol.design.designed_cycle import DesignedCycle
from ucontrol.integrators.event_driven import EventDriven

Vector = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class ReplayResult:
    """The plant's states at the design's nodes and their differences.

    Attributes:
        t: Node times in [s], shape (n,).
        q: Plant's joint positions at the nodes, shape (n, nv).
        v: Plant's joint velocities at the nodes, shape (n, nv).
        q_error: Largest absolute difference of plant and design joint positions over the
            nodes and joints, in [rad] (or [m]).
        v_error: Largest absolute difference of the velocities over the nodes that are not
            impacts, in [rad/s].
        impact_times: Plant's impact times of the contact in [s], one per design impact
            (NaN for a soft landing, slower than 100 ``zeno_velocity``: its time is
            ill-conditioned).
        impact_time_errors: Absolute differences of plant and design impact times in [s]
            (NaN for soft landings).
        landing_speeds: Design's normal speed before each impact in [m/s].
    """

    t: Vector
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    q_error: float
    v_error: float
    impact_times: Vector
    impact_time_errors: Vector
    landing_speeds: Vector


def replay_open_loop(
    task: DesignTask,
    cycle: DesignedCycle,
    *,
    restart: bool = False,
    rtol: float = 100 * np.finfo(float).eps,
    atol: float = 1e-15,
) -> ReplayResult:
    """Replay the designed torques open-loop in the event-driven integrator.

    Args:
        task: The task the cycle was designed for (its scene is the plant).
        cycle: The designed cycle.
        restart: Start every control interval from the design's node state (the defect of
            each interval, as multiple shooting sees it) instead of the plant's state (one
            open-loop run from takeoff, where errors grow with the open-loop instability).
        rtol: Relative tolerance of the plant's solve_ivp; default its floor, 100 machine
            epsilons: the arm under held torques amplifies an error by about 1e7 over the
            two-link flight, so a whole-cycle replay needs every step at rounding.
        atol: Absolute tolerance of the plant's solve_ivp.
    """
    scene = task.scene
    robot = scene.robot
    constraints = scene.constraints
    first = cycle.phases[0]
    integrator = EventDriven(
        robot,
        constraints,
        dt=first.duration / (len(first.t) - 1),
        rtol=rtol,
        atol=atol,
        zeno_velocity=task.zeno_velocity,
    )
    q, v = first.q[0].copy(), first.v[0].copy()
    times, qs, vs = [first.t[0]], [q.copy()], [v.copy()]
    q_error, v_error = 0.0, 0.0
    contact = task.contact
    speeds = [
        -_normal_velocity(robot, contact, phase.q[-1], phase.v[-1]) for phase in cycle.phases[:-1]
    ]
    # a soft landing (slower than 100 zeno_velocity) has no well-conditioned time: not timed
    timed = [speed > 100.0 * task.zeno_velocity for speed in speeds]
    impact_times = [np.nan] * len(speeds)
    for p, phase in enumerate(cycle.phases):
        h = phase.duration / (len(phase.t) - 1)
        integrator.dt = h  # the control period of this phase
        for k in range(len(phase.t) - 1):
            if restart:
                q, v = phase.q[k].copy(), phase.v[k].copy()
            state = integrator.evaluate(q, v)
            outcome = integrator.step(state, phase.tau[k])
            last = k == len(phase.t) - 2 and p < len(speeds)
            if last and timed[p]:  # the step ending at the design's impact
                impact_times[p] = _impact_time(robot, contact, q, v, phase.tau[k], phase.t[k], h)
            q, v = outcome.q, outcome.v
            times.append(phase.t[k + 1])
            qs.append(q.copy())
            vs.append(v.copy())
            q_error = max(q_error, float(np.max(np.abs(q - phase.q[k + 1]))))
            at_impact = k == len(phase.t) - 2 and p < len(cycle.phases) - 1
            if not at_impact:
                v_error = max(v_error, float(np.max(np.abs(v - phase.v[k + 1]))))
    design_times = cycle.impact_times
    return ReplayResult(
        t=np.array(times),
        q=np.array(qs),
        v=np.array(vs),
        q_error=q_error,
        v_error=v_error,
        impact_times=np.array(impact_times),
        impact_time_errors=np.abs(np.array(impact_times) - design_times),
        landing_speeds=np.array(speeds),
    )


def _gap(robot, contact, q: Vector) -> float:  # type: ignore[no-untyped-def]
    p = robot.frame_position(q, contact.frame)
    return float(contact.surface.normal @ (p - contact.surface.point) - contact.radius)


def _normal_velocity(robot, contact, q: Vector, v: Vector) -> float:  # type: ignore[no-untyped-def]
    J = robot.frame_jacobian(q, contact.frame)[:3]
    return float(contact.surface.normal @ (J @ v))


def _impact_time(robot, contact, q0: Vector, v0: Vector, tau: Vector, t0: float, h: float) -> float:  # type: ignore[no-untyped-def]
    """Root of the gap of the free motion from (q0, v0) under ``tau``, within the step [s]."""
    nv = robot.nv
    model, data = robot.model, pin.Data(robot.model)

    def rate(_: float, y: Vector) -> Vector:
        return np.concatenate((y[nv:], pin.aba(model, data, y[:nv], y[nv:], tau)))

    def gap(_: float, y: Vector) -> float:
        return _gap(robot, contact, y[:nv])

    gap.terminal = True  # type: ignore[attr-defined]
    gap.direction = -1.0  # type: ignore[attr-defined]
    solution = solve_ivp(
        rate,
        (0.0, 2.0 * h),
        np.concatenate((q0, v0)),
        method="DOP853",
        rtol=100 * np.finfo(float).eps,
        atol=1e-15,
        events=gap,
    )
    if solution.t_events[0].size:
        return float(t0 + solution.t_events[0][0])
    return float(t0 + h)
