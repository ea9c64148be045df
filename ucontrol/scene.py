"""Declarative scenes: a TOML file -> robot, constraints, integrator and controller.

A scene builds only what it declares. The format is documented in ``docs/scene_format.md``;
unknown keys are an error that names them.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import (
    as_float,
    as_in_interval,
    as_positive,
    as_vector,
    check_keys,
    require_key,
)
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.contact.joint_stop import JointStop
from ucontrol.contact.plane import Plane
from ucontrol.contact.point_contact import PointContact
from ucontrol.contact.sphere_sphere_contact import SphereSphereContact
from ucontrol.control.brogliato_controller import BrogliatoController, BrogliatoGains
from ucontrol.control.circle_path import CirclePath
from ucontrol.control.controller import Controller
from ucontrol.control.desired_cycle import ContactPhase, DesiredCycle
from ucontrol.control.flexible_brogliato_controller import FlexibleBrogliatoController
from ucontrol.control.joint_pd import JointPD
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.control.zero_torque import ZeroTorque
from ucontrol.exceptions import InvalidParameterError, NotFoundError, SceneError
from ucontrol.integrators import compliant, event_driven
from ucontrol.integrators.compliant import Compliant
from ucontrol.integrators.event_driven import EventDriven
from ucontrol.integrators.moreau_jean import ON_UNSOLVED, PERSISTENCE_TOLERANCE, MoreauJean
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.robot_model import RobotModel
from ucontrol.model.urdf_path import resolve_urdf
from ucontrol.solvers.contact_solver import build_contact_solvers, check_contact_solver
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

#: Scene run by ``ucontrol run`` without a scene argument.
DEFAULT_SCENE = "two_link_drop.toml"

INTEGRATORS = ("moreau_jean", "event_driven", "compliant")
#: Analytic references a scene may declare in its ``[reference]`` table.
REFERENCES = ("bouncing_ball",)
CONTROLLERS = ("brogliato", "joint_pd", "zero")

_TOP_KEYS = {
    "name",
    "duration",
    "robot",
    "surfaces",
    "contacts",
    "sphere_contacts",
    "stops",
    "integrator",
    "controller",
    "reference",
}
_ROBOT_KEYS = {"urdf", "floating_base", "q0", "v0", "gravity", "planar_axis", "flexible"}
_FLEXIBLE_KEYS = {"joints", "stiffness", "motor_inertia", "damping", "q0", "v0"}
_SURFACE_KEYS = {"type", "point", "normal"}
_CONTACT_KEYS = {"frame", "surface", "radius", "restitution", "friction", "name"}
_SPHERE_CONTACT_KEYS = {
    "frame",
    "other_frame",
    "radius",
    "other_radius",
    "restitution",
    "friction",
    "name",
}
_STOP_KEYS = {"joint", "lower", "upper", "restitution"}
_INTEGRATOR_KEYS = {
    "name",
    "dt",
    "theta",
    "contact_tolerance",
    "max_iter",
    "rtol",
    "atol",
    "method",
    "zeno_velocity",
    "stiffness",
    "contact_model",
    "restitution_threshold",
    "contact_solver",
    "friction_tolerance",
    "friction_max_iter",
    "on_unsolved",
    "midpoint",
    "persistence_tolerance",
}
_METHODS = {"event_driven": event_driven.METHODS, "compliant": compliant.METHODS}
_REFERENCE_KEYS = {"bouncing_ball": {"type", "contact"}}
_CYCLE_KEYS = (
    "approach_time",
    "depth_gain",
    "depth_exponent",
    "depth_min",
    "depth_max",
    "rest_time",
    "force_fall_time",
    "takeoff_acceleration",
    "takeoff_time",
    "blend_time",
    "takeoff_ramp_time",
)
_BROGLIATO_GAIN_KEYS = ("force_gain", "posture_gain", "null_space_gain")
_CONTROLLER_KEYS = {
    "zero": {"type"},
    "joint_pd": {"type", "kp", "kd", "q_ref", "gravity_compensation"},
    "brogliato": {
        "type",
        "frame",
        "contacts",
        "tangents",
        "gamma1",
        "gamma2",
        "posture",
        "mass_scale",
        "path",
        "contact_phases",
        *_BROGLIATO_GAIN_KEYS,
        *_CYCLE_KEYS,
    },
}
_PATH_KEYS = {"type", "centre", "radius", "period", "axes", "start_angle"}
_CONTACT_PHASE_KEYS = {"contact", "start", "end", "force"}


@dataclass(frozen=True, kw_only=True)
class IntegratorSettings:
    """How a scene advances in time.

    Attributes:
        name: Integrator name, one of :data:`INTEGRATORS`.
        dt: Time step in [s].
        theta: θ of the Moreau–Jean position update, in [1/2, 1].
        contact_tolerance: Absolute tolerance of the contact solver in [m/s].
        max_iter: Iteration cap of the contact solver.
        rtol: Relative tolerance of solve_ivp (event_driven, compliant); None: the
            integrator's default (1e-10 event_driven, 1e-8 compliant).
        atol: Absolute tolerance of solve_ivp in the state's units; None: the integrator's
            default (1e-12 event_driven, 1e-10 compliant).
        method: solve_ivp method: ``"DOP853"`` or ``"RK45"`` (event_driven), ``"Radau"``,
            ``"BDF"`` or ``"LSODA"`` (compliant); None: DOP853 or Radau.
        zeno_velocity: Rebound speed in [m/s] below which event_driven makes an impact
            plastic, cutting accumulations of impacts.
        stiffness: Contact stiffness of compliant, in [N/m] (linear) or [N/m^1.5]
            (Hunt–Crossley).
        contact_model: Force law of compliant, ``"linear"`` or ``"hunt_crossley"``.
        restitution_threshold: Closing speed in [m/s] below which Moreau–Jean treats a contact
            as persistent (e = 0); 0 applies Newton's law to every closing contact.
        contact_solver: Contact solver of Moreau–Jean: ``"proxsuite"``, ``"pinocchio-admm"``,
            ``"pinocchio-pgs"`` or ``"qpsolvers:<solver>"`` (frictionless scenes only).
        friction_tolerance: Natural-map residual of the Coulomb problem a step must reach,
            in [m/s].
        friction_max_iter: Cap on the fixed-point iterations of the proxsuite friction solver.
        on_unsolved: ``"raise"`` or ``"warn"`` when a contact solve ends above its tolerance.
        midpoint: Moreau–Jean evaluates inertia, gravity and Coriolis forces at the step's
            midpoint: second order between impacts (see :class:`MoreauJean`).
        persistence_tolerance: Predicted gap in [m] up to which Moreau–Jean keeps a constraint
            that carried an impulse in the previous step active; 0 turns it off.

    Keys that do not concern the chosen integrator are checked and ignored, so one scene can
    be run with every integrator.
    """

    name: str = "moreau_jean"
    dt: float = 1e-3
    theta: float = 0.5
    contact_tolerance: float = 1e-10
    max_iter: int = 5000
    rtol: float | None = None
    atol: float | None = None
    method: str | None = None
    zeno_velocity: float = 1e-5
    stiffness: float = 1e6
    contact_model: str = "linear"
    restitution_threshold: float = 0.0
    contact_solver: str = "proxsuite"
    friction_tolerance: float = 1e-8
    friction_max_iter: int = 100
    on_unsolved: str = "raise"
    midpoint: bool = False
    persistence_tolerance: float = PERSISTENCE_TOLERANCE

    def __post_init__(self) -> None:
        check_contact_solver(self.contact_solver)
        if not isinstance(self.midpoint, bool):
            raise InvalidParameterError("midpoint", self.midpoint, "true or false")
        tolerance = as_float("persistence_tolerance", self.persistence_tolerance)
        if not tolerance >= 0.0:  # also rejects NaN
            raise InvalidParameterError("persistence_tolerance", tolerance, "a length >= 0 in [m]")
        object.__setattr__(self, "persistence_tolerance", tolerance)
        object.__setattr__(
            self, "friction_tolerance", as_positive("friction_tolerance", self.friction_tolerance)
        )
        object.__setattr__(
            self, "friction_max_iter", int(as_positive("friction_max_iter", self.friction_max_iter))
        )
        if self.on_unsolved not in ON_UNSOLVED:
            raise InvalidParameterError("on_unsolved", self.on_unsolved, f"one of {ON_UNSOLVED}")
        if self.name not in INTEGRATORS:
            raise NotFoundError("integrator", self.name, INTEGRATORS)
        object.__setattr__(self, "dt", as_positive("dt", self.dt))
        object.__setattr__(self, "theta", as_in_interval("theta", self.theta, 0.5, 1.0))
        object.__setattr__(
            self, "contact_tolerance", as_positive("contact_tolerance", self.contact_tolerance)
        )
        object.__setattr__(self, "max_iter", int(as_positive("max_iter", self.max_iter)))
        for key in ("rtol", "atol"):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, as_positive(key, getattr(self, key)))
        methods = _METHODS.get(self.name, (*event_driven.METHODS, *compliant.METHODS))
        if self.method is not None and self.method not in methods:
            raise InvalidParameterError("method", self.method, f"one of {list(methods)}")
        object.__setattr__(self, "zeno_velocity", as_positive("zeno_velocity", self.zeno_velocity))
        object.__setattr__(self, "stiffness", as_positive("stiffness", self.stiffness))
        if self.contact_model not in compliant.CONTACT_MODELS:
            raise InvalidParameterError(
                "contact_model", self.contact_model, f"one of {list(compliant.CONTACT_MODELS)}"
            )

    def solver_options(self) -> dict[str, Any]:
        """The solve_ivp settings given (rtol, atol, method), as keyword arguments."""
        return {
            key: getattr(self, key)
            for key in ("rtol", "atol", "method")
            if getattr(self, key) is not None
        }


@dataclass(frozen=True, kw_only=True)
class Scene:
    """A robot, what it can touch, its initial state, and how to run it.

    Attributes:
        name: Label used in logs.
        robot: The robot.
        contacts: Point contacts.
        stops: Joint stops.
        sphere_contacts: Contacts between two spheres on robot frames.
        planar_axis: Unit normal of the plane the robot moves in, shape (3,): its frictional
            contacts are then planar (one tangent), else spatial (two); None: spatial.
        q0: Initial configuration of the links, shape (nq,).
        v0: Initial velocity of the links, shape (nv,).
        flexible: Flexible joints (their motor coordinates join the state), or None.
        motor_q0: Initial motor positions of the flexible joints, shape (nf,); default their
            link positions (unstretched springs).
        motor_v0: Initial motor velocities, shape (nf,); default their link velocities.
        duration: Default simulated time in [s].
        integrator: Default integrator settings.
        controller: Controller table (``type`` plus parameters); ``{"type": "zero"}`` if none.
        reference: Analytic reference table (``type`` plus parameters), checked when the scene
            is loaded, or None; used by
            :func:`ucontrol.analysis.convergence.run_convergence`.
        source: The TOML file the scene was loaded from, or None for a scene built in code;
            :func:`ucontrol.simulate` records it in the log (``scene_path``) for replays.
    """

    name: str
    robot: RobotModel
    contacts: tuple[PointContact, ...] = ()
    stops: tuple[JointStop, ...] = ()
    sphere_contacts: tuple[SphereSphereContact, ...] = ()
    planar_axis: NDArray[np.float64] | None = None
    q0: NDArray[np.float64]
    v0: NDArray[np.float64]
    flexible: FlexibleJoints | None = None
    motor_q0: NDArray[np.float64] | None = None
    motor_v0: NDArray[np.float64] | None = None
    duration: float = 1.0
    integrator: IntegratorSettings = field(default_factory=IntegratorSettings)
    controller: Mapping[str, Any] = field(default_factory=lambda: {"type": "zero"})
    reference: Mapping[str, Any] | None = None
    source: Path | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "q0", self.robot.check_configuration("q0", self.q0))
        object.__setattr__(self, "v0", self.robot.check_velocity("v0", self.v0))
        object.__setattr__(self, "duration", as_positive("duration", self.duration))
        flexible = self.flexible
        if flexible is None:
            if self.motor_q0 is not None or self.motor_v0 is not None:
                raise SceneError("motor_q0 and motor_v0 need flexible joints")
        else:
            motor_q0 = flexible.link_positions(self.q0) if self.motor_q0 is None else self.motor_q0
            motor_v0 = self.v0[flexible.v_index] if self.motor_v0 is None else self.motor_v0
            object.__setattr__(self, "motor_q0", as_vector("motor_q0", motor_q0, flexible.nf))
            object.__setattr__(self, "motor_v0", as_vector("motor_v0", motor_v0, flexible.nf))
        object.__setattr__(self, "contacts", tuple(self.contacts))
        object.__setattr__(self, "stops", tuple(self.stops))
        object.__setattr__(self, "sphere_contacts", tuple(self.sphere_contacts))
        constraints = ConstraintSet(
            self.robot, self.contacts, self.stops, self.sphere_contacts, self.planar_axis
        )
        object.__setattr__(self, "_constraints", constraints)

    @property
    def constraints(self) -> ConstraintSet:
        """The unilateral constraints, contacts first then stops."""
        constraints: ConstraintSet = self.__dict__["_constraints"]
        return constraints

    def initial_state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The plant's initial (q, v): the links', then the motors' with flexible joints."""
        if self.flexible is None:
            return self.q0, self.v0
        assert self.motor_q0 is not None and self.motor_v0 is not None
        return np.concatenate((self.q0, self.motor_q0)), np.concatenate((self.v0, self.motor_v0))

    def build_integrator(self, dt: float | None = None) -> MoreauJean | EventDriven | Compliant:
        """The integrator of this scene, optionally with another step ``dt`` in [s].

        Raises:
            InvalidParameterError: The scene has friction and the integrator is not
                ``moreau_jean`` (the others are frictionless), or a ``qpsolvers:`` contact
                solver was asked for a scene with friction.
        """
        settings = self.integrator
        h = settings.dt if dt is None else dt
        friction = self.constraints.has_friction
        if friction and settings.name != "moreau_jean":
            raise InvalidParameterError(
                "[integrator] name",
                settings.name,
                "'moreau_jean' for contacts with friction (event_driven and compliant are "
                "frictionless)",
            )
        if settings.name == "compliant":
            return Compliant(
                self.robot,
                self.constraints,
                dt=h,
                stiffness=settings.stiffness,
                contact_model=settings.contact_model,
                flexible=self.flexible,
                **settings.solver_options(),
            )
        if settings.name == "event_driven":
            return EventDriven(
                self.robot,
                self.constraints,
                dt=h,
                zeno_velocity=settings.zeno_velocity,
                impact_solver=ProxsuiteLCPSolver(
                    eps_abs=settings.contact_tolerance, max_iter=settings.max_iter
                ),
                acceleration_solver=ProxsuiteLCPSolver(
                    eps_abs=settings.contact_tolerance, max_iter=settings.max_iter
                ),
                flexible=self.flexible,
                **settings.solver_options(),
            )
        contact_solver, friction_solver = build_contact_solvers(
            settings.contact_solver,
            friction=friction,
            eps_abs=settings.contact_tolerance,
            max_iter=settings.max_iter,
            residual_tolerance=settings.friction_tolerance,
            friction_max_iter=settings.friction_max_iter,
        )
        return MoreauJean(
            self.robot,
            self.constraints,
            dt=h,
            theta=settings.theta,
            solver=contact_solver,
            friction_solver=friction_solver,
            restitution_threshold=settings.restitution_threshold,
            on_unsolved=settings.on_unsolved,
            flexible=self.flexible,
            midpoint=settings.midpoint,
            persistence_tolerance=settings.persistence_tolerance,
        )

    def build_controller(self) -> Controller:
        """The controller declared by the scene's ``[controller]`` table."""
        table = dict(self.controller)
        kind = table.get("type", "zero")
        if kind not in _CONTROLLER_KEYS:
            raise NotFoundError("controller type", kind, CONTROLLERS)
        check_keys("[controller]", table, _CONTROLLER_KEYS[kind])
        if kind == "joint_pd":
            return JointPD(
                self.robot,
                q_ref=table.get("q_ref", self.q0),
                kp=require_key(table, "[controller]", "kp"),
                kd=require_key(table, "[controller]", "kd"),
                gravity_compensation=bool(table.get("gravity_compensation", True)),
                flexible=self.flexible,
            )
        if kind == "brogliato":
            return _brogliato(self, table)
        return ZeroTorque(self.robot.nu)

    @classmethod
    def from_toml(cls, path: str | Path) -> Scene:
        """Load a scene file; relative URDF paths are taken from the file's folder.

        Raises:
            SceneError: The file is missing or not valid TOML.
            UnknownKeyError: A table holds keys the format does not define.
        """
        path = Path(path)
        if not path.is_file():
            raise SceneError(f"scene file {str(path)!r} does not exist")
        try:
            table = tomllib.loads(path.read_text())
        except tomllib.TOMLDecodeError as error:
            raise SceneError(f"scene file {str(path)!r} is not valid TOML: {error}") from error
        scene = cls.from_dict(table, base_dir=path.parent, default_name=path.stem)
        return replace(scene, source=path.resolve())

    @classmethod
    def from_dict(
        cls, table: Mapping[str, Any], *, base_dir: Path, default_name: str = "scene"
    ) -> Scene:
        """Build a scene from its parsed TOML table (see :meth:`from_toml`)."""
        check_keys("the scene", table, _TOP_KEYS)
        robot_table = require_key(table, "the scene", "robot")
        check_keys("[robot]", robot_table, _ROBOT_KEYS)
        gravity = robot_table.get("gravity", [0.0, 0.0, -9.81])
        robot = RobotModel.from_urdf(
            resolve_urdf(str(require_key(robot_table, "[robot]", "urdf")), base_dir),
            floating_base=bool(robot_table.get("floating_base", False)),
            gravity=as_vector("gravity", gravity, 3),
        )
        q0 = robot.check_configuration("q0", robot_table.get("q0", robot.neutral()))
        v0 = robot.check_velocity("v0", robot_table.get("v0", np.zeros(robot.nv)))
        flexible_table = robot_table.get("flexible")
        flexible, motor_q0, motor_v0 = None, None, None
        if flexible_table is not None:
            flexible, motor_q0, motor_v0 = _flexible(flexible_table, robot)
        surfaces = {
            name: _plane(f"[surfaces.{name}]", name, spec)
            for name, spec in table.get("surfaces", {}).items()
        }
        contacts = [_contact(spec, surfaces) for spec in table.get("contacts", [])]
        sphere_contacts = [_sphere_contact(spec) for spec in table.get("sphere_contacts", [])]
        planar_axis = robot_table.get("planar_axis")
        stops = [_stop(spec, robot) for spec in table.get("stops", [])]
        integrator_table = dict(table.get("integrator", {}))
        check_keys("[integrator]", integrator_table, _INTEGRATOR_KEYS)
        scene = cls(
            name=str(table.get("name", default_name)),
            robot=robot,
            contacts=tuple(contacts),
            sphere_contacts=tuple(sphere_contacts),
            planar_axis=None if planar_axis is None else as_vector("planar_axis", planar_axis, 3),
            stops=tuple(stops),
            q0=q0,
            v0=v0,
            flexible=flexible,
            motor_q0=motor_q0,
            motor_v0=motor_v0,
            duration=table.get("duration", 1.0),
            integrator=IntegratorSettings(**integrator_table),
            controller=dict(table.get("controller", {"type": "zero"})),
        )
        if "reference" not in table:
            return scene
        return replace(scene, reference=_reference(table["reference"], scene.contacts))


