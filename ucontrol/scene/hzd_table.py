"""The ``[controller] type = "hzd"`` table of a scene -> an :class:`HZDController`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ucontrol._validation import check_keys, require_key

if TYPE_CHECKING:
    from ucontrol.control.hzd_controller import HZDController
    from ucontrol.scene.scene_data import SceneData

_REQUIRED = ("bezier", "theta_plus", "theta_minus", "kp", "kd")
_OPTIONAL = ("contact_gap", "torque_limit")
#: Keys of a ``[controller] type = "hzd"`` table.
HZD_KEYS = {"type", "legs", "stance", *_REQUIRED, *_OPTIONAL}
#: The legs of ``robots/rabbit.urdf``, the default of ``legs``.
RABBIT_LEGS = [["hip_left", "knee_left", "foot_left"], ["hip_right", "knee_right", "foot_right"]]


def hzd_from_table(scene: SceneData, table: Mapping[str, Any]) -> HZDController:
    """The walking controller of a ``[controller] type = "hzd"`` table.

    Keys: ``bezier`` (4 rows of M + 1 coefficients [rad]), ``theta_plus``, ``theta_minus``
    [rad], ``kp`` [1/s²], ``kd`` [1/s] (required); ``legs`` (two ``[hip, knee, foot]``, the
    feet frames of point contacts; default RABBIT's :data:`RABBIT_LEGS`), ``stance`` (the
    initial stance foot, default the first leg's), ``contact_gap`` [m], ``torque_limit``
    [N m].

    Raises:
        UnknownKeyError: A key not in :data:`HZD_KEYS`.
        InvalidParameterError: A bad value (:class:`HZDSettings`, ``legs``, ``stance``) or a
            robot whose actuated joints are not the hips and knees.
        JointNotFoundError: A joint the robot lacks.
    """
    from ucontrol.control.hzd_controller import HZDController, HZDSettings, legs_from_names

    check_keys("[controller]", table, HZD_KEYS)
    settings = HZDSettings(
        **{key: require_key(table, "[controller]", key) for key in _REQUIRED},
        **{key: table[key] for key in _OPTIONAL if key in table},
    )
    names = scene.constraints.names
    contacts = {contact.frame: names.index(contact.name) for contact in scene.contacts}
    legs = legs_from_names(table.get("legs", RABBIT_LEGS), contacts)
    return HZDController(
        scene.robot,
        legs=legs,
        stance=str(table.get("stance", legs[0].foot)),
        settings=settings,
    )
