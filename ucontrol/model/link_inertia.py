r"""Overrides of links' masses and inertias, applied to a loaded robot.

A scene varies a link's inertial parameters without a new URDF (``[robot.links.NAME]``,
``docs/scene_format.md``): its mass m, its centre of mass c and its rotational inertia
:math:`I_c` about c, in the link's frame, or a factor on m and :math:`I_c` together (the same
shape, a denser material). Pinocchio merges the links welded by fixed joints into the body of
their joint; the override replaces that body's inertia, written in the link's frame, by

.. math:: \mathcal I_{joint} = {}^{joint}X_{link}\, \mathcal I(m, c, I_c)

(``pin.Inertia`` moved by the link frame's placement), the values it does not give kept from
the body's current ones. A link welded to others describes them all: its override is the rigid
body's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_positive, as_vector
from ucontrol.exceptions import InvalidInertiaError, InvalidParameterError
from ucontrol.model.inertia_check import check_body
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class LinkInertia:
    """New inertial parameters of one link; None keeps the current value.

    Attributes:
        link: The link's name (a BODY frame of the model).
        mass: Mass m in [kg], > 0.
        com: Centre of mass c in the link's frame in [m], shape (3,).
        inertia: Rotational inertia about c in the link's axes,
            ``[ixx, iyy, izz, ixy, ixz, iyz]`` in [kg m²] (the URDF's order), positive definite
            with the triangle inequality.
        scale: Factor on the mass and the rotational inertia together, > 0; not with ``mass``
            or ``inertia``.
    """

    link: str
    mass: float | None = None
    com: Vector | None = None
    inertia: Vector | None = None
    scale: float | None = None

    def __post_init__(self) -> None:
        where = f"of link {self.link!r}"
        if self.scale is not None and (self.mass is not None or self.inertia is not None):
            raise InvalidParameterError(
                f"scale {where}",
                self.scale,
                "given alone, without mass or inertia (it scales both)",
            )
        for name in ("mass", "scale"):
            if getattr(self, name) is not None:
                number = as_positive(f"{name} {where}", getattr(self, name))
                object.__setattr__(self, name, number)
        for name, size in (("com", 3), ("inertia", 6)):
            if getattr(self, name) is not None:
                vector = as_vector(f"{name} {where}", getattr(self, name), size)
                object.__setattr__(self, name, vector)

    def applied_to(self, current: pin.Inertia) -> pin.Inertia:
        """The inertia ``current`` (in the link's frame) with this override.

        Raises:
            InvalidInertiaError: The resulting rotational inertia is not positive definite or
                breaks the triangle inequality; the error names the link.
        """
        link = self.link
        mass = float(current.mass) if self.mass is None else self.mass
        com = np.array(current.lever) if self.com is None else self.com
        rotational = np.array(current.inertia)
        if self.inertia is not None:
            ixx, iyy, izz, ixy, ixz, iyz = self.inertia
            rotational = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        if self.scale is not None:
            mass, rotational = mass * self.scale, rotational * self.scale
        moments = check_body(link, mass, rotational)
        if mass <= 0.0 or moments[0] <= 0.0:
            raise InvalidInertiaError(
                link, mass, moments, "a mass > 0 and a positive definite inertia"
            )
        return pin.Inertia(mass, com, rotational)


def with_link_inertias(robot: RobotModel, overrides: Sequence[LinkInertia]) -> RobotModel:
    """A copy of ``robot`` whose links' inertial parameters are overridden.

    Args:
        robot: The robot as loaded.
        overrides: The new parameters, one per link.

    Returns:
        A robot of the same file and kinematics whose bodies carry the new inertias.

    Raises:
        FrameNotFoundError: A name that is no frame of the robot.
        InvalidParameterError: A frame that is no link, a link fixed to the world (its
            inertia never enters M(q)), or two overrides of links welded into one body.
        InvalidInertiaError: An override that gives a non-physical body, naming the link.
    """
    model = robot.model.copy()
    bodies: dict[int, str] = {}
    for override in overrides:
        link = override.link
        frame = model.frames[robot.frame_id(link)]
        if frame.type != pin.FrameType.BODY:
            raise InvalidParameterError("link", link, f"a link (a body), not a {frame.type}")
        joint = int(frame.parentJoint)
        if joint == 0:
            raise InvalidParameterError(
                "link", link, "a link moved by a joint (this one is fixed to the world)"
            )
        if joint in bodies:
            raise InvalidParameterError(
                "link",
                link,
                f"one override per rigid body; {bodies[joint]!r} is welded to it (their joint "
                f"{model.names[joint]!r} moves both): override one of them for the body",
            )
        bodies[joint] = link
        current = frame.placement.actInv(model.inertias[joint])  # [link frame]
        model.inertias[joint] = frame.placement.act(override.applied_to(current))
    return robot.with_model(model)
