r"""Cost of a scene's step, in the same run as Pinocchio's own ADMM and PGS loops.

:func:`bench_scene` (the command ``ucontrol bench [SCENE]``) first runs the scene once in
closed loop with its own controller (:func:`ucontrol.simulate`) and records the generalized
forces it applied (the log's inputs ``u`` on the actuated coordinates, on the motors for
flexible joints). Every loop then replays that force sequence open loop from the scene's
initial state, so that all loops do the same work and none pays for the controller:

- ``ucontrol``: the scene's integrator (:meth:`ucontrol.scene.Scene.build_integrator`),
  ``evaluate`` then ``step``;
- ``pin ADMM`` and ``pin PGS``: :class:`~ucontrol.solvers.PinocchioStepper`, the frictionless
  Moreau–Jean step written with Pinocchio's ``ADMMConstraintSolver`` /
  ``PGSConstraintSolver`` (same dt, θ, tolerance and iteration cap as the scene's
  integrator), only for scenes it models: point contacts against planes without friction,
  a rigid robot, the ``moreau_jean`` integrator without ``midpoint`` or
  ``restitution_threshold``. Otherwise the report names what the scene has that the
  reference lacks and times ucontrol alone.

Per loop: wall time in [µs/step] (``time.perf_counter``, best of ``repeats`` runs after
``warmup`` steps), the ratio of the ucontrol time to it, the largest velocity difference to
the ucontrol trajectory over an untimed run (the loops do the same physics when it is at
round-off), the fraction of steps with an active contact, and the peak of Python allocations
(``tracemalloc``, numpy arrays included) over another untimed run. The report ends with the
process's peak resident set size.

The timing helpers (:func:`time_loop`, :func:`trajectory`, :func:`integrator_step`,
:func:`stepper_step`) are shared with ``experiments/bench_step.py``.
"""

from __future__ import annotations

import copy
import operator
import resource
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene
from ucontrol.simulate import simulate
from ucontrol.solvers.pinocchio_constraint_solver import PinocchioStepper

if TYPE_CHECKING:
    from ucontrol.plant import Integrator

Vector = NDArray[np.float64]
#: One step ``(q, v, tau) -> (q_next, v_next, any_active)`` of a loop.
Step = Callable[[Vector, Vector, Vector], tuple[Vector, Vector, bool]]
#: Generalized forces ``tau`` (shape (nv,)) of step k at (q_k, v_k): ``forces(k, q, v)``.
Forces = Callable[[int, Vector, Vector], Vector]

#: The loop every other is compared with.
UCONTROL = "ucontrol"
#: Reference loops and their :class:`PinocchioStepper` method.
REFERENCES = {"pin ADMM": "admm", "pin PGS": "pgs"}


def integrator_step(integrator: Integrator) -> Step:
    """The :data:`Step` of an integrator: ``evaluate`` at (q, v), then ``step``."""

    def step(q: Vector, v: Vector, tau: Vector) -> tuple[Vector, Vector, bool]:
        outcome = integrator.step(integrator.evaluate(q, v), tau)
        # (count_nonzero: a fifth of ndarray.any's cost, whose Python wrapper is most of it)
        return outcome.q, outcome.v, bool(np.count_nonzero(outcome.active))

    return step


def stepper_step(stepper: PinocchioStepper) -> Step:
    """The :data:`Step` of a :class:`PinocchioStepper`."""

    def step(q: Vector, v: Vector, tau: Vector) -> tuple[Vector, Vector, bool]:
        outcome = stepper.step(q, v, tau)
        return outcome.q, outcome.v, bool(outcome.active.any())

    return step


def time_loop(
    step: Step,
    forces: Forces,
    q0: Vector,
    v0: Vector,
    *,
    steps: int,
    repeats: int,
    warmup: int,
    clock: Callable[[], float] = time.perf_counter,
) -> float:
    """Best-of-``repeats`` time of ``steps`` steps from (q0, v0), in [µs/step].

    Args:
        step: The loop's step.
        forces: The generalized forces of each step.
        q0: Initial configuration, shape (nq,).
        v0: Initial velocity, shape (nv,).
        steps: Steps per timed run.
        repeats: Timed runs; the fastest is kept.
        warmup: Untimed steps from (q0, v0) first (caches, warm starts).
        clock: Time in [s]: wall (``time.perf_counter``, the default) or the process's CPU
            time (``time.process_time``, steadier on a loaded machine), see :data:`CLOCKS`.
    """
    _advance(step, forces, q0, v0, warmup)
    best = np.inf
    for _ in range(repeats):
        start = clock()
        _advance(step, forces, q0, v0, steps)
        best = min(best, clock() - start)
    return 1e6 * best / steps


