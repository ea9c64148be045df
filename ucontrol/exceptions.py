"""Errors raised by ucontrol.

Every error derives from :class:`UControlError` and carries the offending values as attributes,
so that callers can react programmatically and users read what was wrong and what was expected.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any


class UControlError(Exception):
    """Base class of every error raised by ucontrol."""

    def __str__(self) -> str:
        """The message itself (KeyError's own text would be the message's repr)."""
        return str(self.args[0]) if len(self.args) == 1 else super().__str__()


class InvalidParameterError(UControlError, ValueError):
    """A parameter has a value outside its admissible set.

    Attributes:
        name: Name of the argument or scene key.
        value: The value received.
        expected: Human-readable description of the admissible values.
    """

    def __init__(self, name: str, value: Any, expected: str) -> None:
        self.name = name
        self.value = value
        self.expected = expected
        super().__init__(f"`{name}` must be {expected}, got {value!r}")


class ShapeError(InvalidParameterError):
    """An array argument has the wrong shape.

    Attributes:
        name: Name of the argument.
        expected_shape: Required shape.
        shape: Shape received.
    """

    def __init__(self, name: str, expected_shape: tuple[int, ...], shape: tuple[int, ...]) -> None:
        self.expected_shape = tuple(expected_shape)
        self.shape = tuple(shape)
        UControlError.__init__(
            self, f"`{name}` must have shape {self.expected_shape}, got {self.shape}"
        )
        self.name = name
        self.value = shape
        self.expected = f"shape {self.expected_shape}"


class NonFiniteValueError(InvalidParameterError):
    """An array argument holds NaN or infinite entries.

    Attributes:
        name: Name of the argument.
        indices: Indices of the non-finite entries.
    """

    def __init__(self, name: str, value: Any, indices: Sequence[int]) -> None:
        self.indices = list(indices)
        UControlError.__init__(
            self, f"`{name}` must be finite, got non-finite entries at {self.indices}: {value!r}"
        )
        self.name = name
        self.value = value
        self.expected = "finite"


class AssemblyError(InvalidParameterError):
    """A closed chain cannot be assembled: no configuration near the guess closes its loops.

    Attributes:
        name: The configuration's name, e.g. ``"q0"``.
        residual: Largest constraint residual reached, in [m] or [rad].
        constraint: The bilateral constraint row of that residual, e.g. ``"closure[1]"``.
        iterations: Gauss–Newton iterations done.
        configuration: The configuration of smallest residual reached, shape (nq,).
    """

    def __init__(
        self,
        name: str,
        residual: float,
        constraint: str,
        iterations: int,
        configuration: Any,
        reason: str,
    ) -> None:
        self.residual = residual
        self.constraint = constraint
        self.iterations = iterations
        self.configuration = configuration
        UControlError.__init__(
            self,
            f"`{name}` cannot be assembled: bilateral constraint {constraint!r} keeps a residual "
            f"of {residual:.3e} after {iterations} Gauss-Newton iterations ({reason})",
        )
        self.name = name
        self.value = configuration
        self.expected = "a configuration near a closure of the loops"


class RobotFileError(UControlError):
    """A robot description file (URDF, MJCF, SDF) is missing or cannot be read.

    Attributes:
        path: Path of the file.
        reason: What went wrong.
        format: The file's format, ``"URDF"``, ``"MJCF"`` or ``"SDF"``.
    """

    def __init__(self, path: str, reason: str, format: str) -> None:
        self.path = path
        self.reason = reason
        self.format = format
        super().__init__(f"cannot load {format} {path!r}: {reason}")


class URDFError(RobotFileError):
    """A URDF file is missing or cannot be parsed (:class:`RobotFileError` of format URDF)."""

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(path, reason, "URDF")


class MJCFError(RobotFileError):
    """An MJCF (MuJoCo XML) file is missing or Pinocchio's MJCF parser cannot read it."""

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(path, reason, "MJCF")


class SDFError(RobotFileError):
    """An SDF file cannot be read, e.g. because the installed Pinocchio has no SDF parser."""

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(path, reason, "SDF")


