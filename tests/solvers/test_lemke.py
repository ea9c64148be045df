"""Lemke's reference LCP solver against hand-solved problems, enumeration and its errors."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ucontrol.exceptions import (
    InvalidParameterError,
    NonFiniteValueError,
    ShapeError,
    SolverError,
)
from ucontrol.solvers import LemkeResult, complementarity_residual, solve_lcp_lemke

_TOLERANCE = 1e-12  # [m/s] and [N s], problems of unit scale


def _assert_solves_lcp(D: np.ndarray, b: np.ndarray, result: LemkeResult, tol: float) -> None:
    """P >= 0, w = D P + b >= 0 and P · w = 0, each within ``tol``."""
    P, w = result.impulses, result.velocity
    np.testing.assert_allclose(w, D @ P + b, rtol=0.0, atol=tol)
    assert P.min() >= 0.0
    assert w.min() >= -tol
    assert complementarity_residual(D, b, P) <= tol
    assert result.residual == pytest.approx(complementarity_residual(D, b, P), abs=1e-15)
    assert result.converged


def _enumerate_lcp(D: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The solution of a positive definite LCP by trying every active set (small m only)."""
    m = b.size
    for size in range(m + 1):
        for active in itertools.combinations(range(m), size):
            index = list(active)
            P = np.zeros(m)
            if index:
                P[index] = np.linalg.solve(D[np.ix_(index, index)], -b[index])
            w = D @ P + b
            if P.min() >= -1e-12 and w.min() >= -1e-12:
                return P
    raise AssertionError("no active set solves the LCP")


def test_scalar_contact_impulse_stops_the_approach() -> None:
    # 2 P - 4 = 0 -> P = 2 [N s], w = 0 [m/s].
    result = solve_lcp_lemke(np.array([[2.0]]), np.array([-4.0]))
    assert result.impulses == pytest.approx([2.0], abs=_TOLERANCE)
    assert result.velocity == pytest.approx([0.0], abs=_TOLERANCE)
    assert result.pivots == 2  # z0 in, P in and z0 out
    assert result.status == "solved"


def test_scalar_separating_contact_needs_no_pivot() -> None:
    result = solve_lcp_lemke(np.array([[2.0]]), np.array([3.0]))
    assert result.impulses == pytest.approx([0.0], abs=0.0)
    assert result.velocity == pytest.approx([3.0], abs=0.0)
    assert result.pivots == 0
    assert result.residual == 0.0


@pytest.mark.parametrize(
    ("b", "expected_P", "expected_w"),
    [
        ([-1.0, 2.0], [1.0, 0.0], [0.0, 2.0]),
        ([3.0, -8.0], [0.0, 2.0], [3.0, 0.0]),
        ([-2.0, -8.0], [2.0, 2.0], [0.0, 0.0]),
        ([0.0, 5.0], [0.0, 0.0], [0.0, 5.0]),
    ],
)
def test_diagonal_2x2_decouples(b: list[float], expected_P: list[float], expected_w: list[float]):
    D = np.diag([1.0, 4.0])
    result = solve_lcp_lemke(D, np.array(b))
    np.testing.assert_allclose(result.impulses, expected_P, rtol=0.0, atol=_TOLERANCE)
    np.testing.assert_allclose(result.velocity, expected_w, rtol=0.0, atol=_TOLERANCE)


def test_known_3x3_with_one_separating_contact() -> None:
    # Built backwards from P* = (1, 0, 2), w* = (0, 1, 0): b = w* - D P* = (-2, -2, -4).
    D = np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 2.0]])
    b = np.array([-2.0, -2.0, -4.0])
    result = solve_lcp_lemke(D, b)
    np.testing.assert_allclose(result.impulses, [1.0, 0.0, 2.0], rtol=0.0, atol=_TOLERANCE)
    np.testing.assert_allclose(result.velocity, [0.0, 1.0, 0.0], rtol=0.0, atol=_TOLERANCE)
    _assert_solves_lcp(D, b, result, _TOLERANCE)


def test_all_nonnegative_b_returns_zero_impulses_without_pivoting() -> None:
    D = np.array([[2.0, 1.0], [1.0, 2.0]])
    b = np.array([0.0, 0.5])
    result = solve_lcp_lemke(D, b)
    assert np.array_equal(result.impulses, np.zeros(2))
    assert np.array_equal(result.velocity, b)
    assert result.pivots == 0


def test_empty_problem() -> None:
    result = solve_lcp_lemke(np.zeros((0, 0)), np.zeros(0))
    assert result.impulses.shape == (0,)
    assert result.pivots == 0


def test_redundant_contacts_share_the_impulse() -> None:
    # Two identical rows (D singular, rank 1): P1 + P2 = 1 is all that is determined, and w = 0.
    D = np.ones((2, 2))
    b = np.array([-1.0, -1.0])
    result = solve_lcp_lemke(D, b)
    assert result.impulses.sum() == pytest.approx(1.0, abs=_TOLERANCE)
    np.testing.assert_allclose(result.velocity, [0.0, 0.0], rtol=0.0, atol=_TOLERANCE)
    _assert_solves_lcp(D, b, result, _TOLERANCE)


