"""A controller's model of the robot that differs from the plant: robustness to model errors.

Pinocchio merges the links joined by fixed joints into the body of their joint; a link named
here scales (or moves the centre of mass of) that whole body.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from ucontrol._validation import as_positive, as_vector
from ucontrol.exceptions import NotFoundError
from ucontrol.model.robot_model import RobotModel


def perturbed_robot(
    robot: RobotModel,
    *,
    mass_scale: float | Mapping[str, float] = 1.0,
    com_offset: Mapping[str, Any] | None = None,
) -> RobotModel:
    """A copy of ``robot`` with scaled masses and inertias and moved centres of mass.

    Args:
        robot: The plant's robot.
        mass_scale: Factor (> 0) on every body's mass and rotational inertia, or one factor per
            link name (the others unchanged): 1.2 is 20 % heavier.
        com_offset: Displacement of each named link's centre of mass in [m], shape (3,), in
            the frame of its joint; the rotational inertia about the centre of mass is kept.

    Raises:
        NotFoundError: A link name that is no body of the robot (the message lists them).
        InvalidParameterError: A factor that is not > 0, an offset that is not 3 numbers.
    """
    model = robot.model.copy()
    bodies = _bodies(model)
    scales = (
        {joint: as_positive("mass_scale", mass_scale) for joint in range(1, model.njoints)}
        if not isinstance(mass_scale, Mapping)
        else {
            _joint_of(bodies, link): as_positive(f"mass_scale of {link!r}", factor)
            for link, factor in mass_scale.items()
        }
    )
    offsets = {
        _joint_of(bodies, link): as_vector(f"com_offset of {link!r}", offset, 3)
        for link, offset in (com_offset or {}).items()
    }
    for joint in range(1, model.njoints):
        inertia = model.inertias[joint]
        factor = scales.get(joint, 1.0)
        lever = inertia.lever + offsets.get(joint, np.zeros(3))
        model.inertias[joint] = pin.Inertia(inertia.mass * factor, lever, inertia.inertia * factor)
    return robot.with_model(model)


def _bodies(model: pin.Model) -> dict[str, int]:
    """Each link (BODY frame) name and the joint whose body it belongs to."""
    return {
        str(frame.name): int(frame.parentJoint)
        for frame in model.frames
        if frame.type == pin.FrameType.BODY and frame.parentJoint > 0
    }


def _joint_of(bodies: Mapping[str, int], link: str) -> int:
    if link not in bodies:
        raise NotFoundError("link", link, sorted(bodies))
    return bodies[link]
