"""The frictionless solve started from a guessed active set, against the QP and closed forms.

:meth:`ProxsuiteLCPSolver.solve` with ``guess`` solves the LCP on the guessed set first and
calls the QP only when that fails. References: the QP's polished solution of the same problem
(the path without a guess), Lemke's pivoting, and the closed form of a table standing on four
redundant feet, whose minimum-norm impulses share its weight evenly.
"""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.solvers import ProxsuiteLCPSolver, solve_lcp_lemke
from ucontrol.solvers.lcp_refinement import POLISH_THRESHOLD, active_set_solution

#: Agreement of impulses [N s] and velocities [m/s] on problems of unit scale: round-off of
#: the same exact solve (measured at most 4e-16 on the problems below).
_TOLERANCE = 1e-12
#: Agreement with Lemke's pivoting (a different exact method), relative.
_LEMKE_TOLERANCE = 1e-10


def _positive_definite(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    A = rng.standard_normal((m, m))
    return A @ A.T / m + 0.1 * np.eye(m), rng.standard_normal(m)


def _table(mass: float = 3.0, half_x: float = 0.4, half_y: float = 0.25) -> np.ndarray:
    r"""Delassus matrix (4, 4) of a box table's four feet on the ground, rank 3.

    Rows :math:`J_i = [n^T, (p_i \times n)^T]` of a free body at its centre of mass, feet
    :math:`p_i = (\pm a, \pm b, -0.3)`, normal :math:`n = e_z`; inertia of a uniform box.
    """
    feet = [(x, y, -0.3) for x in (half_x, -half_x) for y in (half_y, -half_y)]
    n = np.array([0.0, 0.0, 1.0])
    J = np.array([np.concatenate((n, np.cross(p, n))) for p in feet])
    inertia = mass / 12.0 * np.array([0.5**2 + 0.6**2, 0.8**2 + 0.6**2, 0.8**2 + 0.5**2])
    M_inverse = np.diag(np.concatenate((np.full(3, 1.0 / mass), 1.0 / inertia)))
    D = J @ M_inverse @ J.T
    return (D + D.T) / 2.0


def test_a_table_on_four_feet_shares_its_weight_evenly() -> None:
    # Standing: the free velocity is a step of gravity, -g h on every foot; the impulses
    # stopping it are m g h in all, m g h / 4 per foot by symmetry (the minimum norm).
    mass, g, h = 3.0, 9.81, 1e-3
    D = _table(mass)
    assert np.linalg.matrix_rank(D) == 3
    b = np.full(4, -g * h)
    solution = ProxsuiteLCPSolver().solve(D, b, np.ones(4, dtype=bool))
    assert solution.iterations == 0 and solution.polished  # no QP
    np.testing.assert_allclose(solution.impulses, mass * g * h / 4.0, rtol=0.0, atol=_TOLERANCE)
    np.testing.assert_allclose(solution.velocity, 0.0, rtol=0.0, atol=_TOLERANCE)
    # The QP's polished solution is the same (the path without a guess).
    reference = ProxsuiteLCPSolver().solve(D, b)
    np.testing.assert_allclose(solution.impulses, reference.impulses, rtol=0.0, atol=_TOLERANCE)


def test_a_tilted_load_keeps_the_minimum_norm_split() -> None:
    # An uneven load: the minimum-norm impulses are D⁺(-b), an independent computation.
    D = _table()
    b = -D @ np.array([0.03, 0.01, 0.02, 0.005])
    solution = ProxsuiteLCPSolver().solve(D, b, np.ones(4, dtype=bool))
    assert solution.iterations == 0
    expected = np.linalg.pinv(D, rcond=1e-12) @ -b
    np.testing.assert_allclose(solution.impulses, expected, rtol=0.0, atol=_TOLERANCE)
    assert solution.residual <= POLISH_THRESHOLD


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [2, 3, 5, 8])
def test_the_right_guess_gives_lemke_s_impulses(seed: int, m: int) -> None:
    D, b = _positive_definite(np.random.default_rng(seed), m)
    reference = solve_lcp_lemke(D, b)
    guess = reference.impulses > 0.0
    solution = ProxsuiteLCPSolver().solve(D, b, guess)
    assert solution.iterations == 0 and solution.status == "solved"
    scale = max(1.0, float(np.abs(reference.impulses).max()))
    error = np.abs(solution.impulses - reference.impulses).max() / scale
    assert error / _LEMKE_TOLERANCE <= 1.0, error


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [3, 5, 8])
def test_a_wrong_guess_falls_back_on_the_qp(seed: int, m: int) -> None:
    # A wrong guess is refused (the QP then gives the very impulses it gives without a
    # guess), unless its exact solve happens to solve the LCP (non-negative least squares
    # on a set of separating rows finds P = 0 where b >= 0): positive definite, that is the
    # unique solution.
    D, b = _positive_definite(np.random.default_rng(seed), m)
    lemke = solve_lcp_lemke(D, b).impulses
    right = lemke > 0.0
    refused = 0
    for wrong in (~right, np.zeros(m, dtype=bool), np.ones(m, dtype=bool)):
        if (wrong == right).all():
            continue
        guessed = ProxsuiteLCPSolver().solve(D, b, wrong)
        reference = ProxsuiteLCPSolver().solve(D, b)
        assert guessed.status == "solved"
        if active_set_solution(D, b, wrong, 0.0) is None:
            refused += 1
            np.testing.assert_array_equal(guessed.impulses, reference.impulses)  # the same QP
        else:
            np.testing.assert_allclose(guessed.impulses, lemke, rtol=0.0, atol=_LEMKE_TOLERANCE)
    assert refused >= 1 or not right.any()  # the empty guess is refused when some P > 0


