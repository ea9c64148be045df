"""One contact solved by enumerating its statuses, against Coulomb's law and Pinocchio's ADMM."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.solvers import CoulombProblem, PinocchioContactSolver, ProxsuiteCoulombSolver
from ucontrol.solvers.single_contact_coulomb import solve_single_contact

_AGREEMENT = 1e-8  # max |u - u_ADMM| relative to max |b|


@pytest.mark.parametrize("spatial", [False, True], ids=["planar", "spatial"])
def test_random_contacts_obey_coulomb_and_agree_with_admm(spatial: bool) -> None:
    cases = load_experiment("friction_cases")
    rng = np.random.default_rng(11)
    admm = PinocchioContactSolver("admm")
    statuses = {"separate": 0, "stick": 0, "slide": 0}
    for _ in range(200):
        problem = cases.random_problem(rng, 1, spatial=spatial, redundant=False)
        P = solve_single_contact(problem)
        assert P is not None
        u = problem.velocity(P)
        scale = np.abs(problem.b).max()
        assert problem.residual(P, u) <= 1e-14 * max(scale, 1.0)
        reference = admm.solve_coulomb(problem)
        assert np.abs(u - reference.velocity).max() <= _AGREEMENT * scale
        slip = np.linalg.norm(problem.tangential(u)[0])
        status = "separate" if P[0] == 0.0 else "slide" if slip > 1e-12 * scale else "stick"
        statuses[status] += 1
    assert min(statuses.values()) >= 5, statuses  # every status is exercised (measured >= 8)


def test_frictionless_contact_is_the_lcp_closed_form() -> None:
    problem = CoulombProblem(np.array([[4.0]]), np.array([-2.0]), np.array([0.3]), np.array([0]))
    assert np.array_equal(solve_single_contact(problem), [0.5])


def test_contact_without_solution_is_left_to_the_general_solve() -> None:
    # D singular; u_t = 2 u_n + 3: sliding (u_n = 0) slips forward, so P_t = -mu P_n and
    # u_n = -P_n - 1 < 0. No status holds: the general solve reports it unsolved.
    D = np.array([[1.0, 2.0], [2.0, 4.0]])
    problem = CoulombProblem(D, np.array([-1.0, 1.0]), np.array([1.0]), np.array([1]))
    assert solve_single_contact(problem) is None
    solution = ProxsuiteCoulombSolver(max_iter=5).solve_coulomb(problem)
    assert solution.status != "solved" and solution.residual > 1e-8