class NotFoundError(UControlError, KeyError):
    """A name (frame, joint, integrator, ...) does not exist.

    Attributes:
        kind: What was looked up, e.g. ``"frame"``.
        name: The name asked for.
        available: The names that exist.
    """

    def __init__(self, kind: str, name: str, available: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.available = sorted(available)
        super().__init__(f"unknown {kind} {name!r}; available: {', '.join(self.available)}")


class UserFunctionError(UControlError, LookupError):
    """A user function named ``module:function`` cannot be imported.

    Attributes:
        spec: The name asked for, ``"module:function"``.
        reason: Why it is not available (the module does not import, has no such callable).
    """

    def __init__(self, spec: str, reason: str) -> None:
        self.spec = spec
        self.reason = reason
        super().__init__(f"cannot load the function {spec!r}: {reason}")


class FrameNotFoundError(NotFoundError):
    """A frame name is not in the robot model; :attr:`available` lists the frames that are."""

    def __init__(self, name: str, available: Iterable[str]) -> None:
        super().__init__("frame", name, available)


class JointNotFoundError(NotFoundError):
    """A joint name is not in the robot model; :attr:`available` lists the joints that are."""

    def __init__(self, name: str, available: Iterable[str]) -> None:
        super().__init__("joint", name, available)


class InitialPenetrationError(UControlError):
    """The initial configuration violates a unilateral constraint.

    Attributes:
        constraint: Name of the violated constraint.
        gap: Its gap at the initial configuration in [m] (or [rad] for a rotational stop).
        tolerance: The admissible penetration.
    """

    def __init__(self, constraint: str, gap: float, tolerance: float) -> None:
        self.constraint = constraint
        self.gap = gap
        self.tolerance = tolerance
        super().__init__(
            f"initial configuration penetrates constraint {constraint!r}: gap {gap:.6g} < "
            f"-{tolerance:.1g}; start the robot outside the obstacle"
        )


class PathThroughSurfaceError(InvalidParameterError):
    """A desired path enters an obstacle where no contact phase is declared for it.

    Attributes:
        constraint: Name of the crossed constraint (a point contact).
        time: Time within the period at which the path is deepest inside, in [s].
        gap: The path's gap there, in [m] (negative).
    """

    def __init__(self, constraint: str, time: float, gap: float) -> None:
        self.constraint = constraint
        self.time = time
        self.gap = gap
        UControlError.__init__(
            self,
            f"the desired path goes through {constraint!r} (gap {gap:.4g} m at t = {time:.4g} s "
            "of the period) outside any declared contact phase; declare a contact phase "
            "covering that time or move the path out of the obstacle",
        )
        self.name = "path"
        self.value = gap
        self.expected = f"a gap >= 0 for {constraint!r} outside its contact phases"


class SceneError(UControlError):
    """A scene file is malformed."""


class UnknownKeyError(SceneError, InvalidParameterError):
    """A scene table holds keys that ucontrol does not know.

    Attributes:
        section: The table, e.g. ``"[robot]"``.
        keys: The unknown keys.
        allowed: The keys the table accepts.
    """

    def __init__(self, section: str, keys: Iterable[str], allowed: Iterable[str]) -> None:
        self.section = section
        self.keys = sorted(keys)
        self.allowed = sorted(allowed)
        UControlError.__init__(
            self,
            f"unknown key(s) {', '.join(map(repr, self.keys))} in {section}; "
            f"allowed: {', '.join(self.allowed)}",
        )
        self.name = section
        self.value = self.keys
        self.expected = f"one of {self.allowed}"


class SolverError(UControlError):
    """A contact solver failed to return a usable solution.

    Attributes:
        solver: Name of the solver.
        status: The backend's status.
        residual: Complementarity residual reached, if known.
    """

    def __init__(self, solver: str, status: str, residual: float | None = None) -> None:
        self.solver = solver
        self.status = status
        self.residual = residual
        extra = "" if residual is None else f" (complementarity residual {residual:.3g})"
        super().__init__(f"{solver} failed with status {status}{extra}")


class SimulationError(UControlError):
    """A run failed part-way; everything up to the failure is logged.

    Attributes:
        time: Simulation time of the last valid sample in [s].
        step: Index of the failing step.
        reason: Why the run stopped.
        log: The :class:`ucontrol.log.Log` holding every sample up to the failure.
        log_path: Where the partial log was saved, if the run had an output directory.
    """

    def __init__(self, time: float, step: int, reason: str, log: Any = None) -> None:
        self.time = time
        self.step = step
        self.reason = reason
        self.log = log
        self.log_path: str | None = None
        super().__init__(f"simulation failed at t = {time:.6g} s (step {step}): {reason}")

    def __str__(self) -> str:
        saved = f"; log up to the failure saved to {self.log_path}" if self.log_path else ""
        return f"{self.args[0]}{saved}"


class IntegrationError(UControlError):
    """A continuous-time integrator cannot advance: its ODE solver failed or it met a limit.

    Attributes:
        integrator: Name of the integrator.
        time: Time within the step at which it stopped, in [s] from the start of the step.
        reason: What limit was met and how to get past it.
    """

    def __init__(self, integrator: str, time: float, reason: str) -> None:
        self.integrator = integrator
        self.time = time
        self.reason = reason
        super().__init__(f"{integrator} cannot advance ({time:.6g} s into the step): {reason}")


class PainleveError(IntegrationError):
    """No contact mode with Coulomb friction is consistent (Painlevé), or too many to try.

    Raised by event_driven's sustained friction
    (:func:`ucontrol.integrators.friction_modes.friction_modes`): the rigid model with Coulomb
    friction has no acceleration (or impulse) solution at this state, or more mode
    combinations than it enumerates.
    """


class CompiledCallError(UControlError):
    """A call of a casadi Function (compiled to C, or in casadi's virtual machine) failed.

    Raised by :class:`ucontrol.model.compiled_function.CompiledFunction` and its runners;
    :func:`ucontrol.simulate` stops the run with a :class:`SimulationError` that keeps the log
    up to the failing step.

    Attributes:
        function: Name of the casadi Function.
        failure: What failed: the non-zero status the compiled code returned, or casadi's error.
    """

    def __init__(self, function: str, failure: str) -> None:
        self.function = function
        self.failure = " ".join(failure.split())  # casadi's errors span lines: one line
        super().__init__(f"casadi function {function!r} failed: {self.failure}")


class RunNotFoundError(UControlError):
    """A directory is not the output of a run: it holds no ``log.npz``.

    Attributes:
        directory: The directory given.
    """

    def __init__(self, directory: str) -> None:
        self.directory = directory
        super().__init__(
            f"no log.npz in {directory!r}: not the output directory of a run "
            "(`ucontrol run SCENE --out DIR` writes one)"
        )


class StrideError(IntegrationError):
    """A walker's stride cannot be completed by the stance-flow model it was computed with.

    An :class:`IntegrationError` (integrator ``"stance flow"``), so that a Newton search on a
    stride map treats a trial whose stride fails as a failed trial.

    Attributes:
        time: Time into the stride at which it stopped, in [s].
        reason: What happened (no heel strike within the time allowed, a stance foot that
            would lift off or slip, a strike that is not plastic and sticking).
    """

    def __init__(self, time: float, reason: str) -> None:
        self.integrator = "stance flow"
        self.time = time
        self.reason = reason
        UControlError.__init__(self, f"stride stopped {time:.6g} s in: {reason}")


class OptionalDependencyError(UControlError):
    """A feature needs a package of an optional extra that is not installed.

    Attributes:
        package: The missing package.
        extra: The ucontrol extra that installs it.
    """

    def __init__(self, package: str, extra: str) -> None:
        self.package = package
        self.extra = extra
        super().__init__(
            f"{package} is not installed; install the extra: pip install 'ucontrol[{extra}]' "
            f"(from a clone: pip install -e '.[{extra}]')"
        )


class ViewerError(UControlError):
    """The meshcat viewer could not be started or reached.

    Attributes:
        reason: What went wrong (the server's last messages when it stopped).
    """

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(f"meshcat viewer: {reason}")


class ContactSolveError(SolverError):
    """A contact solve ended with its residual above the solver's tolerance.

    Raised by :class:`ucontrol.integrators.MoreauJean` when ``on_unsolved = "raise"``
    (the default); ``on_unsolved = "warn"`` issues a :class:`ContactSolveWarning` instead.

    Attributes:
        solver: Name of the solver.
        status: The solver's status.
        residual: Natural-map residual reached, in [m/s].
        tolerance: The residual the solver had to reach, in [m/s].
    """

    def __init__(self, solver: str, status: str, residual: float, tolerance: float) -> None:
        self.tolerance = tolerance
        super().__init__(solver, status, residual)
        self.args = (f"{self.args[0]}; tolerance {tolerance:.3g} m/s",)


class ContactSolveWarning(UserWarning):
    """A contact solve ended with its residual above the solver's tolerance; the run goes on.

    Issued by :class:`ucontrol.integrators.MoreauJean` when ``on_unsolved = "warn"``; the step
    uses the solver's best impulses.

    Attributes:
        solver: Name of the solver.
        status: The solver's status.
        residual: Natural-map residual reached, in [m/s].
        tolerance: The residual the solver had to reach, in [m/s].
    """

    def __init__(self, solver: str, status: str, residual: float, tolerance: float) -> None:
        self.solver = solver
        self.status = status
        self.residual = residual
        self.tolerance = tolerance
        super().__init__(
            f"{solver} stopped with status {status}: residual {residual:.3g} m/s above the "
            f"tolerance {tolerance:.3g} m/s; the step goes on with these impulses"
        )


class PathOutOfReachError(InvalidParameterError):
    """A desired path holds a point the robot's frame cannot reach (inverse kinematics fails).

    Attributes:
        frame: Name of the frame that must follow the path.
        time: Time within the period of the first unreachable sample, in [s].
        point: That point of the path in the world frame, in [m], as a list of 3 floats.
        residual: Smallest distance in [m] between the frame and the point that inverse
            kinematics reached (from the previous sample's solution and several restarts
            within the joint limits).
    """

    def __init__(self, frame: str, time: float, point: Sequence[float], residual: float) -> None:
        self.frame = frame
        self.time = time
        self.point = [float(x) for x in point]
        self.residual = residual
        UControlError.__init__(
            self,
            f"the desired path leaves the workspace of frame {frame!r}: the point "
            f"{self.point} at t = {time:.4g} s of the period stays {residual:.3g} m away from "
            "every configuration inverse kinematics found within the joint limits; move or "
            "shrink the path",
        )
        self.name = "path"
        self.value = self.point
        self.expected = f"points that frame {frame!r} can reach"


class DesignError(UControlError):
    """A desired cycle cannot be designed from a task as given."""


class InfeasibleDesignError(DesignError):
    """The optimal-control problem of a task has no feasible cycle.

    Attributes:
        binding: The constraints that cannot be met, each ``(name, violation)`` with the
            violation in the constraint's units, largest first.
        best: The best iterate found (a :class:`ucontrol.design.DesignedCycle` of the
            elastic problem whose named limits were relaxed), or None.
        report: The solver's report of the failed solve (a
            :class:`ucontrol.design.DesignReport`), or None.
    """

    def __init__(
        self, binding: Sequence[tuple[str, float]], best: Any = None, report: Any = None
    ) -> None:
        self.binding = list(binding)
        self.best = best
        self.report = report
        named = "; ".join(f"{name} (violated by {value:.4g})" for name, value in self.binding)
        super().__init__(
            "no feasible cycle: the binding constraint(s) are "
            f"{named or 'unknown (the dynamics or periodicity cannot be met)'}; relax them in "
            "the task file (the best iterate is kept in `best`)"
        )


class InvalidInertiaError(InvalidParameterError):
    """A body of a URDF has inertial parameters no rigid body can have.

    Attributes:
        body: The body (link) name.
        mass: Its mass in [kg].
        moments: Principal moments of inertia about its centre of mass in [kg m²], ascending.
    """

    def __init__(self, body: str, mass: float, moments: Sequence[float], expected: str) -> None:
        self.body = body
        self.mass = mass
        self.moments = list(moments)
        values = f"mass {mass!r} kg, principal moments {[float(m) for m in self.moments]} kg m²"
        super().__init__(f"inertia of link {body!r}", values, expected)


class OutputPathError(InvalidParameterError):
    """An output location cannot be written (checked before any work starts).

    Attributes:
        path: The location asked for.
        reason: Why it cannot be used.
    """

    def __init__(self, name: str, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(name, path, f"a writable location ({reason})")


class OutputWriteError(UControlError):
    """Writing an output file failed (e.g. a full disk); the last complete file is kept.

    Attributes:
        path: The file being written.
        reason: The system's error message.
    """

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"cannot write {path!r}: {reason} (the last complete file is kept)")


class OutputInUseError(UControlError):
    """Another run writes to the same output directory.

    Attributes:
        path: The directory.
        pid: Process id of the run that holds it.
    """

    def __init__(self, path: str, pid: int) -> None:
        self.path = path
        self.pid = pid
        super().__init__(
            f"output directory {path!r} is in use by the run of process {pid}; choose another "
            "--out or wait for it to end"
        )


class LogFileError(UControlError):
    """A log file cannot be read (truncated, corrupt or not a log).

    Attributes:
        path: The file.
        reason: What is wrong with it.
    """

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"cannot read the log {path!r}: {reason}")


