r"""From an approximate QP solution to an exact one of the frictionless contact LCP.

Every QP backend of :math:`0 \le P \perp D P + b \ge 0`
(:class:`~ucontrol.solvers.proxsuite_lcp.ProxsuiteLCPSolver`,
:class:`~ucontrol.solvers.qpsolvers_lcp.QpsolversLCPSolver`) returns impulses accurate to its
tolerance. :func:`refine_lcp_solution` then polishes them: the linear system of the active set the
QP identified is solved directly and kept when it satisfies complementarity better, which brings
restitution to machine precision. Small problems still above the residual tolerance (nearly
dependent constraints, where iterative QP methods stall) are solved again by Lemke's method.
:func:`single_constraint_solution` is the closed form of a one-constraint problem, and
:func:`active_set_solution` the same exact solve on an active set guessed before any QP (the
last step's), kept only when it solves the LCP.

The exact solve on an active set :math:`A` is :math:`D_{AA} P_A = -b_A`, :math:`P = 0`
elsewhere. Redundant constraints (four feet of a table on the ground) make :math:`D_{AA}`
singular; the system is then solved in the least-squares sense with the minimum-norm impulses,
those of :math:`D_{AA}^+` from its eigenvalues (those below :data:`RANK_TOLERANCE` times the
largest taken as 0), which split the load evenly where the geometry is symmetric; a regular
:math:`D_{AA}` has one solution, the same.
"""

from __future__ import annotations

import functools
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import SolverError
from ucontrol.solvers.contact_solution import (
    ContactSolution,
    natural_map_residual,
    velocity_scale,
)
from ucontrol.solvers.lapack_routines import lapack_routine

#: QP solutions with a complementarity residual above this, in [m/s], are polished: Newton's
#: law then holds to this accuracy at every impact whatever the QP's tolerance.
POLISH_THRESHOLD = 1e-13
#: Problems up to this size that the QP and the polish leave above the residual tolerance
#: are solved again by Lemke's pivoting method.
LEMKE_FALLBACK_SIZE = 50
#: Relative size, to the largest, below which an eigenvalue of :math:`D_{AA}` counts as 0:
#: the rank of the active set.
RANK_TOLERANCE = 1e-12

Vector = NDArray[np.float64]


def refine_lcp_solution(
    D: Vector,
    b: Vector,
    x: Vector,
    *,
    polish: bool,
    residual_tolerance: float,
    iterations: int,
    unsolved_status: object,
    start: float,
) -> ContactSolution:
    """Polish the QP solution ``x`` (m,) of ``(D, b)``; Lemke for small stalled problems.

    Args:
        D: Delassus matrix, symmetric positive semidefinite, shape (m, m), [m/s per N s].
        b: Free constraint velocity plus restitution term in [m/s], shape (m,).
        x: Impulses returned by the QP backend in [N s], shape (m,).
        polish: Refine on the active set when the residual exceeds :data:`POLISH_THRESHOLD`.
        residual_tolerance: Residual in [m/s] above which Lemke's method is tried, and up to
            which the solve is ``"solved"``.
        iterations: The backend's iteration count.
        unsolved_status: Status of a solve left above ``residual_tolerance`` (the backend's),
            turned into text (``str``) only then.
        start: ``time.perf_counter()`` at the start of the solve, for its timing.

    Returns:
        The solve; ``polished`` when the polish or Lemke's method replaced the QP's impulses.
    """
    diagonal = D.diagonal()
    impulses = np.maximum(x, 0.0)
    velocity = D.dot(impulses)
    velocity += b
    residual = natural_map_residual(diagonal, impulses, velocity)
    polished = False
    if polish and residual > POLISH_THRESHOLD:
        active = velocity_scale(D) * impulses > velocity
        candidate = _solve_on_active_set(D, b, active)
        if candidate is not None:
            candidate_velocity = D @ candidate + b
            candidate_residual = natural_map_residual(diagonal, candidate, candidate_velocity)
            if candidate_residual <= residual:
                impulses, velocity, residual = candidate, candidate_velocity, candidate_residual
                polished = True
    if residual > residual_tolerance and b.size <= LEMKE_FALLBACK_SIZE:
        # Ill-conditioned D (constraints nearly dependent): pivoting is exact where the
        # proximal iterations stall.
        from ucontrol.solvers.lemke import solve_lcp_lemke  # the rare ill-conditioned case

        try:
            pivoted = solve_lcp_lemke(D, b)
        except SolverError:
            pivoted = None
        if pivoted is not None and pivoted.residual < residual:
            impulses, velocity, residual = pivoted.impulses, pivoted.velocity, pivoted.residual
            polished = True
    return ContactSolution(
        impulses,
        velocity,
        "solved" if residual <= residual_tolerance else str(unsolved_status),
        iterations,
        residual,
        time.perf_counter() - start,
        polished,
    )


