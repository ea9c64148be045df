r"""Frictionless contact impulses with any QP solver of qpsolvers, chosen by name.

The same problem as :class:`~ucontrol.solvers.proxsuite_lcp.ProxsuiteLCPSolver`, the QP
:math:`\min_{P \ge 0} \tfrac12 P^T D P + b^T P` of the LCP :math:`0 \le P \perp D P + b \ge 0`,
handed to ``qpsolvers.solve_problem`` with the bound ``lb = 0``; the result is refined
(:func:`~ucontrol.solvers.lcp_refinement.refine_lcp_solution`) exactly as proxsuite's. This is
the backend switch for comparisons: every QP solver qpsolvers finds installed
(``qpsolvers.available_solvers``, e.g. ``"proxqp"``, ``"osqp"``, ``"clarabel"``, ``"daqp"``,
``"quadprog"``) solves the frictionless problem. Solvers that need a positive definite Hessian
(``quadprog``) fail on redundant constraints (singular D); such a failure is reported as the
status, with an infinite residual, and the caller decides.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import qpsolvers
import scipy.sparse
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.exceptions import NotFoundError
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.contact_solver import QPSOLVERS_PREFIX
from ucontrol.solvers.lcp_refinement import refine_lcp_solution, single_constraint_solution


class QpsolversLCPSolver:
    """Solve frictionless contact LCPs with the qpsolvers backend ``solver``.

    Args:
        solver: Name of a solver in ``qpsolvers.available_solvers``.
        polish: Refine on the active set after the QP solve.
        residual_tolerance: Largest complementarity residual accepted as solved, in [m/s].
        exact_single: Solve one-constraint problems by their closed form.
        **options: Passed to ``qpsolvers.solve_problem`` (the backend's own settings, e.g.
            ``eps_abs`` for ``osqp``).

    Raises:
        NotFoundError: ``solver`` is not an installed qpsolvers backend.
    """

    def __init__(
        self,
        solver: str,
        *,
        polish: bool = True,
        residual_tolerance: float = 1e-8,
        exact_single: bool = True,
        **options: Any,
    ) -> None:
        if solver not in qpsolvers.available_solvers:
            raise NotFoundError("qpsolvers solver", solver, qpsolvers.available_solvers)
        self.solver = solver
        self.name = f"{QPSOLVERS_PREFIX}{solver}"
        self.polish = polish
        self.residual_tolerance = as_positive("residual_tolerance", residual_tolerance)
        self.exact_single = exact_single
        self.options = options
        self._sparse = solver in qpsolvers.sparse_solvers and solver not in qpsolvers.dense_solvers

    def reset(self) -> None:
        """Nothing to forget: each solve is independent of the others (no warm start)."""

    def solve(self, D: NDArray[np.float64], b: NDArray[np.float64]) -> ContactSolution:
        """Impulses P >= 0 with D P + b >= 0 and P · (D P + b) = 0.

        Args:
            D: Delassus matrix, symmetric positive semidefinite, shape (m, m), [m/s per N s].
            b: Free constraint velocity plus restitution term in [m/s], shape (m,).
        """
        start = time.perf_counter()
        m = b.size
        if m == 1 and self.exact_single:
            return single_constraint_solution(D, b, start)
        H = scipy.sparse.csc_matrix(D) if self._sparse else D
        problem = qpsolvers.Problem(H, b, lb=np.zeros(m))
        try:
            solution = qpsolvers.solve_problem(problem, solver=self.solver, **self.options)
        except qpsolvers.QPError as error:  # e.g. quadprog on a singular D
            return self._failure(m, b, f"{type(error).__name__}: {error}", start)
        if not solution.found or solution.x is None:
            return self._failure(m, b, "not_found", start)
        return refine_lcp_solution(
            D,
            b,
            solution.x,
            polish=self.polish,
            residual_tolerance=self.residual_tolerance,
            iterations=_iterations(solution),
            unsolved_status="inaccurate",
            start=start,
        )

    @staticmethod
    def _failure(m: int, b: NDArray[np.float64], status: str, start: float) -> ContactSolution:
        """No impulses, an infinite residual and the backend's ``status``."""
        return ContactSolution(
            np.zeros(m), b.copy(), status, 0, np.inf, time.perf_counter() - start
        )


def _iterations(solution: qpsolvers.Solution) -> int:
    """Iterations reported by the backend (``info.iter`` or ``iterations``), else 0."""
    extras = solution.extras
    info = extras.get("info")
    if info is not None and hasattr(info, "iter"):
        return int(info.iter)
    if "iterations" in extras:
        return int(np.ravel(extras["iterations"])[0])
    return 0
