"""The closed loop: plant + controller (zero-order hold) + log."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol._validation import as_positive, as_vector
from ucontrol.analysis.summary import summarize
from ucontrol.control.controller import ContactState, Controller, LoggingController
from ucontrol.exceptions import (
    InitialPenetrationError,
    InvalidParameterError,
    ShapeError,
    SimulationError,
    UControlError,
)
from ucontrol.log import SOLVED, UNSOLVED, Log
from ucontrol.scene import Scene

#: Largest initial penetration accepted, in [m] (or [rad] for stops).
PENETRATION_TOLERANCE = 1e-9
#: Runs of at least this many steps show a progress bar when ``progress`` is None.
PROGRESS_MIN_STEPS = 20_000
#: With an output directory, the log is rewritten at least this often, in [s] of wall time.
CHECKPOINT_PERIOD_S = 10.0


@dataclass(frozen=True)
class SimulationResult:
    """A finished run.

    Attributes:
        log: Every sample.
        summary: Figures of merit (see :func:`ucontrol.analysis.summarize`).
        out: The output directory, if one was given.
    """

    log: Log
    summary: dict[str, Any]
    out: Path | None


def simulate(
    scene: Scene,
    controller: Controller | None = None,
    duration: float | None = None,
    *,
    dt: float | None = None,
    control_period: float | None = None,
    out: str | Path | None = None,
    progress: bool | None = None,
    observer: Callable[[Log], None] | None = None,
) -> SimulationResult:
    """Run ``scene`` in closed loop with ``controller`` for ``duration`` seconds.

    Args:
        scene: The plant, its initial state and its default settings.
        controller: Called as ``controller(t, q, v, contacts)``; default the scene's. A
            :class:`~ucontrol.control.LoggingController` also adds its own fields to the log.
            With flexible joints q and v hold the motor coordinates after the links' (the
            log keeps them apart: ``q``, ``v`` and ``motor_q``, ``motor_v``).
        duration: Simulated time in [s]; default the scene's.
        dt: Time step in [s]; default the scene's integrator step.
        control_period: Controller period in [s] (zero-order hold); default every step.
            Rounded to a whole number of steps.
        out: Directory for ``log.npz`` and ``summary.json``; the log is also checkpointed there
            during long runs and saved when a run fails or is interrupted (Ctrl-C).
        progress: Show a progress bar; default for runs of at least 20 000 steps.
        observer: Called with the log each time a row is complete (after every step and
            at the end), e.g. a live viewer (:class:`ucontrol.viz.live_viewer.LiveViewer`);
            its last row is the newest.

    Raises:
        InitialPenetrationError: The initial configuration violates a constraint.
        SimulationError: The run failed part-way; its ``log`` holds every sample up to then.
    """
    integrator = scene.build_integrator(dt=dt)
    h = integrator.dt
    duration = as_positive("duration", scene.duration if duration is None else duration)
    hold = (
        1
        if control_period is None
        else max(1, round(as_positive("control_period", control_period) / h))
    )
    controller = scene.build_controller() if controller is None else controller
    robot, constraints, flexible = scene.robot, integrator.constraints, scene.flexible
    q, v = scene.initial_state()  # motors after the links with flexible joints
    gap0 = constraints.gaps(scene.q0)
    if gap0.size and gap0.min() < -PENETRATION_TOLERANCE:
        worst = int(np.argmin(gap0))
        raise InitialPenetrationError(
            constraints.names[worst], float(gap0[worst]), PENETRATION_TOLERANCE
        )

    n_steps = max(1, math.ceil(duration / h - 1e-9))
    log = Log(
        n_steps + 1,
        nq=robot.nq,
        nv=robot.nv,
        nu=robot.nu,
        constraint_names=constraints.names,
        metadata={
            "scene": scene.name,
            "integrator": integrator.name,
            "dt": h,
            "theta": integrator.theta,
            "control_period": hold * h,
            "actuated": robot.actuated.tolist(),
        },
    )
    if scene.source is not None:
        log.metadata["scene_path"] = str(scene.source)
    recorder = controller if isinstance(controller, LoggingController) else None
    if recorder is not None:
        recorder.prepare_log(log)
    if constraints.has_friction:  # world friction impulse of each constraint [N s]
        log.add_field("friction_impulse", (constraints.size, 3))
    actuated = robot.actuated
    if flexible is not None:  # motor states, beside the links' q and v
        log.add_field("motor_q", (flexible.nf,))
        log.add_field("motor_v", (flexible.nf,))
        log.metadata["flexible_joints"] = list(flexible.joints)
        log.metadata["motor_inputs"] = flexible.input_index.tolist()
        actuated = flexible.input_coordinates(actuated)
    out_dir = Path(out) if out is not None else None
    bar = _progress_bar(n_steps, progress)
    contacts_zero = np.zeros(constraints.size)
    inactive = np.zeros(constraints.size, dtype=bool)
    impulse, active = contacts_zero, inactive
    period_impulse, period_active, period_steps = np.zeros(constraints.size), inactive.copy(), 0
    tau = np.zeros(v.size)
    u = np.zeros(robot.nu)
    start = last_checkpoint = time.perf_counter()
    k, row_open, n_events, n_plastic = 0, False, 0, 0
    try:
        for k in range(n_steps + 1):
            t = k * h
            state = integrator.evaluate(q, v)
            log.record_state(
                t,
                q[: robot.nq],
                v[: robot.nv],
                state.gap,
                state.normal_velocity,
                state.kinetic_energy + state.potential_energy,
            )
            if flexible is not None:
                log.record_extra("motor_q", q[robot.nq :])
                log.record_extra("motor_v", v[robot.nv :])
            row_open = True
            if k == n_steps:
                break
            if k % hold == 0:
                if hold > 1:  # what happened over the control period that ends now
                    impulse, active = period_impulse.copy(), period_active.copy()
                    span = max(period_steps, 1) * h
                    period_impulse[:], period_active[:], period_steps = 0.0, False, 0
                else:
                    span = h
                contacts = ContactState(
                    constraints.names, state.gap, state.normal_velocity, impulse, active, span
                )
                output = _as_array(controller(t, q, v, contacts))
                if output.shape != (robot.nu,):
                    raise ShapeError("controller output u", (robot.nu,), output.shape)
                u = output
                tau[actuated] = u
            if recorder is not None:
                recorder.record(log)
            outcome = integrator.step(state, tau)
            solution = outcome.solution
            if outcome.friction_impulse is not None:
                log.record_extra("friction_impulse", outcome.friction_impulse)
            if solution is None:
                log.record_step(u, outcome.impulse, outcome.active, 0, 0.0)
            else:
                log.record_step(
                    u,
                    outcome.impulse,
                    outcome.active,
                    solution.iterations,
                    solution.residual,
                    solution.solve_time_s,
                    SOLVED if solution.status == "solved" else UNSOLVED,
                    solution.outer_iterations,
                )
            row_open = False
            if observer is not None:
                observer(log)
            q, v, impulse, active = outcome.q, outcome.v, outcome.impulse, outcome.active
            if hold > 1:
                period_impulse += impulse
                period_active |= active
                period_steps += 1
            n_events += outcome.events
            n_plastic += outcome.plastic
            if not math.isfinite(float(q.sum() + v.sum() + u.sum())):
                as_vector("controller output u", u)  # names the culprit if it is the controller
                raise _NonFiniteState(f"the state became non-finite at t = {t + h:.6g} s")
            if k % 1000 == 0:
                if bar is not None:
                    bar.update(min(1000, n_steps - bar.n))
                if (
                    out_dir is not None
                    and time.perf_counter() - last_checkpoint > CHECKPOINT_PERIOD_S
                ):
                    log.save(out_dir / "log.npz")
                    last_checkpoint = time.perf_counter()
        if recorder is not None:
            recorder.record(log)
        log.record_step(u, contacts_zero, inactive, 0, 0.0)
        if observer is not None:
            observer(log)
    except KeyboardInterrupt:  # the user's Ctrl-C: keep what ran, then stop as asked
        if row_open:
            log.record_step(u, contacts_zero, inactive, 0, 0.0)
        if out_dir is not None:
            log.save(out_dir / "log.npz")
        raise
    except (UControlError, _NonFiniteState, np.linalg.LinAlgError) as error:
        if row_open:  # the state at t_k is stored, its step is not: close the row
            log.record_step(u, contacts_zero, inactive, 0, 0.0)
        failure = SimulationError(float(log.t[-1]) if len(log) else 0.0, k, str(error), log)
        if out_dir is not None:
            failure.log_path = str(log.save(out_dir / "log.npz"))
        raise failure from error
    finally:
        if bar is not None:
            bar.close()
    wall_time = time.perf_counter() - start
    summary = summarize(log, wall_time_s=wall_time, theta=integrator.theta)
    summary["n_events"] = n_events  # located by event-driven integrators; 0 otherwise
    summary["n_plastic_steps"] = n_plastic  # Moreau–Jean steps whose restitution added energy
    if out_dir is not None:
        log.save(out_dir / "log.npz")
        (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return SimulationResult(log, summary, out_dir)


class _NonFiniteState(ArithmeticError):
    """Internal signal: the state left the finite numbers."""


def _as_array(value: Any) -> np.ndarray:
    """A controller's output as a float array, or a typed error naming it."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError("controller output u", value, "a vector of numbers") from error


def _progress_bar(n_steps: int, progress: bool | None) -> Any:
    if progress is False or (progress is None and n_steps < PROGRESS_MIN_STEPS):
        return None
    from tqdm import tqdm

    return tqdm(total=n_steps, unit="step", unit_scale=True, desc="simulate")
