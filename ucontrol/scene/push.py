"""A push: a velocity change of the robot at a time, declared by a scene's ``[[pushes]]``."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_non_negative, as_vector, check_keys, require_key

#: Keys of a ``[[pushes]]`` table.
PUSH_KEYS = {"time", "velocity"}


@dataclass(frozen=True)
class Push:
    r"""A velocity change of the robot: :math:`v \leftarrow v + \Delta v` at ``time``.

    :func:`ucontrol.simulate` adds it to the state at the first sample at or after ``time``
    (before the controller sees that sample), as an impulse
    :math:`M \Delta v` on the robot would; the run's energy audit leaves that sample's jump
    out. A push after the run's last sample is not applied.

    Attributes:
        time: When, in [s] (>= 0).
        velocity: :math:`\Delta v`, shape (nv,), in [m/s] or [rad/s] per coordinate.
    """

    time: float
    velocity: NDArray[np.float64]

    def sample(self, dt: float) -> int:
        """Index of the first sample at or after :attr:`time` on a grid of step ``dt`` [s]."""
        return math.ceil(self.time / dt - 1e-9)

    @classmethod
    def from_table(cls, table: Mapping[str, Any], nv: int) -> Push:
        """A push of a ``[[pushes]]`` table (``time`` [s], ``velocity``, nv entries).

        Raises:
            UnknownKeyError: A key other than ``time`` and ``velocity``.
            SceneError: A key missing.
            InvalidParameterError: A negative time.
            ShapeError: ``velocity`` without nv entries.
        """
        check_keys("[[pushes]]", table, PUSH_KEYS)
        time = as_non_negative("time", require_key(table, "[[pushes]]", "time"))
        velocity = as_vector("velocity", require_key(table, "[[pushes]]", "velocity"), nv)
        return cls(time, velocity)
