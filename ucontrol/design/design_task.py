r"""A design task: what one cycle must do, read from a task file (TOML).

A task names a base scene (robot, surfaces, contacts with their restitution and friction, joint
stops), the tracked frame, the contact phase of the cycle (which contact, the force bounds, where
to land and to take off), the limits (torques from the URDF ``effort`` or the task, joint limits
from the URDF, a bound on the impact velocity and impulse), the cycle's period and the cost. The
file is read and every value checked before anything is built; errors name the key and value.

Format (every key but ``scene`` and one ``[[contact_phases]]`` entry is optional)::

    scene = "two_link_one_constraint.toml"   # base scene, relative to the task file
    frame = "end_effector"                   # tracked frame; default the contact's frame
    period = 10.0                            # [s] fixed period, or period_min/period_max
    bounces = 0                              # bounce flights between landing and contact
    locked_joints = []                       # joints held at the scene's q0 in the design
                                             # model (e.g. a gripper's fingers)

    [[contact_phases]]
    contact = "end_effector/ground"          # a [[contacts]] name of the scene
    force_min = 1.0                          # [N] during the constrained phase
    force_max = 50.0                         # [N]
    force = 5.0                              # [N] desired plateau (force cost, controller)
    landing = [0.55, 0.0, 0.0]               # [m] where the frame lands (optional)
    takeoff = [0.75, 0.0, 0.0]               # [m] where it takes off (optional)
    duration_min = 1.0                       # [s] of the constrained phase
    duration_max = 8.0
    takeoff_acceleration = 0.5               # [m/s²] normal acceleration at takeoff
    # with landing and takeoff, the frame slides from one toward the other (never back)

    [flight]
    duration_min = 1.0                       # [s]
    duration_max = 8.0
    clearance = 0.05                         # [m] gap >= clearance 4 s (1 - s) along the flight

    [limits]
    torque = [100.0, 100.0]                  # [N m]; default the URDF effort limits
    joint_limits = true                      # the URDF position limits, or these:
    joint_lower = [0.0, -2.5]                # [rad] (or [m])
    joint_upper = [3.1, -0.3]
    impact_velocity = 0.2                    # [m/s] largest normal speed at an impact
    impact_impulse = 1.0                     # [N s] largest impact impulse

    [cost]                                   # weighted sum of the terms
    effort = 1.0                             # ∫ τᵀτ dt               [N² m² s]
    dynamic_effort = 0.0                     # ∫ |τ - g(q)|² dt       [N² m² s]
    impulse = 0.0                            # Σ P²                   [N² s²]
    time = 0.0                               # period P               [s]
    force = 0.0                              # ∫ (λ - force)² dt      [N² s]
    smoothness = 1e-3                        # Σ |τ_{k+1} - τ_k|² / h [N² m² / s]

    [grid]
    flight_intervals = 30                    # control intervals (piecewise-constant τ)
    contact_intervals = 30
    bounce_intervals = 8
    substeps = 4                             # Runge–Kutta steps per control interval
    scheme = "rk4"                           # or "rk8" (order 8, DOP853's tableau)
    landing_interior = false                 # gap >= 0 also inside each landing interval

    [solver]
    max_iter = 1000
    tol = 1e-8
    print_level = 0
    progress_every = 10                      # iterations between two progress lines
    hessian = "exact"                        # or "limited-memory" (L-BFGS: large models)
    warm_start = false                       # true: IPOPT starts from the warm start as given
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import (
    as_non_negative,
    as_positive,
    as_vector,
    check_keys,
    require_key,
)
from ucontrol.contact.point_contact import PointContact
from ucontrol.exceptions import DesignError, InvalidParameterError, NotFoundError, SceneError
from ucontrol.model.robot_model import RobotModel
from ucontrol.scene import Scene

Vector = NDArray[np.float64]

_TOP_KEYS = {
    "scene",
    "frame",
    "period",
    "period_min",
    "period_max",
    "bounces",
    "locked_joints",
    "contact_phases",
    "flight",
    "limits",
    "cost",
    "grid",
    "solver",
}
_PHASE_KEYS = {
    "contact",
    "force_min",
    "force_max",
    "force",
    "landing",
    "takeoff",
    "duration_min",
    "duration_max",
    "takeoff_acceleration",
}
_FLIGHT_KEYS = {"duration_min", "duration_max", "clearance"}
_LIMIT_KEYS = {
    "torque",
    "joint_limits",
    "joint_lower",
    "joint_upper",
    "impact_velocity",
    "impact_impulse",
}
_COST_KEYS = {"effort", "dynamic_effort", "impulse", "time", "force", "smoothness"}
_GRID_KEYS = {
    "flight_intervals",
    "contact_intervals",
    "bounce_intervals",
    "substeps",
    "scheme",
    "landing_interior",
}
#: Explicit Runge–Kutta schemes of the shooting intervals and their orders.
SCHEMES = {"rk4": 4, "rk8": 8}
_SOLVER_KEYS = {"max_iter", "tol", "print_level", "progress_every", "hessian", "warm_start"}
#: IPOPT's Hessian of the Lagrangian: exact (casadi's second derivatives) or L-BFGS.
HESSIANS = ("exact", "limited-memory")


def positive_range(low_name: str, low: Any, high_name: str, high: Any) -> tuple[float, float]:
    """``low`` and ``high`` as floats with 0 < low <= high, or a typed error naming the one off.

    Raises:
        InvalidParameterError: A bound is not a finite number > 0, or ``high < low``.
    """
    low, high = as_positive(low_name, low), as_positive(high_name, high)
    if high < low:
        raise InvalidParameterError(high_name, high, f">= {low_name} = {low}")
    return low, high


def _count(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise InvalidParameterError(name, value, f"an integer >= {low}")
    return int(value)


@dataclass(frozen=True, kw_only=True)
class ContactPhaseSpec:
    """The constrained phase of the cycle on one contact.

    Attributes:
        contact: Name of the scene's point contact.
        force_min: Smallest normal contact force in [N] during the phase, >= 0.
        force_max: Largest normal contact force in [N], > force_min.
        force: Desired plateau in [N], > 0 (the ``force`` cost and the tracking controller).
        landing: World point where the frame lands, shape (3,) in [m], or None (free).
        takeoff: World point where the frame takes off, shape (3,) in [m], or None (free).
        duration_min: Shortest phase in [s], > 0.
        duration_max: Longest phase in [s].
        takeoff_acceleration: Smallest normal acceleration of the frame away from the surface
            just after takeoff, in [m/s²], > 0, so that the contact opens.
    """

    contact: str
    force_min: float = 0.5
    force_max: float = 100.0
    force: float = 5.0
    landing: Vector | None = None
    takeoff: Vector | None = None
    duration_min: float = 0.5
    duration_max: float = 20.0
    takeoff_acceleration: float = 0.5

    def __post_init__(self) -> None:
        object.__setattr__(self, "force_min", as_non_negative("force_min", self.force_min))
        object.__setattr__(self, "force_max", as_positive("force_max", self.force_max))
        object.__setattr__(self, "force", as_positive("force", self.force))
        if not self.force_max > self.force_min:
            raise InvalidParameterError(
                "force_max", self.force_max, f"> force_min = {self.force_min}"
            )
        for name in ("landing", "takeoff"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, as_vector(name, value, 3))
        low, high = positive_range(
            "duration_min", self.duration_min, "duration_max", self.duration_max
        )
        object.__setattr__(self, "duration_min", low)
        object.__setattr__(self, "duration_max", high)
        object.__setattr__(
            self,
            "takeoff_acceleration",
            as_positive("takeoff_acceleration", self.takeoff_acceleration),
        )


@dataclass(frozen=True, kw_only=True)
class FlightSpec:
    """The free flight from takeoff to landing.

    Attributes:
        duration_min: Shortest flight in [s], > 0.
        duration_max: Longest flight in [s].
        clearance: Gap at mid-flight in [m], >= 0: along the flight the gap is at least
            ``clearance * 4 s (1 - s)``, s in [0, 1] the fraction of the flight.
    """

    duration_min: float = 0.5
    duration_max: float = 20.0
    clearance: float = 0.0

    def __post_init__(self) -> None:
        low, high = positive_range(
            "duration_min", self.duration_min, "duration_max", self.duration_max
        )
        object.__setattr__(self, "duration_min", low)
        object.__setattr__(self, "duration_max", high)
        object.__setattr__(self, "clearance", as_non_negative("clearance", self.clearance))


@dataclass(frozen=True, kw_only=True)
class CostWeights:
    """Weights of the cost terms (see the module docstring for each term's units)."""

    effort: float = 1.0
    dynamic_effort: float = 0.0
    impulse: float = 0.0
    time: float = 0.0
    force: float = 0.0
    smoothness: float = 1e-3

    def __post_init__(self) -> None:
        for name in _COST_KEYS:
            object.__setattr__(self, name, as_non_negative(name, getattr(self, name)))
        if not any(getattr(self, name) > 0.0 for name in _COST_KEYS):
            raise InvalidParameterError("[cost]", {}, "at least one weight > 0")


@dataclass(frozen=True, kw_only=True)
class GridSpec:
    """Multiple-shooting grid: control intervals per phase, Runge–Kutta steps per interval.

    Attributes:
        flight_intervals: Control intervals of the flight.
        contact_intervals: Control intervals of the contact phase.
        bounce_intervals: Control intervals of each bounce flight.
        substeps: Runge–Kutta steps per control interval.
        scheme: ``"rk4"`` (classical, order 4) or ``"rk8"`` (the order-8 tableau of
            Dormand–Prince's DOP853, 12 stages): ``"rk8"`` makes the shooting defect reach
            rounding (about 1e-15 rad per interval on the two-link task with 8 substeps).
        landing_interior: Also keep the gap >= 0 inside the last interval of each flight, at
            a quarter, half and three quarters of its Runge–Kutta steps (quintic Hermite
            interpolant of the gap, its velocity and acceleration): a soft landing otherwise
            dips through the surface between two points by up to ~1e-7 m, which the plant
            sees as an early landing.
    """

    flight_intervals: int = 30
    contact_intervals: int = 30
    bounce_intervals: int = 8
    substeps: int = 4
    scheme: str = "rk4"
    landing_interior: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.landing_interior, bool):
            raise InvalidParameterError("landing_interior", self.landing_interior, "true or false")
        for name in _GRID_KEYS - {"scheme", "landing_interior"}:
            object.__setattr__(self, name, _count(name, getattr(self, name), 2))
        if self.scheme not in SCHEMES:
            raise InvalidParameterError("scheme", self.scheme, f"one of {sorted(SCHEMES)}")


