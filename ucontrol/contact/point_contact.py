"""Unilateral point contact of a robot frame against a surface."""

from __future__ import annotations

from dataclasses import dataclass

from ucontrol._validation import as_float, as_in_interval
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
    """

    frame: str
    surface: Plane
    radius: float = 0.0
    restitution: float = 0.0
    friction: float = 0.0
    name: str = ""

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
        if not self.name:
            object.__setattr__(self, "name", f"{self.frame}/{self.surface.name}")