def trajectory(
    step: Step, forces: Forces, q0: Vector, v0: Vector, steps: int
) -> tuple[Vector, float]:
    """Velocities after each of ``steps`` steps from (q0, v0), and the active fraction.

    Returns:
        The velocities, shape (steps, nv), and the fraction of steps with an active contact.
    """
    q, v = q0.copy(), v0.copy()
    velocities = np.empty((steps, v0.size))
    active = 0
    for k in range(steps):
        q, v, is_active = step(q, v, forces(k, q, v))
        velocities[k] = v
        active += is_active
    return velocities, active / steps


def peak_allocation_kb(step: Step, forces: Forces, q0: Vector, v0: Vector, steps: int) -> float:
    """Peak of the Python allocations over ``steps`` steps from (q0, v0), in [kB] (1024 B).

    Measured by ``tracemalloc`` (numpy arrays included, Pinocchio's C++ buffers not) above
    what is allocated when the run starts.
    """
    started = not tracemalloc.is_tracing()
    if started:
        tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        baseline = tracemalloc.get_traced_memory()[0]  # [B]
        _advance(step, forces, q0, v0, steps)
        peak = tracemalloc.get_traced_memory()[1]  # [B]
    finally:
        if started:
            tracemalloc.stop()
    return (peak - baseline) / 1024.0


def _advance(step: Step, forces: Forces, q0: Vector, v0: Vector, steps: int) -> None:
    """Run ``steps`` steps from (q0, v0), keeping nothing."""
    q, v = q0.copy(), v0.copy()
    for k in range(steps):
        q, v, _ = step(q, v, forces(k, q, v))


@dataclass(frozen=True, kw_only=True)
class LoopResult:
    """What one loop cost and did.

    Attributes:
        name: The loop: ``"ucontrol"``, ``"pin ADMM"`` or ``"pin PGS"``.
        time_us: Wall time in [µs/step], best of the timed runs.
        max_dv: Largest difference between its velocities and ucontrol's over the untimed
            run, in [m/s] or [rad/s] (0 for ucontrol itself).
        active_fraction: Fraction of the steps with an active contact, in [0, 1].
        peak_allocation_kb: Peak of the Python allocations over one run, in [kB] (1024 B).
    """

    name: str
    time_us: float
    max_dv: float
    active_fraction: float
    peak_allocation_kb: float


@dataclass(frozen=True, kw_only=True)
class BenchReport:
    """The loops of :func:`bench_scene`, ucontrol first.

    Attributes:
        scene: The scene's name.
        dt: Time step in [s].
        steps: Steps per timed run.
        repeats: Timed runs per loop (the fastest is kept).
        warmup: Untimed steps before the timed runs.
        loops: One result per loop, ucontrol first.
        no_reference: Why the scene has no Pinocchio reference (the features it lacks), or
            None when the reference loops ran.
        peak_rss_mb: Peak resident set size of the process at the end, in [MB]
            (``ru_maxrss`` / 1024, Linux units).
        clock: The clock of the times, ``"wall"`` or ``"cpu"`` (:data:`CLOCKS`).
    """

    scene: str
    dt: float
    steps: int
    repeats: int
    warmup: int
    loops: tuple[LoopResult, ...]
    no_reference: str | None
    peak_rss_mb: float
    clock: str = "wall"

    def loop(self, name: str) -> LoopResult:
        """The result of the loop ``name``."""
        return next(loop for loop in self.loops if loop.name == name)

    @property
    def ratios(self) -> dict[str, float]:
        """Ratio of the ucontrol time to each reference loop's time (< 1: ucontrol faster)."""
        ucontrol = self.loops[0].time_us
        return {loop.name: ucontrol / loop.time_us for loop in self.loops[1:]}

    def markdown(self) -> str:
        """A title line, the table of the loops and the memory line, as markdown."""
        header = (
            "| loop | time [µs/step] | ucontrol / loop | max Δv [m/s, rad/s] | active steps "
            "| peak Python allocations [kB] |"
        )
        lines = [
            f"{self.scene}: dt = {self.dt:g} s, {self.steps} steps of the scene's own forces "
            f"replayed open loop, best of {self.repeats} after {self.warmup} warm-up steps, "
            f"{self.clock} clock",
            "",
            header,
            "|:---|---:|---:|---:|---:|---:|",
        ]
        ucontrol = self.loops[0].time_us
        for loop in self.loops:
            max_dv = "—" if loop.name == UCONTROL else f"{loop.max_dv:.1e}"
            lines.append(
                f"| {loop.name} | {loop.time_us:.1f} | {ucontrol / loop.time_us:.2f} | {max_dv} "
                f"| {100.0 * loop.active_fraction:.1f} % | {loop.peak_allocation_kb:.1f} |"
            )
        lines.append("")
        if self.no_reference is not None:
            lines.append(f"No Pinocchio reference: {self.no_reference}.")
        lines.append(f"Peak resident set size of the process: {self.peak_rss_mb:.0f} MB.")
        return "\n".join(lines)


