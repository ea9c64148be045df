r"""Semismooth Newton on the Alart–Curnier function of a Coulomb problem, all contacts at once.

With :math:`\rho_a = 1 / \sigma_a` (:attr:`CoulombProblem.normal_scale`) the function (in [N s])

.. math:: F_n = P_n - \max(0, P_n - \rho u_n), \qquad
          F_t = P_t - \Pi_{B(\mu \max(P_n, 0))}(P_t - \rho u_t)

vanishes exactly at the solutions of the Coulomb problem of
:mod:`ucontrol.solvers.coulomb_problem` (Alart & Curnier 1991); on a bilateral row it is
:math:`\rho_b u_b` (:math:`\rho_b = 1 / D_{bb}`). An element of its generalized Jacobian is

.. math:: J = E + G \, \mathrm{diag}(\rho) D,

:math:`G` block diagonal (one block per contact: 1 on a closed normal row, the identity on a
sticking contact's tangential rows, :math:`Q = \tfrac{\mu P_n}{\|y\|}(I - d d^T)` on a sliding
one's, :math:`y = P_t - \rho u_t`, :math:`d = y / \|y\|`) and :math:`E` the local part (1 on an
open normal row; :math:`I - Q` and :math:`-\mu d` on a sliding contact's tangential rows). Both
are built for every contact at once (numpy gathers and scatters, no loop over contacts).

:meth:`AlartCurnier.newton` iterates :math:`J \Delta = -F` with a backtracking line search
on :math:`\|F\|^2`. The step (:func:`solve_square`) is an LU solve, or least squares (QR with
column pivoting, minimum norm) where the LU says J is singular to :data:`LSTSQ_CONDITION`:
redundant contacts make it so, and a plain solve then returns a huge step along the null space
(measured: 10 times the impulses, for cond(J) ~ 1e16) that redistributes the impulses between
the redundant contacts. Large sparse problems (a column of beads, whose D is block
tridiagonal) are factorized by sparse LU on J's pattern, that of D's rows contact by contact:
their cost then grows linearly with the contacts. (On a 2-core machine under load, LAPACK's
threads made a dense 200-row LU 25 times slower than one thread, 23 ms against 0.84 ms;
SuperLU runs in one.) Where the contact statuses are right Newton converges quadratically.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.solvers.contact_solution import velocity_scale
from ucontrol.solvers.coulomb_problem import NUMPY_OPS, ConeOps, CoulombProblem

Vector = NDArray[np.float64]

#: Reciprocal condition number of J below which the Newton step is taken by least squares.
LSTSQ_CONDITION = 1e-10
#: Smallest step length of the backtracking line search.
MIN_STEP = 1.0 / 64.0
#: Rows from which a sparse enough Jacobian is factorized by sparse LU.
SPARSE_SIZE = 64
#: Largest fraction of non-zero entries of J factorized by sparse LU.
SPARSE_DENSITY = 0.1
#: Floor of the squared norm of :math:`y` under the square root: a finite ratio (and, in the
#: compiled step's automatic derivative, no 0 / 0) where :math:`y = 0`.
NORM_FLOOR = 1e-300


#: Non-zero entries of a square matrix in compressed columns: row indices, column pointers,
#: and the column of each entry.
Pattern = tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]


@functools.cache
def _lapack() -> tuple[Any, Any, Any, Any, Any]:
    """LAPACK's ``dgetrf``, ``dgecon``, ``dgetrs``, ``dgelsy`` and its workspace query."""
    from ucontrol.solvers.lapack_routines import lapack_routine

    names = ("dgetrf", "dgecon", "dgetrs", "dgelsy", "dgelsy_lwork")
    dgetrf, dgecon, dgetrs, dgelsy, dgelsy_lwork = (lapack_routine(name) for name in names)
    return dgetrf, dgecon, dgetrs, dgelsy, dgelsy_lwork


