"""Result of one contact problem: frictionless (an LCP) or with Coulomb friction."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

#: Largest problem whose natural-map residual is computed on Python floats, in rows.
PYTHON_RESIDUAL_SIZE = 32


def complementarity_residual(
    D: NDArray[np.float64], b: NDArray[np.float64], impulses: NDArray[np.float64]
) -> float:
    r"""Natural-map residual of the LCP :math:`0 \le P \perp D P + b \ge 0`, in [m/s].

    :math:`\| \min(d \odot P, D P + b) \|_\infty` with :math:`d = \mathrm{diag}(D)` (1 where a
    diagonal entry vanishes) so that both arguments are velocities; it is zero exactly at a
    solution. Returns 0 for an empty problem.
    """
    return natural_map_residual(D.diagonal(), impulses, D @ impulses + b)


def velocity_scale(D: NDArray[np.float64]) -> NDArray[np.float64]:
    """Diagonal of ``D`` (1 where it vanishes): turns impulses [N s] into velocities [m/s]."""
    scale = D.diagonal().copy()
    scale[scale <= 0.0] = 1.0
    return scale


def natural_map_residual(
    diagonal: NDArray[np.float64], impulses: NDArray[np.float64], velocity: NDArray[np.float64]
) -> float:
    """``max |min(d ⊙ P, w)|`` in [m/s] for impulses P and velocities w = D P + b, all (m,).

    ``diagonal`` is the diagonal d of D in [m/s per N s] (or :func:`velocity_scale`): an
    entry ``<= 0`` counts as 1. A NaN anywhere gives NaN, and an empty problem 0. Up to
    :data:`PYTHON_RESIDUAL_SIZE` rows a loop on Python floats (cheaper than the numpy
    expression's fixed call costs for so few rows: docs/benchmarks.md), numpy beyond.
    """
    if impulses.size > PYTHON_RESIDUAL_SIZE:
        scale = np.where(diagonal <= 0.0, 1.0, diagonal)
        return float(np.abs(np.minimum(scale * impulses, velocity)).max())
    residual = 0.0
    for d, p, w in zip(diagonal.tolist(), impulses.tolist(), velocity.tolist(), strict=True):
        s = p if d <= 0.0 else d * p  # [m/s]
        if s <= w:
            r = abs(s)
        elif w < s:
            r = abs(w)
        else:  # s or w is NaN
            return math.nan
        if r > residual:
            residual = r
    return residual


class ContactSolution(NamedTuple):
    r"""Impulses solving one contact problem and how they were obtained.

    Frictionless, the problem is the LCP :math:`0 \le P \perp D P + b \ge 0` and there is one
    row per constraint. With friction it is the Coulomb problem of
    :class:`~ucontrol.solvers.coulomb_problem.CoulombProblem`, whose rows are the m normal
    components followed by the tangential ones.

    Attributes:
        impulses: Impulses P in [N s], shape (r,): normal, then tangential with friction.
        velocity: Post-step constraint velocities with restitution, ``D P + b`` in [m/s], (r,).
        status: ``"solved"`` when ``residual`` is within the solver's tolerance, otherwise
            the backend's status text.
        iterations: Backend iterations (summed over the QPs of a fixed point).
        residual: Natural-map residual of the problem in [m/s]: see
            :func:`complementarity_residual`, or
            :meth:`~ucontrol.solvers.coulomb_problem.CoulombProblem.residual` with friction.
        solve_time_s: Wall time of the solve in [s].
        polished: Whether the solution was refined by an exact solve on its active set.
        outer_iterations: Fixed-point iterations (QPs solved) of a Coulomb solve; 0 for one
            QP or a closed form.
    """

    impulses: NDArray[np.float64]
    velocity: NDArray[np.float64]
    status: str
    iterations: int
    residual: float
    solve_time_s: float
    polished: bool = False
    outer_iterations: int = 0
