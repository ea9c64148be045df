"""The compiled solve on a guessed active set against the numpy reference and Lemke's method.

:class:`ProxsuiteLCPSolver` with ``compiled_start`` (the default) against the same solver with
``compiled_start=False`` (the reference, :func:`active_set_solution`) and against Lemke's
pivoting, on random regular problems, on rank-deficient ones (redundant rows, repeated rows, a
box table on four feet) and on guesses that must be refused.
"""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.model.compiled_function import compilation_possible
from ucontrol.solvers import ProxsuiteLCPSolver, solve_lcp_lemke
from ucontrol.solvers.compiled_active_set import MAX_ROWS, compiled_active_set
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.lcp_refinement import POLISH_THRESHOLD, active_set_solution

pytestmark = pytest.mark.skipif(not compilation_possible(), reason="no C compiler")

#: Agreement with the reference, relative to the largest impulse: round-off of two
#: eigendecompositions (Jacobi's rotations, LAPACK's dsyev) of the same matrix (measured 3e-15).
_TOLERANCE = 1e-12
#: Agreement with Lemke's pivoting (a different exact method), relative.
_LEMKE_TOLERANCE = 1e-10


def _solve(D: np.ndarray, b: np.ndarray, guess: np.ndarray, compiled: bool) -> ContactSolution:
    return ProxsuiteLCPSolver(compiled_start=compiled).solve(D, b, guess)


def _rank_deficient(rng: np.random.Generator, m: int, rank: int) -> np.ndarray:
    """A random PSD Delassus matrix (m, m) of the given rank: H H^T with H (m, rank)."""
    H = rng.standard_normal((m, rank))
    D = H @ H.T / rank
    return (D + D.T) / 2.0