def builtin_scene(name: str = DEFAULT_SCENE) -> Path:
    """Path of a scene shipped with ucontrol (the repository's ``robots/`` folder)."""
    path = Path(str(files("ucontrol.robots").joinpath(name)))
    if not path.is_file():
        available = [p.name for p in Path(str(files("ucontrol.robots"))).glob("*.toml")]
        raise NotFoundError("built-in scene", name, available)
    return path


def load_scene(path: str | Path | None = None) -> Scene:
    """Load a scene file, or the built-in default scene when ``path`` is None."""
    return Scene.from_toml(builtin_scene() if path is None else path)


def _reference(table: Mapping[str, Any], contacts: Sequence[PointContact]) -> dict[str, Any]:
    """A checked ``[reference]`` table, with ``contact`` resolved to a contact name.

    ``bouncing_ball``: the gap of ``contact`` (default the first) follows
    :class:`ucontrol.analysis.BouncingBall`, its parameters read from the scene.
    """
    if not isinstance(table, Mapping):
        raise SceneError(f"[reference] must be a table, got {table!r}")
    kind = require_key(table, "[reference]", "type")
    if kind not in _REFERENCE_KEYS:
        raise NotFoundError("reference type", str(kind), REFERENCES)
    check_keys("[reference]", table, _REFERENCE_KEYS[kind])
    names = [contact.name for contact in contacts]
    if not names:
        raise SceneError("[reference] type 'bouncing_ball' needs a [[contacts]] entry")
    contact = str(table.get("contact", names[0]))
    if contact not in names:
        raise NotFoundError("contact", contact, names)
    return {"type": kind, "contact": contact}