class PhysicsWarning(UserWarning):
    """A run went on, but something in its physics deserves a look (the figure is given)."""


class _BeyondToleranceWarning(PhysicsWarning):
    """A constraint left beyond its tolerance by some amount at some time (the message's form).

    Attributes:
        constraint: The constraint's name.
        time: When it happened, in [s].
        tolerance: The tolerance in [m] (or [rad]).
    """

    def __init__(
        self, what: str, constraint: str, amount: float, time: float, tolerance: float, hint: str
    ) -> None:
        self.constraint = constraint
        self.time = time
        self.tolerance = tolerance
        super().__init__(
            f"{what.format(repr(constraint))} by {amount:.4g} at t = {time:.6g} s, beyond the "
            f"tolerance {tolerance:.4g} ({hint})"
        )


class PenetrationWarning(_BeyondToleranceWarning):
    """A constraint was penetrated deeper than the scene's tolerance.

    Attributes:
        constraint: The constraint's name.
        depth: The deepest penetration in [m] (or [rad]).
        time: When it happened, in [s].
        tolerance: The tolerance in [m] (or [rad]).
    """

    def __init__(self, constraint: str, depth: float, time: float, tolerance: float) -> None:
        self.depth = depth
        hint = "set [integrator] penetration_tolerance; a smaller dt reduces it"
        super().__init__("constraint {} penetrated", constraint, depth, time, tolerance, hint)


