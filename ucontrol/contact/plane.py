"""Planar obstacle surfaces."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_vector
from ucontrol.exceptions import InvalidParameterError

if TYPE_CHECKING:
    from ucontrol.contact.surface_motion import SurfaceMotion


@dataclass(frozen=True, kw_only=True)
class Plane:
    """The half-space ``{p : normal · (p - point) >= 0}`` is free; its boundary is the surface.

    With a ``motion`` x(t) the plane translates: at time t it passes through ``point + x(t)``
    (:mod:`ucontrol.contact.surface_motion`).

    Attributes:
        point: A point of the plane in world coordinates in [m], shape (3,) (at x = 0).
        normal: Unit normal pointing into the free side, shape (3,) (normalised on creation).
        name: Label used in logs and errors.
        motion: Prescribed translation of the plane, or None for a fixed plane.
    """

    point: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    normal: NDArray[np.float64] = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    name: str = "plane"
    motion: SurfaceMotion | None = None

    def __post_init__(self) -> None:
        if self.motion is not None and not callable(self.motion):
            raise InvalidParameterError(
                "motion",
                self.motion,
                "a function of t giving (displacement, velocity, acceleration)",
            )
        point = as_vector("point", self.point, 3)
        normal = as_vector("normal", self.normal, 3)
        norm = float(np.linalg.norm(normal))
        if norm < 1e-12:
            raise InvalidParameterError("normal", self.normal, "a non-zero vector")
        object.__setattr__(self, "point", point)
        object.__setattr__(self, "normal", normal / norm)

    def signed_distance(self, p_world: NDArray[np.float64]) -> float:
        """Distance in [m] from ``p_world`` (3,) to the plane, positive on the free side."""
        return float(self.normal @ (p_world - self.point))