def single_constraint_solution(D: Vector, b: Vector, start: float) -> ContactSolution:
    """Exact solution of a one-constraint LCP, the projection ``P = max(0, -b / D)``.

    Args:
        D: Shape (1, 1), in [m/s per N s].
        b: Shape (1,), in [m/s].
        start: ``time.perf_counter()`` at the start of the solve, for its timing.
    """
    d, beta = float(D[0, 0]), float(b[0])
    impulse = -beta / d if beta < 0.0 and d > 0.0 else 0.0
    velocity = d * impulse + beta
    residual = abs(min(d * impulse if d > 0.0 else impulse, velocity))
    return ContactSolution(
        np.array([impulse]),
        np.array([velocity]),
        "solved" if d > 0.0 or beta >= 0.0 else "infeasible",
        0,
        residual,
        time.perf_counter() - start,
        False,
    )


def active_set_solution(
    D: Vector, b: Vector, guess: NDArray[np.bool_], start: float
) -> ContactSolution | None:
    """The exact solve on the active set ``guess``, if it solves the LCP; else None.

    The warm start of a solve: for a contact held step after step the active set of the last
    step is that of this one, and the solve on it (module docstring) is the polish the QP's
    solution would get. It is kept when its impulses are non-negative and its
    natural-map residual is at most :data:`POLISH_THRESHOLD`, the accuracy a polished QP
    solution has; otherwise the caller solves the QP. The readable reference of the compiled
    solve of :mod:`ucontrol.solvers.compiled_active_set`, which
    :class:`~ucontrol.solvers.proxsuite_lcp.ProxsuiteLCPSolver` calls first.

    Args:
        D: Delassus matrix, symmetric positive semidefinite, shape (m, m), [m/s per N s].
        b: Free constraint velocity plus restitution term in [m/s], shape (m,).
        guess: The constraints guessed active, shape (m,).
        start: ``time.perf_counter()`` at the start of the solve, for its timing.
    """
    impulses = _solve_on_active_set(D, b, guess)
    if impulses is None:
        return None
    velocity = D.dot(impulses)
    velocity += b
    residual = natural_map_residual(D.diagonal(), impulses, velocity)
    if not residual <= POLISH_THRESHOLD:
        return None
    return ContactSolution(
        impulses, velocity, "solved", 0, residual, time.perf_counter() - start, True
    )


def _solve_on_active_set(D: Vector, b: Vector, active: NDArray[np.bool_]) -> Vector | None:
    """Impulses with ``D_AA P_A = -b_A`` on ``active`` and 0 elsewhere; None if some P_A < 0.

    (Written for a few rows: Python comparisons where numpy's reductions cost more.)
    """
    count = np.count_nonzero(active)
    if not count:
        return np.zeros(b.size)
    if count == 1:
        i = int(active.argmax())
        d = float(D[i, i])
        if d <= 0.0 or b[i] > 0.0:
            return None
        candidate = np.zeros(b.size)
        candidate[i] = -b[i] / d
        return candidate
    if count == b.size:
        return _non_negative_solve(D, -b)
    rows = np.flatnonzero(active)
    solution = _non_negative_solve(D.take(rows, 0).take(rows, 1), -b.take(rows))
    if solution is None:
        return None
    candidate = np.zeros(b.size)
    candidate[rows] = solution
    return candidate


def _non_negative_solve(A: Vector, y: Vector) -> Vector | None:
    """A solution x >= 0 of the consistent system ``A x = y`` (A symmetric PSD), if one exists.

    The minimum-norm solution from A's eigenvalues (module docstring), the unique one where A
    is regular: None where it is negative. Redundant constraints make A singular, where it may
    be negative although a non-negative one exists, which non-negative least squares finds.
    """
    eigenvalues, vectors, _ = _lapack()(A)  # ascending
    values = eigenvalues.tolist()
    threshold = RANK_TOLERANCE * values[-1]
    dropped = 0  # eigenvalues counted as 0, the first ones
    while dropped < len(values) and values[dropped] <= threshold:
        dropped += 1
    basis = vectors[:, dropped:]
    x: Vector = basis.dot(basis.T.dot(y) / eigenvalues[dropped:])
    if min(x.tolist()) < 0.0:
        if not dropped:  # the unique solution
            return None
        import scipy.optimize  # rare: loaded only when needed

        x = scipy.optimize.nnls(A, y)[0]
    return x


@functools.cache
def _lapack() -> Any:
    """LAPACK's ``dsyev``, loaded by the first exact solve.

    Called directly: numpy's ``eigh`` wrapper costs more than the decomposition of a few rows.
    Loaded without ``scipy.linalg``'s package (:mod:`ucontrol.solvers.lapack_routines`).
    """
    return lapack_routine("dsyev")
