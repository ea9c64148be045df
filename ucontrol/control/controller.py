"""The controller protocol: (time, state, contact information) -> joint torques."""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from ucontrol.log import Log

Vector = NDArray[np.float64]


class ContactState(NamedTuple):
    """What a controller may know of the unilateral constraints at time t.

    Attributes:
        names: One label per constraint (contacts first, then stops).
        gap: Gaps at t in [m] (or [rad] for rotational stops), shape (n,).
        normal_velocity: ``J v`` at t in [m/s] (or [rad/s]), shape (n,).
        impulse: Normal impulses accumulated over the control period that ended at t (the last
            step when the controller runs every step) in [N s], shape (n,).
        active: Whether each constraint was in an active set during that period, shape (n,).
        dt: Length of that period in [s].
    """

    names: list[str]
    gap: Vector
    normal_velocity: Vector
    impulse: Vector
    active: NDArray[np.bool_]
    dt: float

    @property
    def force(self) -> Vector:
        """Mean normal contact force over the last period, ``impulse / dt`` in [N], shape (n,)."""
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


@runtime_checkable
class LoggingController(Protocol):
    """A controller that writes its own per-sample fields (phase, Lyapunov function, ...).

    :func:`ucontrol.simulate` calls :meth:`prepare_log` once before the run and :meth:`record`
    once per log row, after the controller call of that row if there is one: on rows between
    two calls (``control_period`` longer than the step) and on the last row, the fields hold the
    values of the last call, like the torque ``u`` (zero-order hold).
    """

    def prepare_log(self, log: Log) -> None:
        """Declare the fields with :meth:`Log.add_field` (and metadata in ``log.metadata``)."""
        ...

    def record(self, log: Log) -> None:
        """Write the current row of every declared field with :meth:`Log.record_extra`."""
        ...
