"""Building a scene's controller from its ``[controller]`` table: one builder per type.

The table's keys are checked when the scene is loaded (:func:`check_controller_table`), the
controller is built when a run asks for it. The Brogliato laws (which need casadi) are
imported only by a scene that declares one; so are the desired cycle and the pronking law,
whose settings' fields are keys of their tables.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ucontrol._validation import as_bool, check_keys, require_key
from ucontrol.contact.plane import Plane
from ucontrol.control.controller import Controller
from ucontrol.control.friction_compensation import FrictionCompensation
from ucontrol.control.joint_pd import JointPD
from ucontrol.control.zero_torque import ZeroTorque
from ucontrol.exceptions import NotFoundError, SceneError
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.model_uncertainty import perturbed_robot
from ucontrol.scene.hzd_table import HZD_KEYS, hzd_from_table
from ucontrol.scene.impedance_table import (
    IMPEDANCE_KEYS,
    impedance_arguments,
    impedance_from_table,
)
from ucontrol.scene.juggling_table import JUGGLING_KEYS, juggling_from_table
from ucontrol.scene.pronk_table import pronk_from_table, pronk_keys
from ucontrol.scene.raibert_table import RAIBERT_KEYS, raibert_from_table

if TYPE_CHECKING:
    from ucontrol.contact.point_contact import PointContact
    from ucontrol.model.robot_model import RobotModel
    from ucontrol.scene.scene_data import SceneData

_BROGLIATO_GAIN_KEYS = ("force_gain", "posture_gain", "null_space_gain")
#: Keys of ``type = "reference_spreading"`` beyond the impedance ones (``SpreadingSettings``).
_SPREADING_KEYS = ("restitution", "blend_time", "interim_time", "impact_speed", "contact_gap")


def _brogliato_keys() -> set[str]:
    """Keys of a ``type = "brogliato"`` table (the desired cycle's settings among them)."""
    from ucontrol.control.controller_table import CYCLE_KEYS  # the desired cycle's module

    return {
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
        "designed_cycle",
        *_BROGLIATO_GAIN_KEYS,
        *CYCLE_KEYS,
    }


#: Keys of each controller type's table, or the function that lists them (its modules
#: imported only for a scene that declares the type: :func:`_controller_keys`).
_CONTROLLER_KEYS: dict[str, set[str] | Callable[[], set[str]]] = {
    "zero": {"type"},
    "joint_pd": {"type", "kp", "kd", "q_ref", "gravity_compensation"},
    "brogliato": _brogliato_keys,
    "impedance": IMPEDANCE_KEYS,
    "reference_spreading": {*IMPEDANCE_KEYS, *_SPREADING_KEYS},
    "juggling": JUGGLING_KEYS,
    "pronk": pronk_keys,
    "raibert": RAIBERT_KEYS,
    "hzd": HZD_KEYS,
}
#: Controller types a scene may declare.
CONTROLLERS = tuple(_CONTROLLER_KEYS)
_MODEL_KEYS = {"mass_scale", "com_offset", "surfaces", "joint_friction"}
_PLANE_KEYS = {"point", "normal"}


def check_controller_table(table: Mapping[str, Any]) -> str:
    """Check a ``[controller]`` table's type and keys; returns the type.

    Raises:
        SceneError: ``table`` is not a table.
        NotFoundError: Unknown ``type``.
        UnknownKeyError: A key the type does not define.
    """
    if not isinstance(table, Mapping):
        raise SceneError(f"[controller] must be a table, got {table!r}")
    kind = str(table.get("type", "zero"))
    if kind not in _CONTROLLER_KEYS:
        raise NotFoundError("controller type", kind, CONTROLLERS)
    check_keys("[controller]", table, _controller_keys(kind))
    return kind


@functools.cache
def _controller_keys(kind: str) -> set[str]:
    """The keys of a ``kind`` table, ``model`` among them.

    Every controller may run on its own model of the scene (``[controller.model]``).
    """
    keys = _CONTROLLER_KEYS[kind]
    return {*(keys() if callable(keys) else keys), "model"}


def build_controller(scene: SceneData) -> Controller:
    """The controller declared by ``scene.controller``, on its own model of the scene.

    A ``[controller.model]`` table gives the controller a model that differs from the plant
    (:func:`controller_view`); the controller is then built on that view of the scene. Every
    controller but ``zero`` then compensates the joint friction of its model, if any
    (:class:`~ucontrol.control.friction_compensation.FrictionCompensation`).
    """
    table = dict(scene.controller)
    kind = check_controller_table(table)
    view = controller_view(scene, table.pop("model", None))
    controller = _BUILDERS[kind](view, table)
    friction = view.joint_friction
    if kind == "zero" or friction is None or not (friction.coulomb.any() or friction.has_viscous):
        return controller
    return FrictionCompensation(controller, view.robot, friction)


def retarget_controller(controller: Controller, scene: SceneData) -> bool:
    """Give ``controller`` the believed inertias of ``scene``; whether it took them.

    ``controller``, built by :func:`build_controller` for a scene that differs from ``scene``
    in the controller's believed inertias alone (``[controller.model]`` ``mass_scale`` and
    ``com_offset``, ``[controller]`` ``mass_scale``) and believing the same contacts of its
    frame (the same surfaces), takes those of ``scene``
    (:meth:`~ucontrol.control.BrogliatoController.use_inertias`): it then runs as the
    controller :func:`build_controller` builds for ``scene`` once ``reset()``. For the
    campaigns' workers, which keep their built controllers for runs that draw other masses.

    Returns:
        Whether it took them; False, with nothing changed, for every controller but a rigid
        :class:`~ucontrol.control.BrogliatoController` (one compensating joint friction, the
        flexible joints' law, other types), for other believed surfaces of the tracked
        contacts (or moving ones), and for a believed robot whose kinematics are not the
        controller's: then build a new one.

    Raises:
        UnknownKeyError: A key of ``scene``'s ``[controller]`` or ``[controller.model]`` table
            that they do not define.
        NotFoundError: Unknown controller type, or a link name the scene does not have.
    """
    table = dict(scene.controller)
    if check_controller_table(table) != "brogliato":
        return False
    from ucontrol.control.brogliato_controller import BrogliatoController  # as _brogliato
    from ucontrol.control.controller_table import tracked_contacts

    if not isinstance(controller, BrogliatoController):
        return False
    # The robot and contacts of controller_view's scene, without the rest of that scene (its
    # joint friction and checks, which only a build reads).
    model = table.pop("model", None)
    tracked = tracked_contacts(table, controller.task.frame, _believed_contacts(scene, model))
    if not _same_contacts(tracked, controller.task.contacts):
        return False
    robot = _believed_robot(scene, model)
    return controller.use_inertias(_brogliato_robot(robot, table))


def _same_contacts(given: Sequence[PointContact], built: Sequence[PointContact]) -> bool:
    """Whether a controller's tracked contacts ``built`` are those ``given`` (fixed planes)."""
    return len(given) == len(built) and all(
        (a.name, a.frame, a.radius) == (b.name, b.frame, b.radius)
        and a.surface.motion is None
        and b.surface.motion is None
        and np.array_equal(a.surface.point, b.surface.point)
        and np.array_equal(a.surface.normal, b.surface.normal)
        for a, b in zip(given, built, strict=True)
    )


def controller_view(scene: SceneData, model: Mapping[str, Any] | None) -> SceneData:
    """The scene as a controller with a ``[controller.model]`` table believes it is.

    Keys: ``mass_scale`` (a factor, or one per link), ``com_offset`` (per link, [m], in the
    frame of the link's joint), ``surfaces`` (per surface name, its ``point`` and ``normal``
    as the controller believes them: the plant keeps the scene's), ``joint_friction`` (the
    friction in the joints the controller believes in, the ``[joint_friction]`` table's forms;
    without it the controller believes the scene's).

    Raises:
        UnknownKeyError: A key of the table that is not one of these.
        NotFoundError: A link or surface name the scene does not have.
    """
    if model is None:
        return scene
    robot = _believed_robot(scene, model)
    friction = scene.joint_friction
    if "joint_friction" in model:
        friction = JointFriction.from_table(
            scene.robot, model["joint_friction"], "[controller.model] joint_friction"
        )
    return dataclasses.replace(
        scene, robot=robot, contacts=_believed_contacts(scene, model), joint_friction=friction
    )


def _believed_contacts(
    scene: SceneData, model: Mapping[str, Any] | None
) -> tuple[PointContact, ...]:
    """The contacts of :func:`controller_view`: the scene's, on the surfaces ``model`` gives.

    Raises:
        UnknownKeyError: A key of a believed surface's table that is not a plane's.
        NotFoundError: A surface name the scene does not have.
    """
    believed = {} if model is None else model.get("surfaces", {})
    if not believed:
        return scene.contacts
    check_keys("[controller.model.surfaces]", believed, {c.surface.name for c in scene.contacts})
    contacts = []
    for contact in scene.contacts:
        spec = believed.get(contact.surface.name)
        if spec is not None:
            check_keys(f"[controller.model.surfaces.{contact.surface.name}]", spec, _PLANE_KEYS)
            plane = Plane(
                point=spec.get("point", contact.surface.point),
                normal=spec.get("normal", contact.surface.normal),
                name=contact.surface.name,
            )
            contact = dataclasses.replace(contact, surface=plane, name=contact.name)
        contacts.append(contact)
    return tuple(contacts)


def _believed_robot(scene: SceneData, model: Mapping[str, Any] | None) -> RobotModel:
    """The robot of :func:`controller_view`: the scene's with the inertias ``model`` gives.

    Raises:
        UnknownKeyError: A key of ``model`` that :func:`controller_view` does not define.
        NotFoundError: A link name the scene does not have.
    """
    if model is None:
        return scene.robot
    check_keys("[controller.model]", model, _MODEL_KEYS)
    return perturbed_robot(
        scene.robot,
        mass_scale=model.get("mass_scale", 1.0),
        com_offset=model.get("com_offset"),
    )


def _zero(scene: SceneData, table: Mapping[str, Any]) -> Controller:
    return ZeroTorque(scene.robot.nu)


def _joint_pd(scene: SceneData, table: Mapping[str, Any]) -> Controller:
    return JointPD(
        scene.robot,
        q_ref=table.get("q_ref", scene.q0),
        kp=require_key(table, "[controller]", "kp"),
        kd=require_key(table, "[controller]", "kd"),
        gravity_compensation=as_bool(
            "gravity_compensation", table.get("gravity_compensation", True)
        ),
        flexible=scene.flexible,
    )


def _brogliato(scene: SceneData, table: Mapping[str, Any]) -> Controller:
    """The ``type = "brogliato"`` controller of a scene (keys in docs/scene_format.md)."""
    # casadi comes with the Brogliato controllers: imported by the scenes that declare one
    from ucontrol.control.brogliato_controller import BrogliatoController, BrogliatoGains
    from ucontrol.control.controller_table import CYCLE_KEYS, tracked_contacts
    from ucontrol.control.desired_cycle import DesiredCycle
    from ucontrol.control.path_table import cycle_from_table  # the paths, for these alone
    from ucontrol.control.task_coordinates import TaskCoordinates

    section = "[controller]"
    frame = str(require_key(table, section, "frame"))
    tracked = tracked_contacts(table, frame, scene.contacts)
    task = TaskCoordinates(scene.robot, frame, tracked, table.get("tangents", ()))
    if "designed_cycle" not in table:
        require_key(table, section, "path")
        require_key(table, section, "contact_phases")
    base_dir = scene.source.parent if scene.source is not None else None
    path, phases = cycle_from_table(table, base_dir, section)  # or a designed cycle file
    cycle = DesiredCycle(
        path=path,
        contact_phases=tuple(phases),
        **{key: table[key] for key in CYCLE_KEYS if key in table},
    )
    gains = BrogliatoGains(
        gamma1=require_key(table, section, "gamma1"),
        gamma2=require_key(table, section, "gamma2"),
        **{key: table[key] for key in _BROGLIATO_GAIN_KEYS if key in table},
    )
    robot = _brogliato_robot(scene.robot, table)
    posture = table.get("posture", scene.q0)
    if scene.flexible is not None:  # the passivity-based law, through the motors (casadi)
        from ucontrol.control.flexible_brogliato_controller import FlexibleBrogliatoController

        return FlexibleBrogliatoController(
            robot, scene.flexible, task, cycle, gains, posture=posture
        )
    return BrogliatoController(robot, task, cycle, gains, posture=posture)


def _brogliato_robot(believed: RobotModel, table: Mapping[str, Any]) -> RobotModel:
    """The robot of a ``type = "brogliato"`` controller: ``believed`` with ``mass_scale``.

    Args:
        believed: The robot of the scene as the controller believes it
            (:func:`controller_view`).
        table: The ``[controller]`` table.
    """
    return believed.with_scaled_inertia(table.get("mass_scale", 1.0))


def _reference_spreading(scene: SceneData, table: Mapping[str, Any]) -> Controller:
    """The ``type = "reference_spreading"`` controller: the impedance keys and the settings."""
    from ucontrol.control.reference_spreading import (
        ReferenceSpreadingController,
        SpreadingSettings,
    )

    settings = SpreadingSettings(**{key: table[key] for key in _SPREADING_KEYS if key in table})
    general = {key: value for key, value in table.items() if key not in _SPREADING_KEYS}
    return ReferenceSpreadingController(**impedance_arguments(scene, general), settings=settings)


_BUILDERS: dict[str, Callable[[SceneData, Mapping[str, Any]], Controller]] = {
    "zero": _zero,
    "joint_pd": _joint_pd,
    "brogliato": _brogliato,
    "impedance": impedance_from_table,
    "reference_spreading": _reference_spreading,
    "juggling": juggling_from_table,
    "pronk": pronk_from_table,
    "raibert": raibert_from_table,
    "hzd": hzd_from_table,
}