def reference_obstacles(scene: Scene) -> list[str]:
    """What ``scene`` has that :class:`PinocchioStepper` does not model; empty if nothing.

    The stepper advances a rigid robot with frictionless point contacts against planes by the
    ``moreau_jean`` rule, restitution on every active contact, matrices at step k.
    """
    settings = scene.integrator
    obstacles = []
    if scene.stops:
        joints = ", ".join(stop.joint for stop in scene.stops)
        obstacles.append(f"the scene has joint stops ({joints})")
    if scene.sphere_contacts:
        obstacles.append("the scene has sphere–sphere contacts")
    if scene.constraints.has_friction:
        obstacles.append("the scene has friction (PinocchioStepper's step is frictionless)")
    if scene.flexible is not None:
        obstacles.append(f"the scene has flexible joints ({', '.join(scene.flexible.joints)})")
    if settings.name != "moreau_jean":
        obstacles.append(f"the scene's integrator is {settings.name}, not moreau_jean")
    if settings.midpoint:
        obstacles.append("the scene's integrator evaluates at the midpoint (midpoint = true)")
    if settings.restitution_threshold > 0.0:
        obstacles.append(
            f"the scene's integrator has restitution_threshold = "
            f"{settings.restitution_threshold:g} m/s"
        )
    return obstacles


def recorded_forces(scene: Scene, steps: int, dt: float | None = None) -> Vector:
    """Generalized forces of ``steps`` steps of the scene's closed loop, shape (steps, nv).

    Runs :func:`ucontrol.simulate` with the scene's controller and maps the log's inputs ``u``
    to the actuated coordinates as it does (the motors' for flexible joints, whose coordinates
    then follow the links': shape (steps, nv + nf)).

    Args:
        scene: The scene.
        steps: Number of steps.
        dt: Time step in [s]; default the scene's.
    """
    h = scene.integrator.dt if dt is None else dt
    log = simulate(scene, duration=steps * h, dt=h, progress=False).log
    robot, flexible = scene.robot, scene.flexible
    actuated = robot.actuated if flexible is None else flexible.input_coordinates(robot.actuated)
    tau = np.zeros((steps, scene.initial_state()[1].size))
    tau[:, actuated] = log.u[:steps]
    return tau