def _plane(section: str, name: str, spec: Mapping[str, Any]) -> Plane:
    check_keys(section, spec, _SURFACE_KEYS)
    kind = spec.get("type", "plane")
    if kind != "plane":
        raise InvalidParameterError(f"{section} type", kind, "'plane'")
    return Plane(
        point=spec.get("point", [0.0, 0.0, 0.0]),
        normal=require_key(spec, section, "normal"),
        name=name,
    )


def _contact(spec: Mapping[str, Any], surfaces: Mapping[str, Plane]) -> PointContact:
    check_keys("[[contacts]]", spec, _CONTACT_KEYS)
    surface = require_key(spec, "[[contacts]]", "surface")
    if isinstance(surface, Mapping):
        plane = _plane("[[contacts]] surface", "plane", surface)
    elif surface in surfaces:
        plane = surfaces[surface]
    else:
        raise NotFoundError("surface", str(surface), surfaces)
    return PointContact(
        frame=str(require_key(spec, "[[contacts]]", "frame")),
        surface=plane,
        radius=spec.get("radius", 0.0),
        restitution=spec.get("restitution", 0.0),
        friction=spec.get("friction", 0.0),
        name=str(spec.get("name", "")),
    )


def _sphere_contact(spec: Mapping[str, Any]) -> SphereSphereContact:
    check_keys("[[sphere_contacts]]", spec, _SPHERE_CONTACT_KEYS)
    return SphereSphereContact(
        frame=str(require_key(spec, "[[sphere_contacts]]", "frame")),
        other_frame=str(require_key(spec, "[[sphere_contacts]]", "other_frame")),
        **{
            key: spec[key]
            for key in ("radius", "other_radius", "restitution", "friction")
            if key in spec
        },
        name=str(spec.get("name", "")),
    )