def test_redundant_contacts_with_a_gap() -> None:
    # Rank 1, three rows: the third contact is open by 0.5 [m/s] more and must stay inactive.
    D = np.ones((3, 3))
    b = np.array([-1.0, -1.0, -0.5])
    result = solve_lcp_lemke(D, b)
    assert result.impulses.sum() == pytest.approx(1.0, abs=_TOLERANCE)
    assert result.impulses[2] == 0.0
    np.testing.assert_allclose(result.velocity, [0.0, 0.0, 0.5], rtol=0.0, atol=_TOLERANCE)


@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize("m", [1, 2, 4, 6])
def test_positive_definite_matches_active_set_enumeration(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, m))
    D = A @ A.T / m + 0.5 * np.eye(m)
    b = rng.standard_normal(m)
    result = solve_lcp_lemke(D, b)
    expected = _enumerate_lcp(D, b)
    np.testing.assert_allclose(result.impulses, expected, rtol=0.0, atol=1e-10)
    _assert_solves_lcp(D, b, result, 1e-10)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize(("m", "r"), [(4, 1), (10, 3), (17, 1), (24, 10), (30, 8)])
@pytest.mark.parametrize("duplicated_rows", [False, True])
def test_terminates_on_degenerate_rank_deficient_problems(
    seed: int, m: int, r: int, duplicated_rows: bool
) -> None:
    # D = A A^T of rank r < m and b = A c (+ gaps on half the seeds): many exact ties in the
    # ratio test; several of these failed with a naive float ratio test.
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, r))
    if duplicated_rows:
        A[m // 2 :] = A[: m - m // 2]
    D = A @ A.T
    b = A @ rng.standard_normal(r)
    if seed % 2:
        b += np.maximum(rng.standard_normal(m), 0.0)
    result = solve_lcp_lemke(D, b)
    _assert_solves_lcp(D, b, result, 1e-9 * max(1.0, float(np.abs(b).max())))
    assert result.pivots <= 2 * m + 2


def test_result_is_frozen() -> None:
    result = solve_lcp_lemke(np.array([[1.0]]), np.array([-1.0]))
    with pytest.raises(AttributeError):
        result.pivots = 0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("D", "b"),
    [
        ([[0.0]], [-1.0]),  # no impulse can stop the approach
        ([[1.0, -1.0], [-1.0, 1.0]], [-1.0, -1.0]),  # w1 + w2 = -2 whatever P
    ],
)
def test_infeasible_problem_raises_ray_solver_error(D: list, b: list) -> None:
    with pytest.raises(SolverError, match="secondary ray") as info:
        solve_lcp_lemke(np.array(D), np.array(b))
    assert info.value.solver == "lemke"
    assert "ray" in info.value.status


def test_pivot_limit_raises_solver_error() -> None:
    D = np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 2.0]])
    with pytest.raises(SolverError, match="pivot limit 2") as info:
        solve_lcp_lemke(D, np.array([-2.0, -2.0, -4.0]), max_pivots=2)
    assert info.value.solver == "lemke"


@pytest.mark.parametrize(
    ("D", "b", "name", "expected", "shape"),
    [
        (np.ones((2, 3)), np.ones(2), "D", (2, 2), (2, 3)),
        (np.ones(3), np.ones(3), "D", (3, 3), (3,)),
        (np.eye(3), np.ones(2), "b", (3,), (2,)),
        (np.eye(2), np.ones((2, 1)), "b", (2,), (2, 1)),
    ],
)
def test_wrong_shapes_raise_shape_error(D, b, name, expected, shape) -> None:
    with pytest.raises(ShapeError) as info:
        solve_lcp_lemke(D, b)
    assert info.value.name == name
    assert info.value.expected_shape == expected
    assert info.value.shape == shape


@pytest.mark.parametrize(
    ("D", "b", "name"),
    [
        (np.array([[1.0, np.nan], [np.nan, 1.0]]), np.ones(2), "D"),
        (np.eye(2), np.array([-1.0, np.inf]), "b"),
    ],
)
def test_non_finite_inputs_raise(D: np.ndarray, b: np.ndarray, name: str) -> None:
    with pytest.raises(NonFiniteValueError) as info:
        solve_lcp_lemke(D, b)
    assert info.value.name == name


def test_non_symmetric_matrix_raises() -> None:
    with pytest.raises(InvalidParameterError, match="`D` must be symmetric"):
        solve_lcp_lemke(np.array([[1.0, 0.5], [0.0, 1.0]]), np.array([-1.0, -1.0]))


def test_non_numeric_matrix_raises() -> None:
    with pytest.raises(InvalidParameterError, match="`D`"):
        solve_lcp_lemke([["a"]], [-1.0])  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("keyword", "value"),
    [("max_pivots", 0), ("max_pivots", 2.5), ("max_pivots", True), ("tol", 0.0), ("tol", -1e-3)],
)
def test_bad_settings_raise(keyword: str, value: object) -> None:
    with pytest.raises(InvalidParameterError, match=f"`{keyword}`"):
        solve_lcp_lemke(np.eye(1), np.array([-1.0]), **{keyword: value})  # type: ignore[arg-type]
