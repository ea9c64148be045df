r"""Frictionless contact impulses as a proxsuite QP.

The velocity-level Signorini–Newton problem of one Moreau–Jean step,

.. math:: 0 \le P \perp D P + b \ge 0, \qquad D = J W^{-1} J^T,\;
          b = J v_\text{free} + e \odot J v_k,

is the optimality system of the convex QP :math:`\min_{P \ge 0} \tfrac12 P^T D P + b^T P`,
solved here with proxsuite's dense solver. Redundant constraints make :math:`D` singular; the
proximal method still converges and the velocity :math:`v = v_\text{free} + W^{-1} J^T P` is unique.

With bilateral constraints (:meth:`ProxsuiteLCPSolver.solve_mixed`) the last rows are
equalities (as in :class:`~ucontrol.solvers.coulomb_problem.CoulombProblem`), their impulses
free in sign: :math:`D_{b\cdot} P + b_b = 0`, and the QP has the bounds :math:`P \ge 0` on the
unilateral rows only (a mixed LCP).
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.solvers.compiled_active_set import compiled_active_set
from ucontrol.solvers.contact_solution import (
    ContactSolution,
    natural_map_residual,
    velocity_scale,
)
from ucontrol.solvers.lcp_refinement import (
    POLISH_THRESHOLD,
    active_set_solution,
    refine_lcp_solution,
    single_constraint_solution,
)
from ucontrol.solvers.proxsuite_qp import INFINITY, WarmStartedQP


class ProxsuiteLCPSolver:
    """Solve frictionless contact LCPs with reused, warm-started proxsuite QP objects.

    One QP object is kept per problem size and updated in place; each solve starts from the
    previous solution of that size (:class:`~ucontrol.solvers.proxsuite_qp.WarmStartedQP`). A
    QP solution whose complementarity residual exceeds
    :data:`~ucontrol.solvers.lcp_refinement.POLISH_THRESHOLD` is then polished: the linear
    system of its active set is solved directly and kept when it satisfies complementarity
    better, which brings restitution to machine precision. Small problems still above
    ``residual_tolerance`` (nearly dependent constraints, where the proximal iterations stall)
    are solved again by Lemke's method
    (:func:`~ucontrol.solvers.lcp_refinement.refine_lcp_solution`).

    The status is ``"solved"`` when the complementarity residual, measured by us, is at most
    ``residual_tolerance``; otherwise it is proxsuite's status and the caller decides.

    Args:
        eps_abs: Absolute tolerance of proxsuite in [m/s].
        max_iter: Iteration cap of proxsuite.
        polish: Refine on the active set after the QP solve.
        residual_tolerance: Largest complementarity residual accepted as solved, in [m/s].
        exact_single: Solve one-constraint problems by their closed form
            ``P = max(0, -b / D)`` (the QP's exact solution) instead of calling proxsuite.
        active_set_start: Try the exact solve on a guessed active set before the QP when
            :meth:`solve` is given one (Moreau–Jean gives its last step's); False always
            solves the QP.
        compiled_start: Run the active-set start's solve and check compiled where a C
            compiler is available (:mod:`ucontrol.solvers.compiled_active_set`, 2 to
            :data:`~ucontrol.solvers.compiled_active_set.MAX_ROWS` rows), the numpy reference
            (:func:`~ucontrol.solvers.lcp_refinement.active_set_solution`) where it does not
            accept its impulses; False runs the reference alone.
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
        active_set_start: bool = True,
        compiled_start: bool = True,
    ):
        self.residual_tolerance = as_positive("residual_tolerance", residual_tolerance)
        self.exact_single = exact_single
        self.active_set_start = active_set_start
        self.compiled_start = compiled_start
        self.polish = polish
        self._qp = WarmStartedQP(eps_abs=eps_abs, max_iter=max_iter, fixed_constraints=True)
        self.eps_abs = self._qp.eps_abs
        self.max_iter = self._qp.max_iter
        self._bounds: dict[int, tuple[NDArray[np.float64], ...]] = {}
        self._mixed_bounds: dict[tuple[int, int], tuple[NDArray[np.float64], ...]] = {}

    def reset(self) -> None:
        """Forget the warm starts: the next solves start as a new solver's."""
        self._qp.reset()

    def solve(
        self,
        D: NDArray[np.float64],
        b: NDArray[np.float64],
        guess: NDArray[np.bool_] | None = None,
    ) -> ContactSolution:
        """Impulses P >= 0 with D P + b >= 0 and P · (D P + b) = 0.

        Args:
            D: Delassus matrix, symmetric positive semidefinite, shape (m, m), [m/s per N s].
            b: Free constraint velocity plus restitution term in [m/s], shape (m,).
            guess: Constraints guessed active (the last step's held ones), shape (m,), or
                None. With ``active_set_start``, the exact solve on that set is returned
                without a QP when it solves the problem
                (:func:`~ucontrol.solvers.lcp_refinement.active_set_solution`): the impulses
                the QP's solution gets from the polish on the same set.
        """
        start = time.perf_counter()
        m = b.size
        if m == 1 and self.exact_single:
            return single_constraint_solution(D, b, start)
        if guess is not None and self.active_set_start:
            compiled = compiled_active_set(m) if self.compiled_start else None
            solved = compiled(D, b, guess) if compiled is not None else None
            if solved is not None:
                impulses, velocity, residual = solved
                return ContactSolution(
                    impulses, velocity, "solved", 0, residual, time.perf_counter() - start, True
                )
            guessed = active_set_solution(D, b, guess, start)
            if guessed is not None:
                return guessed
        bounds = self._bounds.get(m)
        if bounds is None:  # P >= 0 as the inequalities I P >= 0
            bounds = self._bounds[m] = (np.eye(m), np.zeros(m), np.full(m, INFINITY))
        results = self._qp.solve(D, b, *bounds)
        return refine_lcp_solution(
            D,
            b,
            results.x,
            polish=self.polish,
            residual_tolerance=self.residual_tolerance,
            iterations=int(results.info.iter),
            unsolved_status=results.info.status,
            start=start,
        )

    def solve_mixed(
        self, D: NDArray[np.float64], b: NDArray[np.float64], equalities: int
    ) -> ContactSolution:
        r"""Impulses of the mixed problem: the last ``equalities`` rows bilateral.

        :math:`w = D P + b` with :math:`w_i = 0` (:math:`P_i` free) on the last rows and
        :math:`0 \le P_i \perp w_i \ge 0` on the others. The QP's solution is polished on
        its active set (least squares: dependent rows, as redundant closures give, keep the
        minimum-norm impulses). The residual is the largest of :math:`|w_i|` on the bilateral
        rows and the natural-map residual on the others, in [m/s].

        Args:
            D: Delassus matrix, symmetric positive semidefinite, shape (m, m).
            b: Free constraint velocities plus offsets in [m/s], shape (m,).
            equalities: Number of bilateral rows, last in ``D`` and ``b``.
        """
        if equalities == 0:
            return self.solve(D, b)
        start = time.perf_counter()
        m = b.size
        unilateral = m - equalities
        if unilateral:
            bounds = self._mixed_bounds.get((m, equalities))
            if bounds is None:
                C = np.zeros((unilateral, m))
                C[:, :unilateral] = np.eye(unilateral)
                bounds = (C, np.zeros(unilateral), np.full(unilateral, INFINITY))
                self._mixed_bounds[(m, equalities)] = bounds
            results = self._qp.solve(D, b, *bounds)
        else:
            results = self._qp.solve(D, b, None, None, None)
        impulses = np.array(results.x)
        impulses[:unilateral] = np.maximum(impulses[:unilateral], 0.0)
        diagonal = D.diagonal()[:unilateral]
        velocity = D @ impulses + b
        residual = _mixed_residual(diagonal, impulses, velocity, equalities)
        polished = False
        if self.polish and residual > POLISH_THRESHOLD:
            active = np.ones(m, dtype=bool)
            scale = velocity_scale(D)[:unilateral]
            active[:unilateral] = scale * impulses[:unilateral] > velocity[:unilateral]
            candidate = np.zeros(m)
            rows = np.flatnonzero(active)
            candidate[rows] = np.linalg.lstsq(D[np.ix_(rows, rows)], -b[rows], rcond=None)[0]
            if (candidate[:unilateral] >= 0.0).all():
                candidate_velocity = D @ candidate + b
                candidate_residual = _mixed_residual(
                    diagonal, candidate, candidate_velocity, equalities
                )
                if candidate_residual <= residual:
                    impulses, velocity, residual = candidate, candidate_velocity, candidate_residual
                    polished = True
        status = "solved" if residual <= self.residual_tolerance else str(results.info.status)
        return ContactSolution(
            impulses,
            velocity,
            status,
            int(results.info.iter),
            residual,
            time.perf_counter() - start,
            polished,
        )


def _mixed_residual(
    diagonal: NDArray[np.float64],
    impulses: NDArray[np.float64],
    velocity: NDArray[np.float64],
    equalities: int,
) -> float:
    """Largest bilateral velocity and unilateral natural-map residual, in [m/s].

    ``diagonal`` is that of D on the unilateral rows, shape (m - equalities,).
    """
    unilateral = impulses.size - equalities
    residual = float(np.abs(velocity[unilateral:]).max())
    if unilateral:
        residual = max(
            residual,
            natural_map_residual(diagonal, impulses[:unilateral], velocity[:unilateral]),
        )
    return residual