def _flexible(
    spec: Mapping[str, Any], robot: RobotModel
) -> tuple[FlexibleJoints, Any | None, Any | None]:
    """The ``[robot.flexible]`` table: joints (default every actuated one), K, B, D, motor q0/v0."""
    section = "[robot.flexible]"
    check_keys(section, spec, _FLEXIBLE_KEYS)
    joints = spec.get("joints")
    if joints is None:  # every actuated joint
        joints = [
            name
            for name in robot.joint_names
            if robot.model.joints[robot.joint_id(name)].idx_v in robot.actuated
        ]
    flexible = FlexibleJoints.from_robot(
        robot,
        joints,
        stiffness=require_key(spec, section, "stiffness"),
        motor_inertia=require_key(spec, section, "motor_inertia"),
        damping=spec.get("damping", 0.0),
    )
    return flexible, spec.get("q0"), spec.get("v0")


def _stop(spec: Mapping[str, Any], robot: RobotModel) -> JointStop:
    """A joint stop; without ``lower``/``upper`` it takes the URDF's position limits."""
    check_keys("[[stops]]", spec, _STOP_KEYS)
    joint = str(require_key(spec, "[[stops]]", "joint"))
    lower, upper = spec.get("lower"), spec.get("upper")
    if lower is None and upper is None:
        joint_model = robot.model.joints[robot.joint_id(joint)]
        lower = float(robot.model.lowerPositionLimit[joint_model.idx_q])
        upper = float(robot.model.upperPositionLimit[joint_model.idx_q])
    return JointStop(
        joint=joint, lower=lower, upper=upper, restitution=spec.get("restitution", 0.0)
    )


