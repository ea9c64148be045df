"""Reading a scene's TOML table: every key and value checked before anything is built.

:func:`scene_fields` turns the parsed table into the arguments of
:class:`~ucontrol.scene.Scene`; the format is documented in ``docs/scene_format.md`` and
unknown keys are an error that names them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ucontrol._validation import (
    as_bool,
    as_vector,
    check_keys,
    import_callable,
    require_key,
    table_type,
)
from ucontrol.contact.plane import Plane
from ucontrol.contact.point_contact import PointContact
from ucontrol.exceptions import InvalidParameterError, NotFoundError, SceneError
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.robot_model import RobotModel
from ucontrol.model.urdf_path import resolve_urdf
from ucontrol.scene.controller_builders import check_controller_table
from ucontrol.scene.integrator_settings import IntegratorSettings

if TYPE_CHECKING:  # each kind imported by the reader of its table, for a scene that has one
    from ucontrol.contact.bilateral import BilateralConstraint
    from ucontrol.contact.clearance_joint import ClearanceJoint
    from ucontrol.contact.collision_pair import CollisionPair, EnvironmentShape
    from ucontrol.contact.joint_stop import JointStop
    from ucontrol.contact.sphere_sphere_contact import SphereSphereContact
    from ucontrol.scene.push import Push

#: Analytic references a scene may declare in its ``[reference]`` table.
REFERENCES = ("bouncing_ball",)

_TOP_KEYS = {
    "name",
    "duration",
    "robot",
    "surfaces",
    "contacts",
    "sphere_contacts",
    "shapes",
    "collision_pairs",
    "bilateral",
    "clearance",
    "stops",
    "integrator",
    "controller",
    "reference",
    "sensors",
    "actuators",
    "joint_friction",
    "pushes",
}
_ROBOT_KEYS = {
    "urdf",
    "mjcf",
    "sdf",
    "floating_base",
    "q0",
    "v0",
    "gravity",
    "planar_axis",
    "flexible",
    "actuated",
    "passive",
    "assemble",
    "links",
}
#: The keys of ``[robot]`` naming its description file, and the loader of each format.
_ROBOT_FILES: dict[str, Callable[..., RobotModel]] = {
    "urdf": RobotModel.from_urdf,
    "mjcf": RobotModel.from_mjcf,
    "sdf": RobotModel.from_sdf,
}
_LINK_KEYS = {"mass", "com", "inertia", "scale"}
_FLEXIBLE_KEYS = {"joints", "stiffness", "motor_inertia", "damping", "q0", "v0"}
_SURFACE_KEYS = {"type", "point", "normal", "motion"}
_MOTION_KEYS = {
    "sinusoid": {"type", "amplitude", "frequency", "phase"},
    "polynomial": {"type", "coefficients"},
    "ramp": {"type", "velocity"},
    "python": {"type", "function"},
}
_CONTACT_KEYS = {
    "frame",
    "surface",
    "radius",
    "restitution",
    "friction",
    "name",
    "closes_ahead_of",
    "direction_of_travel",
    "ahead_frame",
}
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
_CLEARANCE_KEYS = {"joint", "clearance", "journal_radius", "restitution", "friction", "name"}
_SHAPE_KEYS = {
    "halfspace": {"type", "point", "normal", "motion"},
    "box": {"type", "position", "rpy", "size", "motion"},
    "sphere": {"type", "position", "radius", "motion"},
    "mesh": {"type", "file", "position", "rpy", "scale", "motion"},
}
_PAIR_KEYS = {"link", "other", "restitution", "friction", "points", "name"}
_BILATERAL_KEYS = {
    "point": {"type", "frame", "other_frame", "name"},
    "weld": {"type", "frame", "other_frame", "name"},
    "coupling": {"type", "joint", "other_joint", "ratio", "offset", "name"},
}
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
    "reference_speed",
    "restitution_threshold",
    "contact_solver",
    "friction_tolerance",
    "friction_max_iter",
    "on_unsolved",
    "midpoint",
    "persistence_tolerance",
    "persistence_speed",
    "penetration_tolerance",
    "newton_law",
    "impact_law",
    "tangential_restitution",
    "lzb_stiffness",
    "lzb_exponent",
    "lzb_impulse_step",
    "lzb_max_steps",
}
_REFERENCE_KEYS = {"bouncing_ball": {"type", "contact"}}


def scene_fields(
    table: Mapping[str, Any], *, base_dir: Path, default_name: str = "scene"
) -> dict[str, Any]:
    """The checked arguments of :class:`~ucontrol.scene.Scene` from a parsed scene table.

    The ``reference`` entry holds the raw ``[reference]`` table (or None): it is checked
    against the scene's contacts by :func:`check_reference`.
    """
    check_keys("the scene", table, _TOP_KEYS)
    robot_table = require_key(table, "the scene", "robot")
    check_keys("[robot]", robot_table, _ROBOT_KEYS)
    robot = _robot(robot_table, base_dir)
    if "links" in robot_table:
        robot = _with_link_overrides(robot_table["links"], robot)
    q0 = robot_table.get("q0", robot.neutral())
    v0 = robot_table.get("v0", np.zeros(robot.nv))
    clearances = tuple(_clearance(spec) for spec in table.get("clearance", []))
    if clearances:
        robot, q0, v0 = _with_clearances(robot, clearances, q0, v0)
    q0 = robot.check_configuration("q0", q0)
    v0 = robot.check_velocity("v0", v0)
    flexible_table = robot_table.get("flexible")
    flexible, motor_q0, motor_v0 = None, None, None
    if flexible_table is not None:
        flexible, motor_q0, motor_v0 = _flexible(flexible_table, robot)
    surfaces = {
        name: _plane(f"[surfaces.{name}]", name, spec, base_dir)
        for name, spec in table.get("surfaces", {}).items()
    }
    contacts = [_contact(spec, surfaces, base_dir) for spec in table.get("contacts", [])]
    sphere_contacts = [_sphere_contact(spec) for spec in table.get("sphere_contacts", [])]
    shapes = {
        name: _shape(f"[shapes.{name}]", name, spec, base_dir)
        for name, spec in table.get("shapes", {}).items()
    }
    collision_pairs = [
        _collision_pair(spec, shapes, surfaces) for spec in table.get("collision_pairs", [])
    ]
    planar_axis = robot_table.get("planar_axis")
    stops = [_stop(spec, robot) for spec in table.get("stops", [])]
    integrator_table = dict(table.get("integrator", {}))
    controller = dict(table.get("controller", {"type": "zero"}))
    check_controller_table(controller)
    check_keys("[integrator]", integrator_table, _INTEGRATOR_KEYS)
    bilateral = tuple(_bilateral(spec) for spec in table.get("bilateral", []))
    if "assemble" in robot_table:
        q0 = _assembled_q0(robot_table["assemble"], robot, bilateral, q0)
    return dict(
        name=str(table.get("name", default_name)),
        robot=robot,
        contacts=tuple(contacts),
        sphere_contacts=tuple(sphere_contacts),
        collision_pairs=tuple(collision_pairs),
        bilateral=bilateral,
        clearances=clearances,
        planar_axis=None if planar_axis is None else as_vector("planar_axis", planar_axis, 3),
        stops=tuple(stops),
        q0=q0,
        v0=v0,
        flexible=flexible,
        motor_q0=motor_q0,
        motor_v0=motor_v0,
        duration=table.get("duration", 1.0),
        integrator=IntegratorSettings(**integrator_table),
        controller=controller,
        reference=table.get("reference"),
        **_sensors_and_actuators(table),
        joint_friction=_joint_friction(table, robot),
        pushes=_pushes(table.get("pushes", []), robot.nv),
    )


def _pushes(specs: Sequence[Any], nv: int) -> tuple[Push, ...]:
    """The ``[[pushes]]`` entries (``nv``: the robot's velocity size)."""
    if not specs:
        return ()
    from ucontrol.scene.push import Push

    return tuple(Push.from_table(spec, nv) for spec in specs)


def _robot(robot_table: Mapping[str, Any], base_dir: Path) -> RobotModel:
    """The robot of the ``[robot]`` table, from the one description file it names.

    ``actuated`` or ``passive`` (joint names, not both) set the actuated coordinates.

    Raises:
        SceneError: The table names no file, or more than one, or both joint lists.
        RobotFileError: The file cannot be read (URDF, MJCF; SDF is refused).
        JointNotFoundError: A joint list names a joint the robot does not have.
    """
    given = [key for key in _ROBOT_FILES if key in robot_table]
    if len(given) != 1:
        raise SceneError(
            f"[robot] needs exactly one of the keys 'urdf', 'mjcf', 'sdf' (the robot's "
            f"description file), got {given or 'none'}"
        )
    key = given[0]
    robot = _ROBOT_FILES[key](
        resolve_urdf(str(robot_table[key]), base_dir),
        floating_base=as_bool("floating_base", robot_table.get("floating_base", False)),
        gravity=as_vector("gravity", robot_table.get("gravity", [0.0, 0.0, -9.81]), 3),
    )
    lists = {name: robot_table[name] for name in ("actuated", "passive") if name in robot_table}
    if not lists:
        return robot
    if len(lists) > 1:
        raise SceneError("[robot] takes `actuated` or `passive` (joint names), not both")
    ((name, joints),) = lists.items()
    if not isinstance(joints, list) or not all(isinstance(joint, str) for joint in joints):
        raise InvalidParameterError(f"[robot] {name}", joints, "a list of joint names")
    return robot.with_actuation(**{name: joints})


def _with_link_overrides(spec: Any, robot: RobotModel) -> RobotModel:
    """The robot with the masses and inertias of ``[robot.links.NAME]`` tables.

    Raises:
        SceneError: ``links`` or one of its entries is not a table.
        UnknownKeyError: A key other than mass, com, inertia, scale.
        FrameNotFoundError: A link the robot does not have.
        InvalidParameterError: A value of the wrong shape or sign (naming the link).
        InvalidInertiaError: A non-physical body (naming the link).
    """
    from ucontrol.model.link_inertia import LinkInertia, with_link_inertias

    if not isinstance(spec, Mapping):
        raise SceneError(f"[robot.links] must be a table of link tables, got {spec!r}")
    overrides = []
    for link, values in spec.items():
        check_keys(f"[robot.links.{link}]", values, _LINK_KEYS)
        overrides.append(LinkInertia(link=str(link), **values))
    return with_link_inertias(robot, overrides)


def _assembled_q0(
    spec: Any, robot: RobotModel, bilateral: Sequence[BilateralConstraint], q0: Any
) -> Any:
    """``q0`` projected onto the bilateral constraints (``[robot] assemble``).

    ``assemble = true`` moves every coordinate; ``assemble = ["crank_joint"]`` holds those
    joints' coordinates at their ``q0`` values; ``false`` leaves ``q0`` as written.

    Raises:
        InvalidParameterError: ``assemble`` is neither a boolean nor a list of joint names.
        JointNotFoundError: A held joint the robot does not have.
        AssemblyError: No closure near ``q0`` (:func:`ucontrol.contact.assembly.assemble`).
    """
    from ucontrol.contact.assembly import assemble

    if isinstance(spec, bool):
        fixed: list[str] = []
    elif isinstance(spec, list) and all(isinstance(name, str) for name in spec):
        fixed = spec
    else:
        raise InvalidParameterError(
            "[robot] assemble", spec, "true, false or a list of joint names held fixed"
        )
    if spec is False:
        return q0
    return assemble(robot, bilateral, q0, fixed=fixed, name="q0")


def _sensors_and_actuators(table: Mapping[str, Any]) -> dict[str, Any]:
    """The ``[sensors]`` and ``[actuators]`` settings, imported only when declared."""
    fields: dict[str, Any] = {}
    if "sensors" in table:
        from ucontrol.sensors.sensor_settings import SensorSettings

        fields["sensors"] = SensorSettings.from_table(table["sensors"])
    if "actuators" in table:
        from ucontrol.sensors.sensor_settings import ActuatorSettings

        fields["actuators"] = ActuatorSettings.from_table(table["actuators"])
    return fields


def _joint_friction(table: Mapping[str, Any], robot: RobotModel) -> Any:
    """The ``[joint_friction]`` settings, or None when the scene declares none."""
    if "joint_friction" not in table:
        return None
    from ucontrol.model.joint_friction import JointFriction

    return JointFriction.from_table(robot, table["joint_friction"])


def check_reference(table: Any, contacts: Sequence[PointContact]) -> dict[str, Any]:
    """A checked ``[reference]`` table, with ``contact`` resolved to a contact name.

    ``bouncing_ball``: the gap of ``contact`` (default the first) follows
    :class:`ucontrol.analysis.BouncingBall`, its parameters read from the scene.
    """
    kind = table_type("[reference]", table, _REFERENCE_KEYS, "reference type")
    names = [contact.name for contact in contacts]
    if not names:
        raise SceneError("[reference] type 'bouncing_ball' needs a [[contacts]] entry")
    contact = str(table.get("contact", names[0]))
    if contact not in names:
        raise NotFoundError("contact", contact, names)
    return {"type": kind, "contact": contact}


def _plane(section: str, name: str, spec: Mapping[str, Any], base_dir: Path) -> Plane:
    check_keys(section, spec, _SURFACE_KEYS)
    kind = spec.get("type", "plane")
    if kind != "plane":
        raise InvalidParameterError(f"{section} type", kind, "'plane'")
    motion = spec.get("motion")
    return Plane(
        point=spec.get("point", [0.0, 0.0, 0.0]),
        normal=require_key(spec, section, "normal"),
        name=name,
        motion=None if motion is None else _motion(f"{section} motion", motion, base_dir),
    )


def _motion(section: str, spec: Any, base_dir: Path) -> Any:
    """A surface's ``motion``: one table, or an array of them whose motions add.

    A table is a sinusoid, a polynomial, a ramp (constant velocity from the origin) or a
    Python function ``module:name`` of t returning (x, v, a), its module searched first in
    the scene file's folder (``base_dir``).

    Raises:
        SceneError: An empty array, or an entry that is not a table.
        NotFoundError: An unknown motion type.
        UserFunctionError: A ``python`` motion whose function cannot be imported.
        InvalidParameterError: A ``python`` motion whose function does not return three
            finite 3-vectors at t = 0, or whose velocity and acceleration are not the
            derivatives of its displacement and velocity there
            (:func:`~ucontrol.contact.surface_motion.check_motion`).
    """
    from ucontrol.contact.surface_motion import (
        MotionSum,
        Polynomial,
        Sinusoid,
        UserMotion,
        check_motion,
    )

    if isinstance(spec, list):
        if not spec:
            raise SceneError(f"{section} must be a table or a non-empty array of tables, got []")
        return MotionSum(
            tuple(_motion(f"{section}[{k}]", term, base_dir) for k, term in enumerate(spec))
        )
    kind = table_type(section, spec, _MOTION_KEYS, "motion type")
    if kind == "sinusoid":
        return Sinusoid(
            amplitude=require_key(spec, section, "amplitude"),
            frequency=require_key(spec, section, "frequency"),
            phase=spec.get("phase", 0.0),
        )
    if kind == "ramp":
        velocity = as_vector(f"{section} velocity", require_key(spec, section, "velocity"), 3)
        return Polynomial(coefficients=np.stack((np.zeros(3), velocity)))
    if kind == "python":
        function = import_callable(require_key(spec, section, "function"), (str(base_dir),))
        motion = UserMotion(function)
        check_motion(motion, np.zeros(1))  # a typed error now rather than mid-run
        return motion
    return Polynomial(coefficients=require_key(spec, section, "coefficients"))


def _contact(
    spec: Mapping[str, Any], surfaces: Mapping[str, Plane], base_dir: Path
) -> PointContact:
    check_keys("[[contacts]]", spec, _CONTACT_KEYS)
    surface = require_key(spec, "[[contacts]]", "surface")
    if isinstance(surface, Mapping):
        plane = _plane("[[contacts]] surface", "plane", surface, base_dir)
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
        closes_ahead_of=str(spec.get("closes_ahead_of", "")),
        direction_of_travel=spec.get("direction_of_travel"),
        ahead_frame=str(spec.get("ahead_frame", "")),
    )


