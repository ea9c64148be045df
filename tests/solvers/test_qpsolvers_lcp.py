"""Every installed qpsolvers backend solves the frictionless contact LCP like Lemke's method."""

from __future__ import annotations

import numpy as np
import pytest
import qpsolvers

from ucontrol.exceptions import NotFoundError
from ucontrol.solvers import QpsolversLCPSolver, solve_lcp_lemke

_TOLERANCE = 1e-8  # relative agreement of the impulses [N s]
#: Backends that need a positive definite Hessian and fail on redundant constraints.
_POSITIVE_DEFINITE_ONLY = {"quadprog"}


@pytest.mark.parametrize("solver", qpsolvers.available_solvers)
@pytest.mark.parametrize("m", [2, 5, 12])
def test_matches_lemke(solver: str, m: int) -> None:
    rng = np.random.default_rng(m)
    A = rng.standard_normal((m, m))
    D = A @ A.T / m + 0.1 * np.eye(m)
    b = rng.standard_normal(m)
    solution = QpsolversLCPSolver(solver).solve(D, b)
    reference = solve_lcp_lemke(D, b)
    assert solution.status == "solved"
    assert solution.residual <= 1e-12  # polished
    assert np.allclose(solution.impulses, reference.impulses, rtol=_TOLERANCE, atol=1e-12)


@pytest.mark.parametrize(
    "solver", sorted(set(qpsolvers.available_solvers) - _POSITIVE_DEFINITE_ONLY)
)
def test_redundant_constraints(solver: str) -> None:
    """Four rows on two degrees of freedom: D singular, velocities unique."""
    rng = np.random.default_rng(0)
    J = rng.standard_normal((4, 2))
    D = J @ J.T
    b = J @ np.array([0.3, -1.0])
    solution = QpsolversLCPSolver(solver).solve(D, b)
    reference = solve_lcp_lemke(D, b)
    assert solution.status == "solved"
    assert np.allclose(solution.velocity, reference.velocity, atol=1e-10)


def test_positive_definite_only_backend_reports_failure() -> None:
    if "quadprog" not in qpsolvers.available_solvers:
        pytest.skip("quadprog is not installed (extra `dev`)")
    solution = QpsolversLCPSolver("quadprog").solve(np.ones((2, 2)), np.array([-1.0, -1.0]))
    assert solution.status.startswith("ProblemError")
    assert solution.residual == np.inf


def test_single_constraint_closed_form() -> None:
    solution = QpsolversLCPSolver("proxqp").solve(np.array([[2.0]]), np.array([-1.0]))
    assert solution.impulses.tolist() == [0.5]
    assert solution.iterations == 0


def test_unknown_backend_lists_the_installed_ones() -> None:
    with pytest.raises(NotFoundError, match="unknown qpsolvers solver 'nope'; available") as info:
        QpsolversLCPSolver("nope")
    assert set(info.value.available) == set(qpsolvers.available_solvers)
