"""Unilateral contact between two spheres carried by two robot frames."""

from __future__ import annotations

from dataclasses import dataclass

from ucontrol._validation import as_float, as_in_interval
from ucontrol.exceptions import InvalidParameterError


@dataclass(frozen=True, kw_only=True)
class SphereSphereContact:
    r"""Spheres of radii r1, r2 centred on frames ``frame`` and ``other_frame`` cannot overlap.

    Gap :math:`g = \|p_1(q) - p_2(q)\| - r_1 - r_2`, normal :math:`n = (p_1 - p_2) / \|p_1 - p_2\|`
    (from the second sphere to the first), normal velocity :math:`u_n = n \cdot (v_1 - v_2)` and
    row :math:`J_n = n^T (J_{lin}(F_1) - J_{lin}(F_2))` in LOCAL_WORLD_ALIGNED. The contact points
    are :math:`p_1 - r_1 n` and :math:`p_2 + r_2 n`; friction acts on their relative velocity,
    which includes the spheres' rotations. The normal is undefined when the centres coincide,
    which the gap excludes for positive radii.

    Attributes:
        frame: Name of the URDF frame at the centre of the first sphere.
        other_frame: Name of the URDF frame at the centre of the second sphere (may be fixed
            to the world).
        radius: Radius of the first sphere in [m], >= 0.
        other_radius: Radius of the second sphere in [m], >= 0.
        restitution: Newton's coefficient of restitution in [0, 1].
        friction: Coulomb coefficient, >= 0 (0: frictionless).
        name: Label used in logs; default ``"<frame>/<other_frame>"``.
    """

    frame: str
    other_frame: str
    radius: float = 0.0
    other_radius: float = 0.0
    restitution: float = 0.0
    friction: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        if self.frame == self.other_frame:
            raise InvalidParameterError("other_frame", self.other_frame, "a frame other than frame")
        for key in ("radius", "other_radius", "friction"):
            value = as_float(key, getattr(self, key))
            if value < 0.0:
                raise InvalidParameterError(key, getattr(self, key), ">= 0")
            object.__setattr__(self, key, value)
        object.__setattr__(
            self, "restitution", as_in_interval("restitution", self.restitution, 0.0, 1.0)
        )
        if not self.name:
            object.__setattr__(self, "name", f"{self.frame}/{self.other_frame}")