def _sphere_contact(spec: Mapping[str, Any]) -> SphereSphereContact:
    from ucontrol.contact.sphere_sphere_contact import SphereSphereContact

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


def _shape(section: str, name: str, spec: Any, base_dir: Path) -> EnvironmentShape:
    """An ``[shapes.NAME]`` table: a halfspace, box, sphere or mesh, fixed or moving.

    A mesh's ``file`` is relative to the scene file (``base_dir``); ``motion`` is read as a
    surface's (:func:`_motion`).
    """
    from ucontrol.contact.collision_pair import EnvironmentShape

    kind = table_type(section, spec, _SHAPE_KEYS, "shape type")
    motion = spec.get("motion")
    fields: dict[str, Any] = {
        "name": name,
        "type": kind,
        "motion": None if motion is None else _motion(f"{section} motion", motion, base_dir),
    }
    if kind == "halfspace":
        fields["position"] = spec.get("point", [0.0, 0.0, 0.0])
        fields["normal"] = require_key(spec, section, "normal")
    else:
        fields["position"] = spec.get("position", [0.0, 0.0, 0.0])
    if kind in ("box", "mesh"):
        fields["rpy"] = spec.get("rpy", [0.0, 0.0, 0.0])
    if kind == "box":
        fields["size"] = require_key(spec, section, "size")
    elif kind == "sphere":
        fields["radius"] = require_key(spec, section, "radius")
    elif kind == "mesh":
        mesh = require_key(spec, section, "file")
        if not isinstance(mesh, str):
            raise InvalidParameterError(f"{section} file", mesh, "a path (a string)")
        fields["mesh"] = (base_dir / mesh).resolve()
        fields["scale"] = spec.get("scale", [1.0, 1.0, 1.0])
    return EnvironmentShape(**fields)