def _brogliato(scene: Scene, table: Mapping[str, Any]) -> BrogliatoController:
    """The ``type = "brogliato"`` controller of a scene (keys in docs/scene_format.md)."""
    section = "[controller]"
    frame = str(require_key(table, section, "frame"))
    contacts = {contact.name: contact for contact in scene.contacts}
    names = table.get("contacts", [c.name for c in scene.contacts if c.frame == frame])
    for name in names:
        if name not in contacts:
            raise NotFoundError("contact", str(name), contacts)
    task = TaskCoordinates(
        scene.robot, frame, [contacts[name] for name in names], table.get("tangents", ())
    )
    path_table = require_key(table, section, "path")
    check_keys("[controller.path]", path_table, _PATH_KEYS)
    if path_table.get("type", "circle") != "circle":
        raise InvalidParameterError("[controller.path] type", path_table["type"], "'circle'")
    path = CirclePath(
        centre=require_key(path_table, "[controller.path]", "centre"),
        radius=require_key(path_table, "[controller.path]", "radius"),
        period=require_key(path_table, "[controller.path]", "period"),
        **{key: path_table[key] for key in ("axes", "start_angle") if key in path_table},
    )
    phases = []
    for spec in require_key(table, section, "contact_phases"):
        entry = "[[controller.contact_phases]]"
        check_keys(entry, spec, _CONTACT_PHASE_KEYS)
        phases.append(
            ContactPhase(**{key: require_key(spec, entry, key) for key in _CONTACT_PHASE_KEYS})
        )
    cycle = DesiredCycle(
        path=path,
        contact_phases=tuple(phases),
        **{key: table[key] for key in _CYCLE_KEYS if key in table},
    )
    gains = BrogliatoGains(
        gamma1=require_key(table, section, "gamma1"),
        gamma2=require_key(table, section, "gamma2"),
        **{key: table[key] for key in _BROGLIATO_GAIN_KEYS if key in table},
    )
    robot = scene.robot.with_scaled_inertia(table.get("mass_scale", 1.0))
    posture = table.get("posture", scene.q0)
    if scene.flexible is not None:  # the passivity-based law, through the motors
        return FlexibleBrogliatoController(
            robot, scene.flexible, task, cycle, gains, posture=posture
        )
    return BrogliatoController(robot, task, cycle, gains, posture=posture)