def least_squares(A: Vector, y: Vector) -> Vector:
    """The minimum-norm least-squares solution x (n,) of ``A x = y``, A of shape (k, n).

    QR with column pivoting (LAPACK's ``gelsy``, as ``scipy.linalg.lstsq`` calls it, without
    that wrapper's checks), singular values below :data:`LSTSQ_CONDITION` relative dropped.
    """
    k, n = A.shape
    if k == 0 or n == 0:
        return np.zeros(n)
    _, _, _, gelsy, gelsy_lwork = _lapack()
    rhs = np.zeros((max(k, n), 1))
    rhs[:k, 0] = y
    lwork, _ = gelsy_lwork(k, n, 1, LSTSQ_CONDITION)
    pivots = np.zeros(n, dtype=np.int32)
    _, x, _, _, _ = gelsy(A, rhs, pivots, LSTSQ_CONDITION, int(lwork), overwrite_a=False)
    return np.array(x[:n, 0])


def solve_square(A: Vector, y: Vector, pattern: Pattern | None = None) -> Vector:
    """The solution x (n,) of ``A x = y``, A of shape (k, n): LU, or :func:`least_squares`.

    Least squares where A is not square or LU says it is singular to :data:`LSTSQ_CONDITION`
    (LAPACK's condition estimate; for sparse LU, the spread of U's diagonal). A square A of
    at least :data:`SPARSE_SIZE` rows, at most :data:`SPARSE_DENSITY` of them non-zero, is
    factorized by sparse LU (SuperLU, a fill-reducing column order) on its non-zero
    ``pattern`` (:func:`sparsity` of A when not given).
    """
    k, n = A.shape
    if k != n:
        return least_squares(A, y)
    if n >= SPARSE_SIZE:
        if pattern is None:
            pattern = sparsity(A != 0.0)
        if pattern is not None:
            return _sparse_solve(A, y, pattern)
    getrf, gecon, getrs, _, _ = _lapack()
    norm = float(np.abs(A).sum(axis=0).max(initial=0.0))  # 1-norm
    lu, pivots, info = getrf(A)
    if info == 0:
        rcond, info = gecon(lu, norm)
        if info == 0 and rcond > LSTSQ_CONDITION:
            x, info = getrs(lu, pivots, y)
            if info == 0:
                return np.asarray(x)
    return least_squares(A, y)


def sparsity(pattern: NDArray[np.bool_]) -> Pattern | None:
    """The compressed columns of a boolean ``pattern`` (n, n).

    None where it is denser than :data:`SPARSE_DENSITY`.
    """
    if pattern.mean() > SPARSE_DENSITY:
        return None
    columns, rows = np.nonzero(pattern.T)  # column-major order
    counts = np.bincount(columns, minlength=pattern.shape[0])
    return rows, np.concatenate(([0], np.cumsum(counts))), columns


def _sparse_solve(A: Vector, y: Vector, pattern: Pattern) -> Vector:
    """:func:`solve_square` by sparse LU on ``pattern``."""
    from scipy.sparse import csc_matrix
    from scipy.sparse.linalg import splu

    rows, indptr, columns = pattern
    n = y.size
    matrix = csc_matrix((A[rows, columns], rows, indptr), shape=(n, n))
    try:
        factor = splu(matrix, permc_spec="COLAMD")
    except RuntimeError:  # exactly singular
        return least_squares(A, y)
    pivots = np.abs(factor.U.diagonal())
    if not pivots.min(initial=np.inf) > LSTSQ_CONDITION * pivots.max(initial=0.0):
        return least_squares(A, y)
    return np.asarray(factor.solve(y))


