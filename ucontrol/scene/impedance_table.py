"""The ``[controller] type = "impedance"`` table of a scene -> an :class:`ImpedanceController`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ucontrol._validation import check_keys, require_key
from ucontrol.exceptions import InvalidParameterError

if TYPE_CHECKING:
    from ucontrol.control.impedance_controller import ImpedanceController
    from ucontrol.scene.scene_data import SceneData

_GAIN_KEYS = ("stiffness", "damping", "joint_damping", "posture_stiffness", "posture_damping")
#: Keys of the ``[controller]`` table of type ``"impedance"``.
IMPEDANCE_KEYS = {
    "type",
    "frame",
    "contacts",
    "posture",
    "project",
    "force_rise_time",
    "force_fall_time",
    "check_reach",
    "path",
    "contact_phases",
    "designed_cycle",
    "impact_invariant",
    "invariant_window",
    *_GAIN_KEYS,
}
_OPTION_KEYS = ("force_rise_time", "force_fall_time", "impact_invariant", "invariant_window")


def impedance_from_table(scene: SceneData, table: Mapping[str, Any]) -> ImpedanceController:
    """Build the impedance controller a ``[controller]`` table declares for ``scene``.

    Keys (docs/task_paths.md): ``frame``, ``stiffness``, ``damping`` (required);
    ``joint_damping``, ``posture_stiffness``, ``posture_damping``, ``posture`` (default the
    scene's q0), ``contacts`` (default the scene's contacts on ``frame``), ``project``,
    ``force_rise_time``, ``force_fall_time``, ``impact_invariant`` and ``invariant_window``
    (docs/impact_control.md), ``check_reach`` (default true: inverse kinematics
    along the path from q0, :func:`ucontrol.control.path_reach.check_reach`), the
    ``[controller.path]`` table (:func:`ucontrol.control.path_table.path_from_table`) and
    optional ``[[controller.contact_phases]]`` (contact, start, end, force), or instead of
    both ``designed_cycle`` (a file of ``ucontrol design``, relative to the scene file:
    :func:`ucontrol.control.path_table.cycle_from_table`).

    Raises:
        InvalidParameterError: The scene has flexible joints (this law drives rigid joints),
            or a value is invalid.
        SceneError: A required key is missing or a table is malformed.
        UnknownKeyError: A table holds unknown keys.
        NotFoundError: A contact name is not a contact of the scene.
        PathOutOfReachError: The path leaves the frame's workspace.
        PathThroughSurfaceError: The path crosses a surface outside its contact phase.
    """
    from ucontrol.control.impedance_controller import ImpedanceController

    check_keys("[controller]", table, IMPEDANCE_KEYS)
    return ImpedanceController(**impedance_arguments(scene, table))


def impedance_arguments(scene: SceneData, table: Mapping[str, Any]) -> dict[str, Any]:
    """The keyword arguments of :class:`ImpedanceController` a checked table declares.

    Shared by the task-space laws built on it (``impedance``, ``reference_spreading``); the
    keys and errors are those of :func:`impedance_from_table`, whose caller checked the keys.
    """
    from ucontrol.control.controller_table import tracked_contacts
    from ucontrol.control.impedance_controller import ImpedanceGains
    from ucontrol.control.path_reach import check_reach
    from ucontrol.control.path_table import cycle_from_table

    section = "[controller]"
    if scene.flexible is not None:
        raise InvalidParameterError(
            f"{section} type",
            table.get("type", "impedance"),
            f"a controller for flexible joints ('brogliato' or 'joint_pd'): "
            f"{table.get('type', 'impedance')!r} drives rigid joints and the scene declares "
            "[robot.flexible]",
        )
    frame = str(require_key(table, section, "frame"))
    tracked = tracked_contacts(table, frame, scene.contacts)
    base_dir = scene.source.parent if scene.source is not None else None
    path, phases = cycle_from_table(table, base_dir, section)  # or a designed cycle file
    gains = ImpedanceGains(
        stiffness=require_key(table, section, "stiffness"),
        damping=require_key(table, section, "damping"),
        **{key: table[key] for key in _GAIN_KEYS[2:] if key in table},
    )
    for key in ("project", "check_reach", "impact_invariant"):
        if key in table and not isinstance(table[key], bool):
            raise InvalidParameterError(f"{section} {key}", table[key], "true or false")
    if table.get("check_reach", True):
        check_reach(path, scene.robot, frame, scene.q0)
    return {
        "robot": scene.robot,
        "frame": frame,
        "path": path,
        "gains": gains,
        "contacts": tracked,
        "contact_phases": phases,
        "posture": table.get("posture", scene.q0),
        "project": table.get("project", True),
        **{key: table[key] for key in _OPTION_KEYS if key in table},
    }
