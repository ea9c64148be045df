"""The compiled Alart–Curnier Newton step against the numpy reference it stands for.

- one step from random impulses against :meth:`AlartCurnier.value` and :func:`solve_square`
  (the numpy polish's step), on layouts mixing frictionless, planar and spatial contacts;
- its residual and marginal flag against :meth:`CoulombProblem.residual` and the solver's
  ``_marginal``, including contacts built to be marginal;
- no result where J is singular (redundant contacts), and none generated beyond ``MAX_ROWS``;
- the solver with and without it on warm-started sequences: both solved, same impulses;
- the ctypes call (no extension) bitwise the builtin's, and a failed build leaving the numpy
  polish alone.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from ucontrol.model.compiled_function import compilation_possible
from ucontrol.solvers import ProxsuiteCoulombSolver, compiled_coulomb_newton
from ucontrol.solvers.alart_curnier import AlartCurnier, solve_square
from ucontrol.solvers.compiled_coulomb_newton import (
    MAX_ROWS,
    CompiledCoulombNewton,
    _residual,
    compiled_newton,
)
from ucontrol.solvers.coulomb_problem import CoulombProblem
from ucontrol.solvers.proxsuite_coulomb import _marginal

pytestmark = pytest.mark.skipif(not compilation_possible(), reason="no C compiler")

_LAYOUTS = [(2, 2, 2, 2), (1, 0, 2), (2, 1)]
_STEP_TOLERANCE = 1e-9  # relative agreement of the Newton iterates; measured 5.2e-15


def _problem(rng: np.random.Generator, tangents: tuple[int, ...], dofs: int) -> CoulombProblem:
    """A random problem: D = H H^T / dofs of a random H (rows, dofs), b and mu random."""
    size = len(tangents) + sum(tangents)
    H = rng.standard_normal((size, dofs))
    b = rng.standard_normal(size)
    mu = rng.uniform(0.1, 1.2, len(tangents))
    return CoulombProblem(H @ H.T / dofs, b, mu, np.array(tangents))


def _numpy_step(problem: CoulombProblem, P: np.ndarray) -> np.ndarray:
    """The numpy polish's full Newton step from P (the reference)."""
    F, J = AlartCurnier(problem).value(P, problem.velocity(P))
    return P + solve_square(J, -F)


@pytest.mark.parametrize("tangents", _LAYOUTS)
def test_one_step_is_the_numpy_newton_step(tangents: tuple[int, ...]) -> None:
    rng = np.random.default_rng(30)
    newton = CompiledCoulombNewton(tangents)
    worst = 0.0
    for _ in range(100):
        problem = _problem(rng, tangents, dofs=18)
        P = rng.standard_normal(problem.size)  # separating, sticking and sliding statuses
        newton.polish(problem, P, iterations=1, target=0.0, tolerance=1e-8)
        expected = _numpy_step(problem, P)
        error = np.abs(newton._next - expected).max() / (1.0 + np.abs(expected).max())
        worst = max(worst, error)
        candidate = np.concatenate((np.maximum(expected[: problem.m], 0.0), expected[problem.m :]))
        np.testing.assert_allclose(newton._candidate, candidate, rtol=0, atol=1e-8)
        np.testing.assert_allclose(
            newton._velocity, problem.velocity(newton._candidate), rtol=0, atol=1e-12
        )
        assert newton._residual[0] == pytest.approx(
            problem.residual(newton._candidate), rel=1e-12, abs=1e-15
        )
    assert worst <= _STEP_TOLERANCE


