"""The proxsuite contact solver against the Lemke reference on random and robot problems.

Positive definite Delassus matrices have unique impulses, compared directly. Redundant contacts
(more constraint rows than degrees of freedom) make ``D = J M^-1 J^T`` singular: the impulses
are then not unique, but the post-step velocities are, so those are compared, and both
solutions must satisfy complementarity.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from ucontrol.model import RobotModel
from ucontrol.solvers import (
    ContactSolution,
    ProxsuiteLCPSolver,
    complementarity_residual,
    solve_lcp_lemke,
)

_TOLERANCE = 1e-8  # relative agreement of impulses [N s] or velocities [m/s]
_RESIDUAL_TOLERANCE = 1e-8  # complementarity residual [m/s], problems of unit scale
_PENETRATION_TOLERANCE = 1e-10  # most negative admissible post-step velocity [m/s]
_SEEDS = range(6)
_SIZES = [1, 2, 3, 5, 8, 13, 20]
_TWO_LINK_URDF = Path(__file__).resolve().parents[2] / "robots" / "two_link.urdf"


@dataclass(frozen=True)
class _ContactProblem:
    """A frictionless contact step: ``D = J M^-1 J^T``, ``b = J (v_free + e v_k) + gap rates``."""

    J: np.ndarray  # (m, n)
    M: np.ndarray  # (n, n)
    v_free: np.ndarray  # (n,)
    b: np.ndarray  # (m,) [m/s]

    @property
    def D(self) -> np.ndarray:
        D = self.J @ np.linalg.solve(self.M, self.J.T)
        return (D + D.T) / 2.0

    def velocity(self, impulses: np.ndarray) -> np.ndarray:
        """Generalized velocity after the step, ``v_free + M^-1 J^T P``, shape (n,)."""
        return self.v_free + np.linalg.solve(self.M, self.J.T @ impulses)


def _redundant_contact_problem(rng: np.random.Generator, m: int, n: int) -> _ContactProblem:
    """Contact problem with m rows on n < m degrees of freedom, solvable by construction.

    With one restitution coefficient e, ``v = -e v_k`` satisfies ``J v + e J v_k >= 0``, so the
    velocity QP is feasible; non-negative gap rates on some rows keep it so.
    """
    J = rng.standard_normal((m, n))
    L = rng.standard_normal((n, n))
    M = L @ L.T + n * np.eye(n)
    v_free = rng.standard_normal(n)
    v_k = rng.standard_normal(n)
    restitution = rng.uniform(0.0, 1.0)
    gap_rates = np.where(rng.uniform(size=m) < 0.5, 0.0, rng.uniform(0.0, 1.0, size=m))
    b = J @ (v_free + restitution * v_k) + gap_rates
    return _ContactProblem(J=J, M=M, v_free=v_free, b=b)


def _positive_definite_problem(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    A = rng.standard_normal((m, m))
    D = A @ A.T / m + 0.1 * np.eye(m)
    return D, rng.standard_normal(m)


def _assert_valid_solution(D: np.ndarray, b: np.ndarray, solution: ContactSolution) -> None:
    """P >= 0, w >= 0 and complementarity of a proxsuite solution, with its reported fields."""
    P, w = solution.impulses, solution.velocity
    assert P.shape == b.shape
    assert solution.status == "solved"
    assert P.min() >= 0.0
    assert w.min() >= -_PENETRATION_TOLERANCE, f"penetration {w.min():.3g} m/s"
    np.testing.assert_allclose(w, D @ P + b, rtol=0.0, atol=1e-12)
    residual = complementarity_residual(D, b, P)
    assert residual < _RESIDUAL_TOLERANCE, f"complementarity residual {residual:.3g} m/s"
    assert solution.residual == pytest.approx(residual, abs=1e-15)


def _relative_error(actual: np.ndarray, expected: np.ndarray, scale: float) -> float:
    return float(np.max(np.abs(actual - expected), initial=0.0)) / max(scale, 1.0)


def _assert_same_velocities(D: np.ndarray, b: np.ndarray, solution: ContactSolution) -> None:
    """Velocities of ``solution`` against Lemke's, both complementary."""
    reference = solve_lcp_lemke(D, b)
    assert reference.residual < _RESIDUAL_TOLERANCE
    _assert_valid_solution(D, b, solution)
    error = _relative_error(solution.velocity, reference.velocity, float(np.abs(b).max()))
    assert error / _TOLERANCE <= 1.0, f"velocity error {error:.3g}"


