"""The Tresca fixed point of proxsuite QPs against analytic solutions and Pinocchio's ADMM.

Random problems come from ``experiments/friction_cases.py`` (:func:`random_problem`): built like
a Moreau–Jean step, 1 to 20 contacts, planar and spatial, half of them redundant (fewer degrees
of freedom than contact rows: D singular, impulses not unique). Coulomb's law is checked
contact by contact (:func:`_assert_coulomb`), independently of the residual function.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.exceptions import InvalidParameterError
from ucontrol.solvers import (
    ContactSolution,
    CoulombProblem,
    PinocchioContactSolver,
    ProxsuiteCoulombSolver,
)

_TOLERANCE = 1e-8  # [m/s], natural-map residual the solvers must reach
_AGREEMENT = 1e-8  # max |u_ucontrol - u_ADMM| relative to max |b|
_EXACT = 1e-12  # analytic cases, relative


def _assert_coulomb(problem: CoulombProblem, P: np.ndarray, tolerance: float) -> None:
    """Signorini and Coulomb's law on every contact, to ``tolerance`` relative to the scales."""
    u = problem.velocity(P)
    P_scale = max(np.max(np.abs(P)), 1e-300)
    u_scale = max(np.max(np.abs(problem.b)), 1e-300)
    P_t, u_t = problem.tangential(P), problem.tangential(u)
    for a in range(problem.m):
        P_n, u_n, mu = P[a], u[a], problem.mu[a]
        assert P_n >= -tolerance * P_scale and u_n >= -tolerance * u_scale
        assert min(P_n / P_scale, u_n / u_scale) <= tolerance  # complementarity
        assert np.linalg.norm(P_t[a]) <= mu * P_n + tolerance * P_scale  # in the cone
        speed = np.linalg.norm(u_t[a])
        if speed > tolerance * u_scale:  # sliding: maximal friction, opposite to the slip
            assert np.allclose(P_t[a], -mu * P_n * u_t[a] / speed, atol=tolerance * P_scale)


def _solved(solution: ContactSolution) -> bool:
    return solution.status == "solved" and solution.residual <= _TOLERANCE


@pytest.mark.parametrize("tangents", [1, 2])
@pytest.mark.parametrize(
    ("b_t", "expected"),
    [
        (0.2, "stick"),  # |b_t| < mu |b_n|: friction holds the contact
        (3.0, "slide"),
    ],
)
def test_single_contact_analytic(tangents: int, b_t: float, expected: str) -> None:
    mu, D = 0.5, np.diag([2.0, 1.0, 1.0][: 1 + tangents])  # no normal-tangential coupling
    b = np.array([-1.0, b_t, 0.5 * b_t][: 1 + tangents])
    solution = ProxsuiteCoulombSolver().solve_coulomb(
        CoulombProblem(D, b, np.array([mu]), np.array([tangents]))
    )
    P_n = 0.5  # u_n = 2 P_n - 1 = 0
    if expected == "stick":
        P = np.concatenate(([P_n], -b[1:]))
    else:
        P = np.concatenate(([P_n], -mu * P_n * b[1:] / np.linalg.norm(b[1:])))
    assert solution.status == "solved"
    assert np.allclose(solution.impulses, P, rtol=_EXACT, atol=_EXACT)


def test_separating_contact_gets_nothing() -> None:
    problem = CoulombProblem(np.eye(3), np.array([0.5, 2.0, -1.0]), np.array([0.8]), np.array([2]))
    solution = ProxsuiteCoulombSolver().solve_coulomb(problem)
    assert np.all(solution.impulses == 0.0)
    assert solution.residual == 0.0


