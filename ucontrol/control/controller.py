"""The controller protocol: (time, state, contact information) -> joint torques."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

Vector = NDArray[np.float64]


@dataclass(frozen=True)
class ContactState:
    """What a controller may know of the unilateral constraints at time t.

    Attributes:
        names: One label per constraint (contacts first, then stops).
        gap: Gaps at t in [m] (or [rad] for rotational stops), shape (n,).
        normal_velocity: ``J v`` at t in [m/s] (or [rad/s]), shape (n,).
        impulse: Normal impulses of the step that ended at t in [N s], shape (n,).
        active: Whether each constraint was in that step's active set, shape (n,).
        dt: Length of that step in [s].
    """

    names: list[str]
    gap: Vector
    normal_velocity: Vector
    impulse: Vector
    active: NDArray[np.bool_]
    dt: float

    @property
    def force(self) -> Vector:
        """Mean normal contact force over the last step, ``impulse / dt`` in [N], shape (n,)."""
        return self.impulse / self.dt


class Controller(Protocol):
    """Anything called as ``controller(t, q, v, contacts)`` returning actuator torques.

    The returned vector has shape (nu,): one torque [N m] or force [N] per actuated velocity
    coordinate (every joint of a fixed-base robot). It is held constant (zero-order hold) until
    the next call.
    """

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Torques to apply from time ``t`` [s] at state (q (nq,), v (nv,))."""
        ...
