r"""The fallbacks of the contact solvers, each on the problem that needs it.

- The QP backend of the frictionless LCP :math:`0 \le P \perp D P + b \ge 0` is followed by
  Lemke's pivoting when its solution stays above the residual tolerance: two nearly parallel
  contact rows make :math:`D` singular (three rows in two dimensions) with 2 x 2 blocks of
  condition number ~1e12, where the proximal iterations stop at their own tolerance.
- An LCP without solution (:math:`D` positive semidefinite, :math:`b` outside the range that
  can be compensated) ends Lemke's pivoting on a secondary ray: the solve is reported unsolved.
- The Tresca fixed point of the Coulomb solver stops as ``"stalled"`` when its thresholds no
  longer move above the residual tolerance (here a tolerance below round-off).

References are independent of the code: exact rational enumeration of the active sets for
the LCP, the stick/slip case analysis of one planar contact for Coulomb.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest

from ucontrol.exceptions import SolverError
from ucontrol.solvers import lcp_refinement, lemke
from ucontrol.solvers.coulomb_problem import CoulombProblem
from ucontrol.solvers.lemke import solve_lcp_lemke
from ucontrol.solvers.proxsuite_coulomb import ProxsuiteCoulombSolver
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver


def _exact_lcp_velocity(D: list[list[Fraction]], b: list[Fraction]) -> list[Fraction]:
    """``w = D P + b`` of a solution of the LCP, by exact enumeration of the active sets.

    For a positive semidefinite D, ``w`` is the same for every solution.
    """
    m = len(b)
    for size in range(m + 1):
        for active in itertools.combinations(range(m), size):
            P = _solve_exact([[D[i][j] for j in active] for i in active], [-b[i] for i in active])
            if P is None or any(p < 0 for p in P):
                continue
            full = [Fraction(0)] * m
            for i, p in zip(active, P, strict=True):
                full[i] = p
            w = [sum(D[i][j] * full[j] for j in range(m)) + b[i] for i in range(m)]
            if all(x >= 0 for x in w):
                return w
    raise AssertionError("the LCP has no solution")


def _solve_exact(A: list[list[Fraction]], y: list[Fraction]) -> list[Fraction] | None:
    """Gauss–Jordan elimination in rationals; None when A is singular."""
    n = len(y)
    rows = [[*A[i], y[i]] for i in range(n)]
    for k in range(n):
        pivot = next((i for i in range(k, n) if rows[i][k] != 0), None)
        if pivot is None:
            return None
        rows[k], rows[pivot] = rows[pivot], rows[k]
        for i in range(n):
            if i != k and rows[i][k] != 0:
                factor = rows[i][k] / rows[k][k]
                rows[i] = [a - factor * c for a, c in zip(rows[i], rows[k], strict=True)]
    return [rows[i][n] / rows[i][i] for i in range(n)]


def test_nearly_parallel_contacts_fall_back_on_lemke(monkeypatch: pytest.MonkeyPatch) -> None:
    # A point mass (unit inertia) on three rows whose normals differ by eps = 1e-6 rad: the
    # Delassus matrix J J^T is singular, its 2 x 2 blocks of condition number ~1e12. The QP
    # stops at its tolerance (eps_abs = 1e-10 m/s), above the residual tolerance 1e-13 m/s
    # asked: Lemke's method takes over and pivots to the exact solution.
    eps = Fraction(1, 10**6)
    J = [[Fraction(1), Fraction(0)], [Fraction(1), eps], [Fraction(1), -2 * eps]]
    D_exact = [[sum(a * c for a, c in zip(r, s, strict=True)) for s in J] for r in J]
    b_exact = [Fraction(-1), Fraction(-1) - 3 * eps, Fraction(-1) + 5 * eps]
    D = np.array(D_exact, dtype=float)
    b = np.array(b_exact, dtype=float)
    pivots = []

    def spied(D: np.ndarray, b: np.ndarray) -> lemke.LemkeResult:
        result = solve_lcp_lemke(D, b)
        pivots.append(result.pivots)
        return result

    monkeypatch.setattr(lemke, "solve_lcp_lemke", spied)  # imported where it is called
    solver = ProxsuiteLCPSolver(polish=False, residual_tolerance=1e-13)
    solution = solver.solve(D, b)
    assert pivots and pivots[0] > 0  # the fallback ran
    assert solution.status == "solved" and solution.polished
    w_exact = np.array(_exact_lcp_velocity(D_exact, b_exact), dtype=float)
    # Measured: |w - w_exact| = 1.1e-16 m/s (velocities ~1e-6 m/s, D entries ~1).
    np.testing.assert_allclose(solution.velocity, w_exact, atol=1e-15)
    assert solution.residual <= 1e-13
    # The QP alone (no fallback) stays above that tolerance on this problem.
    monkeypatch.setattr(lcp_refinement, "LEMKE_FALLBACK_SIZE", 0)
    assert ProxsuiteLCPSolver(polish=False, residual_tolerance=1e-13).solve(D, b).residual > 1e-13


def test_an_lcp_without_solution_is_reported_unsolved() -> None:
    # Two opposite rows of one coordinate (a body between two walls it touches) both
    # approaching at 1 m/s: w1 + w2 = b1 + b2 = -2 < 0 for every P, so no impulse stops both.
    # Lemke's method, tried as the fallback, ends on a secondary ray.
    D = np.array([[1.0, -1.0], [-1.0, 1.0]])
    b = np.array([-1.0, -1.0])
    with pytest.raises(SolverError, match="secondary ray"):
        solve_lcp_lemke(D, b)
    solution = ProxsuiteLCPSolver(max_iter=50).solve(D, b)
    assert solution.status != "solved"
    assert solution.residual > 1e-8


def test_a_numerically_singular_basis_raises_a_solver_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Unreachable from data: the lexicographic ratio test only pivots on entries above their
    # round-off bound, so the new basis is regular in floating point (an exhaustive search
    # over symmetric matrices with entries in {-1, 0, 1, 2} and b in {-1, 0, 1}^m, m <= 3,
    # found none). The guard is pinned by a factorisation that fails at the second pivot.
    calls = []

    def failing_inv(B: np.ndarray) -> np.ndarray:
        calls.append(B.shape)
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(lemke.np.linalg, "inv", failing_inv)
    with pytest.raises(SolverError, match="singular basis after 1 pivots"):
        solve_lcp_lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-1.0, -1.0]))
    assert calls == [(2, 2)]


def _coulomb_reference(D: np.ndarray, b: np.ndarray, mu: float) -> np.ndarray:
    """Impulses (P_n, P_t) of one planar Coulomb contact with b_n < 0: stick or slip."""
    stick = np.linalg.solve(D, -b)
    if stick[0] >= 0.0 and abs(stick[1]) <= mu * stick[0]:
        return stick
    for sign in (1.0, -1.0):  # slip with u_t of sign `sign`, P_t = -sign mu P_n
        P_n = -b[0] / (D[0, 0] - sign * mu * D[0, 1])
        u_t = (D[1, 0] - sign * mu * D[1, 1]) * P_n + b[1]
        if P_n >= 0.0 and sign * u_t > 0.0:
            return np.array([P_n, -sign * mu * P_n])
    raise AssertionError("no Coulomb solution")


def test_a_coulomb_solve_below_round_off_stalls_on_the_solution(rng: np.random.Generator) -> None:
    # One planar contact, random positive definite Delassus matrix, approaching at 1 m/s
    # with a random tangential velocity. Asked for a residual of 1e-300 m/s, the fixed point
    # reaches the solution, its thresholds stop moving, and the solve ends "stalled" there.
    mu = 0.5
    statuses = set()
    for _ in range(6):
        A = rng.normal(size=(2, 2))
        D = A @ A.T + 0.1 * np.eye(2)
        b = np.array([-1.0, rng.normal()])
        solver = ProxsuiteCoulombSolver(residual_tolerance=1e-300)
        solution = solver.solve_coulomb(CoulombProblem(D, b, np.array([mu]), np.array([1])))
        statuses.add(solution.status)
        if solution.status != "stalled":  # an exact zero residual is "solved"
            assert solution.residual == 0.0
            continue
        # Measured: residual 2.2e-16 to 1.3e-15 m/s; impulses within 2.7e-15 N s of the case
        # analysis.
        assert solution.residual <= 1e-14
        np.testing.assert_allclose(solution.impulses, _coulomb_reference(D, b, mu), atol=2e-14)
    assert "stalled" in statuses


@pytest.mark.parametrize("tangential", [0.1, 3.0])  # [m/s]: mostly sticking, mostly slipping
def test_the_tresca_fixed_point_alone_converges_to_coulomb(
    rng: np.random.Generator, tangential: float
) -> None:
    # Without the polish (the fallback that solves the stick/slip pattern directly), the
    # fixed point of Tresca QPs with thresholds s = mu P_n must itself end on Coulomb's law:
    # the case analysis of one planar contact, approaching at 1 m/s.
    mu = 0.5
    for _ in range(4):
        A = rng.normal(size=(2, 2))
        D = A @ A.T + 0.5 * np.eye(2)
        b = np.array([-1.0, tangential * rng.choice([-1.0, 1.0])])
        solver = ProxsuiteCoulombSolver(polish=False)
        solution = solver.solve_coulomb(CoulombProblem(D, b, np.array([mu]), np.array([1])))
        assert solution.status == "solved" and not solution.polished
        # Measured: impulses within 5.6e-9 N s of the case analysis (residual tolerance 1e-8).
        np.testing.assert_allclose(solution.impulses, _coulomb_reference(D, b, mu), atol=5e-8)