def test_random_problems_agree_with_admm() -> None:
    """Acceptance: 1 to 20 contacts, redundant ones included; both converge and agree."""
    cases = load_experiment("friction_cases")
    rng = np.random.default_rng(2024)
    ours, admm = ProxsuiteCoulombSolver(), PinocchioContactSolver("admm")
    kinds = {"redundant": 0, "spatial": 0}
    for _ in range(120):
        m = int(rng.integers(1, 21))
        spatial, redundant = bool(rng.random() < 0.5), bool(rng.random() < 0.5)
        problem = cases.random_problem(rng, m, spatial=spatial, redundant=redundant)
        first, second = ours.solve_coulomb(problem), admm.solve_coulomb(problem)
        assert _solved(first), (m, spatial, redundant, first.status, first.residual)
        assert _solved(second), (m, spatial, redundant, second.status, second.residual)
        _assert_coulomb(problem, first.impulses, 1e-7)
        difference = np.max(np.abs(first.velocity - second.velocity)) / np.max(np.abs(problem.b))
        assert difference <= _AGREEMENT, (m, spatial, redundant, difference)
        kinds["redundant"] += redundant
        kinds["spatial"] += spatial
    assert min(kinds.values()) >= 40  # both kinds are well represented


def test_pgs_agrees_where_it_converges() -> None:
    """Pinocchio's PGS (swept until our residual is met) stalls on a few coupled problems."""
    cases = load_experiment("friction_cases")
    rng = np.random.default_rng(7)
    pgs = PinocchioContactSolver("pgs")
    converged = 0
    for _ in range(30):
        problem = cases.random_problem(rng, int(rng.integers(1, 6)), spatial=True, redundant=False)
        solution = pgs.solve_coulomb(problem)
        if not _solved(solution):
            assert solution.status == "max_iterations_reached"  # reported, with its residual
            continue
        converged += 1
        reference = ProxsuiteCoulombSolver().solve_coulomb(problem)
        scale = np.max(np.abs(problem.b))
        assert np.max(np.abs(solution.velocity - reference.velocity)) <= 1e-6 * scale
    assert converged >= 25


def test_tangential_impact_after_sliding() -> None:
    """Painlevé: from a sliding warm start the solve reaches the sticking impulse."""
    mu = 1.5
    D = np.array([[1.87577975, 1.36394614], [1.36394614, 3.12422025]])  # the rod at 1 rad
    solver = ProxsuiteCoulombSolver()
    sliding = CoulombProblem(D, np.array([-0.00981, 0.01]), np.array([mu]), np.array([1]))
    assert solver.solve_coulomb(sliding).status == "solved"
    painleve = CoulombProblem(D, np.array([-0.00981, 1.0]), np.array([mu]), np.array([1]))
    solution = solver.solve_coulomb(painleve)
    assert solution.status == "solved"
    _assert_coulomb(painleve, solution.impulses, 1e-10)
    assert solution.impulses[0] > 30 * 0.00981  # far above m g h: an impact
    assert abs(solution.velocity[1]) <= 1e-12  # the end sticks


def test_warm_start_that_solves_takes_no_qp() -> None:
    cases = load_experiment("friction_cases")
    problem = cases.random_problem(np.random.default_rng(3), 8, spatial=True, redundant=True)
    solver = ProxsuiteCoulombSolver()
    first = solver.solve_coulomb(problem)
    second = solver.solve_coulomb(problem)
    assert first.outer_iterations >= 1
    assert (second.outer_iterations, second.iterations) == (0, 0)
    assert np.allclose(second.velocity, first.velocity, atol=1e-10)
    assert second.residual <= 4e-14  # measured 3.6e-15 m/s: the warm start is the solution


def test_unsolved_is_reported_not_hidden() -> None:
    cases = load_experiment("friction_cases")
    problem = cases.random_problem(np.random.default_rng(4), 10, spatial=True, redundant=False)
    solution = ProxsuiteCoulombSolver(max_iter=1, polish=False).solve_coulomb(problem)
    assert solution.status == "max_iterations_reached"
    assert solution.residual > _TOLERANCE
    assert solution.outer_iterations == 1


def test_bad_settings_raise() -> None:
    with pytest.raises(InvalidParameterError, match="`facets` must be >= 3"):
        ProxsuiteCoulombSolver(facets=2)
    with pytest.raises(InvalidParameterError, match="`residual_tolerance` must be > 0"):
        ProxsuiteCoulombSolver(residual_tolerance=0.0)