def _collision_pair(
    spec: Mapping[str, Any],
    shapes: Mapping[str, EnvironmentShape],
    surfaces: Mapping[str, Plane],
) -> CollisionPair:
    """A ``[[collision_pairs]]`` entry; ``other`` names a shape, a surface or a link."""
    from ucontrol.contact.collision_pair import CollisionPair, EnvironmentShape

    check_keys("[[collision_pairs]]", spec, _PAIR_KEYS)
    other_name = str(require_key(spec, "[[collision_pairs]]", "other"))
    other: EnvironmentShape | str = other_name
    if other_name in shapes:
        other = shapes[other_name]
    elif other_name in surfaces:  # a [surfaces] plane is a halfspace
        plane = surfaces[other_name]
        other = EnvironmentShape(
            name=other_name,
            type="halfspace",
            position=plane.point,
            normal=plane.normal,
            motion=plane.motion,
        )
    return CollisionPair(
        link=str(require_key(spec, "[[collision_pairs]]", "link")),
        other=other,
        **{key: spec[key] for key in ("restitution", "friction", "points", "name") if key in spec},
    )


def _bilateral(spec: Any) -> BilateralConstraint:
    """A ``[[bilateral]]`` entry: a point or weld closure, or a joint coupling."""
    from ucontrol.contact.bilateral import FrameClosure, JointCoupling

    section = "[[bilateral]]"
    kind = table_type(section, spec, _BILATERAL_KEYS, "bilateral type")
    name = str(spec.get("name", ""))
    if kind == "coupling":
        return JointCoupling(
            joint=str(require_key(spec, section, "joint")),
            other_joint=str(require_key(spec, section, "other_joint")),
            ratio=spec.get("ratio", 1.0),
            offset=spec.get("offset", 0.0),
            name=name,
        )
    return FrameClosure(
        frame=str(require_key(spec, section, "frame")),
        other_frame=str(require_key(spec, section, "other_frame")),
        kind=kind,
        name=name,
    )