def test_an_inconsistent_guessed_set_is_not_taken() -> None:
    # Two identical rows: with equal offsets the load is split evenly, (0.5, 0.5); with
    # different ones no impulses satisfy both rows, and the least-squares ones are refused.
    D = np.ones((2, 2))
    both = np.ones(2, dtype=bool)
    solution = active_set_solution(D, np.array([-1.0, -1.0]), both, 0.0)
    assert solution is not None
    np.testing.assert_allclose(solution.impulses, 0.5, rtol=0.0, atol=_TOLERANCE)
    assert active_set_solution(D, np.array([-1.0, -1.0 + 1e-6]), both, 0.0) is None


def test_without_the_switch_the_guess_is_ignored() -> None:
    D = _table()
    b = np.full(4, -9.81e-3)
    solver = ProxsuiteLCPSolver(active_set_start=False)
    solution = solver.solve(D, b, np.ones(4, dtype=bool))
    assert solution.iterations > 0  # proxsuite ran
    np.testing.assert_array_equal(
        solution.impulses, ProxsuiteLCPSolver(active_set_start=False).solve(D, b).impulses
    )


#: Largest velocity difference between the table's steps with and without the guess
#: [m/s, rad/s], and of the impulses [N s]: the QP's solutions that its residual lets go
#: unpolished (below 1e-13 m/s) are accurate to its tolerance, 1e-10 (measured 5.6e-14 and
#: 2.2e-11 over the 500 steps).
_STEP_TOLERANCE = 1e-10


def test_a_table_standing_on_four_feet_skips_the_qp() -> None:
    # The table dropped on its four redundant feet, stepped with the fast path and with the
    # QP for every problem (the reference): same velocities and impulses, and once it stands
    # its problems are solved without proxsuite.
    from ucontrol.integrators import MoreauJean
    from ucontrol.scene import load_scene

    scene = load_scene("table_drop")
    fast = scene.build_integrator()
    assert isinstance(fast, MoreauJean) and "active-set start" in fast.fast_paths
    reference = MoreauJean(
        scene.robot,
        fast.constraints,
        dt=fast.dt,
        theta=fast.theta,
        solver=ProxsuiteLCPSolver(active_set_start=False),
    )
    assert "active-set start" not in reference.fast_paths
    q, v = scene.initial_state()
    tau = np.zeros(v.size)
    without_qp = with_problem = 0
    for _ in range(500):
        outcome = fast.step(fast.evaluate(q, v), tau)
        expected = reference.step(reference.evaluate(q, v), tau)
        dv = np.abs(outcome.v - expected.v).max()
        dP = np.abs(outcome.impulse - expected.impulse).max()
        assert dv <= _STEP_TOLERANCE
        assert dP <= _STEP_TOLERANCE
        if outcome.solution is not None and outcome.solution.impulses.size > 1:
            with_problem += 1
            without_qp += outcome.solution.iterations == 0
            assert outcome.solution.residual <= POLISH_THRESHOLD
        q, v = outcome.q, outcome.v
    assert with_problem > 200 and without_qp >= with_problem - 10  # measured 212 and 206
