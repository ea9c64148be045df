"""Banded Delassus matrices: the band order from the rows' sparsity, exact status solves.

References: the band of D checked on the permuted matrix itself, each status's equations
(module docstring of ucontrol.solvers.banded_delassus) checked on the solution, and the
general polish (``banded=False``) on a column of beads stepped by Moreau–Jean.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.integrators import MoreauJean
from ucontrol.solvers import CoulombProblem, ProxsuiteCoulombSolver
from ucontrol.solvers.banded_delassus import (
    BANDED_SIZE,
    SEPARATE,
    SLIDE,
    STICK,
    band_order,
    contact_statuses,
    solve_on_statuses,
    status_polish,
)

#: Round-off accepted on a status solve's impulses, per unit condition number of D, [N s].
EQUATION_TOLERANCE = 1e-12
#: Largest velocity difference between the banded and the general polish, [m/s] or [rad/s]
#: (6.2e-16 measured over 15 steps of 40 beads: round-off of two factorizations).
VELOCITY_TOLERANCE = 1e-12


def _chain_problem(
    m: int, tangents: int, seed: int, shuffle: bool = True
) -> tuple[CoulombProblem, np.ndarray]:
    """A chain of m bodies, contact a touching bodies a - 1 and a, contacts shuffled.

    Returns:
        The problem (D = J W⁻¹ Jᵀ, W block diagonal: exact zeros between contacts that share
        no body) and the chain position of each contact, shape (m,).
    """
    rng = np.random.default_rng(seed)
    dofs = 3  # per body
    rows_per_contact = 1 + tangents
    chain = rng.permutation(m) if shuffle else np.arange(m)  # contact j sits at chain[j]
    J_contact = np.zeros((m, rows_per_contact, m * dofs))
    for j, a in enumerate(chain):
        for body in (a - 1, a):
            if body >= 0:
                J_contact[j, :, body * dofs : (body + 1) * dofs] = rng.normal(
                    size=(rows_per_contact, dofs)
                )
    blocks = [rng.normal(size=(dofs, dofs)) for _ in range(m)]
    W_inv = np.zeros((m * dofs, m * dofs))
    for body, block in enumerate(blocks):
        W_inv[body * dofs : (body + 1) * dofs, body * dofs : (body + 1) * dofs] = np.linalg.inv(
            block @ block.T + dofs * np.eye(dofs)
        )
    # Normals first, then the tangential rows contact after contact.
    J = np.vstack((J_contact[:, 0, :], J_contact[:, 1:, :].reshape(m * tangents, -1)))
    D = J @ W_inv @ J.T
    b = rng.normal(size=J.shape[0])
    problem = CoulombProblem(D, b, np.full(m, 0.5), np.full(m, tangents, dtype=np.intp))
    return problem, chain


@pytest.mark.parametrize("tangents", [1, 2])
def test_band_order_found_from_the_sparsity_of_shuffled_contacts(tangents: int) -> None:
    problem, _ = _chain_problem(40, tangents, seed=tangents)
    band = band_order(problem)
    assert band is not None
    # Each contact's 1 + tangents rows coupled to its two neighbours' rows: 2 (1 + tangents) - 1
    # (plus one for a sliding spatial contact's rows, which combine its two rows of D).
    spread = 2 * (1 + tangents) - 1
    assert band.bandwidth == spread + (tangents == 2)
    permuted = problem.D[np.ix_(band.order, band.order)]
    rows, columns = np.nonzero(permuted)
    assert np.abs(rows - columns).max() == spread  # independent: on D itself
    assert np.array_equal(band.position[band.order], np.arange(problem.size))


def test_dense_or_small_delassus_is_not_banded() -> None:
    rng = np.random.default_rng(3)
    m = 40
    A = rng.normal(size=(2 * m, 2 * m))
    dense = CoulombProblem(A @ A.T, rng.normal(size=2 * m), np.full(m, 0.5), np.ones(m, int))
    assert band_order(dense) is None
    small, _ = _chain_problem(BANDED_SIZE // 2 - 1, 1, seed=4)  # 62 rows
    assert small.size < BANDED_SIZE
    assert band_order(small) is None
    assert status_polish(small, np.zeros(small.size), small.b, 1.0, 0.0) is None


def _known_solution(
    problem: CoulombProblem, seed: int
) -> tuple[CoulombProblem, np.ndarray, np.ndarray, np.ndarray]:
    """``problem`` with b chosen so that random statuses and impulses solve it exactly.

    Separating contacts: P = 0, u_n > 0; sticking: u = 0, ‖P_t‖ < μ P_n; sliding: u_n = 0,
    u_t = -s d (s > 0), P_t = μ P_n d; then b = u - D P (clear of every status's boundary).

    Returns:
        The problem, its solution P (r,), the statuses (m,) and sliding directions (m, 2).
    """
    rng = np.random.default_rng(seed)
    m, size, mu = problem.m, problem.size, problem.mu
    status = rng.choice([SEPARATE, STICK, SLIDE], size=m)
    angles = rng.uniform(0.0, 2.0 * np.pi, m)
    d = np.column_stack((np.cos(angles), np.sin(angles)))
    if not problem.spatial:
        d = np.column_stack((np.where(d[:, 0] < 0.0, -1.0, 1.0), np.zeros(m)))
    P_n = np.where(status == SEPARATE, 0.0, rng.uniform(0.5, 1.5, m))
    P_t = np.where((status == SLIDE)[:, None], mu[:, None] * P_n[:, None] * d, 0.0)
    stick = status == STICK
    P_t[stick] = 0.5 * mu[stick, None] * P_n[stick, None] * d[stick]
    u_n = np.where(status == SEPARATE, rng.uniform(0.5, 1.5, m), 0.0)
    u_t = np.where((status == SLIDE)[:, None], -rng.uniform(0.5, 1.5, m)[:, None] * d, 0.0)
    separate = status == SEPARATE
    u_t[separate] = rng.normal(size=(separate.sum(), 2))
    P, u = np.zeros(size + 1), np.zeros(size + 1)  # last entry: sink of the missing rows
    P[:m], u[:m] = P_n, u_n
    for component in range(problem.tangents.max()):
        P[problem.tangent_rows[:, component]] = P_t[:, component]
        u[problem.tangent_rows[:, component]] = u_t[:, component]
    P, u = P[:size], u[:size]
    known = CoulombProblem(problem.D, u - problem.D @ P, mu, problem.tangents)
    assert known.residual(P) <= 1e-14  # the construction solves Coulomb's law
    d[status != SLIDE] = 0.0
    return known, P, status, d


@pytest.mark.parametrize("tangents", [1, 2])
def test_status_solve_returns_the_known_solution(tangents: int) -> None:
    chain, _ = _chain_problem(40, tangents, seed=10 + tangents)
    problem, P_known, status, directions = _known_solution(chain, seed=tangents)
    band = band_order(problem)
    assert band is not None
    statuses = contact_statuses(problem, P_known, problem.velocity(P_known))
    assert np.array_equal(statuses[0], status)
    assert np.allclose(statuses[1], directions, rtol=0.0, atol=1e-15)
    P = solve_on_statuses(problem, band, *statuses)
    assert P is not None
    assert np.abs(P - P_known).max() <= EQUATION_TOLERANCE * np.linalg.cond(problem.D)
    assert problem.residual(P) <= 1e-12


@pytest.mark.parametrize("tangents", [1, 2])
def test_polish_from_a_nearby_start_finds_the_statuses(tangents: int) -> None:
    """From a perturbed solution the natural map's statuses are right: one solve is exact."""
    chain, _ = _chain_problem(40, tangents, seed=20 + tangents)
    problem, P_known, status, _ = _known_solution(chain, seed=5 + tangents)
    start = P_known + 1e-4 * np.random.default_rng(6).normal(size=problem.size)
    start[: problem.m] = np.maximum(start[: problem.m], 0.0)
    u = problem.velocity(start)
    assert np.array_equal(contact_statuses(problem, start, u)[0], status)
    result = status_polish(problem, start, u, problem.residual(start, u), 0.0)
    assert result is not None
    P, _, residual, improved = result
    assert improved and residual <= 1e-12
    assert np.abs(P - P_known).max() <= 1e-10


def test_a_pattern_outside_the_band_finds_the_order_again() -> None:
    problem, _ = _chain_problem(40, 1, seed=30, shuffle=False)
    first = band_order(problem)
    assert first is not None and first.bandwidth == 3
    D = problem.D.copy()
    D[0, 39] = D[39, 0] = 1e-3  # contacts 0 and 39 now coupled: same layout, wider band
    D[np.arange(80), np.arange(80)] += 1.0
    coupled = CoulombProblem(D, problem.b, problem.mu, problem.tangents)
    second = band_order(coupled)
    assert second is not None and second.bandwidth > 3
    permuted = D[np.ix_(second.order, second.order)]
    rows, columns = np.nonzero(permuted)
    assert np.abs(rows - columns).max() <= second.bandwidth


def test_bead_column_banded_polish_agrees_with_the_general_one() -> None:
    """Moreau–Jean on 40 beads (80 rows): both polishes, step by step, same velocities."""
    bench = load_experiment("bench_contacts")
    robot, constraints, q0, v0 = bench.column(40)
    runs = []
    for banded in (True, False):
        integrator = MoreauJean(
            robot, constraints, dt=1e-3, friction_solver=ProxsuiteCoulombSolver(banded=banded)
        )
        q, v, tau = q0, v0, np.zeros(v0.size)
        velocities, residuals = [], []
        for _ in range(15):
            outcome = integrator.step(integrator.evaluate(q, v), tau)
            q, v = outcome.q, outcome.v
            velocities.append(v)
            residuals.append(outcome.solution.residual)
            assert outcome.solution.status == "solved"
            assert outcome.solution.impulses.size == 80
        runs.append((np.array(velocities), np.array(residuals)))
    (v_banded, r_banded), (v_general, r_general) = runs
    assert np.abs(v_banded - v_general).max() <= VELOCITY_TOLERANCE
    assert r_banded.max() <= max(r_general.max(), 1e-15)  # round-off, no worse
