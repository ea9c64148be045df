r"""The Coulomb problem with bilateral rows against the elimination of those rows.

With bilateral rows :math:`u_b = D_{b\cdot} P + b_b = 0` (impulses free in sign) last, the
mixed Coulomb problem is the plain Coulomb problem of the contact rows with the Schur complement
:math:`D' = D_{cc} - D_{cb} D_{bb}^{+} D_{bc}`, :math:`b' = b_c - D_{cb} D_{bb}^{+} b_b` (the
Delassus operator of the constrained system), the bilateral impulses then
:math:`P_b = -D_{bb}^{+}(D_{bc} P_c + b_b)`. The reference solves that reduced problem,
without bilateral rows, with the same solver; the velocities
:math:`v = v_\text{free} + W^{-1} J^T P` are compared (unique also when the bilateral rows are
dependent).
"""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.exceptions import InvalidParameterError
from ucontrol.solvers import ProxsuiteCoulombSolver
from ucontrol.solvers.coulomb_problem import CoulombProblem

MU = 0.3


def _system(rng: np.random.Generator, n: int = 12, duplicate: bool = False) -> dict:
    """A random inertia, two planar and one spatial contact rows, and two bilateral rows."""
    A = rng.standard_normal((n, n))
    W = A @ A.T + n * np.eye(n)  # [kg], SPD
    normals = rng.standard_normal((3, n))
    tangents = rng.standard_normal((4, n))  # 1 + 1 + 2 tangential rows
    bilateral = rng.standard_normal((2, n))
    if duplicate:  # a closure declared twice: dependent rows
        bilateral = np.vstack((bilateral, bilateral[:1]))
    J = np.vstack((normals, tangents, bilateral))
    v_free = rng.standard_normal(n)
    v_free -= np.linalg.lstsq(bilateral, bilateral @ v_free, rcond=None)[0]  # J_b v_free ~ 0
    v_free += np.linalg.solve(W, normals.T @ np.full(3, -1.0))  # closing contacts
    Winv_Jt = np.linalg.solve(W, J.T)
    return {
        "J": J,
        "Winv_Jt": Winv_Jt,
        "D": J @ Winv_Jt,
        "b": J @ v_free,
        "v_free": v_free,
        "equalities": bilateral.shape[0],
    }


@pytest.mark.parametrize("duplicate", [False, True], ids=["independent", "dependent"])
def test_bilateral_rows_match_their_elimination(rng: np.random.Generator, duplicate: bool) -> None:
    tangents = np.array([1, 1, 2])
    mu = np.full(3, MU)
    closed = sliding = 0
    for _ in range(5):
        system = _system(rng, duplicate=duplicate)
        D, b, e = system["D"], system["b"], system["equalities"]
        r = D.shape[0] - e
        problem = CoulombProblem(D, b, mu, tangents, e)
        solution = ProxsuiteCoulombSolver().solve_coulomb(problem)
        assert solution.status == "solved"
        # Reduced problem: the bilateral rows eliminated (pseudo-inverse: dependent rows).
        D_bb_pinv = np.linalg.pinv(D[r:, r:], rcond=1e-12)
        D_red = D[:r, :r] - D[:r, r:] @ D_bb_pinv @ D[r:, :r]
        b_red = b[:r] - D[:r, r:] @ D_bb_pinv @ b[r:]
        D_red = 0.5 * (D_red + D_red.T)
        reference = ProxsuiteCoulombSolver().solve_coulomb(
            CoulombProblem(D_red, b_red, mu, tangents)
        )
        assert reference.status == "solved"
        P_b = -D_bb_pinv @ (D[r:, :r] @ reference.impulses + b[r:])
        P_ref = np.concatenate((reference.impulses, P_b))
        v = system["v_free"] + system["Winv_Jt"] @ solution.impulses
        v_ref = system["v_free"] + system["Winv_Jt"] @ P_ref
        # Measured over 20 draws: 1.1e-15 (independent) and 2.6e-14 (dependent) [m/s].
        np.testing.assert_allclose(v, v_ref, rtol=0, atol=2e-13)
        # Contact impulses are unique (n = 12 > 10 rows); measured 1.8e-14 / 7.7e-13 [N s].
        np.testing.assert_allclose(solution.impulses[:r], reference.impulses, rtol=0, atol=5e-12)
        assert np.max(np.abs(system["J"][r:] @ v)) <= 5e-14  # measured 7.2e-15 [m/s]
        assert solution.residual <= 5e-13  # measured 6.7e-14 [m/s]
        P_n = solution.impulses[:3]
        closed += np.count_nonzero(P_n > 0.0)
        P_t = np.array([abs(solution.impulses[3]), abs(solution.impulses[4])])
        sliding += np.count_nonzero(np.abs(P_t - MU * P_n[:2]) <= 1e-12 * (1.0 + P_n[:2]))
    assert closed >= 5 and sliding >= 2  # contacts closed and sliding: a real test


def test_residual_counts_the_bilateral_velocity(rng: np.random.Generator) -> None:
    system = _system(rng)
    D, b, e = system["D"], system["b"], system["equalities"]
    problem = CoulombProblem(D, b, np.full(3, MU), np.array([1, 1, 2]), e)
    solution = ProxsuiteCoulombSolver().solve_coulomb(problem)
    P = solution.impulses.copy()
    P[-1] += 1e-3  # [N s]: the last bilateral row no longer holds
    u = D @ P + b
    assert problem.residual(P) >= np.max(np.abs(u[-e:])) > 0.0
    assert problem.size == D.shape[0] and problem.equality_rows.tolist() == [7, 8]


@pytest.mark.parametrize("equalities", [-1, 1.5])
def test_bad_equalities_are_refused(equalities: float) -> None:
    with pytest.raises(InvalidParameterError, match="equalities"):
        CoulombProblem(np.eye(2), np.zeros(2), np.array([0.5]), np.array([1]), equalities)  # type: ignore[arg-type]
