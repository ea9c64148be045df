"""Unilateral point contact of a robot frame against a surface."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ucontrol._validation import as_float, as_in_interval, as_vector
from ucontrol.contact.plane import Plane
from ucontrol.exceptions import InvalidParameterError


@dataclass(frozen=True, kw_only=True)
class PointContact:
    r"""A sphere of radius ``radius`` centred on frame ``frame`` that cannot cross ``surface``.

    Gap :math:`g = n \cdot (p_F(q) - p_0) - r`, normal velocity :math:`u_n = J_n v` with
    :math:`J_n = n^T J_{lin}(F)` in LOCAL_WORLD_ALIGNED.

    Attributes:
        frame: Name of the URDF frame at the centre of the sphere.
        surface: The obstacle.
        radius: Sphere radius in [m], >= 0.
        restitution: Newton's coefficient of restitution in [0, 1].
        friction: Coulomb coefficient, >= 0 (0: frictionless).
        name: Label used in logs; default ``"<frame>/<surface>"``.
        closes_ahead_of: Frame of another point contact, or ``""``: this contact, unless held
            by the last step, closes only while frame ``ahead_frame`` is ahead of that one
            along ``direction_of_travel`` (a walker's swing foot passes through the ground
            until its hip is past the stance foot, mid-stance: the scuffing rule of the
            walking models, docs/legged.md).
        direction_of_travel: Unit direction in which "ahead" is measured, shape (3,) (given
            any non-zero length); required with ``closes_ahead_of``.
        ahead_frame: Frame whose position is measured against ``closes_ahead_of``'s; ``""``:
            the contact's own.
    """

    frame: str
    surface: Plane
    radius: float = 0.0
    restitution: float = 0.0
    friction: float = 0.0
    name: str = ""
    closes_ahead_of: str = ""
    direction_of_travel: tuple[float, float, float] | None = None
    ahead_frame: str = ""

    def __post_init__(self) -> None:
        radius = as_float("radius", self.radius)
        if radius < 0.0:
            raise InvalidParameterError("radius", self.radius, ">= 0")
        friction = as_float("friction", self.friction)
        if friction < 0.0:
            raise InvalidParameterError("friction", self.friction, ">= 0")
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "friction", friction)
        object.__setattr__(
            self, "restitution", as_in_interval("restitution", self.restitution, 0.0, 1.0)
        )
        if self.closes_ahead_of:
            if self.direction_of_travel is None:
                raise InvalidParameterError(
                    "direction_of_travel",
                    None,
                    f"a direction with closes_ahead_of = {self.closes_ahead_of!r}",
                )
            direction = as_vector("direction_of_travel", self.direction_of_travel, 3)
            norm = float(np.linalg.norm(direction))
            if not norm > 0.0:
                raise InvalidParameterError(
                    "direction_of_travel", self.direction_of_travel, "a non-zero vector"
                )
            object.__setattr__(
                self, "direction_of_travel", tuple(float(x) for x in direction / norm)
            )
        elif self.direction_of_travel is not None or self.ahead_frame:
            raise InvalidParameterError(
                "closes_ahead_of",
                "",
                "the frame of another contact with direction_of_travel or ahead_frame",
            )
        if not self.name:
            object.__setattr__(self, "name", f"{self.frame}/{self.surface.name}")