@dataclass(frozen=True, kw_only=True)
class SolverSpec:
    """IPOPT settings and how often a progress line is written.

    Attributes:
        max_iter: Largest number of IPOPT iterations.
        tol: IPOPT's convergence tolerance.
        print_level: IPOPT's output level (0: none).
        progress_every: Iterations between two progress lines.
        hessian: ``"exact"`` (casadi's second derivatives) or ``"limited-memory"`` (IPOPT's
            L-BFGS: more iterations, each much cheaper for a many-joint robot).
        warm_start: IPOPT starts from the warm start as given (``warm_start_init_point``)
            instead of pushing it into the interior of the bounds: half the iterations on the
            two-link task, but the Panda's, far from feasible, wanders (docs/benchmarks.md).
    """

    max_iter: int = 1000
    tol: float = 1e-8
    print_level: int = 0
    progress_every: int = 10
    hessian: str = "exact"
    warm_start: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.warm_start, bool):
            raise InvalidParameterError("warm_start", self.warm_start, "true or false")
        object.__setattr__(self, "max_iter", _count("max_iter", self.max_iter, 1))
        object.__setattr__(self, "tol", as_positive("tol", self.tol))
        object.__setattr__(self, "print_level", _count("print_level", self.print_level, 0))
        object.__setattr__(self, "progress_every", _count("progress_every", self.progress_every, 1))
        if self.hessian not in HESSIANS:
            raise InvalidParameterError("hessian", self.hessian, f"one of {list(HESSIANS)}")