def _clearance(spec: Any) -> ClearanceJoint:
    """A ``[[clearance]]`` entry: a revolute joint with radial clearance."""
    if not isinstance(spec, Mapping):
        raise SceneError(f"[[clearance]] entries must be tables, got {spec!r}")
    from ucontrol.contact.clearance_joint import ClearanceJoint

    check_keys("[[clearance]]", spec, _CLEARANCE_KEYS)
    return ClearanceJoint(
        joint=str(require_key(spec, "[[clearance]]", "joint")),
        clearance=require_key(spec, "[[clearance]]", "clearance"),
        **{key: spec[key] for key in _CLEARANCE_KEYS - {"joint", "clearance"} if key in spec},
    )


def _with_clearances(
    robot: RobotModel, clearances: Sequence[ClearanceJoint], q0: Any, v0: Any
) -> tuple[RobotModel, Any, Any]:
    """The robot with play at the clearance joints, and ``q0``, ``v0`` on it.

    ``q0`` and ``v0`` may be written for the robot without play (both of its sizes): each
    journal then starts centred, its play at rest.
    """
    from ucontrol.model.joint_clearance import ideal_to_play, with_joint_clearance

    played = with_joint_clearance(robot, [clearance.joint for clearance in clearances])
    if np.size(q0) == robot.nq and np.size(v0) == robot.nv:
        q, v = robot.check_configuration("q0", q0), robot.check_velocity("v0", v0)
        q0, v0 = ideal_to_play(robot, played, q, v)
    return played, q0, v0


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
    from ucontrol.contact.joint_stop import JointStop

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