def _jacobian_pattern(problem: CoulombProblem) -> Pattern | None:
    """Where J can be non-zero, in compressed columns: (row indices, column pointers, columns).

    A row of J combines the rows of D of its own contact (bilateral rows: their own) and the
    contact's own columns; None where that pattern is denser than :data:`SPARSE_DENSITY`.
    """
    m, group = problem.m, problem.row_groups
    order = np.argsort(group, kind="stable")  # each group's rows together, groups in order
    starts = np.searchsorted(group[order], np.arange(m + problem.equalities))
    touched = np.logical_or.reduceat((problem.D != 0.0)[order], starts, axis=0)
    own = group[:, None] == group[None, :]  # a contact's own block
    return sparsity(touched[group] | own)


def alart_curnier_terms(
    ops: ConeOps, P: Sequence[Any], x: Sequence[Any], rho_u: Sequence[Any], mu: Any
) -> tuple[Any, Any, Any]:
    r"""The Alart–Curnier function of a contact: its normal and two tangential terms, [N s].

    :math:`F_n = P_n - \max(x_n, 0)` and :math:`F_t = P_t - \Pi_{B(r)}(x_t)`,
    :math:`r = \mu \max(P_n, 0)` (module docstring, :math:`x = P - \rho u`), written as
    :math:`\rho u` where the point is not projected (a closed normal row, a sticking
    contact: no cancellation in :math:`P - x`); a planar contact's second components are 0,
    and the squared norm under the ratio is floored at :data:`NORM_FLOOR`.

    Args:
        ops: The operations of the numbers given
            (:class:`~ucontrol.solvers.coulomb_problem.ConeOps`).
        P: Normal and two tangential impulses in [N s].
        x: Normal and two tangential components of :math:`P - \rho u` in [N s].
        rho_u: Normal and two tangential components of :math:`\rho u` in [N s].
        mu: Friction coefficient(s) >= 0.
    """
    radius = mu * ops.fmax(P[0], 0.0)  # [N s]
    square = x[1] ** 2 + x[2] ** 2  # [N² s²]
    slide = ops.sqrt(square) > radius
    ratio = radius / ops.sqrt(ops.fmax(square, NORM_FLOOR))
    return (
        ops.where(x[0] <= 0.0, P[0], rho_u[0]),
        ops.where(slide, P[1] - ratio * x[1], rho_u[1]),
        ops.where(slide, P[2] - ratio * x[2], rho_u[2]),
    )


