r"""Period-one gaits: Newton on the stride map at heel strike or on the apex map.

The section is chosen by the user (``section``): the **heel strike**, a state just after a foot
has struck and become the stance foot (the flow's ``stride(q, v)``), or the **apex**, a flight
state whose body's vertical velocity crosses 0 downwards (the flow's ``apex(q, v)``, e.g.
:class:`~ucontrol.analysis.hop_flow.HopFlow` for a hopper in closed loop). A chart of it,
``to_state(z) -> (q, v)`` and ``from_state(q, v) -> z``, says which coordinates describe it
(for the rimless wheel the post-strike speed alone; for a walker the post-strike angles and
rates with the legs relabelled; for a hopper every coordinate at the apex but x and ż). The
stride map

.. math:: P(z) = \text{from\_state}\big(\text{stride}(\text{to\_state}(z))\big)

(``apex`` in place of ``stride`` at the apex section) runs one
:meth:`~ucontrol.analysis.stance_flow.StanceFlow.stride` (stance flow to the next
strike, then the strike). A period-one gait is a fixed point :math:`z^* = P(z^*)`, found by
:func:`~ucontrol.analysis.poincare.fixed_point` (damped Newton, the Jacobian by central
differences, :func:`~ucontrol.analysis.poincare.finite_difference_jacobian`); its multipliers
are the eigenvalues of :math:`DP(z^*)`. A chart that keeps every coordinate of the state gives
the trivial multipliers of the section too (0: the directions the strike removes): drop them
with ``drop_trivial``. Every evaluation is bounded (a stride by ``max_duration`` of its flow,
the search by ``max_iter``): a section never crossed is a
:class:`~ucontrol.exceptions.StrideError`, a search that does not converge a
:class:`~ucontrol.exceptions.SolverError`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.analysis.poincare import finite_difference_jacobian, fixed_point
from ucontrol.exceptions import InvalidParameterError

Vector = NDArray[np.float64]


class StrideResult(Protocol):
    """What :func:`find_gait` reads of a stride: its duration and the post-strike state."""

    @property
    def duration(self) -> float:
        """Time from the start to the heel strike (the walker's time unit)."""

    @property
    def q(self) -> Vector:
        """Configuration at the strike."""

    @property
    def v(self) -> Vector:
        """Velocity just after the strike."""


class Hopper(Protocol):
    """A flow with an apex section, such as :class:`~ucontrol.analysis.hop_flow.HopFlow`."""

    def apex(self, q: Vector, v: Vector) -> StrideResult:
        """Flow from an apex to the next one."""


#: The Poincaré sections :func:`find_gait` knows, and the flow's method for each.
SECTIONS = {"heel_strike": "stride", "apex": "apex"}


class Walker(Protocol):
    """A walker's stride map.

    A :class:`~ucontrol.analysis.stance_flow.StanceFlow`, or a model such as
    :class:`~ucontrol.analysis.simplest_walker.SimplestWalker`.
    """

    def stride(self, q: Vector, v: Vector) -> StrideResult:
        """Flow from a post-strike state to the next heel strike, then strike."""


@dataclass(frozen=True)
class Gait:
    """A period-one gait: a fixed point of the stride map.

    Attributes:
        z: The fixed point in the chart's coordinates, shape (k,).
        q: Configuration just after the strike, shape (nq,).
        v: Velocity just after the strike, shape (nv,).
        period: Step period (section to section) in [s] (in the walker's time unit).
        multipliers: Eigenvalues of the stride map's Jacobian, largest modulus first, the
            ``drop_trivial`` smallest ones dropped.
        jacobian: The stride map's Jacobian at ``z``, shape (k, k).
        residual: ‖P(z) - z‖ at the end.
        iterations: Newton iterations.
    """

    z: Vector
    q: Vector
    v: Vector
    period: float
    multipliers: NDArray[np.complex128]
    jacobian: NDArray[np.float64]
    residual: float
    iterations: int

    @property
    def stable(self) -> bool:
        """Whether every multiplier is inside the unit circle."""
        return bool(np.max(np.abs(self.multipliers), initial=0.0) < 1.0)


def find_gait(
    flow: Walker | Hopper,
    to_state: Callable[[Vector], tuple[Vector, Vector]],
    from_state: Callable[[Vector, Vector], Vector],
    z0: Vector,
    *,
    section: str = "heel_strike",
    tol: float = 1e-10,
    max_iter: int = 20,
    step: float = 1e-5,
    drop_trivial: int = 0,
) -> Gait:
    """Find a period-one gait by Newton on the stride map at heel strike or at apex.

    Args:
        flow: The walker's stance flow and strike map (``stride(q, v)``), or a hopper's flow
            (``apex(q, v)``).
        to_state: The state (q (nq,), v (nv,)) on the section of section coordinates z (k,).
        from_state: The section coordinates (k,) of a state on the section.
        z0: First guess, shape (k,).
        section: ``"heel_strike"`` (the flow's ``stride``) or ``"apex"`` (its ``apex``).
        tol: Residual ‖P(z) - z‖ at which Newton stops, relative to max(1, ‖z‖).
        max_iter: Newton iterations at most.
        step: Relative step of the central differences of the Jacobian.
        drop_trivial: Multipliers closest to 0 to drop (the section's own directions).

    Raises:
        InvalidParameterError: An unknown ``section``, or a flow without its method.
        StrideError: A stride from the guess fails (no strike within the flow's
            ``max_duration``: the section is never crossed; a foot lifting off or slipping).
        SolverError: Newton did not converge in ``max_iter`` iterations.
    """
    tol = as_positive("tol", tol)
    step = as_positive("step", step)
    if section not in SECTIONS:
        raise InvalidParameterError("section", section, f"one of {sorted(SECTIONS)}")
    run = getattr(flow, SECTIONS[section], None)
    if not callable(run):
        raise InvalidParameterError(
            "flow", type(flow).__name__, f"a flow with a {SECTIONS[section]}(q, v) method"
        )

    def stride_map(z: Vector) -> Vector:
        q, v = to_state(z)
        stride = run(q, v)
        return np.asarray(from_state(stride.q, stride.v), dtype=float)

    point = fixed_point(
        stride_map,
        np.asarray(z0, dtype=float),
        jacobian=lambda z: finite_difference_jacobian(stride_map, z, step),
        tol=tol,
        max_iter=max_iter,
        drop_trivial=drop_trivial,
    )
    q, v = to_state(point.z)
    stride = run(q, v)
    return Gait(
        z=point.z,
        q=np.asarray(q, dtype=float),
        v=np.asarray(v, dtype=float),
        period=stride.duration,
        multipliers=point.multipliers,
        jacobian=point.jacobian,
        residual=point.residual,
        iterations=point.iterations,
    )