class PlasticRedoWarning(PhysicsWarning):
    """Steps were redone with a plastic impact law in a scene whose restitutions are all 1.

    Attributes:
        steps: How many steps were redone.
    """

    def __init__(self, steps: int) -> None:
        self.steps = steps
        super().__init__(
            f"{steps} step(s) were redone with a plastic impact law (e = 0) because Newton's law "
            "would have added energy, although every restitution of the scene is 1; with "
            "theta > 1/2 the scheme dissipates at impacts (use theta = 0.5)"
        )


class EnergyGainWarning(PhysicsWarning):
    """The energy rose, net of the actuators' work, over steps without any impact.

    Only numerical error adds energy there (a step too large for the dynamics, a projection
    onto closed chains): the figure is the largest rise of the accumulated gain.

    Attributes:
        gain: The rise in [J].
        start: When it began, in [s].
        end: When it peaked, in [s].
        bound: The bound it exceeds, in [J].
    """

    def __init__(self, gain: float, start: float, end: float, bound: float) -> None:
        self.gain = gain
        self.start = start
        self.end = end
        self.bound = bound
        super().__init__(
            f"the energy rose by {gain:.4g} J net of the actuators' work from t = {start:.6g} s "
            f"to t = {end:.6g} s without any impact, beyond the bound {bound:.4g} J (a smaller "
            "dt reduces it)"
        )


