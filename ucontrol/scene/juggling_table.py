"""The ``[controller] type = "juggling"`` table of a scene -> a :class:`JugglingController`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ucontrol._validation import as_float, check_keys, require_key
from ucontrol.exceptions import NotFoundError

if TYPE_CHECKING:
    from ucontrol.control.juggling_controller import JugglingController
    from ucontrol.scene.scene_data import SceneData

#: Keys of a ``[controller] type = "juggling"`` table.
JUGGLING_KEYS = {
    "type",
    "paddle_joint",
    "ball_joint",
    "contact",
    "apex",
    "hit_height",
    "restitution",
    "kp",
    "kd",
    "max_paddle_speed",
    "estimate_restitution",
    "frame",
    "arm_joints",
    "hit_x",
}


def juggling_from_table(scene: SceneData, table: Mapping[str, Any]) -> JugglingController:
    """The juggling controller of a ``[controller] type = "juggling"`` table.

    Keys: ``paddle_joint``, ``ball_joint``, ``contact`` (name of the ball/paddle sphere
    contact), ``apex`` [m] (required), ``hit_height`` [m], ``restitution`` (default the
    contact's), ``kp`` [1/s²], ``kd`` [1/s], ``max_paddle_speed`` [m/s],
    ``estimate_restitution`` (true/false). With ``frame`` (a tip frame) the paddle is that
    frame of an arm: :class:`ArmJugglingController` with ``arm_joints`` (default shoulder,
    elbow) and ``hit_x`` [m] (required, the ball's horizontal line); ``hit_height`` is then
    the tip's height at the hits.

    Raises:
        UnknownKeyError: A key not in :data:`JUGGLING_KEYS`.
        NotFoundError: The contact is not one of the scene's constraints.
        InvalidParameterError: A bad value, or an apex out of reach.
    """
    from ucontrol.control.juggling_controller import (
        ArmJugglingController,
        JugglingController,
        JugglingSettings,
    )

    check_keys("[controller]", table, JUGGLING_KEYS)
    constraints = scene.constraints
    name = str(table.get("contact", constraints.names[0]))
    if name not in constraints.names:
        raise NotFoundError("contact", name, constraints.names)
    index = constraints.names.index(name)
    pairs: list[Any] = [*scene.contacts, *scene.sphere_contacts]
    pair = next((c for c in pairs if c.name == name), None)
    restitution = table.get("restitution", getattr(pair, "restitution", 0.8))
    distance = float(getattr(pair, "radius", 0.0)) + float(getattr(pair, "other_radius", 0.0))
    settings = JugglingSettings(
        apex=require_key(table, "[controller]", "apex"),
        hit_height=table.get("hit_height", 0.0),
        restitution=restitution,
        kp=table.get("kp", 900.0),
        kd=table.get("kd", 60.0),
        max_paddle_speed=table.get("max_paddle_speed", 10.0),
        estimate_restitution=table.get("estimate_restitution", False),
    )
    if "frame" in table:
        return ArmJugglingController(
            scene.robot,
            frame=str(table["frame"]),
            arm_joints=tuple(str(name) for name in table.get("arm_joints", ("shoulder", "elbow"))),
            ball_joint=str(table.get("ball_joint", "ball_height")),
            contact=index,
            distance=distance,
            settings=settings,
            hit_x=as_float("hit_x", require_key(table, "[controller]", "hit_x")),
            q_hit=scene.q0,
        )
    return JugglingController(
        scene.robot,
        paddle_joint=str(table.get("paddle_joint", "paddle_height")),
        ball_joint=str(table.get("ball_joint", "ball_height")),
        contact=index,
        distance=distance,
        settings=settings,
    )