class AlartCurnier:
    r"""The Alart–Curnier function of one Coulomb problem and its semismooth Newton.

    Args:
        problem: The Coulomb problem.

    Attributes:
        rho: Scale of each row (r,): :math:`1 / \sigma_a` on contact a's rows,
            :math:`1 / D_{bb}` on a bilateral row, in [N s per m/s].
    """

    def __init__(self, problem: CoulombProblem) -> None:
        self.problem = problem
        size = problem.size
        contacts = size - problem.equalities  # rows of the contacts
        rho = np.empty(size)
        rho[:contacts] = (1.0 / problem.normal_scale)[problem.row_groups[:contacts]]
        equal = problem.equality_rows
        if equal.size:
            rho[equal] = 1.0 / velocity_scale(problem.D[np.ix_(equal, equal)])
        self.rho = rho
        scaled = np.zeros((size + 1, size + 1))  # last row and column: sink of missing rows
        scaled[:size, :size] = rho[:, None] * problem.D
        self._scaled = scaled  # diag(rho) D, padded
        self._frictional = np.flatnonzero(problem.tangents > 0)
        self._pattern = _jacobian_pattern(problem) if size >= SPARSE_SIZE else None

    def value(self, P: Vector, u: Vector) -> tuple[Vector, Vector]:
        """F (r,) at impulses P (r,) with velocities u = D P + b (r,), and an element J (r, r)."""
        problem, rho = self.problem, self.rho
        m, size = problem.m, problem.size
        rho_u = rho * u
        x = P - rho_u
        F = np.append(rho_u, 0.0)  # bilateral rows; last entry: sink of the missing rows
        pairs = problem.tangent_rows  # (m, 2), size where missing
        P_ext, x_ext = np.append(P, 0.0), np.append(x, 0.0)
        terms = alart_curnier_terms(
            NUMPY_OPS,
            (P[:m], P_ext[pairs[:, 0]], P_ext[pairs[:, 1]]),
            (x[:m], x_ext[pairs[:, 0]], x_ext[pairs[:, 1]]),
            (rho_u[:m], F[pairs[:, 0]], F[pairs[:, 1]]),
            problem.mu,
        )
        F[:m] = terms[0]
        F[pairs[:, 0]], F[pairs[:, 1]] = terms[1], terms[2]
        F = F[:size]
        J = self._scaled.copy()
        open_ = np.flatnonzero(x[:m] <= 0.0)
        J[open_] = 0.0
        J[open_, open_] = 1.0
        frictional = self._frictional
        if frictional.size == 0:
            return F, J[:size, :size]
        rows = pairs[frictional]
        y = x_ext[rows]
        norm_y = np.sqrt(np.einsum("ij,ij->i", y, y))
        P_n = P[frictional]
        mu = problem.mu[frictional]
        radius = mu * np.maximum(P_n, 0.0)
        slide = norm_y > radius
        if not slide.any():
            return F, J[:size, :size]
        s = np.flatnonzero(slide)
        rows, y, norm_y, mu, P_n = rows[s], y[s], norm_y[s], mu[s], P_n[s]
        ratio = radius[s] / norm_y
        d = y / norm_y[:, None]  # (k, 2)
        eye = np.eye(2)
        Q = ratio[:, None, None] * (eye - d[:, :, None] * d[:, None, :])  # (k, 2, 2)
        block = np.einsum("kij,kjc->kic", Q, self._scaled[rows])  # (k, 2, size + 1)
        k = np.arange(s.size)[:, None]
        local = eye - Q
        block[k, 0, rows] += local[:, 0, :]
        block[k, 1, rows] += local[:, 1, :]
        normal = frictional[s]
        pressed = np.where(P_n > 0.0, mu, 0.0)
        block[k, np.arange(2), normal[:, None]] -= pressed[:, None] * d
        J[rows] = block
        return F, J[:size, :size]

    def newton(
        self, P: Vector, u: Vector, residual: float, iterations: int, target: float
    ) -> tuple[Vector, Vector, float, bool]:
        """Semismooth Newton iterations from (P, u), kept while they lower the residual.

        Args:
            P: Impulses in [N s], shape (r,).
            u: Their velocities ``D P + b`` in [m/s], shape (r,).
            residual: Their natural-map residual in [m/s].
            iterations: Cap on the Newton iterations.
            target: Natural-map residual in [m/s] at which to stop.

        Returns:
            The best impulses (r,) by natural-map residual (normal ones clipped at 0), their
            velocities (r,), residual in [m/s], and whether Newton improved on ``P``.
        """
        problem, m = self.problem, self.problem.m
        best = (P, u, residual, False)
        F, J = self.value(P, u)
        merit = F @ F
        for _ in range(iterations):
            step = solve_square(J, -F, self._pattern)
            alpha = 1.0
            while alpha >= MIN_STEP:
                candidate = P + alpha * step
                candidate_u = problem.velocity(candidate)
                candidate_F, candidate_J = self.value(candidate, candidate_u)
                candidate_merit = candidate_F @ candidate_F
                if candidate_merit < (1.0 - 1e-4 * alpha) * merit:
                    break
                alpha *= 0.5
            else:
                break
            P, u, F, J, merit = candidate, candidate_u, candidate_F, candidate_J, candidate_merit
            clipped, clipped_u = P, u
            if P[:m].min(initial=0.0) < 0.0:
                clipped = P.copy()
                clipped[:m] = np.maximum(P[:m], 0.0)
                clipped_u = problem.velocity(clipped)
            value = problem.residual(clipped, clipped_u)
            if value < best[2]:
                best = (clipped, clipped_u, value, True)
            if best[2] <= target or merit == 0.0:
                break
        return best