class BilateralResidualWarning(_BeyondToleranceWarning):
    """A bilateral constraint h(q) = 0 was left unsolved beyond the tolerance.

    Attributes:
        constraint: The bilateral constraint's name.
        residual: The largest :math:`|h(q)|` in [m] (or [rad]).
        time: When it happened, in [s].
        tolerance: The tolerance in [m] (or [rad]).
    """

    def __init__(self, constraint: str, residual: float, time: float, tolerance: float) -> None:
        self.residual = residual
        hint = "a singular closed chain, or a step too large for it"
        what = "bilateral constraint {} left unsolved"
        super().__init__(what, constraint, residual, time, tolerance, hint)


class SolverIterationCapWarning(PhysicsWarning):
    """The contact solver reached its iteration cap in some steps (solved or not).

    A frictionless problem that needs the cap is degenerate: redundant or singular rows, e.g.
    a closed chain at a singular configuration; each such step costs the cap's iterations.

    Attributes:
        steps: Steps whose solve reached the cap.
        solves: Steps with a contact solve.
        cap: The cap (``[integrator] max_iter``).
        time: The first such step's time in [s].
    """

    def __init__(self, steps: int, solves: int, cap: int, time: float) -> None:
        self.steps = steps
        self.solves = solves
        self.cap = cap
        self.time = time
        super().__init__(
            f"the contact solver reached its iteration cap ({cap}) in {steps} of {solves} "
            f"solves, the first at t = {time:.6g} s: degenerate rows (redundant constraints, a "
            "closed chain at a singular configuration) that each cost the whole cap"
        )


