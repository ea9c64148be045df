"""Result of one frictionless contact problem (a linear complementarity problem)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray


def complementarity_residual(
    D: NDArray[np.float64], b: NDArray[np.float64], impulses: NDArray[np.float64]
) -> float:
    r"""Natural-map residual of the LCP :math:`0 \le P \perp D P + b \ge 0`, in [m/s].

    :math:`\| \min(d \odot P, D P + b) \|_\infty` with :math:`d = \mathrm{diag}(D)` (1 where a
    diagonal entry vanishes) so that both arguments are velocities; it is zero exactly at a
    solution. Returns 0 for an empty problem.
    """
    if impulses.size == 0:
        return 0.0
    return natural_map_residual(velocity_scale(D), impulses, D @ impulses + b)


def velocity_scale(D: NDArray[np.float64]) -> NDArray[np.float64]:
    """Diagonal of ``D`` (1 where it vanishes): turns impulses [N s] into velocities [m/s]."""
    scale = D.diagonal().copy()
    scale[scale <= 0.0] = 1.0
    return scale


def natural_map_residual(
    scale: NDArray[np.float64], impulses: NDArray[np.float64], velocity: NDArray[np.float64]
) -> float:
    """``max |min(scale ⊙ P, w)|`` in [m/s] for impulses P and velocities w = D P + b."""
    return float(np.max(np.abs(np.minimum(scale * impulses, velocity))))


class ContactSolution(NamedTuple):
    r"""Impulses solving :math:`0 \le P \perp D P + b \ge 0` and how they were obtained.

    Attributes:
        impulses: Normal impulses P in [N s], shape (m,).
        velocity: Post-step constraint velocities with restitution, ``D P + b`` in [m/s], (m,).
        status: ``"solved"`` or the backend's status text.
        iterations: Backend iterations.
        residual: Complementarity residual, see :func:`complementarity_residual`, in [m/s].
        solve_time_s: Wall time of the solve in [s].
        polished: Whether the solution was refined by an exact solve on its active set.
    """

    impulses: NDArray[np.float64]
    velocity: NDArray[np.float64]
    status: str
    iterations: int
    residual: float
    solve_time_s: float
    polished: bool = False
