"""Planar obstacle surfaces."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_vector
from ucontrol.exceptions import InvalidParameterError


@dataclass(frozen=True, kw_only=True)
class Plane:
    """The half-space ``{p : normal · (p - point) >= 0}`` is free; its boundary is the surface.

    Attributes:
        point: A point of the plane in world coordinates in [m], shape (3,).
        normal: Unit normal pointing into the free side, shape (3,) (normalised on creation).
        name: Label used in logs and errors.
    """

    point: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    normal: NDArray[np.float64] = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    name: str = "plane"

    def __post_init__(self) -> None:
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
