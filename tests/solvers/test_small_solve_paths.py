"""The cheap paths of the frictionless solve against their general forms and Lemke.

- :func:`natural_map_residual` (a loop on Python floats) against the numpy expression of the
  natural map, bitwise, with vanishing diagonals, NaNs and empty problems;
- a :class:`WarmStartedQP` that updates only ``H`` and ``g`` (``fixed_constraints``) against
  one updated with every array along warm-started sequences (to round-off: proxsuite's dense
  results depend on the memory alignment of its buffers, so that two QPs given the same
  problems may differ in the last bits), and its refined solutions against Lemke's;
- the backend's status turned into text only for an unsolved problem.
"""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.exceptions import InvalidParameterError
from ucontrol.solvers import ProxsuiteLCPSolver, lcp_refinement, solve_lcp_lemke
from ucontrol.solvers.contact_solution import (
    PYTHON_RESIDUAL_SIZE,
    natural_map_residual,
    velocity_scale,
)
from ucontrol.solvers.lcp_refinement import refine_lcp_solution
from ucontrol.solvers.proxsuite_qp import INFINITY, WarmStartedQP

_SIZES = [1, 2, 3, 4, 7]
_TOLERANCE = 5e-13  # relative agreement of post-step velocities with Lemke's, measured 5.0e-14


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(14)


def _numpy_natural_map(D: np.ndarray, P: np.ndarray, w: np.ndarray) -> float:
    """``max |min(scale ⊙ P, w)|`` with numpy, 0 for an empty problem (the reference)."""
    if P.size == 0:
        return 0.0
    return float(np.max(np.abs(np.minimum(velocity_scale(D) * P, w))))


@pytest.mark.parametrize("m", [0, *_SIZES, PYTHON_RESIDUAL_SIZE, PYTHON_RESIDUAL_SIZE + 1, 100])
def test_natural_map_residual_is_the_numpy_expression(rng: np.random.Generator, m: int) -> None:
    for _ in range(200):
        A = rng.standard_normal((m, m))
        D = A @ A.T
        if m:  # vanishing and negative (round-off) diagonal entries count as 1
            D[rng.integers(m), rng.integers(m)] = rng.choice([0.0, -1e-18, 2.0])
        P = np.maximum(rng.standard_normal(m), 0.0)
        w = rng.standard_normal(m) * rng.choice([1e-14, 1.0])
        if m and rng.uniform() < 0.3:  # ties between scaled impulse and velocity
            w[0] = velocity_scale(D)[0] * P[0]
        assert natural_map_residual(D.diagonal(), P, w) == _numpy_natural_map(D, P, w)


@pytest.mark.parametrize("m", [3, PYTHON_RESIDUAL_SIZE + 1])
@pytest.mark.parametrize("where", ["impulse", "velocity", "diagonal"])
def test_natural_map_residual_keeps_a_nan(rng: np.random.Generator, where: str, m: int) -> None:
    D, P, w = np.eye(m), rng.uniform(0.0, 1.0, m), rng.standard_normal(m)
    row = rng.integers(m)
    {"impulse": P, "velocity": w, "diagonal": D}[where][..., row] = np.nan  # D: a column
    assert np.isnan(_numpy_natural_map(D, P, w))
    assert np.isnan(natural_map_residual(D.diagonal(), P, w))


def _problem_sequence(rng: np.random.Generator, m: int, redundant: bool) -> list:
    """60 slowly varying contact problems (D, b), ``D = J J^T`` and ``b = J c + gap rates``.

    Positive definite with m + 2 degrees of freedom, singular (redundant contacts) with m - 1:
    ``b`` in the range of J plus non-negative gap rates keeps the LCP solvable (the velocity
    ``-c`` is feasible).
    """
    n = max(m - 1, 1) if redundant else m + 2
    J, J_drift = rng.standard_normal((m, n)), rng.standard_normal((m, n))
    c, c_drift = rng.standard_normal(n), rng.standard_normal(n)
    gap_rates = np.where(rng.uniform(size=m) < 0.5, 0.0, rng.uniform(0.0, 1.0, size=m))
    problems = []
    for k in range(60):
        Jk = J + 0.02 * np.sin(0.1 * k) * J_drift
        problems.append((Jk @ Jk.T, Jk @ (c + np.cos(0.05 * k) * c_drift) + gap_rates))
    return problems


@pytest.mark.parametrize("redundant", [False, True])
@pytest.mark.parametrize("m", _SIZES)
def test_fixed_constraints_qp_is_the_fully_updated_qp(
    rng: np.random.Generator, m: int, redundant: bool
) -> None:
    fixed, full = WarmStartedQP(fixed_constraints=True), WarmStartedQP()
    inequalities = (np.eye(m), np.zeros(m), np.full(m, INFINITY))
    for D, b in _problem_sequence(rng, m, redundant):
        expected = full.solve(D, b, *inequalities)
        x, z, iterations = np.array(expected.x), np.array(expected.z), expected.info.iter
        actual = fixed.solve(D, b, *inequalities)
        scale = max(np.abs(x).max(), 1.0)  # [N s]
        np.testing.assert_allclose(actual.x, x, rtol=0.0, atol=1e-15 * scale)  # measured 4.4e-16
        np.testing.assert_allclose(actual.z, z, rtol=0.0, atol=1e-15 * max(np.abs(z).max(), 1.0))
        assert actual.info.iter == iterations


@pytest.mark.parametrize("redundant", [False, True])
@pytest.mark.parametrize("m", _SIZES[1:])
def test_warm_started_sequence_matches_lemke(
    rng: np.random.Generator, m: int, redundant: bool
) -> None:
    solver = ProxsuiteLCPSolver()
    for D, b in _problem_sequence(rng, m, redundant):
        solution = solver.solve(D, b)
        reference = solve_lcp_lemke(D, b)
        assert solution.status == "solved"
        assert solution.residual <= 1e-12  # measured 9.2e-14 [m/s] (polish threshold 1e-13)
        error = np.max(np.abs(solution.velocity - reference.velocity)) / max(np.abs(b).max(), 1.0)
        assert error <= _TOLERANCE, f"velocity error {error:.3g}"


def test_fixed_constraints_and_changing_bounds_are_exclusive() -> None:
    with pytest.raises(InvalidParameterError, match="fixed_constraints"):
        WarmStartedQP(bounds_change=True, fixed_constraints=True)


class _Status:
    """A backend status whose text is its name (as proxsuite's enums)."""

    def __str__(self) -> str:
        return "QPSolverOutput.PROXQP_MAX_ITER_REACHED"


def test_the_status_becomes_text_only_when_unsolved(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(lcp_refinement, "LEMKE_FALLBACK_SIZE", 0)  # keep the unsolved result
    D, b = np.eye(2), np.array([-1.0, 2.0])  # solution P = (1, 0)
    args = {"polish": False, "iterations": 3, "unsolved_status": _Status(), "start": 0.0}
    solved = refine_lcp_solution(D, b, np.array([1.0, 0.0]), residual_tolerance=1e-8, **args)
    assert solved.status == "solved"
    off = refine_lcp_solution(D, b, np.array([0.5, 0.0]), residual_tolerance=1e-8, **args)
    assert off.residual == 0.5  # |min(0.5, -0.5)| [m/s]
    assert off.status == "QPSolverOutput.PROXQP_MAX_ITER_REACHED"