class VideoError(UControlError):
    """A video of a run could not be written (ffmpeg missing or failing).

    Attributes:
        reason: What went wrong (ffmpeg's last messages when it failed).
    """

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(f"video: {reason}")


class CampaignError(UControlError):
    """A campaign file or a campaign run is not usable; the message says why."""


class CampaignFileError(CampaignError):
    """A campaign file is missing, not TOML, or its tables are malformed.

    Attributes:
        path: The campaign file.
        reason: What is wrong.
    """

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"campaign file {path!r}: {reason}")


class ParameterKeyError(CampaignError, KeyError):
    """A dotted key does not address a value of the base scene (or the scene rejects it).

    Attributes:
        key: The dotted key, e.g. ``"contacts.0.restitution"``.
        reason: Why it does not apply.
    """

    def __init__(self, key: str, reason: str) -> None:
        self.key = key
        self.reason = reason
        super().__init__(f"parameter {key!r}: {reason}")


class DistributionError(CampaignError, InvalidParameterError):
    """A distribution's parameters are out of range.

    Attributes:
        key: The swept dotted key.
        name: The distribution parameter, e.g. ``"high"``.
        value: The value received.
        expected: What it must be.
    """

    def __init__(self, key: str, name: str, value: Any, expected: str) -> None:
        self.key = key
        UControlError.__init__(
            self, f"distribution of {key!r}: `{name}` must be {expected}, got {value!r}"
        )
        self.name = name
        self.value = value
        self.expected = expected


class EmptyGridError(CampaignError, InvalidParameterError):
    """A grid parameter has no values (the cartesian product would be empty).

    Attributes:
        key: The dotted key whose list of values is empty.
    """

    def __init__(self, key: str, value: Any) -> None:
        self.key = key
        UControlError.__init__(
            self, f"grid of {key!r} must be a non-empty list of values, got {value!r}"
        )
        self.name = key
        self.value = value
        self.expected = "a non-empty list of values"


class UnknownMetricError(CampaignError, KeyError):
    """A metric is neither a ``summary.json`` key, a verdict, nor an importable function.

    Attributes:
        metric: The metric asked for.
        reason: Why it is not available.
        available: The metric names that exist for this scene.
    """

    def __init__(self, metric: str, reason: str, available: Iterable[str] = ()) -> None:
        self.metric = metric
        self.reason = reason
        self.available = sorted(available)
        listed = f"; available: {', '.join(self.available)}" if self.available else ""
        super().__init__(f"unknown metric {metric!r}: {reason}{listed}")


class CriterionError(CampaignError, InvalidParameterError):
    """A success criterion is not a valid expression of the allowed form.

    Attributes:
        expression: The criterion text.
        reason: What is not allowed in it.
    """

    def __init__(self, expression: str, reason: str) -> None:
        self.expression = expression
        self.reason = reason
        UControlError.__init__(self, f"success criterion {expression!r}: {reason}")
        self.name = "success"
        self.value = expression
        self.expected = "a comparison of metrics (see docs/campaigns.md)"


class OutputDirectoryError(CampaignError, OSError):
    """The output directory cannot be created or written.

    Attributes:
        directory: The directory given with ``--out``.
        reason: The operating system's reason.
    """

    def __init__(self, directory: str, reason: str) -> None:
        self.directory = directory
        self.reason = reason
        UControlError.__init__(self, f"output directory {directory!r} is not writable: {reason}")


class CampaignMismatchError(CampaignError):
    """The output directory holds the runs of another campaign (different plan or metrics).

    Attributes:
        directory: The output directory.
        found: The fingerprint recorded there.
        expected: The fingerprint of the campaign being run.
    """

    def __init__(self, directory: str, found: str, expected: str) -> None:
        self.directory = directory
        self.found = found
        self.expected = expected
        super().__init__(
            f"{directory!r} holds another campaign (fingerprint {found[:12]}, this one "
            f"{expected[:12]}): choose another --out, or delete the directory to start again"
        )


class SchedulerUnreachableError(CampaignError, ConnectionError):
    """No Dask scheduler answered at the address given.

    Attributes:
        address: The scheduler address, e.g. ``"tcp://host:8786"``.
        reason: The connection error.
    """

    def __init__(self, address: str, reason: str) -> None:
        self.address = address
        self.reason = reason
        UControlError.__init__(self, f"no Dask scheduler reachable at {address!r}: {reason}")
