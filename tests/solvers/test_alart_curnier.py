"""The Alart–Curnier function's Jacobian, its Newton step, and warm starts across steps."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.solvers import CoulombProblem, ProxsuiteCoulombSolver
from ucontrol.solvers.alart_curnier import (
    SPARSE_SIZE,
    AlartCurnier,
    alart_curnier_terms,
    least_squares,
    solve_square,
    sparsity,
)
from ucontrol.solvers.coulomb_problem import FLOAT_OPS, NUMPY_OPS

_FD_STEP = 1e-7  # [N s], central differences
_FD_TOLERANCE = 1e-6  # relative to max |J|


def _random_problem(rng: np.random.Generator) -> CoulombProblem:
    """A random problem: 1 to 4 contacts of 0, 1 or 2 tangents, at most one bilateral row."""
    m = int(rng.integers(1, 5))
    tangents = rng.integers(0, 3, m)
    equalities = int(rng.integers(0, 2))
    r = m + int(tangents.sum()) + equalities
    A = rng.normal(size=(r, r + 2))
    mu = rng.uniform(0.1, 1.0, m)
    return CoulombProblem(A @ A.T, rng.normal(size=r), mu, tangents, equalities)


@pytest.mark.parametrize("seed", range(40))
def test_jacobian_matches_central_differences_away_from_kinks(seed: int) -> None:
    rng = np.random.default_rng(seed)
    problem = _random_problem(rng)
    function = AlartCurnier(problem)
    P = rng.normal(size=problem.size)
    _, J = function.value(P, problem.velocity(P))
    columns = []
    for j in range(problem.size):
        e = np.zeros(problem.size)
        e[j] = _FD_STEP
        plus = function.value(P + e, problem.velocity(P + e))[0]
        minus = function.value(P - e, problem.velocity(P - e))[0]
        columns.append((plus - minus) / (2.0 * _FD_STEP))
    finite = np.column_stack(columns)
    assert np.abs(finite - J).max() <= _FD_TOLERANCE * max(1.0, np.abs(J).max())


def test_function_vanishes_at_the_analytic_sliding_solution() -> None:
    # One spatial contact, D = I: sliding along -b_t with P_n = -b_n, P_t = mu P_n d.
    mu, b = 0.5, np.array([-1.0, 3.0, 4.0])
    problem = CoulombProblem(np.eye(3), b, np.array([mu]), np.array([2]))
    P = np.array([1.0, -0.3, -0.4])  # d = -(3, 4)/5
    F, _ = AlartCurnier(problem).value(P, problem.velocity(P))
    assert np.abs(F).max() <= 1e-15


def test_solve_is_least_squares_where_the_matrix_is_singular() -> None:
    rng = np.random.default_rng(0)
    J = rng.normal(size=(4, 4))
    J[3] = J[2]  # two redundant rows
    F = rng.normal(size=4)
    expected = np.linalg.lstsq(J, -F, rcond=1e-10)[0]  # minimum norm, by SVD
    assert np.allclose(solve_square(J, -F), expected, atol=1e-12)
    regular = rng.normal(size=(4, 4))
    assert np.allclose(solve_square(regular, -F), np.linalg.solve(regular, -F), atol=1e-12)
    wide = rng.normal(size=(2, 5))
    assert np.allclose(least_squares(wide, F[:2]), np.linalg.pinv(wide) @ F[:2], atol=1e-12)


@pytest.mark.parametrize("seed", range(10))
def test_warm_start_from_a_nearby_problem_solves_without_a_qp(seed: int) -> None:
    cases = load_experiment("friction_cases")
    rng = np.random.default_rng(seed)
    problem = cases.random_problem(rng, 6, spatial=True, redundant=False)
    solver = ProxsuiteCoulombSolver()
    assert solver.solve_coulomb(problem).status == "solved"
    nearby = CoulombProblem(
        problem.D,
        problem.b * (1.0 + 1e-4 * rng.normal(size=problem.size)),
        problem.mu,
        problem.tangents,
    )
    warm = solver.solve_coulomb(nearby)
    cold = ProxsuiteCoulombSolver().solve_coulomb(nearby)  # the QP fixed point from scratch
    assert warm.status == "solved" and warm.outer_iterations == 0
    assert warm.residual <= 1e-12
    scale = np.abs(nearby.b).max()
    assert np.abs(warm.velocity - cold.velocity).max() <= 1e-8 * scale


@pytest.mark.parametrize("singular", [False, True])
def test_sparse_lu_agrees_with_dense_least_squares(singular: bool) -> None:
    rng = np.random.default_rng(5)
    n = 2 * SPARSE_SIZE
    A = np.diag(rng.uniform(1.0, 2.0, n)) + np.diag(rng.normal(size=n - 1), 1)
    A += np.diag(rng.normal(size=n - 1), -1)  # tridiagonal: sparse
    if singular:
        A[n // 2] = A[n // 2 - 1]
    y = rng.normal(size=n)
    assert sparsity(A != 0.0) is not None
    expected = np.linalg.lstsq(A, y, rcond=1e-10)[0]
    assert np.allclose(solve_square(A, y), expected, atol=1e-10)


def test_terms_are_the_disk_projection_on_floats_and_arrays() -> None:
    """F_t = P_t - Π(x_t) on the disk of radius μ max(P_n, 0), on floats and arrays alike.

    The clip of a planar contact, the radial projection of a spatial one; the same bits on
    floats and on numpy arrays.
    """
    rng = np.random.default_rng(5)
    P, x = rng.normal(size=(3, 300)), rng.normal(size=(3, 300))
    mu = rng.uniform(0.0, 1.5, 300)
    x[2, :100] = 0.0  # planar contacts
    x[1:, 100:120] = 0.0  # y = 0: a finite ratio
    rho_u = P - x  # [N s]
    arrays = np.array(alart_curnier_terms(NUMPY_OPS, P, x, rho_u, mu))
    floats = np.array(
        [
            alart_curnier_terms(FLOAT_OPS, p, z, w, m)
            for p, z, w, m in zip(P.T, x.T, rho_u.T, mu, strict=True)
        ]
    ).T
    assert np.array_equal(arrays, floats)
    np.testing.assert_allclose(arrays[0], P[0] - np.maximum(x[0], 0.0), rtol=0.0, atol=1e-15)
    radius = mu * np.maximum(P[0], 0.0)
    clipped = np.clip(x[1, :100], -radius[:100], radius[:100])
    np.testing.assert_allclose(arrays[1, :100], P[1, :100] - clipped, rtol=0.0, atol=1e-15)
    norm = np.hypot(x[1, 100:], x[2, 100:])
    scale = np.where(norm > radius[100:], radius[100:] / np.where(norm > 0, norm, 1.0), 1.0)
    projected = scale * x[1:, 100:]
    np.testing.assert_allclose(arrays[1:, 100:], P[1:, 100:] - projected, rtol=0.0, atol=1e-15)