def _assert_same(solution: ContactSolution, reference: np.ndarray, scale: float) -> None:
    assert solution.iterations == 0 and solution.status == "solved" and solution.polished
    error = np.abs(solution.impulses - reference).max() / scale
    assert error / _TOLERANCE <= 1.0, error
    assert solution.residual <= POLISH_THRESHOLD


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("m", range(2, MAX_ROWS + 1))
def test_regular_problems_agree_with_the_reference_and_lemke(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    D = _rank_deficient(rng, m, m) + 0.05 * np.eye(m)
    b = rng.standard_normal(m)
    lemke = solve_lcp_lemke(D, b).impulses
    guess = lemke > 0.0
    reference = _solve(D, b, guess, compiled=False)
    assert reference.iterations == 0  # the reference's exact solve, no QP
    scale = max(1.0, float(np.abs(lemke).max()))
    _assert_same(_solve(D, b, guess, compiled=True), reference.impulses, scale)
    assert np.abs(reference.impulses - lemke).max() / scale <= _LEMKE_TOLERANCE


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize(("m", "rank"), [(2, 1), (3, 1), (3, 2), (4, 1), (4, 2), (4, 3)])
def test_rank_deficient_problems_keep_the_minimum_norm_impulses(
    seed: int, m: int, rank: int
) -> None:
    # Consistent: b = -D p with p > 0, every row active. The minimum-norm impulses D⁺(-b)
    # (numpy's SVD pseudo-inverse, independent of both eigensolvers) solve the LCP when they
    # are non-negative; both paths must then give them, and Lemke some solution of the same
    # velocities.
    rng = np.random.default_rng(100 + seed)
    D = _rank_deficient(rng, m, rank)
    b = -D @ rng.uniform(0.5, 1.5, m)
    expected = np.linalg.pinv(D, rcond=1e-12) @ -b
    every = np.ones(m, dtype=bool)
    if expected.min() < 0.0:  # refused by the compiled check: the reference decides
        assert compiled_active_set(m)(D, b, every) is None  # type: ignore[misc]
        return
    scale = float(np.abs(expected).max())
    _assert_same(_solve(D, b, every, compiled=True), expected, scale)
    _assert_same(_solve(D, b, every, compiled=True), _solve(D, b, every, False).impulses, scale)
    lemke = solve_lcp_lemke(D, b)
    velocity = _solve(D, b, every, compiled=True).velocity
    np.testing.assert_allclose(velocity, lemke.velocity, rtol=0.0, atol=1e-10)


def test_a_box_table_shares_its_weight_evenly() -> None:
    # Four feet at (±a, ±b) under a box of mass m: D of rank 3; standing still, each foot
    # carries m g h / 4 (the minimum-norm split, by symmetry).
    mass, g, h = 3.0, 9.81, 1e-3
    feet = [(x, y, -0.3) for x in (0.4, -0.4) for y in (0.25, -0.25)]
    n = np.array([0.0, 0.0, 1.0])
    J = np.array([np.concatenate((n, np.cross(p, n))) for p in feet])
    inertia = mass / 12.0 * np.array([0.5**2 + 0.6**2, 0.8**2 + 0.6**2, 0.8**2 + 0.5**2])
    D = J @ np.diag(np.concatenate((np.full(3, 1.0 / mass), 1.0 / inertia))) @ J.T
    D = (D + D.T) / 2.0
    assert np.linalg.matrix_rank(D) == 3
    solution = _solve(D, np.full(4, -g * h), np.ones(4, dtype=bool), compiled=True)
    _assert_same(solution, np.full(4, mass * g * h / 4.0), 1.0)


def test_repeated_rows_and_a_subset_guess() -> None:
    # Rows 0 and 2 identical (D singular), row 1 separating (b > 0, not guessed): the load
    # of the repeated pair splits evenly and the separating row keeps P = 0, u > 0.
    D = np.array([[2.0, 0.5, 2.0], [0.5, 1.0, 0.5], [2.0, 0.5, 2.0]])
    b = np.array([-1.0, 0.7, -1.0])
    guess = np.array([True, False, True])
    solution = _solve(D, b, guess, compiled=True)
    _assert_same(solution, np.array([0.25, 0.0, 0.25]), 1.0)
    assert solution.velocity[1] > 0.0
    # Lemke's pivoting gives another solution of the singular LCP (not the minimum-norm
    # one), with the same velocities.
    np.testing.assert_allclose(
        solution.velocity, solve_lcp_lemke(D, b).velocity, rtol=0.0, atol=1e-12
    )


@pytest.mark.parametrize("seed", range(5))
def test_wrong_guesses_are_refused_as_by_the_reference(seed: int) -> None:
    # Every guess of a random 4-row problem: the compiled solve accepts exactly the guesses
    # whose impulses the reference accepts (up to guesses at the residual's threshold, none
    # here), with the same impulses.
    rng = np.random.default_rng(200 + seed)
    D = _rank_deficient(rng, 4, 4) + 0.05 * np.eye(4)
    b = rng.standard_normal(4)
    compiled = compiled_active_set(4)
    assert compiled is not None
    accepted = 0
    for code in range(16):
        guess = np.array([(code >> i) & 1 for i in range(4)], dtype=bool)
        reference = active_set_solution(D, b, guess, 0.0)
        result = compiled(D, b, guess)
        assert (result is None) == (reference is None), guess
        if result is not None and reference is not None:
            accepted += 1
            np.testing.assert_allclose(result[0], reference.impulses, rtol=0.0, atol=1e-12)
    assert accepted == 1  # positive definite: one active set solves the LCP


def test_sizes_outside_the_generated_ones_have_no_compiled_solve() -> None:
    assert compiled_active_set(1) is None
    assert compiled_active_set(MAX_ROWS + 1) is None
    # Beyond MAX_ROWS the solver runs the reference: the same impulses as without the switch.
    m = MAX_ROWS + 2
    rng = np.random.default_rng(7)
    D = _rank_deficient(rng, m, m) + 0.05 * np.eye(m)
    b = -D @ rng.uniform(0.5, 1.5, m)
    every = np.ones(m, dtype=bool)
    np.testing.assert_array_equal(
        _solve(D, b, every, compiled=True).impulses, _solve(D, b, every, False).impulses
    )


def test_without_compilation_the_reference_solves(monkeypatch: pytest.MonkeyPatch) -> None:
    # UCONTROL_NO_COMPILE: no compiled solve; the solver's impulses are the reference's.
    D = _rank_deficient(np.random.default_rng(3), 4, 2)
    b = -D @ np.array([1.0, 0.5, 0.7, 1.2])
    every = np.ones(4, dtype=bool)
    reference = active_set_solution(D, b, every, 0.0)
    assert reference is not None
    monkeypatch.setenv("UCONTROL_NO_COMPILE", "1")
    compiled_active_set.cache_clear()
    try:
        assert compiled_active_set(4) is None
        solution = _solve(D, b, every, compiled=True)
    finally:
        monkeypatch.delenv("UCONTROL_NO_COMPILE")
        compiled_active_set.cache_clear()
    np.testing.assert_array_equal(solution.impulses, reference.impulses)
    assert compiled_active_set(4) is not None