def bench_scene(
    scene: Scene,
    *,
    steps: int = 2000,
    repeats: int = 5,
    warmup: int = 100,
    dt: float | None = None,
    clock: str = "wall",
) -> BenchReport:
    """Time the scene's step against Pinocchio's ADMM and PGS loops (module docstring).

    Args:
        scene: The scene; its controller is run once to record the forces.
        steps: Steps per timed run, >= 1.
        repeats: Timed runs per loop, the fastest kept, >= 1.
        warmup: Untimed steps before the timed runs, >= 0.
        dt: Time step in [s]; default the scene's.
        clock: ``"wall"`` or ``"cpu"`` (the process's CPU time: on a loaded machine the
            loops' ratios then hold, where wall times also count the waits for a core).

    Raises:
        InvalidParameterError: ``steps``, ``repeats`` or ``warmup`` is not an integer in its
            range, ``dt`` is not > 0, or ``clock`` is not a name of :data:`CLOCKS`.
        SimulationError: The recording run failed.
    """
    steps = _as_count("steps", steps, 1)
    repeats = _as_count("repeats", repeats, 1)
    warmup = _as_count("warmup", warmup, 0)
    _check_clock(clock)
    h = scene.integrator.dt if dt is None else as_positive("dt", dt)
    tau = recorded_forces(scene, max(steps, warmup), h)
    rows = list(tau)

    def forces(k: int, q: Vector, v: Vector) -> Vector:
        return rows[k]

    q0, v0 = scene.initial_state()
    obstacles = reference_obstacles(scene)
    loops = _loops(scene, h, references=not obstacles)
    times = {
        name: time_loop(
            build(),
            forces,
            q0,
            v0,
            steps=steps,
            repeats=repeats,
            warmup=warmup,
            clock=CLOCKS[clock],
        )
        for name, build in loops.items()
    }
    # Untimed runs on fresh loops: integrators keep state between steps (warm starts).
    runs = {name: trajectory(build(), forces, q0, v0, steps) for name, build in loops.items()}
    reference = runs[UCONTROL][0]
    results = tuple(
        LoopResult(
            name=name,
            time_us=times[name],
            max_dv=float(np.max(np.abs(runs[name][0] - reference))),
            active_fraction=runs[name][1],
            peak_allocation_kb=peak_allocation_kb(build(), forces, q0, v0, steps),
        )
        for name, build in loops.items()
    )
    return BenchReport(
        scene=scene.name,
        dt=h,
        steps=steps,
        repeats=repeats,
        warmup=warmup,
        loops=results,
        no_reference="; ".join(obstacles) if obstacles else None,
        clock=clock,
        peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    )


def _loops(scene: Scene, dt: float, *, references: bool) -> dict[str, Callable[[], Step]]:
    """A builder of each loop's :data:`Step`: ucontrol, then the references if asked."""
    loops = {UCONTROL: lambda: integrator_step(scene.build_integrator(dt))}
    if not references:
        return loops
    settings = scene.integrator
    for name, method in REFERENCES.items():
        loops[name] = partial(
            _stepper_loop,
            scene,
            dt=dt,
            theta=settings.theta,
            method=method,
            tolerance=settings.contact_tolerance,
            max_iter=settings.max_iter,
        )
    return loops


def _stepper_loop(scene: Scene, **options: Any) -> Step:
    """The :data:`Step` of a :class:`PinocchioStepper` of the scene's contacts."""
    return stepper_step(PinocchioStepper(scene.robot.model, scene.contacts, **options))


def _check_clock(clock: str) -> None:
    """Raise :class:`InvalidParameterError` unless ``clock`` names one of :data:`CLOCKS`."""
    if clock not in CLOCKS:
        raise InvalidParameterError("clock", clock, f"one of {sorted(CLOCKS)}")


def _as_count(name: str, value: Any, minimum: int) -> int:
    """``value`` as an integer >= ``minimum``, or :class:`InvalidParameterError`."""
    expected = f"an integer >= {minimum}"
    if isinstance(value, bool):
        raise InvalidParameterError(name, value, expected)
    try:
        count = operator.index(value)
    except TypeError as error:
        raise InvalidParameterError(name, value, expected) from error
    if count < minimum:
        raise InvalidParameterError(name, value, expected)
    return count


