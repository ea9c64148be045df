"""The closed loop: plant + controller (zero-order hold) + log.

The module is callable: ``ucontrol.simulate(scene, ...)`` is :func:`simulate`, whether
``from ucontrol import simulate`` finds this module (imported before) or the function.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import time
import types
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_positive, as_vector
from ucontrol.analysis.energy_balance import step_work, work_of
from ucontrol.analysis.impacts import impact_cells, impact_mask, impacts_of
from ucontrol.analysis.summary import summarize
from ucontrol.control.controller import ContactState, Controller, LoggingController
from ucontrol.exceptions import (
    BilateralResidualWarning,
    EnergyGainWarning,
    InitialPenetrationError,
    InvalidParameterError,
    PenetrationWarning,
    PhysicsWarning,
    PlasticRedoWarning,
    ShapeError,
    SimulationError,
    SolverIterationCapWarning,
    UControlError,
)
from ucontrol.log import NO_SOLVE, SOLVED, UNSOLVED, Log
from ucontrol.model.robot_model import RobotModel
from ucontrol.output_files import OutputLock, check_output_dir, write_atomically
from ucontrol.scene import Scene
from ucontrol.scene.scene_data import BILATERAL_TOLERANCE

if TYPE_CHECKING:
    from ucontrol.contact.bilateral import BilateralSet
    from ucontrol.contact.constraint_set import ConstraintSet
    from ucontrol.plant import Integrator, PlantEvaluation, StepOutcome

#: Largest initial penetration accepted, in [m] (or [rad] for stops).
PENETRATION_TOLERANCE = 1e-9
#: Runs of at least this many steps show a progress bar when ``progress`` is None.
PROGRESS_MIN_STEPS = 20_000
#: With an output directory, the log is rewritten at least this often, in [s] of wall time.
CHECKPOINT_PERIOD_S = 10.0
#: Largest rise of the energy over steps without impact, net of the actuators' work, as a
#: fraction of 1 J + the largest absolute energy of the run; beyond it a run warns
#: (:class:`~ucontrol.exceptions.EnergyGainWarning`). The built-in scenes stay below 2e-3
#: (``four_bar``, ``free_ball`` at their dt; docs/outputs.md).
ENERGY_GAIN_BOUND = 1e-2


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
        progress: Show a progress bar; default for runs of at least 20 000 steps when standard
            error is a terminal.
        observer: Called with the log each time a row is complete (after every step and
            at the end), e.g. a live viewer (:class:`ucontrol.viz.live_viewer.LiveViewer`);
            its last row is the newest.

    Raises:
        InitialPenetrationError: The initial configuration violates a constraint.
        SimulationError: The run failed part-way; its ``log`` holds every sample up to then.
        KeyboardInterrupt: Ctrl-C; it carries ``time`` (the last sample's, in [s]) and, with
            ``out``, ``log_path`` (the log written up to then).
    """
    _check_arguments(scene, controller, progress, observer)
    out_dir = None if out is None else check_output_dir("out", out)
    integrator = scene.build_integrator(dt=dt)
    h = integrator.dt
    duration = as_positive("duration", scene.duration if duration is None else duration)
    hold = 1 if control_period is None else _hold_steps(control_period, h)
    controller = scene.build_controller() if controller is None else controller
    _check_initial_penetration(integrator.constraints, scene.q0)
    n_steps = _step_count(scene, duration, h)
    if scene.sensors is not None:
        scene.sensors.check_delay(-(-n_steps // hold))  # control periods of the run
    loop = _ClosedLoop(scene, integrator, controller, n_steps + 1, hold, observer)
    log = loop.log
    lock = None if out_dir is None else OutputLock(out_dir)
    if lock is not None:
        lock.acquire()
    bar = _progress_bar(n_steps, progress)
    start = last_checkpoint = time.perf_counter()
    cpu_start = time.process_time()
    k = 0
    try:
        loop.share_plant_data()
        pushed = bool(loop.pushes)  # (a scene without pushes skips the call)
        sample, control, advance = loop.sample, loop.control, loop.advance  # the stages
        for k in range(n_steps):
            if pushed:
                loop.push(k)
            t = k * h  # [s]
            state = sample(t)
            if k % hold == 0:
                control(t, state)
            advance(state)
            if k % 1000 == 0:
                last_checkpoint = _report_progress(bar, k + 1, log, out_dir, last_checkpoint)
        k = n_steps
        loop.push(n_steps)
        loop.sample(n_steps * h)
        loop.finish()
        if bar is not None:
            bar.update(n_steps - bar.n)
        times = (time.perf_counter() - start, time.process_time() - cpu_start)
        summary = _run_summary(scene, loop, times, interrupted=None)
        if out_dir is not None:
            log.save(out_dir / "log.npz")
            _write_summary(out_dir, summary)
    except KeyboardInterrupt as interrupt:  # Ctrl-C (or a signal): keep what ran, then stop
        loop.close_row()
        interrupt.time = float(log.t[len(log) - 1]) if len(log) else 0.0  # type: ignore[attr-defined]
        if out_dir is not None:
            interrupt.log_path = str(log.save(out_dir / "log.npz"))  # type: ignore[attr-defined]
            signum = int(getattr(interrupt, "signum", signal.SIGINT))
            interrupted = signal.Signals(signum).name
            with warnings.catch_warnings():  # the one line of the interruption says it all
                warnings.simplefilter("ignore", PhysicsWarning)
                times = (time.perf_counter() - start, time.process_time() - cpu_start)
                summary = _run_summary(scene, loop, times, interrupted)
            _write_summary(out_dir, summary)
        raise
    except (UControlError, _NonFiniteState, np.linalg.LinAlgError) as error:
        loop.close_row()  # the state at t_k is stored, its step is not: close the row
        failure = SimulationError(float(log.t[-1]) if len(log) else 0.0, k, str(error), log)
        if out_dir is not None:
            failure.log_path = str(log.save(out_dir / "log.npz"))
        raise failure from error
    finally:
        loop.release()
        if bar is not None:
            bar.close()
        if lock is not None:
            lock.release()
    return SimulationResult(log, summary, out_dir)


class _ClosedLoop:
    """What a run carries from step to step, and the stages of one step.

    A step k samples the plant at t_k (:meth:`sample`, which opens the log row), lets the
    controller choose the input at the start of each control period (:meth:`control`), then
    advances the plant under the held input (:meth:`advance`, which closes the row).

    Args:
        scene: The scene run (its initial state, robot and flexible joints).
        integrator: The scene's integrator.
        controller: The controller in the loop.
        capacity: Rows of the log, in samples.
        hold: Steps per control period.
        observer: Called with the log each time a row is complete, or None.
    """

    def __init__(
        self,
        scene: Scene,
        integrator: Integrator,
        controller: Controller,
        capacity: int,
        hold: int,
        observer: Callable[[Log], None] | None,
    ) -> None:
        self.integrator, self.controller, self.hold, self.observer = (
            integrator,
            controller,
            hold,
            observer,
        )
        robot, flexible, size = scene.robot, scene.flexible, integrator.constraints.size
        self.nq, self.nv, self.nu, self.flexible = robot.nq, robot.nv, robot.nu, flexible
        self.recorder = controller if isinstance(controller, LoggingController) else None
        self.log = _new_log(scene, integrator, self.recorder, capacity, hold)
        self.actuated = (
            robot.actuated if flexible is None else flexible.input_coordinates(robot.actuated)
        )
        self.q, self.v = scene.initial_state()  # motors after the links with flexible joints
        self.u = np.zeros(robot.nu)
        self.u_sum = 0.0
        self.tau = np.zeros(self.v.size)
        # The input is tau itself when it acts on every velocity coordinate, in order.
        self.tau_is_u = bool(np.array_equal(self.actuated, np.arange(self.v.size)))
        self.no_impulse = np.zeros(size)
        self.none_active = np.zeros(size, dtype=bool)
        # The last step's impulses and active set, and their sums over the control period.
        self.impulse, self.active = self.no_impulse, self.none_active
        self.period_impulse, self.period_active, self.period_steps = (
            np.zeros(size),
            self.none_active.copy(),
            0,
        )
        self.row_open = False
        self.n_events = 0
        self.n_plastic = 0
        period = hold * integrator.dt
        self.sensors = self.actuators = None
        if scene.sensors is not None:  # what the controller sees, imported only when declared
            from ucontrol.sensors.measurement import Sensors

            believed = getattr(controller, "robot", None)  # the momentum observer's model
            self.sensors = Sensors(
                scene.sensors,
                robot,
                _measured_geometry(scene, integrator.constraints),
                flexible,
                period,
                believed if isinstance(believed, RobotModel) else None,
            )
        if scene.actuators is not None:
            from ucontrol.sensors.actuators import Actuators

            self.actuators = Actuators(scene.actuators, robot, period)
        self.measured_q, self.measured_v, self.commanded_u = self.q, self.v, self.u
        self.plant_model = robot.model
        # The scene's velocity changes by sample index (the links' coordinates come first).
        self.pushes: dict[int, NDArray[np.float64]] = {}
        for push in scene.pushes:
            k = push.sample(integrator.dt)
            self.pushes[k] = self.pushes.get(k, np.zeros(robot.nv)) + push.velocity
        self.shares_plant_data = False
        self.names, self.dt = integrator.constraints.names, integrator.dt
        # The controller sees the plant's own state and its output acts as it is: the rows
        # need only its own fields.
        self.direct = self.sensors is None and self.actuators is None

    def share_plant_data(self) -> None:
        """Let the controller read M and h from the plant's evaluation, where that is exact.

        When it sees the plant's own state (no sensors, rigid joints) and has a model equal to
        the plant's (not, e.g., a perturbed plant in a campaign or a controller's believed
        masses): each controller call follows the plant's evaluation at that state
        (:meth:`sample`). :meth:`release` undoes it.
        """
        use = getattr(self.controller, "use_plant_data", None)
        own = getattr(getattr(self.controller, "robot", None), "model", None)
        if use is None or not isinstance(own, pin.Model):
            return
        if own is not self.plant_model and own != self.plant_model:  # Pinocchio's equality
            return
        if self.sensors is None and self.flexible is None:
            # (read only to share it: reading it makes the plant fill the whole data)
            data = getattr(self.integrator, "evaluation_data", None)
            if data is not None:
                self.shares_plant_data = bool(use(data))

    def release(self) -> None:
        """Give the controller back its own Pinocchio data (the end of the run)."""
        if self.shares_plant_data:
            self.controller.use_plant_data(None)  # type: ignore[attr-defined]
            self.shares_plant_data = False

    def push(self, k: int) -> None:
        """Add the pushes of sample k to the velocity (the scene's ``[[pushes]]``)."""
        change = self.pushes.get(k)
        if change is not None:
            self.v = self.v.copy()
            self.v[: self.nv] += change

    def sample(self, t: float) -> PlantEvaluation:
        """Evaluate the plant at t [s] and open the log row of that sample."""
        state = self.integrator.evaluate(self.q, self.v, t)
        energy = state.kinetic_energy + state.potential_energy
        if not math.isfinite(energy):
            raise _NonFiniteState(f"the energy became non-finite ({energy}) at t = {t:.6g} s")
        log, q, v = self.log, self.q, self.v
        if self.flexible is None:
            log.record_state(t, q, v, state.gap, state.normal_velocity, energy)
        else:  # the links' coordinates, then the motors'
            log.record_state(
                t, q[: self.nq], v[: self.nv], state.gap, state.normal_velocity, energy
            )
            log.record_extra("motor_q", q[self.nq :])
            log.record_extra("motor_v", v[self.nv :])
        self.row_open = True
        return state

    def control(self, t: float, state: PlantEvaluation) -> None:
        """The controller's input at t [s], held until the next control period."""
        if self.hold > 1:  # what happened over the control period that ends now
            impulse, active = self.period_impulse.copy(), self.period_active.copy()
            span = max(self.period_steps, 1) * self.dt
            self.period_impulse[:], self.period_active[:], self.period_steps = 0.0, False, 0
        else:
            impulse, active, span = self.impulse, self.active, self.dt
        contacts = ContactState(self.names, state.gap, state.normal_velocity, impulse, active, span)
        q, v = self.q, self.v
        if self.sensors is not None:
            q, v, contacts = self.sensors.measure(q, v, contacts, t, self.tau)
            self.measured_q, self.measured_v = q, v
        output = self.controller(t, q, v, contacts)
        if type(output) is not np.ndarray or output.dtype != np.float64:
            output = _as_array(output)
        if output.shape != (self.nu,):
            raise ShapeError("controller output u", (self.nu,), output.shape)
        self.commanded_u = output
        self.u = output if self.actuators is None else self.actuators.apply(output)
        # The input's part of the finiteness check (a sum of Python floats: fewer calls).
        self.u_sum = sum(self.u.tolist())
        if self.tau_is_u:
            self.tau = self.u
        else:
            self.tau[self.actuated] = self.u

    def advance(self, state: PlantEvaluation) -> None:
        """One plant step from ``state`` under the held input; closes the log row."""
        log = self.log
        if not self.direct:
            self._record_controller_fields()
        elif self.recorder is not None:  # the controller's own fields
            self.recorder.record(log)
        outcome = self.integrator.step(state, self.tau)
        if outcome.solution is None and outcome.friction_impulse is None and not outcome.impacts:
            log.record_step_without_solve(self.u, outcome.impulse, outcome.active)
        else:
            _record_step(log, self.u, outcome)
        self.row_open = False
        if self.observer is not None:
            self.observer(log)
        self.q, self.v, self.impulse, self.active = outcome[:4]  # (q, v, impulse, active)
        if self.hold > 1:
            self.period_impulse += outcome.impulse
            self.period_active |= outcome.active
            self.period_steps += 1
        self.n_events += outcome.events
        self.n_plastic += outcome.plastic
        # One finiteness check per step: a non-finite entry makes the sum non-finite.
        if not math.isfinite(sum(self.q.tolist()) + sum(self.v.tolist()) + self.u_sum):
            as_vector("controller output u", self.u)  # names the culprit if it is the controller
            t = float(log.t[len(log) - 1]) + self.dt
            raise _NonFiniteState(f"the state became non-finite at t = {t:.6g} s")

    def _record_controller_fields(self) -> None:
        """The controller's own fields, and what it measured and commanded, in the open row."""
        if self.recorder is not None:
            self.recorder.record(self.log)
        if self.sensors is not None:
            self.log.record_extra("measured_q", self.measured_q)
            self.log.record_extra("measured_v", self.measured_v)
            self.sensors.record_observer(self.log)
        if self.actuators is not None:
            self.log.record_extra("commanded_u", self.commanded_u)

    def close_row(self) -> None:
        """Close an open log row as a step without impulses (the end, or a failure)."""
        if self.row_open:
            self.log.record_step_without_solve(self.u, self.no_impulse, self.none_active)
            self.row_open = False

    def finish(self) -> None:
        """Complete the last row: the controller's fields, no step after it."""
        self._record_controller_fields()
        self.close_row()
        if self.observer is not None:
            self.observer(self.log)


def _run_summary(
    scene: Scene, loop: _ClosedLoop, times: tuple[float, float], interrupted: str | None
) -> dict[str, Any]:
    """The summary of the rows of ``loop.log``, ``interrupted`` by that signal or None.

    Args:
        scene: The scene run.
        loop: The closed loop, its last row closed.
        times: Wall time and CPU time (the process's) of the loop in [s].
        interrupted: The signal's name (``"SIGINT"`` for Ctrl-C) for a run stopped early,
            None for a run to its end.
    """
    log = loop.log
    wall_time, cpu_time = times
    theta = loop.integrator.theta
    impacts, work = impact_mask(log), step_work(log, theta)  # shared by summary and checks
    summary = summarize(
        log, wall_time_s=wall_time, cpu_time_s=cpu_time, theta=theta, impacts=impacts, work=work
    )
    summary["n_events"] = loop.n_events  # located by event-driven integrators; 0 otherwise
    summary["n_plastic_steps"] = loop.n_plastic  # Moreau–Jean steps redone plastic
    summary["interrupted"] = interrupted is not None
    summary["interrupted_by"] = interrupted
    _report_physics(scene, log, summary, impacts=impacts, work=work)
    return summary


def _write_summary(out_dir: Path, summary: dict[str, Any]) -> None:
    text = (json.dumps(summary, indent=2) + "\n").encode()
    write_atomically(out_dir / "summary.json", lambda stream: _write(stream, text))


def _write(stream: IO[bytes], data: bytes) -> None:
    stream.write(data)


def _report_progress(
    bar: Any, done: int, log: Log, out_dir: Path | None, last_checkpoint: float
) -> float:
    """Show ``done`` steps on the progress bar and checkpoint the log when one is due.

    Returns:
        The wall time [s] (``time.perf_counter``) of the last checkpoint.
    """
    if bar is not None:
        bar.update(done - bar.n)
    if out_dir is None or time.perf_counter() - last_checkpoint <= CHECKPOINT_PERIOD_S:
        return last_checkpoint
    log.save(out_dir / "log.npz")
    return time.perf_counter()


#: Largest log a run may allocate, in [bytes]: a longer run is refused before it starts.
MAX_LOG_BYTES = 8 * 2**30


def _check_arguments(scene: Any, controller: Any, progress: Any, observer: Any) -> None:
    """Typed errors for arguments of the wrong kind (before anything is built)."""
    if not isinstance(scene, Scene):
        raise InvalidParameterError("scene", scene, "a Scene (e.g. ucontrol.load_scene(path))")
    if controller is not None and not callable(controller):
        raise InvalidParameterError("controller", controller, "callable(t, q, v, contacts)")
    if observer is not None and not callable(observer):
        raise InvalidParameterError("observer", observer, "callable(log) or None")
    if progress not in (None, True, False):
        raise InvalidParameterError("progress", progress, "True, False or None")


def _step_count(scene: Scene, duration: float, h: float) -> int:
    """Steps of a run, refused when its log would not fit in :data:`MAX_LOG_BYTES`."""
    steps = max(1, math.ceil(duration / h - 1e-9))
    robot, n = scene.robot, scene.constraints.size
    row_bytes = 8 * (8 + 2 * robot.nq + 2 * robot.nv + robot.nu + 5 * n)  # [bytes], about
    if steps * row_bytes > MAX_LOG_BYTES:
        need = steps * row_bytes / 2**30
        raise InvalidParameterError(
            "duration",
            duration,
            f"at most {MAX_LOG_BYTES * h / row_bytes:.4g} s at dt = {h:g} s (duration / dt = "
            f"{steps:.4g} steps would need {need:.4g} GiB of log)",
        )
    return steps


def _report_physics(
    scene: Scene,
    log: Log,
    summary: dict[str, Any],
    *,
    impacts: NDArray[np.bool_] | None = None,
    work: NDArray[np.float64] | None = None,
) -> None:
    """Warnings, and summary entries, for what a run should not have done silently.

    Args:
        scene: The scene run.
        log: The run's log.
        summary: The run's summary, completed in place.
        impacts: ``impact_mask(log)``, shape (N, n), or None to compute it.
        work: ``step_work(log)`` in [J], shape (N - 1,), or None to compute it.
    """
    tolerance = scene.integrator.penetration_tolerance
    beyond = log.gap < -tolerance
    summary["penetration_tolerance"] = tolerance
    summary["n_penetrations_beyond_tolerance"] = int(beyond.sum())
    if beyond.any():
        row, column = np.unravel_index(int(np.argmin(log.gap)), log.gap.shape)
        warnings.warn(
            PenetrationWarning(
                log.constraint_names[column],
                float(-log.gap[row, column]),
                float(log.t[row]),
                tolerance,
            ),
            stacklevel=4,
        )
    restitutions = scene.constraints.restitution
    plastic = summary.get("n_plastic_steps", 0)
    if plastic and restitutions.size and np.all(restitutions == 1.0):
        warnings.warn(PlasticRedoWarning(plastic), stacklevel=4)
    dt = float(log.t[1] - log.t[0]) if len(log) > 1 else 0.0  # the run's step [s]
    pushed = [push.sample(dt) for push in scene.pushes] if dt > 0.0 else []
    _report_energy_gain(log, summary, pushed, impacts_of(log, impacts), work_of(log, None, work))
    if scene.constraints.bilateral is not None:
        _report_bilateral(scene.constraints.bilateral, log, summary)
    if summary.get("integrator") == "moreau_jean":
        _report_iteration_cap(scene.integrator.max_iter, log, summary)


def _report_energy_gain(
    log: Log,
    summary: dict[str, Any],
    pushed: list[int],
    impacts: NDArray[np.bool_],
    work: NDArray[np.float64],
) -> None:
    r"""The largest rise of the energy, net of the actuators' work, over steps without impact.

    The gains :math:`E_{k+1} - E_k - W_k` of the steps without impact and without a push
    (``pushed``: the sample indices of the scene's pushes) are accumulated and
    the largest rise of that sum (after its lowest point before) is compared with
    :data:`ENERGY_GAIN_BOUND` :math:`(1 + \max_k |E_k|)` [J].

    Args:
        log: The run's log.
        summary: The run's summary, completed in place.
        pushed: Sample indices of the scene's pushes.
        impacts: ``impact_mask(log)``, shape (N, n).
        work: ``step_work(log)`` in [J], shape (N - 1,).
    """
    steps = max(len(log) - 1, 0)
    gain = np.diff(log.energy[: steps + 1]) - work  # [J] per step
    gain[impact_cells(impacts[:steps])[0]] = 0.0
    gain[[k - 1 for k in pushed if 0 < k <= steps]] = 0.0  # the step that ends at a push
    accumulated = np.concatenate(([0.0], np.cumsum(gain)))
    low = np.minimum.accumulate(accumulated)
    end = int(np.argmax(accumulated - low))
    rise = float(accumulated[end] - low[end])
    bound = ENERGY_GAIN_BOUND * (1.0 + float(np.max(np.abs(log.energy), initial=0.0)))
    summary["energy_gain_without_impacts"] = rise
    summary["energy_gain_bound"] = bound
    if rise > bound:
        start = int(np.flatnonzero(accumulated[: end + 1] == low[end])[-1])
        warnings.warn(
            EnergyGainWarning(rise, float(log.t[start]), float(log.t[end]), bound), stacklevel=5
        )


def _report_bilateral(bilateral: BilateralSet, log: Log, summary: dict[str, Any]) -> None:
    """The largest residual :math:`|h(q)|` of the bilateral constraints over the samples."""
    residuals = np.abs(np.array([bilateral.residuals(q) for q in log.q]))  # (N, rows)
    beyond = residuals.max(axis=1, initial=0.0) > BILATERAL_TOLERANCE
    summary["max_bilateral_residual"] = float(residuals.max(initial=0.0))
    summary["n_bilateral_residuals_beyond_tolerance"] = int(beyond.sum())
    if beyond.any():
        row, column = np.unravel_index(int(np.argmax(residuals)), residuals.shape)
        name = bilateral.names[column]
        warnings.warn(
            BilateralResidualWarning(
                name, float(residuals[row, column]), float(log.t[row]), BILATERAL_TOLERANCE
            ),
            stacklevel=5,
        )


def _report_iteration_cap(cap: int, log: Log, summary: dict[str, Any]) -> None:
    """Frictionless Moreau–Jean solves that reached ``[integrator] max_iter``."""
    solves = log.solver_status != NO_SOLVE
    frictionless = solves & (log.solver_outer_iterations == 0)
    capped = np.flatnonzero(frictionless & (log.solver_iterations >= cap))
    summary["n_solves_at_iteration_cap"] = int(capped.size)
    if capped.size:
        warnings.warn(
            SolverIterationCapWarning(
                int(capped.size), int(solves.sum()), cap, float(log.t[capped[0]])
            ),
            stacklevel=5,
        )


def _hold_steps(control_period: float, h: float) -> int:
    """Steps per control period of ``control_period`` [s] with step ``h`` [s], at least 1."""
    return max(1, round(as_positive("control_period", control_period) / h))


def _check_initial_penetration(constraints: ConstraintSet, q0: NDArray[np.float64]) -> None:
    gap0 = constraints.gaps(q0)
    if gap0.size and gap0.min() < -PENETRATION_TOLERANCE:
        worst = int(np.argmin(gap0))
        raise InitialPenetrationError(
            constraints.names[worst], float(gap0[worst]), PENETRATION_TOLERANCE
        )


def _new_log(
    scene: Scene,
    integrator: Integrator,
    recorder: LoggingController | None,
    capacity: int,
    hold: int,
) -> Log:
    """An empty log with the fields this run records."""
    robot, constraints, flexible = scene.robot, integrator.constraints, scene.flexible
    log = Log(
        capacity,
        nq=robot.nq,
        nv=robot.nv,
        nu=robot.nu,
        constraint_names=constraints.names,
        metadata={
            "scene": scene.name,
            "integrator": integrator.name,
            "dt": integrator.dt,
            "theta": integrator.theta,
            "control_period": hold * integrator.dt,
            "actuated": robot.actuated.tolist(),
        },
    )
    if scene.source is not None:
        log.metadata["scene_path"] = str(scene.source)
    if recorder is not None:
        recorder.prepare_log(log)
    if constraints.has_friction:  # world friction impulse of each constraint [N s]
        log.add_field("friction_impulse", (constraints.size, 3))
    n_q, n_v = robot.nq + (0 if flexible is None else flexible.nf), robot.nv
    if scene.sensors is not None:  # what the controller saw (motors after the links)
        log.add_field("measured_q", (n_q,))
        log.add_field("measured_v", (n_v + (0 if flexible is None else flexible.nf),))
        if scene.sensors.observer == "momentum":  # the observer's residual and impact flag
            log.add_field("momentum_residual", (robot.nv,))
            log.add_field("impact_detected", (), dtype=bool)
    if scene.actuators is not None:  # the controller's output before the limits
        log.add_field("commanded_u", (robot.nu,))
    if flexible is not None:  # motor states, beside the links' q and v
        log.add_field("motor_q", (flexible.nf,))
        log.add_field("motor_v", (flexible.nf,))
        log.metadata["flexible_joints"] = list(flexible.joints)
        log.metadata["motor_inputs"] = flexible.input_index.tolist()
    return log


def _record_step(log: Log, u: NDArray[np.float64], outcome: StepOutcome) -> None:
    """The input, impulses, impacts and contact solve of a step, in the open row of ``log``."""
    solution = outcome.solution
    if outcome.impacts:
        log.record_impacts(outcome.impacts)
    if outcome.friction_impulse is not None:
        log.record_extra("friction_impulse", outcome.friction_impulse)
    if solution is None:
        log.record_step_without_solve(u, outcome.impulse, outcome.active)
        return
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


class _NonFiniteState(ArithmeticError):
    """Internal signal: the state left the finite numbers."""


def _as_array(value: Any) -> np.ndarray:
    """A controller's output as a float array, or a typed error naming it."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError("controller output u", value, "a vector of numbers") from error


def _progress_bar(n_steps: int, progress: bool | None) -> Any:
    """A progress bar when asked, or by default for long runs on a terminal."""
    if progress is False or (
        progress is None and (n_steps < PROGRESS_MIN_STEPS or not sys.stderr.isatty())
    ):
        return None
    from tqdm import tqdm

    return tqdm(total=n_steps, unit="step", unit_scale=True, desc="simulate")


class _CallableModule(types.ModuleType):
    """This module, calling :func:`simulate` when called.

    The package's attribute ``simulate`` names the function, but once this module is imported
    the import system binds the module there: both must run a simulation.
    """

    def __call__(self, *args: Any, **kwargs: Any) -> SimulationResult:
        return simulate(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule


def _measured_geometry(scene: Scene, constraints: ConstraintSet) -> ConstraintSet:
    """The constraints whose gaps the sensors report: the plant's, or the controller's belief.

    With the measurement-only observer (``observer = "momentum"``) the gaps and normal
    velocities come from the measured state and the surfaces of the controller's model
    (:meth:`~ucontrol.scene.scene.Scene.believed_constraints`), so a controller never sees the
    true surface; with the oracle, from the plant's own constraints.
    """
    assert scene.sensors is not None
    if scene.sensors.observer != "momentum":
        return constraints
    believed = scene.believed_constraints()
    return constraints if believed is scene.constraints else believed
