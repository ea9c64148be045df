"""The ``[controller] type = "pronk"`` table of a scene -> a :class:`PronkingController`."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from ucontrol._validation import check_keys, require_key
from ucontrol.exceptions import NotFoundError

if TYPE_CHECKING:
    from ucontrol.control.pronking_controller import PronkingController
    from ucontrol.scene.scene_data import SceneData

#: Share of the feet's smallest Coulomb coefficient the commanded forces use by default.
FRICTION_MARGIN = 0.8


@functools.cache
def _setting_keys() -> tuple[str, ...]:
    """Gains and limits of the table passed on to :class:`PronkSettings` as they are."""
    from ucontrol.control.pronking_controller import PronkSettings  # with the pronking scenes

    return tuple(
        field.name
        for field in dataclasses.fields(PronkSettings)
        if field.name not in {"stand_height", "apex", "friction"}
    )


def pronk_keys() -> set[str]:
    """Keys of a ``[controller] type = "pronk"`` table (its settings' fields among them)."""
    return {"type", "feet", "posture", "stand_height", "apex", "friction", *_setting_keys()}


def pronk_from_table(scene: SceneData, table: Mapping[str, Any]) -> PronkingController:
    """The pronking controller of a ``[controller] type = "pronk"`` table.

    Keys: ``feet`` (frames of point contacts of the scene; default every point contact's),
    ``posture`` (touchdown posture, shape (nq,); default the scene's q0), ``stand_height``
    [m] (required), ``apex`` [m] (required when ``hops`` > 0), ``friction`` (the controller's
    μ_c; default :data:`FRICTION_MARGIN` times the smallest μ of the feet's contacts) and the
    fields of :class:`PronkSettings` of the same names.

    Raises:
        UnknownKeyError: A key not in :func:`pronk_keys`.
        NotFoundError: A foot that is no point contact's frame.
        InvalidParameterError: A bad value (:class:`PronkSettings`, :class:`PronkingController`).
    """
    from ucontrol.control.pronking_controller import PronkingController, PronkSettings

    check_keys("[controller]", table, pronk_keys())
    by_frame = {contact.frame: contact for contact in scene.contacts}
    feet = [str(name) for name in table.get("feet", list(by_frame))]
    for name in feet:
        if name not in by_frame:
            raise NotFoundError("foot", name, list(by_frame))
    pairs = [by_frame[name] for name in feet]
    names = scene.constraints.names
    hops = table.get("hops", 0)
    stand_height = require_key(table, "[controller]", "stand_height")
    settings = PronkSettings(
        stand_height=stand_height,
        apex=require_key(table, "[controller]", "apex") if hops else stand_height,
        friction=table.get("friction", FRICTION_MARGIN * min(pair.friction for pair in pairs)),
        **{key: table[key] for key in _setting_keys() if key in table},
    )
    return PronkingController(
        scene.robot,
        feet=feet,
        contacts=[names.index(pair.name) for pair in pairs],
        normals=np.array([pair.surface.normal for pair in pairs]),
        posture=table.get("posture", scene.q0),
        settings=settings,
    )
