r"""Frictionless contact impulses as a proxsuite QP.

The velocity-level Signorini–Newton problem of one Moreau–Jean step,

.. math:: 0 \le P \perp D P + b \ge 0, \qquad D = J W^{-1} J^T,\;
          b = J v_\text{free} + e \odot J v_k,

is the optimality system of the convex QP :math:`\min_{P \ge 0} \tfrac12 P^T D P + b^T P`,
solved here with proxsuite's dense solver. Redundant constraints make :math:`D` singular; the
proximal method still converges and the velocity :math:`v = v_\text{free} + W^{-1} J^T P` is unique.
"""

from __future__ import annotations

import time

import numpy as np
import proxsuite
import scipy.optimize
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.exceptions import SolverError
from ucontrol.solvers.contact_solution import (
    ContactSolution,
    natural_map_residual,
    velocity_scale,
)
from ucontrol.solvers.lemke import solve_lcp_lemke

_WARM_START = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT

#: QP solutions with a complementarity residual above this, in [m/s], are polished: Newton's
#: law then holds to this accuracy at every impact whatever proxsuite's tolerance.
POLISH_THRESHOLD = 1e-13
#: Problems up to this size that proxsuite and the polish leave above the residual tolerance
#: are solved again by Lemke's pivoting method.
LEMKE_FALLBACK_SIZE = 50


class ProxsuiteLCPSolver:
    """Solve frictionless contact LCPs with reused, warm-started proxsuite QP objects.

    One QP object is kept per problem size and updated in place; each solve starts from the
    previous solution of that size. A QP solution whose complementarity residual exceeds
    :data:`POLISH_THRESHOLD` is then polished: the linear system of its active set is solved
    directly and kept when it satisfies complementarity better, which brings restitution to
    machine precision. Small problems still above ``residual_tolerance`` (nearly dependent
    constraints, where the proximal iterations stall) are solved again by Lemke's method.

    The status is ``"solved"`` when the complementarity residual, measured by us, is at most
    ``residual_tolerance``; otherwise it is proxsuite's status and the caller decides.

    Args:
        eps_abs: Absolute tolerance of proxsuite in [m/s].
        max_iter: Iteration cap of proxsuite.
        polish: Refine on the active set after the QP solve.
        residual_tolerance: Largest complementarity residual accepted as solved, in [m/s].
        exact_single: Solve one-constraint problems by their closed form
            ``P = max(0, -b / D)`` (the QP's exact solution) instead of calling proxsuite.
    """

    name = "proxsuite"

    def __init__(
        self,
        *,
        eps_abs: float = 1e-10,
        max_iter: int = 5000,
        polish: bool = True,
        residual_tolerance: float = 1e-8,
        exact_single: bool = True,
    ):
        self.eps_abs = as_positive("eps_abs", eps_abs)
        self.max_iter = int(as_positive("max_iter", max_iter))
        self.residual_tolerance = as_positive("residual_tolerance", residual_tolerance)
        self.exact_single = exact_single
        self.polish = polish
        self._qps: dict[int, proxsuite.proxqp.dense.QP] = {}

    def _solved_qp(
        self, D: NDArray[np.float64], b: NDArray[np.float64]
    ) -> proxsuite.proxqp.dense.QP:
        """The QP object of this size, updated with (D, b) and solved."""
        m = b.size
        qp = self._qps.get(m)
        if qp is None:
            qp = proxsuite.proxqp.dense.QP(m, 0, m)
            qp.settings.eps_abs = self.eps_abs
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = self.max_iter
            qp.settings.verbose = False
            qp.init(D, b, None, None, np.eye(m), np.zeros(m), np.full(m, 1e20))
            qp.solve()
            # Only once a result exists: warm-starting from none crashes proxsuite 0.8.
            qp.settings.initial_guess = _WARM_START
            self._qps[m] = qp
            return qp
        qp.update(D, b, None, None, None, None, None)
        qp.solve()
        return qp

    def solve(self, D: NDArray[np.float64], b: NDArray[np.float64]) -> ContactSolution:
        """Impulses P >= 0 with D P + b >= 0 and P · (D P + b) = 0.

        Args:
            D: Delassus matrix, symmetric positive semidefinite, shape (m, m), [m/s per N s].
            b: Free constraint velocity plus restitution term in [m/s], shape (m,).
        """
        start = time.perf_counter()
        if b.size == 1 and self.exact_single:
            return _single_constraint_solution(D, b, start)
        qp = self._solved_qp(D, b)
        info = qp.results.info
        scale = velocity_scale(D)
        impulses = np.maximum(qp.results.x, 0.0)
        velocity = D @ impulses + b
        residual = natural_map_residual(scale, impulses, velocity)
        polished = False
        if self.polish and residual > POLISH_THRESHOLD:
            candidate = _solve_on_active_set(D, b, scale * impulses > velocity)
            if candidate is not None:
                candidate_velocity = D @ candidate + b
                candidate_residual = natural_map_residual(scale, candidate, candidate_velocity)
                if candidate_residual <= residual:
                    impulses, velocity, residual = candidate, candidate_velocity, candidate_residual
                    polished = True
        if residual > self.residual_tolerance and b.size <= LEMKE_FALLBACK_SIZE:
            # Ill-conditioned D (constraints nearly dependent): pivoting is exact where the
            # proximal iterations stall.
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
            "solved" if residual <= self.residual_tolerance else str(info.status),
            int(info.iter),
            residual,
            time.perf_counter() - start,
            polished,
        )


def _single_constraint_solution(
    D: NDArray[np.float64], b: NDArray[np.float64], start: float
) -> ContactSolution:
    """Exact solution of a one-constraint LCP, the projection ``P = max(0, -b / D)``."""
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


def _solve_on_active_set(
    D: NDArray[np.float64], b: NDArray[np.float64], active: NDArray[np.bool_]
) -> NDArray[np.float64] | None:
    """Impulses with ``D_AA P_A = -b_A`` on ``active`` and 0 elsewhere; None if some P_A < 0."""
    candidate = np.zeros(b.size)
    if not active.any():
        return candidate
    if active.all():
        D_active, b_active = D, b
    else:
        D_active, b_active = D[np.ix_(active, active)], b[active]
    if b_active.size == 1:
        if D_active[0, 0] <= 0.0:
            return None
        P_active = -b_active / D_active[0, 0]
    else:
        P_active = _non_negative_solve(D_active, -b_active)
    if np.any(P_active < 0.0):
        return None
    candidate[active] = P_active
    return candidate


def _non_negative_solve(A: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.floating]:
    """A solution x >= 0 of the consistent system ``A x = y`` (A symmetric PSD), if one exists.

    A direct solve first (regular A); redundant constraints make A singular, where the
    minimum-norm least-squares solution may be negative although a non-negative one exists,
    which non-negative least squares finds.
    """
    x: NDArray[np.floating]
    try:
        x = np.linalg.solve(A, y)
        if np.all(x >= 0.0) and np.max(np.abs(A @ x - y)) <= 1e-12 * (1.0 + np.max(np.abs(y))):
            return x
    except np.linalg.LinAlgError:
        pass
    x = np.linalg.lstsq(A, y, rcond=1e-12)[0]
    if np.any(x < 0.0):
        x = scipy.optimize.nnls(A, y)[0]
    return x