@pytest.mark.parametrize("tangents", _LAYOUTS)
def test_residual_and_marginal_flag_are_the_numpy_ones(tangents: tuple[int, ...]) -> None:
    rng = np.random.default_rng(31)
    m, size = len(tangents), len(tangents) + sum(tangents)
    D, P, u = ca.SX.sym("D", size, size), ca.SX.sym("P", size), ca.SX.sym("u", size)
    mu = ca.SX.sym("mu", m)
    tolerance = ca.SX.sym("tolerance")
    offsets = np.concatenate(([m], m + np.cumsum(tangents)))
    rows = [list(range(offsets[a], offsets[a + 1])) for a in range(m)]
    sigma = [ca.if_else(D[a, a] > 0.0, D[a, a], 1.0) for a in range(m)]
    function = ca.Function(
        "residual", [D, P, u, mu, tolerance], list(_residual(P, u, mu, sigma, rows, tolerance))
    )
    flags = set()
    for _ in range(200):
        problem = _problem(rng, tangents, dofs=18)
        impulses = rng.standard_normal(size)
        impulses[:m] = np.abs(impulses[:m])
        velocity = problem.velocity(impulses)
        if rng.uniform() < 0.5:  # contact 0 at its friction bound, sliding slower than 1e-8
            direction = np.ones(tangents[0]) / np.sqrt(max(tangents[0], 1))
            impulses[offsets[0] : offsets[1]] = problem.mu[0] * impulses[0] * direction
            velocity[offsets[0] : offsets[1]] = -1e-9 * direction
        residual, marginal = function(problem.D, impulses, velocity, problem.mu, 1e-8)
        assert float(residual) == pytest.approx(
            problem.residual(impulses, velocity), rel=1e-13, abs=1e-15
        )
        expected = _marginal(problem, impulses, velocity, 1e-8)
        assert bool(float(marginal)) == expected
        flags.add(expected)
    assert flags == ({True, False} if tangents[0] else {False})


@pytest.mark.parametrize("tangents", _LAYOUTS)
def test_open_contacts_step_to_exactly_zero(tangents: tuple[int, ...]) -> None:
    """A contact whose normal row is open (P_n - ρ u_n <= 0) gets P_n = 0, not round-off.

    Its row of the Alart–Curnier function is :math:`F_n = P_n`, so that the Newton iterate is
    0 in exact arithmetic; the QR solve leaves about 1e-18 N s, which would make the contact
    held in the step's memory (its impulse > 0) and change its impact law at the next steps.
    """
    rng = np.random.default_rng(35)
    newton = CompiledCoulombNewton(tangents)
    m, opened = len(tangents), 0
    for _ in range(200):
        problem = _problem(rng, tangents, dofs=18)
        P = rng.standard_normal(problem.size)
        P[:m] = np.abs(P[:m])  # pressed contacts, some of them opening
        x_n = P[:m] - AlartCurnier(problem).rho[:m] * problem.velocity(P)[:m]
        result = newton.polish(problem, P, iterations=1, target=0.0, tolerance=1e-8)
        if result is None:  # (J singular to LSTSQ_CONDITION: no step)
            continue
        open_ = x_n <= 0.0
        assert np.all(result[0][:m][open_] == 0.0), result[0][:m][open_]
        opened += int(open_.sum())
    assert opened >= 50


def test_polish_reaches_round_off_from_a_near_solution() -> None:
    rng = np.random.default_rng(32)
    newton = CompiledCoulombNewton((2, 2, 2, 2))
    solver = ProxsuiteCoulombSolver(compiled_newton=False)
    for _ in range(20):
        problem = _problem(rng, (2, 2, 2, 2), dofs=18)
        solution = solver.solve_coulomb(problem)
        assert solution.status == "solved"
        start = solution.impulses * (1.0 + 1e-3 * rng.standard_normal(problem.size))
        result = newton.polish(problem, start, iterations=20, target=1e-14, tolerance=1e-8)
        assert result is not None
        P, u, residual, _ = result
        assert residual == pytest.approx(problem.residual(P, u), abs=1e-15)
        assert residual <= 1e-12
        np.testing.assert_allclose(P, solution.impulses, rtol=0, atol=1e-9)


