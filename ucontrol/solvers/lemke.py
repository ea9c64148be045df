r"""Reference LCP solver: Lemke's complementary pivoting with a lexicographic ratio test.

Solves the frictionless contact problem

.. math:: w = D P + b, \qquad P \ge 0, \quad w \ge 0, \quad P^T w = 0,

by pivoting on the tableau of :math:`w - D P - \mathbf{1} z_0 = b` (covering vector of ones,
artificial variable :math:`z_0`). Each pivot brings in the complement of the variable that
has just left; the run stops when :math:`z_0` leaves the basis (a solution) or when the entering
column has no positive entry (a secondary ray). For :math:`D` positive semidefinite (copositive
plus) a ray means the LCP has no solution, so every feasible contact problem is solved, also
when redundant constraints make :math:`D` singular. The lexicographic ratio test, on the rows of
:math:`[B^{-1} b \;\; B^{-1}]`, never revisits a basis, so the method terminates on degenerate
problems too.

Pivoting is independent of proxsuite's proximal iterations, which makes it the reference of
the tests. It is written for small problems (tens of contacts): the basis is refactored at every
pivot (:math:`O(m^3)`), ties are judged against componentwise round-off bounds so that
degenerate rows of a singular :math:`D` that tie in exact arithmetic also tie here (a plain
floating-point comparison lets round-off pick the row and can end on a spurious ray), and the
final values are recomputed from the original data of the final basis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_positive, as_vector
from ucontrol.exceptions import (
    InvalidParameterError,
    NonFiniteValueError,
    ShapeError,
    SolverError,
)
from ucontrol.solvers.contact_solution import complementarity_residual

_SYMMETRY_TOLERANCE = 1e-9  # relative to max |D|


@dataclass(frozen=True)
class LemkeResult:
    r"""Solution of :math:`0 \le P \perp D P + b \ge 0` found by Lemke's method.

    Attributes:
        impulses: Normal impulses P in [N s], shape (m,).
        velocity: Post-step constraint velocities ``w = D P + b`` in [m/s], shape (m,).
        pivots: Number of pivots performed (0 when ``b >= 0``).
        status: ``"solved"``; failures raise :class:`~ucontrol.exceptions.SolverError` instead.
        residual: Complementarity residual, see
            :func:`~ucontrol.solvers.complementarity_residual`, in [m/s].
    """

    impulses: NDArray[np.float64]
    velocity: NDArray[np.float64]
    pivots: int
    status: str
    residual: float

    @property
    def converged(self) -> bool:
        """Whether the pivoting ended on a complementary basis."""
        return self.status == "solved"


def solve_lcp_lemke(
    D: NDArray[np.float64],
    b: NDArray[np.float64],
    *,
    max_pivots: int | None = None,
    tol: float = 1e-12,
) -> LemkeResult:
    r"""Solve the LCP :math:`w = D P + b,\ 0 \le P \perp w \ge 0` by complementary pivoting.

    Args:
        D: Delassus matrix, symmetric positive semidefinite (possibly singular), shape (m, m),
            in [m/s per N s].
        b: Free constraint velocity plus restitution term in [m/s], shape (m,).
        max_pivots: Pivot cap; default ``20 (m + 1)``.
        tol: Relative round-off level of the ratio test. Each quantity it computes is
            trusted up to ``tol`` times its componentwise condition number: entries of the
            entering column below that bound are not pivots, and ratios whose uncertainty
            intervals overlap tie and are compared lexicographically. Between ``1e-14`` and
            ``1e-10`` the results on random rank-deficient problems do not change.

    Returns:
        The impulses, velocities, pivot count and complementarity residual. When ``b >= 0``
        the impulses are zero and no pivot is made.

    Raises:
        ShapeError: ``D`` is not square or ``b`` does not have length ``m``.
        NonFiniteValueError: ``D`` or ``b`` holds NaN or infinity.
        InvalidParameterError: ``D`` is not symmetric, or ``max_pivots`` / ``tol`` is not > 0.
        SolverError: The pivoting ended on a secondary ray (the LCP has no solution when ``D``
            is positive semidefinite), reached ``max_pivots``, or met a numerically singular
            basis.
    """
    D = _as_square_matrix("D", D)
    m = D.shape[0]
    b = as_vector("b", b, m)
    tol = as_positive("tol", tol)
    if max_pivots is None:
        max_pivots = 20 * (m + 1)
    elif isinstance(max_pivots, bool) or int(as_positive("max_pivots", max_pivots)) != max_pivots:
        raise InvalidParameterError("max_pivots", max_pivots, "a positive integer")
    max_pivots = int(max_pivots)

    if np.all(b >= 0.0):
        return LemkeResult(
            impulses=np.zeros(m), velocity=b.copy(), pivots=0, status="solved", residual=0.0
        )

    # Variables 0..m-1 are w, m..2m-1 are P, 2m is z0; columns of [I, -D, -1].
    columns = np.hstack([np.eye(m), -D, -np.ones((m, 1))])
    z0 = 2 * m
    basis = np.arange(m)  # basis[i]: variable basic in row i

    # First pivot: z0 enters, the most negative row leaves (ties: largest index, which keeps
    # the rows of [B^-1 b, B^-1] lexicographically positive).
    row = int(np.flatnonzero(b == b.min())[-1])
    entering = z0
    pivots = 0
    while True:
        if pivots >= max_pivots:
            raise SolverError("lemke", f"pivot limit {max_pivots} reached")
        leaving = int(basis[row])
        basis[row] = entering
        pivots += 1
        if leaving == z0:
            break
        entering = leaving + m if leaving < m else leaving - m  # complement of the leaver
        # Refactor every pivot (m is small): no drift accumulates in B^-1.
        B = columns[:, basis]
        try:
            B_inv = np.linalg.inv(B)
        except np.linalg.LinAlgError as error:
            raise SolverError("lemke", f"singular basis after {pivots} pivots") from error
        z0_row = int(np.flatnonzero(basis == z0)[0])
        row = _lexicographic_ratio_test(B, B_inv, b, columns[:, entering], z0_row, tol)
        if row < 0:
            raise SolverError("lemke", f"secondary ray after {pivots} pivots (no solution)")

    # Recompute the basic values from the original data rather than the updated tableau.
    basic_values = np.linalg.solve(columns[:, basis], b)
    impulses = np.zeros(m)
    is_impulse = (basis >= m) & (basis < z0)
    impulses[basis[is_impulse] - m] = basic_values[is_impulse]
    impulses = np.maximum(impulses, 0.0)  # clears round-off below zero [N s]
    velocity = D @ impulses + b  # [m/s]
    return LemkeResult(
        impulses=impulses,
        velocity=velocity,
        pivots=pivots,
        status="solved",
        residual=complementarity_residual(D, b, impulses),
    )


def _as_square_matrix(name: str, value: object) -> NDArray[np.float64]:
    """Return ``value`` as a finite, symmetric float matrix of shape (m, m)."""
    try:
        matrix = np.array(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError(name, value, "a square matrix of numbers") from error
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
        size = matrix.shape[0] if matrix.ndim >= 1 else -1
        raise ShapeError(name, (size, size), matrix.shape)
    bad = np.flatnonzero(~np.isfinite(matrix))
    if bad.size:
        raise NonFiniteValueError(name, value, bad.tolist())
    scale = float(np.max(np.abs(matrix), initial=0.0))
    if np.max(np.abs(matrix - matrix.T), initial=0.0) > _SYMMETRY_TOLERANCE * scale:
        raise InvalidParameterError(name, value, "symmetric")
    return matrix


def _lexicographic_ratio_test(
    B: NDArray[np.float64],
    B_inv: NDArray[np.float64],
    b: NDArray[np.float64],
    column: NDArray[np.float64],
    z0_row: int,
    tol: float,
) -> int:
    """Row leaving the basis: lexicographic minimum of ``[B^-1 b, B^-1] / (B^-1 column)``.

    Every computed quantity ``x`` of the test comes with a round-off bound, ``tol`` times its
    componentwise (Skeel) condition number: ``tol |B^-1| (|B| |x| + |rhs|)`` for solutions of
    ``B x = rhs``. Only rows whose entry of ``d = B^-1 column`` exceeds its bound compete;
    returns -1 when there is none (a ray). Ratios whose uncertainty intervals overlap the
    smallest one tie, and the tie goes to the next column of ``B^-1``, so that round-off does
    not decide between degenerate rows. When ``z0`` is among the rows of smallest ratio it
    leaves, which ends the run.
    """
    abs_B = np.abs(B)
    abs_B_inv = np.abs(B_inv)
    direction = B_inv @ column
    direction_noise = tol * (abs_B_inv @ (abs_B @ np.abs(direction) + np.abs(column)))
    candidates = np.flatnonzero(direction > direction_noise)
    if candidates.size <= 1:
        return int(candidates[0]) if candidates.size else -1
    values = B_inv @ b
    value_noise = tol * (abs_B_inv @ (abs_B @ np.abs(values) + np.abs(b)))
    inverse_noise = tol * (abs_B_inv @ abs_B @ abs_B_inv + abs_B_inv)
    d = direction[candidates]
    d_noise = direction_noise[candidates]
    for index in range(B_inv.shape[1] + 1):
        if index == 0:
            numerators, noise = values[candidates], value_noise[candidates]
        else:
            numerators = B_inv[candidates, index - 1]
            noise = inverse_noise[candidates, index - 1]
        ratios = numerators / d
        ratio_noise = (noise + np.abs(ratios) * d_noise) / d
        tied = ratios - ratio_noise <= np.min(ratios + ratio_noise)
        candidates, d, d_noise = candidates[tied], d[tied], d_noise[tied]
        if index == 0 and z0_row in candidates:
            return z0_row
        if candidates.size == 1:
            break
    return int(candidates[np.argmin(ratios[tied])])