@dataclass(frozen=True)
class ClosedLoopResult:
    r"""Cost of one scene's closed loop (:func:`bench_closed_loop`), split by stage.

    All times are per step in [µs/step], from one run (the median of the timed runs by total),
    over the window between the first and the last call of the run's observer (steps 1 to
    n - 1 of n and the evaluation of the last state; the set-up, the first step and the
    summary excluded): ``total`` is that window's time,
    ``controller`` the time inside the controller's calls, ``plant`` the time inside the
    integrator's ``evaluate`` and ``step`` less the contact solves, ``solver`` the contact solves
    (the log's ``solver_time``, a wall time; with the CPU clock scaled by the integrator's ratio
    of CPU to wall time, measured alongside), and ``loop`` the rest (logging, sensors, the loop,
    the timers themselves): ``controller + plant + solver + loop = total`` by definition.
    ``untimed`` is the cost per step of runs without the stage timers and without an
    observer, as a user's run, from the difference of a whole run and a two-step run (which
    cancels the set-up; the whole run's cost per step, an upper bound, where a run too short
    for the difference to exceed the set-up's jitter gives none): the cost of which the
    real-time factor is taken.

    Attributes:
        scene: Scene name.
        dt: Time step in [s].
        steps: Steps timed per run.
        repeats: Timed runs (after one untimed warm-up run).
        clock: ``"wall"`` (``time.perf_counter``) or ``"cpu"`` (``time.process_time``: this
            process's CPU time, less disturbed by other processes on a shared machine).
        nv: Velocity size of the plant (links and motors).
        n_constraints: Unilateral constraints of the plant (contacts and stops).
        total_us: Time per step.
        controller_us: Controller time per step.
        plant_us: Integrator time per step, contact solves excluded.
        solver_us: Contact-solve time per step.
        loop_us: The rest per step.
        untimed_us: Time per step of a run without timers or observer (median of as many).
    """

    scene: str
    dt: float
    steps: int
    repeats: int
    clock: str
    nv: int
    n_constraints: int
    total_us: float
    controller_us: float
    plant_us: float
    solver_us: float
    loop_us: float
    untimed_us: float

    @property
    def real_time_factor(self) -> float:
        """Simulated time over the untimed runs' time (> 1: faster than real time)."""
        return 1e6 * self.dt / self.untimed_us

    def row(self) -> str:
        """This result as a row of :func:`closed_loop_markdown`'s table."""
        return (
            f"| {self.scene} | {self.nv} | {self.n_constraints} | {self.untimed_us:.1f} "
            f"| {self.real_time_factor:.1f}× | {self.total_us:.1f} | {self.controller_us:.1f} "
            f"| {self.plant_us:.1f} | {self.solver_us:.1f} | {self.loop_us:.1f} |"
        )


#: Header of the closed-loop table: the untimed cost and its real-time factor, then the timed
#: run's total and its split.
CLOSED_LOOP_HEADER = (
    "| scene | nv | constraints | untimed [µs/step] | real time | timed total | controller "
    "| plant | contact solve | log + loop |\n|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
)

#: Clocks of :func:`bench_closed_loop`.
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def closed_loop_markdown(results: list[ClosedLoopResult]) -> str:
    """The closed-loop results as one markdown table (times in [µs/step])."""
    return "\n".join([CLOSED_LOOP_HEADER, *(result.row() for result in results)])