def test_singular_jacobian_gives_no_result() -> None:
    # Two identical contacts (redundant rows): D singular, so is J where both stick.
    rng = np.random.default_rng(33)
    H = rng.standard_normal((3, 6))
    H = np.vstack((H[:1], H[:1], H[1:], H[1:]))  # normals, then tangents, of twin contacts
    D = H @ H.T
    b = np.array([-1.0, -1.0, 0.1, 0.2, 0.1, 0.2])
    problem = CoulombProblem(D, b, np.ones(2), np.array([2, 2]))
    newton = CompiledCoulombNewton((2, 2))
    # From P = 0 both normal rows are closed: J's normal rows are rho D's, equal.
    assert newton.polish(problem, np.zeros(6), 5, 1e-14, 1e-8) is None
    solved = ProxsuiteCoulombSolver().solve_coulomb(problem)  # the numpy path solves it
    assert solved.status == "solved"


def test_only_small_layouts_without_bilateral_rows_are_generated() -> None:
    spatial = np.full(MAX_ROWS // 3 + 1, 2, dtype=np.intp)
    assert compiled_newton(spatial.tobytes(), 0) is None
    assert compiled_newton(spatial[:2].tobytes(), 1) is None
    assert compiled_newton(spatial[:2].tobytes(), 0) is not None


@pytest.mark.parametrize("tangents", _LAYOUTS)
def test_solver_with_and_without_it_agree_on_warm_sequences(
    tangents: tuple[int, ...], monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = np.random.default_rng(34)
    solved_fast = []
    polish = CompiledCoulombNewton.polish

    def counted(self, problem, P, iterations, target, tolerance):  # type: ignore[no-untyped-def]
        result = polish(self, problem, P, iterations, target, tolerance)
        solved_fast.append(result is not None and result[2] <= tolerance and not result[3])
        return result

    monkeypatch.setattr(CompiledCoulombNewton, "polish", counted)
    fast, reference = ProxsuiteCoulombSolver(), ProxsuiteCoulombSolver(compiled_newton=False)
    problem = _problem(rng, tangents, dofs=18)
    D, b = problem.D, problem.b
    for _ in range(60):  # a slowly drifting problem, as successive time steps make
        D = D + 1e-3 * np.diag(rng.uniform(0.0, 1.0, problem.size))
        b = b + 2e-2 * rng.standard_normal(problem.size)
        problem = CoulombProblem(D, b, problem.mu, np.array(tangents))
        a, r = fast.solve_coulomb(problem), reference.solve_coulomb(problem)
        assert a.status == r.status == "solved"
        assert a.residual <= 1e-8
        np.testing.assert_allclose(a.impulses, r.impulses, rtol=0, atol=1e-7)
    assert sum(solved_fast) >= 30  # most steps solved by the compiled Newton


def test_ctypes_call_where_the_extension_is_missing(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(35)
    problem = _problem(rng, (2, 1), dofs=18)
    P = rng.standard_normal(problem.size)
    native = CompiledCoulombNewton((2, 1)).polish(problem, P, 3, 0.0, 1e-8)
    monkeypatch.setattr(compiled_coulomb_newton, "native_runner", lambda *args: None)
    through_ctypes = CompiledCoulombNewton((2, 1)).polish(problem, P, 3, 0.0, 1e-8)
    assert native is not None and through_ctypes is not None
    np.testing.assert_array_equal(native[0], through_ctypes[0])
    assert native[2] == through_ctypes[2]


@pytest.mark.parametrize("failure", [OSError("no compiler here"), ImportError("no casadi")])
def test_failed_build_leaves_the_numpy_polish(
    monkeypatch: pytest.MonkeyPatch, failure: Exception
) -> None:
    def broken(tangents: tuple[int, ...]) -> None:
        raise failure

    monkeypatch.setattr(compiled_coulomb_newton, "_library", broken)
    compiled_newton.cache_clear()
    try:
        assert compiled_newton(np.array([2, 0], dtype=np.intp).tobytes(), 0) is None
        rng = np.random.default_rng(36)
        solver = ProxsuiteCoulombSolver()
        for _ in range(3):  # warm-started solves of one layout: the numpy polish alone
            solution = solver.solve_coulomb(_problem(rng, (2, 0), dofs=18))
            assert solution.status == "solved"
    finally:
        compiled_newton.cache_clear()
