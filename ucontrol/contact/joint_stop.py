"""Joint-limit stops as unilateral constraints."""

from __future__ import annotations

from dataclasses import dataclass

from ucontrol._validation import as_float, as_in_interval
from ucontrol.exceptions import InvalidParameterError


@dataclass(frozen=True, kw_only=True)
class JointStop:
    """Mechanical stops ``lower <= q_joint <= upper`` of a one-degree-of-freedom joint.

    Each finite bound is one unilateral constraint with gap ``q - lower`` or ``upper - q``
    (in [rad] for revolute joints, [m] for prismatic ones).

    Attributes:
        joint: Joint name in the URDF (revolute or prismatic, nq = nv = 1).
        lower: Lower bound, or None for no lower stop.
        upper: Upper bound, or None for no upper stop.
        restitution: Newton's coefficient of restitution in [0, 1].
    """

    joint: str
    lower: float | None = None
    upper: float | None = None
    restitution: float = 0.0

    def __post_init__(self) -> None:
        if self.lower is None and self.upper is None:
            raise InvalidParameterError("lower/upper", None, "at least one bound")
        lower = None if self.lower is None else as_float("lower", self.lower)
        upper = None if self.upper is None else as_float("upper", self.upper)
        if lower is not None and upper is not None and not lower < upper:
            raise InvalidParameterError("upper", upper, f"> lower = {lower}")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(
            self, "restitution", as_in_interval("restitution", self.restitution, 0.0, 1.0)
        )