def bench_closed_loop(
    scene: Scene,
    *,
    duration: float | None = None,
    repeats: int = 3,
    dt: float | None = None,
    clock: str = "wall",
) -> ClosedLoopResult:
    """Time the scene's closed loop (its own controller), split by stage.

    Each run builds a fresh controller (:meth:`Scene.build_controller`; compiled laws are
    built before the timing) and calls :func:`ucontrol.simulate` with the controller and the
    scene's integrator wrapped in timers and an observer that opens the timed window after the
    first step; the first run is untimed (warm-up).

    Args:
        scene: The scene.
        duration: Simulated time per run in [s], at least two steps; default the scene's.
        repeats: Timed runs, >= 1; the one of median total time is reported.
        dt: Time step in [s]; default the scene's.
        clock: ``"wall"`` or ``"cpu"`` (see :class:`ClosedLoopResult`).

    Raises:
        InvalidParameterError: ``repeats`` is not an integer >= 1, ``duration`` or ``dt`` not
            > 0, or ``clock`` is not a name of :data:`CLOCKS`.
        SimulationError: A run failed.
    """
    repeats = _as_count("repeats", repeats, 1)
    if duration is not None:
        duration = as_positive("duration", duration)
    _check_clock(clock)
    runs = []
    for k in range(repeats + 1):
        timers = _Timers(CLOCKS[clock])
        controller = _TimedController(scene.build_controller(), timers)
        result = simulate(
            _timed_scene(scene, timers),
            controller,
            duration,
            dt=dt,
            progress=False,
            observer=timers.observe,
        )
        if k == 0:
            continue  # warm-up
        log = result.log
        solver = float(np.sum(log.solver_time[timers.first_row : len(log) - 1]))  # wall [s]
        if clock != "wall" and timers.plant_wall > 0.0:  # its share of the integrator's CPU time
            solver *= timers.step_cpu / timers.plant_wall
        steps = timers.rows - 2  # full steps in the window: 1 to n - 1
        runs.append((timers.window, steps, timers, solver, float(log.metadata["dt"])))
    runs.sort(key=operator.itemgetter(0))
    total, steps, timers, solver, h = runs[len(runs) // 2]
    per_step = 1e6 / max(steps, 1)  # [µs/s per step]
    untimed = []
    now = CLOCKS[clock]
    for _ in range(repeats):  # runs as a user's, without timers or observer
        costs = []
        for span in (2.0 * h, duration):  # their difference cancels the set-up
            start = now()
            run = simulate(scene, duration=span, dt=dt, progress=False)
            costs.append((now() - start, len(run.log) - 1))
        (short, short_steps), (full, full_steps) = costs
        difference = (full - short) * 1e6 / max(full_steps - short_steps, 1)
        # A run too short for the difference to exceed the set-up's jitter (a loaded machine)
        # gives the whole run's cost per step instead: an upper bound, never a negative cost.
        untimed.append(difference if difference > 0.0 else full * 1e6 / max(full_steps, 1))
    return ClosedLoopResult(
        scene=scene.name,
        dt=h,
        steps=steps,
        repeats=repeats,
        clock=clock,
        nv=int(timers.nv),
        n_constraints=int(timers.n_constraints),
        total_us=total * per_step,
        controller_us=timers.controller * per_step,
        plant_us=(timers.plant - solver) * per_step,
        solver_us=solver * per_step,
        loop_us=(total - timers.controller - timers.plant) * per_step,
        untimed_us=float(np.median(untimed)),
    )


class _Timers:
    """Time spent in the controller and in the integrator within the observed window [s]."""

    def __init__(self, now: Callable[[], float]) -> None:
        self.now = now
        self.wall = time.perf_counter if now is not time.perf_counter else None
        self.controller = self.plant = self.plant_wall = self.step_cpu = 0.0
        self.rows = 0  # observer calls
        self.first_row = 0  # log row of the first observer call
        self.start = self.window = 0.0
        self.nv = self.n_constraints = 0

    def observe(self, log: Any) -> None:
        """Open the window at the first call (after the first step), extend it at each."""
        now = self.now()
        if self.rows == 0:
            self.start, self.first_row = now, len(log)
            self.controller = self.plant = self.plant_wall = self.step_cpu = 0.0
        self.rows += 1
        self.window = now - self.start


class _TimedController:
    """A controller whose calls are timed; anything else goes to the controller itself.

    It is a :class:`~ucontrol.control.LoggingController` exactly when the controller is
    (``prepare_log`` and ``record`` are looked up on the controller).
    """

    def __init__(self, controller: Any, timers: _Timers) -> None:
        self._controller = controller
        self._timers = timers

    def __call__(self, t: float, q: Vector, v: Vector, contacts: Any) -> Any:
        timers = self._timers
        start = timers.now()
        u = self._controller(t, q, v, contacts)
        timers.controller += timers.now() - start
        return u

    def __getattr__(self, name: str) -> Any:
        return getattr(self._controller, name)


def _timed_scene(scene: Scene, timers: _Timers) -> Scene:
    """A copy of ``scene`` whose ``build_integrator`` returns a timed integrator."""
    timed = copy.copy(scene)

    def build_integrator(dt: float | None = None) -> _TimedIntegrator:
        integrator = scene.build_integrator(dt=dt)
        timers.nv = integrator.evaluate(*scene.initial_state()).v.size
        timers.n_constraints = integrator.constraints.size
        return _TimedIntegrator(integrator, timers)

    object.__setattr__(timed, "build_integrator", build_integrator)  # frozen dataclass
    return timed


class _TimedIntegrator:
    """An integrator whose ``evaluate`` and ``step`` are timed."""

    def __init__(self, integrator: Any, timers: _Timers) -> None:
        self._integrator = integrator
        self._timers = timers

    def evaluate(self, q: Vector, v: Vector, t: float | None = None) -> Any:
        timers = self._timers
        start = timers.now()
        state = self._integrator.evaluate(q, v, t)
        timers.plant += timers.now() - start
        return state

    def step(self, state: Any, tau: Vector) -> Any:
        timers = self._timers
        wall = timers.wall
        if wall is None:
            start = timers.now()
            outcome = self._integrator.step(state, tau)
            timers.plant += timers.now() - start
            return outcome
        start, start_wall = timers.now(), wall()  # the solver's wall time needs the ratio
        outcome = self._integrator.step(state, tau)
        timers.plant_wall += wall() - start_wall
        elapsed = timers.now() - start
        timers.plant += elapsed
        timers.step_cpu += elapsed
        return outcome

    def __getattr__(self, name: str) -> Any:
        return getattr(self._integrator, name)