@pytest.mark.parametrize("seed", _SEEDS)
@pytest.mark.parametrize("m", _SIZES)
def test_positive_definite_impulses_match_lemke(seed: int, m: int) -> None:
    D, b = _positive_definite_problem(np.random.default_rng(seed), m)
    solution = ProxsuiteLCPSolver().solve(D, b)
    reference = solve_lcp_lemke(D, b)
    _assert_valid_solution(D, b, solution)
    error = _relative_error(solution.impulses, reference.impulses, np.abs(reference.impulses).max())
    assert error / _TOLERANCE <= 1.0, f"impulse error {error:.3g}"


@pytest.mark.parametrize("seed", _SEEDS)
@pytest.mark.parametrize("m", [s for s in _SIZES if s > 1])
@pytest.mark.parametrize("dof", ["one", "third", "all_but_one"])
def test_redundant_contacts_velocities_match_lemke(seed: int, m: int, dof: str) -> None:
    n = {"one": 1, "third": max(1, m // 3), "all_but_one": m - 1}[dof]
    problem = _redundant_contact_problem(np.random.default_rng(seed), m, n)
    D, b = problem.D, problem.b
    assert np.linalg.matrix_rank(D) <= n < m
    solution = ProxsuiteLCPSolver().solve(D, b)
    reference = solve_lcp_lemke(D, b)
    _assert_valid_solution(D, b, solution)
    assert reference.residual < _RESIDUAL_TOLERANCE
    scale = float(np.abs(b).max())
    error = _relative_error(solution.velocity, reference.velocity, scale)
    assert error / _TOLERANCE <= 1.0, f"constraint velocity error {error:.3g}"
    v, v_reference = problem.velocity(solution.impulses), problem.velocity(reference.impulses)
    error = _relative_error(v, v_reference, float(np.abs(v_reference).max()))
    assert error / _TOLERANCE <= 1.0, f"generalized velocity error {error:.3g}"


@pytest.mark.parametrize("seed", _SEEDS)
@pytest.mark.parametrize("kind", ["positive_definite", "redundant"])
def test_warm_started_sequence_stays_correct(seed: int, kind: str) -> None:
    # One solver, slowly varying problems of one size (as in a simulation), interleaved with
    # problems of another size that use a second cached QP object.
    rng = np.random.default_rng(seed)
    m = 8
    solver = ProxsuiteLCPSolver()
    if kind == "positive_definite":
        A = rng.standard_normal((m, m))
        b = rng.standard_normal(m)
    else:
        problem = _redundant_contact_problem(rng, m, 3)
        A = problem.J @ np.linalg.cholesky(np.linalg.inv(problem.M))
        b = problem.b
    other_D, other_b = _positive_definite_problem(rng, 3)
    for step in range(40):
        A = A + 1e-2 * rng.standard_normal(A.shape)
        D = A @ A.T + (0.1 * np.eye(m) if kind == "positive_definite" else 0.0)
        if kind == "positive_definite":
            b = b + 5e-2 * rng.standard_normal(m)
        else:  # stay solvable: b in range(A) plus non-negative gap rates
            b = A @ rng.standard_normal(A.shape[1]) + np.maximum(rng.standard_normal(m), 0.0)
        solution = solver.solve(D, b)
        _assert_same_velocities(D, b, solution)
        if kind == "positive_definite":
            reference = solve_lcp_lemke(D, b)
            scale = float(np.abs(reference.impulses).max())
            assert _relative_error(solution.impulses, reference.impulses, scale) <= _TOLERANCE
        if step % 10 == 0:
            _assert_same_velocities(other_D, other_b, solver.solve(other_D, other_b))


@pytest.mark.parametrize("m", [1, 4, 12])
def test_nonnegative_b_gives_zero_impulses(m: int) -> None:
    rng = np.random.default_rng(m)
    D, b = _positive_definite_problem(rng, m)
    b_open = np.abs(b)
    b_open[0] = 0.0  # a contact exactly at rest needs no impulse either
    cold = ProxsuiteLCPSolver().solve(D, b_open)
    np.testing.assert_allclose(cold.impulses, 0.0, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(cold.velocity, b_open, rtol=0.0, atol=1e-12)
    assert solve_lcp_lemke(D, b_open).pivots == 0
    # Warm-started from a solution with active contacts.
    solver = ProxsuiteLCPSolver()
    solver.solve(D, -np.abs(b))
    warm = solver.solve(D, b_open)
    np.testing.assert_allclose(warm.impulses, 0.0, rtol=0.0, atol=1e-12)
    _assert_valid_solution(D, b_open, warm)


def _two_link_problem(
    robot: RobotModel, rng: np.random.Generator, q: np.ndarray, m: int = 4
) -> _ContactProblem:
    """Constraints along m unit directions on the arm's end-effector: m > nv = 2."""
    J_xy = robot.frame_jacobian(q, "end_effector")[:2]  # planar linear velocity, (2, nv)
    angles = rng.uniform(0.0, 2.0 * np.pi, size=m)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])  # (m, 2) unit rows
    J = directions @ J_xy  # (m, nv)
    M = robot.mass_matrix(q)
    v_free = rng.standard_normal(robot.nv)
    v_k = rng.standard_normal(robot.nv)
    restitution = rng.uniform(0.0, 1.0)
    b = J @ (v_free + restitution * v_k)
    return _ContactProblem(J=J, M=M, v_free=v_free, b=b)


@pytest.fixture(scope="module")
def two_link() -> RobotModel:
    return RobotModel.from_urdf(_TWO_LINK_URDF)


@pytest.mark.parametrize("seed", range(10))
def test_two_link_end_effector_contacts_match_lemke(two_link: RobotModel, seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = np.array([rng.uniform(0.0, np.pi), rng.uniform(-np.pi + 0.1, -0.1)])
    problem = _two_link_problem(two_link, rng, q)
    D, b = problem.D, problem.b
    assert D.shape == (4, 4)
    assert np.linalg.matrix_rank(D) == two_link.nv == 2
    solution = ProxsuiteLCPSolver().solve(D, b)
    reference = solve_lcp_lemke(D, b)
    _assert_valid_solution(D, b, solution)
    v, v_reference = problem.velocity(solution.impulses), problem.velocity(reference.impulses)
    error = _relative_error(v, v_reference, float(np.abs(v_reference).max()))
    assert error / _TOLERANCE <= 1.0, f"joint velocity error {error:.3g} rad/s"
    error = _relative_error(solution.velocity, reference.velocity, float(np.abs(b).max()))
    assert error / _TOLERANCE <= 1.0, f"constraint velocity error {error:.3g} m/s"


def test_two_link_along_a_motion_with_one_solver(two_link: RobotModel) -> None:
    rng = np.random.default_rng(42)
    solver = ProxsuiteLCPSolver()
    for t in np.linspace(0.0, 1.0, 30):
        q = np.array([0.5 + 1.5 * t, -2.5 + 2.0 * t])
        problem = _two_link_problem(two_link, rng, q)
        solution = solver.solve(problem.D, problem.b)
        _assert_same_velocities(problem.D, problem.b, solution)
        reference = solve_lcp_lemke(problem.D, problem.b)
        v, v_reference = problem.velocity(solution.impulses), problem.velocity(reference.impulses)
        assert _relative_error(v, v_reference, float(np.abs(v_reference).max())) <= _TOLERANCE


def test_checks_reject_a_wrong_solution() -> None:
    # The comparisons above can fail: a slightly wrong impulse is caught.
    D, b = _positive_definite_problem(np.random.default_rng(0), 5)
    solution = ProxsuiteLCPSolver().solve(D, b)
    impulses = solution.impulses + 1e-6 * (solution.impulses > 0)
    wrong = ContactSolution(
        impulses=impulses,
        velocity=D @ impulses + b,
        status="solved",
        iterations=0,
        residual=complementarity_residual(D, b, impulses),
        solve_time_s=0.0,
    )
    with pytest.raises(AssertionError):
        _assert_same_velocities(D, b, wrong)


def test_redundant_contacts_polish_keeps_separating_contacts_free() -> None:
    # Least squares on the singular active set gives a negative minimum-norm solution here.
    rng = np.random.default_rng(101)
    m = 5
    r = int(rng.integers(1, m))  # 2
    A = rng.standard_normal((m, r))
    D = A @ A.T
    b = A @ rng.standard_normal(r) + np.maximum(rng.standard_normal(m), 0.0)
    _assert_same_velocities(D, b, ProxsuiteLCPSolver().solve(D, b))