@dataclass(frozen=True, kw_only=True)
class DesignTask:
    """Everything the optimal-control problem of one cycle needs.

    Attributes:
        scene: The base scene (robot, contacts, stops, hand-made cycle in its controller).
        frame: The tracked frame.
        contact_phase: The constrained phase (one contact per cycle).
        flight: The free flight.
        period: Fixed period in [s], or None when it is free in [period_min, period_max].
        period_min: Shortest period in [s].
        period_max: Longest period in [s].
        bounces: Bounce flights between the first landing and the constrained phase.
        torque_limit: Largest absolute torque of each joint in [N m] (or [N]), shape (nv,).
        joint_limits: Lower and upper joint positions, shape (2, nv), or None.
        impact_velocity: Largest normal speed at an impact in [m/s] (inf: none).
        impact_impulse: Largest impact impulse in [N s] (inf: none).
        cost: Weights of the cost terms.
        grid: The multiple-shooting grid.
        solver: IPOPT settings.
        source: The task file, or None.
    """

    scene: Scene
    frame: str
    contact_phase: ContactPhaseSpec
    flight: FlightSpec = field(default_factory=FlightSpec)
    period: float | None = None
    period_min: float = 0.0
    period_max: float = math.inf
    bounces: int = 0
    torque_limit: Vector
    joint_limits: NDArray[np.float64] | None = None
    impact_velocity: float = math.inf
    impact_impulse: float = math.inf
    cost: CostWeights = field(default_factory=CostWeights)
    grid: GridSpec = field(default_factory=GridSpec)
    solver: SolverSpec = field(default_factory=SolverSpec)
    source: Path | None = None

    def __post_init__(self) -> None:
        robot = self.scene.robot
        robot.frame_id(self.frame)
        contact = self.contact  # checks the name
        object.__setattr__(self, "bounces", _count("bounces", self.bounces, 0))
        if self.bounces and contact.restitution == 0.0:
            raise InvalidParameterError(
                "bounces", self.bounces, f"0 for the plastic contact {contact.name!r} (e = 0)"
            )
        torque = as_vector("torque", self.torque_limit, robot.nv)
        if np.any(torque <= 0.0):
            raise InvalidParameterError("torque", torque.tolist(), "limits > 0")
        object.__setattr__(self, "torque_limit", torque)
        if self.period is not None:
            object.__setattr__(self, "period", as_positive("period", self.period))
        object.__setattr__(self, "period_min", as_non_negative("period_min", self.period_min))
        period_max = float(self.period_max)
        if not period_max > self.period_min:
            raise InvalidParameterError("period_max", self.period_max, f"> {self.period_min}")
        object.__setattr__(self, "period_max", period_max)
        for name in ("impact_velocity", "impact_impulse"):
            value = float(getattr(self, name))
            if not value > 0.0:
                raise InvalidParameterError(name, getattr(self, name), "> 0")
            object.__setattr__(self, name, value)
        if robot.model.nq != robot.nv:
            raise DesignError("design needs a robot with nq = nv (revolute/prismatic joints)")

    @property
    def contact(self) -> PointContact:
        """The scene's point contact of the contact phase."""
        contacts = {contact.name: contact for contact in self.scene.contacts}
        name = self.contact_phase.contact
        if name not in contacts:
            raise NotFoundError("contact", name, list(contacts))
        return contacts[name]

    @property
    def zeno_velocity(self) -> float:
        """The plant's plastic threshold in [m/s]: an impact rebounding slower is plastic."""
        return float(self.scene.integrator.zeno_velocity)

    @classmethod
    def from_toml(cls, path: str | Path) -> DesignTask:
        """Read and check a task file; the scene path is relative to the file.

        Raises:
            SceneError: The file is missing, not TOML, or misses a required key.
            UnknownKeyError: A table holds a key the format does not define.
            InvalidParameterError: A value is out of its admissible set (names key and value).
            NotFoundError: The contact or frame is not in the scene.
        """
        path = Path(path)
        if not path.is_file():
            raise SceneError(f"task file {str(path)!r} does not exist")
        try:
            table = tomllib.loads(path.read_text())
        except tomllib.TOMLDecodeError as error:
            raise SceneError(f"task file {str(path)!r} is not valid TOML: {error}") from error
        return cls.from_dict(table, base_dir=path.parent, source=path.resolve())

    @classmethod
    def from_dict(
        cls, table: Mapping[str, Any], *, base_dir: Path, source: Path | None = None
    ) -> DesignTask:
        """Build a task from its parsed TOML table (see :meth:`from_toml`)."""
        check_keys("the task", table, _TOP_KEYS)
        scene_path = Path(str(require_key(table, "the task", "scene")))
        if not scene_path.is_absolute():
            scene_path = base_dir / scene_path
        scene = Scene.from_toml(scene_path)
        if table.get("locked_joints"):
            scene = locked_scene(scene, table["locked_joints"])
        phases = require_key(table, "the task", "contact_phases")
        if not isinstance(phases, list) or len(phases) != 1:
            raise InvalidParameterError(
                "contact_phases", phases, "one [[contact_phases]] entry (one contact per cycle)"
            )
        check_keys("[[contact_phases]]", phases[0], _PHASE_KEYS)
        require_key(phases[0], "[[contact_phases]]", "contact")
        phase = ContactPhaseSpec(**phases[0])
        sections = {}
        for name, keys in (
            ("flight", _FLIGHT_KEYS),
            ("limits", _LIMIT_KEYS),
            ("cost", _COST_KEYS),
            ("grid", _GRID_KEYS),
            ("solver", _SOLVER_KEYS),
        ):
            sections[name] = dict(table.get(name, {}))
            check_keys(f"[{name}]", sections[name], keys)
        limits = sections["limits"]
        model = scene.robot.model
        torque = limits.get("torque", np.asarray(model.effortLimit, dtype=float))
        joint_limits = None
        if limits.get("joint_limits", True) is True:
            nv = scene.robot.nv
            lower = as_vector(
                "joint_lower", limits.get("joint_lower", model.lowerPositionLimit), nv
            )
            upper = as_vector(
                "joint_upper", limits.get("joint_upper", model.upperPositionLimit), nv
            )
            if np.any(upper <= lower):
                raise InvalidParameterError(
                    "joint_upper", upper.tolist(), f"> joint_lower = {lower.tolist()}"
                )
            joint_limits = np.vstack((lower, upper))
        elif limits["joint_limits"] is not False:
            raise InvalidParameterError("joint_limits", limits["joint_limits"], "true or false")
        contacts = [contact.name for contact in scene.contacts]
        if phase.contact not in contacts:
            raise NotFoundError("contact", phase.contact, contacts)
        frame = str(
            table.get("frame", next(c.frame for c in scene.contacts if c.name == phase.contact))
        )
        return cls(
            scene=scene,
            frame=frame,
            contact_phase=phase,
            flight=FlightSpec(**sections["flight"]),
            period=table.get("period"),
            period_min=table.get("period_min", 0.0),
            period_max=table.get("period_max", math.inf),
            bounces=table.get("bounces", 0),
            torque_limit=torque,
            joint_limits=joint_limits,
            impact_velocity=limits.get("impact_velocity", math.inf),
            impact_impulse=limits.get("impact_impulse", math.inf),
            cost=CostWeights(**sections["cost"]),
            grid=GridSpec(**sections["grid"]),
            solver=SolverSpec(**sections["solver"]),
            source=source,
        )


