r"""A gait-design task: one walking step of a planar biped, read from a task file (TOML).

The robot has a planar floating base (two prismatic joints along x and z, one revolute about y:
the hip's position and the torso's angle), two legs of a hip and a knee each and a point foot at
the end of each leg, and walks along +x on the flat ground z = 0. The task names the legs, the
stance foot of the designed step, the step length (or the walking speed), the bounds of the step
time, the friction coefficient, the swing foot's clearance, the limits, the grid and IPOPT's
settings. The file is read and every value checked before anything is built; errors name the
key and the value.

Format (``kind = "gait"`` tells ``ucontrol design`` that the file is a gait task; every key but
``kind``, ``urdf``, ``legs`` and ``step_length`` is optional)::

    kind = "gait"
    urdf = "rabbit.urdf"                     # relative to the task file
    passive = ["x", "z", "pitch"]            # the planar base (x, z, pitch), in that order
    legs = [["hip_left", "knee_left", "foot_left"], ["hip_right", "knee_right", "foot_right"]]
    stance = "foot_left"                     # stance foot of the designed step
    step_length = 0.4                        # [m] from the old to the new stance foot
    # speed = 1.0                            # [m/s] fixes the step time to step_length/speed
    step_time_min = 0.25                     # [s] bounds of a free step time
    step_time_max = 0.8
    friction = 0.7                           # Coulomb coefficient of the design's feet
    scene_friction = 0.8                     # the written scene's (default: friction); above
                                             # friction, a margin for the tracking controller
    clearance = 0.05                         # [m] swing foot height >= clearance 4 s (1 - s)
    force_min = 0.0                          # [N] smallest normal force on the stance foot

    [limits]
    torque = 150.0                           # [N m] on every actuated joint
    knee = [0.0, 2.5]                        # [rad] knee bounds (bent one way, no hyperextension)
    hip = [-1.5, 1.5]                        # [rad] hip bounds
    pitch = [-0.5, 0.5]                      # [rad] torso angle bounds
    hip_height = 0.0                         # [m] smallest height of the hips above the ground
    impact_impulse = 50.0                    # [N s] largest normal heel-strike impulse

    [grid]
    intervals = 30                           # control intervals (piecewise-constant torques)
    substeps = 2                             # classical Runge–Kutta (RK4) steps per interval

    [fit]
    degree = 5                               # Bézier degree M of the virtual constraints (4-6)
    weight = 1e5                             # [N² m² s / m / rad²] on the mean squared misfit
                                             # of q_a from a Bézier h_d(s) (0: none)
    kp = 400.0                               # [1/s²] the HZD controller's output gains
    kd = 40.0                                # [1/s]

    [solver]
    max_iter = 500
    tol = 1e-8
    print_level = 0
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import (
    as_float,
    as_int,
    as_non_negative,
    as_positive,
    as_vector,
    check_keys,
    require_key,
)
from ucontrol.design.design_task import positive_range
from ucontrol.design.designed_gait import output_indices, relabelling_matrix
from ucontrol.exceptions import InvalidParameterError, NotFoundError, SceneError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]

#: Top-level keys passed to :class:`GaitTask` as they are.
_PLAIN_KEYS = (
    "stance",
    "speed",
    "step_time_min",
    "step_time_max",
    "friction",
    "scene_friction",
    "clearance",
    "force_min",
)
_TOP_KEYS = {"kind", "urdf", "passive", "legs", "step_length", "limits", "grid", "fit", "solver"}
_TOP_KEYS |= set(_PLAIN_KEYS)
_LIMIT_KEYS = {"torque", "knee", "hip", "pitch", "hip_height", "impact_impulse"}
_GRID_KEYS = {"intervals", "substeps"}
_FIT_KEYS = {"degree", "weight", "kp", "kd"}
_SOLVER_KEYS = {"max_iter", "tol", "print_level"}
#: Bézier degrees of the fitted virtual constraints (four endpoint coefficients are fixed).
DEGREES = (4, 5, 6)


@dataclass(frozen=True, kw_only=True)
class GaitTask:
    """Everything the optimal-control problem of one walking step needs.

    Attributes:
        robot: The biped; its first three joints are the planar base (x, z, pitch), passive.
        legs: ``((hip, knee, foot), (hip, knee, foot))`` joint and frame names of the legs.
        stance: The stance foot of the designed step (a foot of ``legs``).
        step_length: Distance from the old to the new stance foot in [m], > 0.
        speed: Walking speed in [m/s] fixing the step time, or None (step time free).
        step_time_min: Shortest step in [s], > 0.
        step_time_max: Longest step in [s].
        friction: Coulomb friction coefficient of the feet in the design, > 0.
        scene_friction: Coefficient of the feet in the written scene, > 0, or None (the
            design's): above ``friction``, a margin for the controller's own torques.
        clearance: Swing foot height in [m] at mid-step: along the step its height is at
            least ``clearance * 4 s (1 - s)``, s in [0, 1] the fraction of the step time.
        force_min: Smallest normal force on the stance foot in [N], >= 0.
        torque_limit: Largest absolute torque of the actuated joints in [N m], > 0.
        knee_bounds: Knee angle bounds (lower, upper) in [rad].
        hip_bounds: Hip angle bounds (lower, upper) in [rad].
        pitch_bounds: Torso angle bounds (lower, upper) in [rad].
        hip_height_min: Smallest height of the hips above the ground in [m].
        impact_impulse: Largest normal heel-strike impulse in [N s].
        intervals: Control intervals of the step (piecewise-constant torques).
        substeps: RK4 steps per control interval.
        degree: Bézier degree of the fitted virtual constraints, in :data:`DEGREES`.
        fit_weight: Weight of the step's mean squared misfit from a Bézier virtual constraint
            of that degree in the cost, in [N² m² s / m / rad²], >= 0 (0: none): a step that
            the fit then reproduces.
        kp: Proportional gain of the HZD controller in [1/s²].
        kd: Derivative gain of the HZD controller in [1/s].
        max_iter: Largest number of IPOPT iterations.
        tol: IPOPT's convergence tolerance.
        print_level: IPOPT's output level (0: none).
        source: The task file, or None.
    """

    robot: RobotModel
    legs: tuple[tuple[str, str, str], tuple[str, str, str]]
    stance: str
    step_length: float
    speed: float | None = None
    step_time_min: float = 0.25
    step_time_max: float = 0.8
    friction: float = 0.7
    scene_friction: float | None = None
    clearance: float = 0.05
    force_min: float = 0.0
    torque_limit: float = 150.0
    knee_bounds: tuple[float, float] = (0.0, 2.5)
    hip_bounds: tuple[float, float] = (-1.5, 1.5)
    pitch_bounds: tuple[float, float] = (-0.5, 0.5)
    hip_height_min: float = 0.0
    impact_impulse: float = 50.0
    intervals: int = 30
    substeps: int = 2
    degree: int = 5
    fit_weight: float = 1e5
    kp: float = 400.0
    kd: float = 40.0
    max_iter: int = 500
    tol: float = 1e-8
    print_level: int = 0
    source: Path | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        robot = self.robot
        names = robot.joint_names
        if robot.nq != robot.nv or len(names) < 3 or list(robot.passive_joints) != names[:3]:
            raise InvalidParameterError(
                "passive",
                list(robot.passive_joints),
                "the robot's first three joints (its planar base x, z, pitch), passive",
            )
        if len(self.legs) != 2 or any(len(leg) != 3 for leg in self.legs):
            raise InvalidParameterError("legs", self.legs, "two [hip, knee, foot] triples")
        for hip, knee, foot in self.legs:
            robot.joint_id(hip)
            robot.joint_id(knee)
            robot.frame_id(foot)
        used = [name for leg in self.legs for name in leg[:2]]
        if sorted(used) != sorted(names[3:]):
            raise InvalidParameterError(
                "legs", self.legs, f"the hips and knees of the robot, each once: {names[3:]}"
            )
        feet = [leg[2] for leg in self.legs]
        if self.stance not in feet:
            raise NotFoundError("stance foot", self.stance, feet)
        object.__setattr__(self, "step_length", as_positive("step_length", self.step_length))
        if self.speed is not None:
            object.__setattr__(self, "speed", as_positive("speed", self.speed))
        low, high = positive_range(
            "step_time_min", self.step_time_min, "step_time_max", self.step_time_max
        )
        object.__setattr__(self, "step_time_min", low)
        object.__setattr__(self, "step_time_max", high)
        object.__setattr__(self, "friction", as_positive("friction", self.friction))
        if self.scene_friction is not None:
            object.__setattr__(
                self, "scene_friction", as_positive("scene_friction", self.scene_friction)
            )
        for name in ("clearance", "force_min", "fit_weight"):
            object.__setattr__(self, name, as_non_negative(name, getattr(self, name)))
        for name in ("torque_limit", "impact_impulse", "kp", "kd", "tol"):
            object.__setattr__(self, name, as_positive(name, getattr(self, name)))
        for key, name in (
            ("knee", "knee_bounds"),
            ("hip", "hip_bounds"),
            ("pitch", "pitch_bounds"),
        ):
            object.__setattr__(self, name, _bounds(key, getattr(self, name)))
        object.__setattr__(self, "hip_height_min", as_float("hip_height", self.hip_height_min))
        object.__setattr__(self, "intervals", as_int("intervals", self.intervals, 4))
        object.__setattr__(self, "substeps", as_int("substeps", self.substeps, 1))
        object.__setattr__(self, "max_iter", as_int("max_iter", self.max_iter, 1))
        object.__setattr__(self, "print_level", as_int("print_level", self.print_level, 0))
        if self.degree not in DEGREES:
            raise InvalidParameterError("degree", self.degree, f"one of {list(DEGREES)}")

    @property
    def written_friction(self) -> float:
        """Coulomb coefficient of the feet in the written scene."""
        return self.friction if self.scene_friction is None else self.scene_friction

    @property
    def swing(self) -> str:
        """The swing foot of the designed step."""
        return next(leg[2] for leg in self.legs if leg[2] != self.stance)

    @property
    def stance_leg(self) -> tuple[str, str, str]:
        """``(hip, knee, foot)`` of the stance leg."""
        return next(leg for leg in self.legs if leg[2] == self.stance)

    @property
    def swing_leg(self) -> tuple[str, str, str]:
        """``(hip, knee, foot)`` of the swing leg."""
        return next(leg for leg in self.legs if leg[2] != self.stance)

    @property
    def actuated_indices(self) -> NDArray[np.intp]:
        """Indices in v of q_a = (stance hip, stance knee, swing hip, swing knee), shape (4,)."""
        return output_indices(self.robot, self.legs, self.stance)

    def relabelling(self) -> Vector:
        """The matrix R (nv, nv) swapping the legs' joints: the base rows are the identity."""
        return relabelling_matrix(self.robot, self.legs)

    @classmethod
    def from_toml(cls, path: str | Path) -> GaitTask:
        """Read and check a gait task file (module docstring).

        Raises:
            SceneError: The file cannot be read or is not TOML.
            UnknownKeyError: A table holds a key the format does not know.
            InvalidParameterError: A value is out of its range (the key and value named).
            URDFError: The URDF does not exist or is not valid.
        """
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError) as error:
            raise SceneError(f"cannot read gait task {path}: {error}") from error
        return cls.from_dict(data, base=path.parent, source=path)

    @classmethod
    def from_dict(
        cls, data: dict[str, Any], *, base: Path = Path("."), source: Path | None = None
    ) -> GaitTask:
        """Build a task from a parsed task file; ``base`` resolves the URDF's relative path."""
        check_keys("gait task", data, _TOP_KEYS)
        kind = data.get("kind", "gait")
        if kind != "gait":
            raise InvalidParameterError("kind", kind, '"gait"')
        urdf = base / str(require_key(data, "gait task", "urdf"))
        passive = data.get("passive", ["x", "z", "pitch"])
        robot = RobotModel.from_urdf(urdf)
        robot = RobotModel(robot.model, urdf_path=robot.urdf_path, passive_joints=passive)
        legs_raw = require_key(data, "gait task", "legs")
        try:
            legs = tuple(tuple(str(name) for name in leg) for leg in legs_raw)
        except TypeError as error:
            expected = "two [hip, knee, foot] triples"
            raise InvalidParameterError("legs", legs_raw, expected) from error
        kwargs: dict[str, Any] = {key: data[key] for key in _PLAIN_KEYS if key in data}
        kwargs.setdefault("stance", legs[0][2] if legs and len(legs[0]) == 3 else "")
        limits = data.get("limits", {})
        check_keys("limits", limits, _LIMIT_KEYS)
        for key, name in (
            ("torque", "torque_limit"),
            ("knee", "knee_bounds"),
            ("hip", "hip_bounds"),
            ("pitch", "pitch_bounds"),
            ("hip_height", "hip_height_min"),
            ("impact_impulse", "impact_impulse"),
        ):
            if key in limits:
                kwargs[name] = limits[key]
        for section, keys in (("grid", _GRID_KEYS), ("fit", _FIT_KEYS), ("solver", _SOLVER_KEYS)):
            table = data.get(section, {})
            check_keys(section, table, keys)
            kwargs.update(table)
        if "weight" in kwargs:
            kwargs["fit_weight"] = kwargs.pop("weight")
        return cls(
            robot=robot,
            legs=legs,  # type: ignore[arg-type]
            step_length=require_key(data, "gait task", "step_length"),
            source=source,
            **kwargs,
        )


def _bounds(name: str, value: Any) -> tuple[float, float]:
    """``value`` as finite bounds (lower, upper) with lower < upper, or a typed error."""
    bounds = as_vector(name, value, 2)
    if not bounds[0] < bounds[1]:
        raise InvalidParameterError(name, value, "[lower, upper] with lower < upper")
    return float(bounds[0]), float(bounds[1])
