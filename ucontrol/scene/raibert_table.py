"""The ``[controller] type = "raibert"`` table of a scene -> a :class:`RaibertController`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ucontrol._validation import check_keys, require_key
from ucontrol.exceptions import InvalidParameterError, NotFoundError

if TYPE_CHECKING:
    from ucontrol.control.raibert_controller import RaibertController
    from ucontrol.scene.scene_data import SceneData

_SETTING_KEYS = (
    "speed",
    "leg_length",
    "leg_stiffness",
    "leg_damping",
    "placement_gain",
    "stance_time",
    "hip_kp",
    "hip_kd",
    "attitude_kp",
    "attitude_kd",
    "max_thrust",
    "contact_gap",
)
#: Keys of a ``[controller] type = "raibert"`` table.
RAIBERT_KEYS = {"type", "contact", "joints", "apex", *_SETTING_KEYS}


def raibert_from_table(scene: SceneData, table: Mapping[str, Any]) -> RaibertController:
    """The hopping controller of a ``[controller] type = "raibert"`` table.

    Keys: ``apex`` [m] (required), the other fields of
    :class:`~ucontrol.control.raibert_controller.RaibertSettings`, ``contact`` (the foot's
    constraint, default the first) and ``joints`` (the x, z, pitch, hip and leg joints, default
    those names).

    Raises:
        UnknownKeyError: A key not in :data:`RAIBERT_KEYS`.
        NotFoundError: The contact is not one of the scene's constraints.
        JointNotFoundError: A joint the robot lacks.
        InvalidParameterError: A bad value (``joints`` not five names); the hip or the leg
            passive.
    """
    from ucontrol.control.raibert_controller import RaibertController, RaibertSettings

    check_keys("[controller]", table, RAIBERT_KEYS)
    names = scene.constraints.names
    name = str(table.get("contact", names[0] if names else ""))
    if name not in names:
        raise NotFoundError("contact", name, names)
    settings = RaibertSettings(
        apex=require_key(table, "[controller]", "apex"),
        **{key: table[key] for key in _SETTING_KEYS if key in table},
    )
    joints = tuple(str(joint) for joint in table.get("joints", ("x", "z", "pitch", "hip", "leg")))
    if len(joints) != 5:
        raise InvalidParameterError("joints", list(joints), "five names: x, z, pitch, hip, leg")
    return RaibertController(
        scene.robot,
        contact=names.index(name),
        settings=settings,
        joints=joints,  # type: ignore[arg-type]
    )