def locked_scene(scene: Scene, joints: Any) -> Scene:
    """The scene with ``joints`` held at its ``q0``: the design model of a task.

    Joints the task does not use (a gripper's fingers: 15 g on the Panda, whose accelerations
    under any torque scale the problem badly) are removed from the design's model with
    Pinocchio's ``buildReducedModel``; the designed cycle then has the remaining joints only,
    and the tracking controllers take its frame path (a closed loop runs on the whole scene).

    Raises:
        InvalidParameterError: ``joints`` is not a list of joint names.
        NotFoundError: A name is not a joint of the robot.
        DesignError: The scene has joint stops, flexible joints or joint friction (not
            reduced with the model).
    """
    robot = scene.robot
    if not isinstance(joints, list) or not all(isinstance(name, str) for name in joints):
        raise InvalidParameterError("locked_joints", joints, "a list of joint names")
    names = robot.joint_names
    for name in joints:
        if name not in names:
            raise NotFoundError("joint", name, names)
    if scene.stops or scene.flexible is not None or scene.joint_friction is not None:
        raise DesignError(
            "locked_joints needs a scene without joint stops, flexible joints or joint friction"
        )
    model = robot.model
    ids = [model.getJointId(name) for name in joints]
    reduced = pin.buildReducedModel(model, ids, scene.q0)
    keep = [model.joints[i].idx_q for i in range(1, model.njoints) if model.names[i] not in joints]
    return replace(
        scene,
        robot=RobotModel(reduced, urdf_path=robot.urdf_path, mjcf_path=robot.mjcf_path),
        q0=scene.q0[keep],
        v0=scene.v0[keep],
    )
