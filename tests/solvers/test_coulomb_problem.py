"""The Coulomb problem's natural-map residual and cone projection, against their definitions."""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.solvers import CoulombProblem, complementarity_residual
from ucontrol.solvers.coulomb_problem import FLOAT_OPS, NUMPY_OPS, project_on_cone

_ROUND_OFF = 1e-14  # [m/s] on problems of unit scale


def _single(mu: float, D: np.ndarray, b: np.ndarray) -> CoulombProblem:
    """One contact with len(b) - 1 tangential rows."""
    return CoulombProblem(D, b, np.array([mu]), np.array([b.size - 1]))


def test_frictionless_residual_is_the_lcp_natural_map() -> None:
    rng = np.random.default_rng(0)
    A = rng.standard_normal((5, 5))
    D = A @ A.T + np.eye(5)
    b = rng.standard_normal(5)
    problem = CoulombProblem(D, b, np.full(5, 0.7), np.zeros(5, dtype=int))  # mu ignored
    for _ in range(10):
        P = np.maximum(rng.standard_normal(5), 0.0)
        assert problem.residual(P) == pytest.approx(complementarity_residual(D, b, P), abs=1e-15)


@pytest.mark.parametrize("tangents", [1, 2])
def test_residual_vanishes_at_the_three_statuses(tangents: int) -> None:
    D = np.eye(1 + tangents)
    mu = 0.5
    # separating: P = 0, u_n > 0, any u_t
    b = np.array([1.0, 2.0, -1.0][: 1 + tangents])
    assert _single(mu, D, b).residual(np.zeros(1 + tangents)) <= _ROUND_OFF
    # sticking: u = 0 with |P_t| < mu P_n
    b = np.array([-1.0, 0.3, -0.2][: 1 + tangents])
    assert _single(mu, D, b).residual(-b) <= _ROUND_OFF
    # sliding: u_n = 0, P_t = -mu P_n u_t / |u_t|
    b = np.array([-1.0, 2.0, 1.0][: 1 + tangents])
    direction = b[1:] / np.linalg.norm(b[1:])
    P = np.concatenate(([1.0], -mu * direction))
    problem = _single(mu, D, b)
    u = problem.velocity(P)
    assert u[0] == pytest.approx(0.0, abs=1e-15)
    assert np.allclose(u[1:] / np.linalg.norm(u[1:]), direction)
    assert problem.residual(P) <= _ROUND_OFF


@pytest.mark.parametrize(
    ("P", "reason"),
    [
        ([1.0, 0.8], "outside the cone"),
        ([1.0, 0.2], "sticks while sliding"),
        ([1.0, 0.5], "friction along the sliding velocity"),
        ([0.0, 0.0], "lets the contact penetrate"),
    ],
)
def test_residual_is_positive_away_from_a_solution(P: list[float], reason: str) -> None:
    problem = _single(0.5, np.eye(2), np.array([-1.0, 2.0]))
    assert problem.residual(np.array(P)) > 0.01, reason


def project_on_cones(z_n: np.ndarray, z_t: np.ndarray, mu: np.ndarray) -> tuple:
    """:func:`project_on_cone` on numpy arrays of contacts: normal (m,), tangential (m, 2)."""
    p_n, p_1, p_2 = project_on_cone(NUMPY_OPS, z_n, z_t[:, 0], z_t[:, 1], mu)
    return p_n, np.column_stack((p_1, p_2))


def test_projection_on_cones() -> None:
    rng = np.random.default_rng(1)
    mu = rng.uniform(0.0, 1.5, 200)
    z_n, z_t = rng.standard_normal(200), rng.standard_normal((200, 2))
    p_n, p_t = project_on_cones(z_n, z_t, mu)
    assert np.all(np.linalg.norm(p_t, axis=1) <= mu * p_n + 1e-12)  # in the cone
    again = project_on_cones(p_n, p_t, mu)  # idempotent
    assert np.allclose(again[0], p_n) and np.allclose(again[1], p_t)
    # Moreau: z - p is in the polar cone and orthogonal to p
    r_n, r_t = z_n - p_n, z_t - p_t
    assert np.allclose(r_n * p_n + np.sum(r_t * p_t, axis=1), 0.0, atol=1e-12)
    assert np.all(mu * np.linalg.norm(r_t, axis=1) <= -r_n + 1e-12)


def test_layout_and_gathers() -> None:
    tangents = np.array([2, 0, 1])
    problem = CoulombProblem(np.eye(6), np.arange(6.0), np.array([0.5, 0.5, 0.2]), tangents)
    assert problem.m == 3 and problem.size == 6 and problem.spatial
    assert problem.tangent_rows.tolist() == [[3, 4], [6, 6], [5, 6]]
    assert problem.mu.tolist() == [0.5, 0.0, 0.2]  # no tangential row: frictionless
    assert problem.tangential(np.arange(6.0)).tolist() == [[3.0, 4.0], [0.0, 0.0], [5.0, 0.0]]
    assert problem.row_groups.tolist() == [0, 1, 2, 0, 0, 2]  # each row's contact
    closed = CoulombProblem(np.eye(8), np.zeros(8), np.array([0.5, 0.5, 0.2]), tangents, 2)
    assert closed.row_groups.tolist() == [0, 1, 2, 0, 0, 2, 3, 4]  # then the bilateral rows


def test_layouts_are_shared_read_only_and_mu_is_the_problems_own() -> None:
    """Problems of one layout share its arrays: no problem can change another's layout."""
    tangents = np.array([2, 1])
    mu = np.array([0.5, 0.2])
    first = CoulombProblem(np.eye(5), np.zeros(5), mu, tangents)
    second = CoulombProblem(2.0 * np.eye(5), np.ones(5), np.array([0.1, 0.3]), tangents.copy())
    assert second.tangent_rows is first.tangent_rows
    for array in (first.tangent_rows, first.tangents, first.equality_rows):
        with pytest.raises(ValueError, match="read-only"):
            array[...] = 0
    mu[:] = 9.0  # the caller's array: each problem keeps its own coefficients
    assert first.mu.tolist() == [0.5, 0.2] and second.mu.tolist() == [0.1, 0.3]
    assert second.normal_scale.tolist() == [2.0, 2.0]


def test_bad_problems_raise() -> None:
    with pytest.raises(ShapeError, match="`b` must have shape"):
        CoulombProblem(np.eye(3), np.zeros(2), np.array([0.5]), np.array([2]))
    with pytest.raises(ShapeError, match="`D` must have shape"):
        CoulombProblem(np.eye(2), np.zeros(3), np.array([0.5]), np.array([2]))
    with pytest.raises(ShapeError, match="`mu` must have shape"):
        CoulombProblem(np.eye(3), np.zeros(3), np.array([0.5, 0.5]), np.array([2]))
    with pytest.raises(InvalidParameterError, match="`mu` must be >= 0"):
        CoulombProblem(np.eye(3), np.zeros(3), np.array([-0.5]), np.array([2]))
    with pytest.raises(InvalidParameterError, match="`tangents` must be 0, 1 or 2"):
        CoulombProblem(np.eye(4), np.zeros(4), np.array([0.5]), np.array([3]))


def _random_problem(rng: np.random.Generator, tangents: list[int], equalities: int = 0):
    """A random Coulomb problem of the layout ``tangents``, with ``equalities`` bilateral rows."""
    size = len(tangents) + sum(tangents) + equalities
    A = rng.standard_normal((size, size))
    D = A @ A.T + 0.1 * np.eye(size)
    mu = rng.uniform(0.0, 1.0, len(tangents))
    return CoulombProblem(D, rng.standard_normal(size), mu, np.array(tangents), equalities)


def test_residual_of_a_few_rows_is_the_projections_definition() -> None:
    """Problems of a few rows (Python floats) against the numpy projection of each contact."""
    rng = np.random.default_rng(2)
    for tangents, equalities in [([2], 0), ([1], 0), ([0], 0), ([2, 0, 1], 0), ([2, 2], 2)]:
        problem = _random_problem(rng, tangents, equalities)
        m, sigma = problem.m, problem.normal_scale
        for _ in range(20):
            P = rng.standard_normal(problem.size)
            P[:m] = np.abs(P[:m]) * rng.integers(0, 2, m)  # some contacts open
            u = problem.velocity(P)
            u_t = problem.tangential(u)
            z_n = sigma * P[:m] - u[:m] - problem.mu * np.linalg.norm(u_t, axis=1)
            sigma_P_t = sigma[:, None] * problem.tangential(P)
            pi_n, pi_t = project_on_cones(z_n, sigma_P_t - u_t, problem.mu)
            terms = [np.abs(sigma * P[:m] - pi_n).max(), np.abs(sigma_P_t - pi_t).max()]
            terms.append(np.abs(u[problem.size - equalities :]).max(initial=0.0))
            assert problem.residual(P) == pytest.approx(max(terms), rel=1e-14, abs=1e-15)


def test_residual_of_many_rows_is_its_contacts_largest() -> None:
    """A block-diagonal problem of 45 rows (numpy) against its blocks' own (Python floats)."""
    rng = np.random.default_rng(3)
    layout, count = [2, 1, 0, 2], 5  # 4 contacts, 9 rows per block
    blocks = [_random_problem(rng, layout) for _ in range(count)]
    n = blocks[0].size
    P_blocks = [np.abs(rng.standard_normal(n)) for _ in blocks]
    D, b, P = np.zeros((n * count, n * count)), np.zeros(n * count), np.zeros(n * count)
    for k, block in enumerate(blocks):
        rows = slice(n * k, n * k + n)
        D[rows, rows], b[rows], P[rows] = block.D, block.b, P_blocks[k]
    # The whole problem's rows: every block's normal rows, then every block's tangential rows.
    m = len(layout)
    normal = [n * k + a for k in range(count) for a in range(m)]
    tangential = [n * k + t for k in range(count) for t in range(m, n)]
    rows = np.array(normal + tangential)
    whole = CoulombProblem(
        D[np.ix_(rows, rows)],
        b[rows],
        np.concatenate([block.mu for block in blocks]),
        np.tile(layout, count),
    )
    assert whole.size > 32  # the numpy form
    expected = max(block.residual(P_k) for block, P_k in zip(blocks, P_blocks, strict=True))
    assert whole.residual(P[rows]) == pytest.approx(expected, rel=1e-13)


def test_residual_is_nan_where_an_impulse_is() -> None:
    problem = _single(0.5, np.eye(3), np.array([-1.0, 0.3, -0.2]))
    assert np.isnan(problem.residual(np.array([np.nan, 0.0, 0.0])))
    assert np.isnan(problem.residual(np.array([1.0, 0.0, np.nan])))


def test_projection_on_floats_is_the_numpy_one_bitwise() -> None:
    """One definition on two kinds of numbers, the same bits.

    Also at the apex, on the axis, for mu = 0, subnormal tangential parts and NaNs.
    """
    rng = np.random.default_rng(4)
    z = rng.standard_normal((3, 400)) * rng.choice([1e-300, 1e-8, 1.0, 1e8], (3, 400))
    mu = rng.choice([0.0, 0.3, 1.0, 2.5], 400)
    z[1:, :40] = 0.0  # on the normal axis
    z[1, 40:60], z[2, 40:60] = 5e-324, 0.0  # subnormal tangential parts
    z[0, 60:70] = np.nan
    z[1, 70:80] = np.nan
    arrays = np.array(project_on_cone(NUMPY_OPS, z[0], z[1], z[2], mu))
    floats = np.array(
        [
            project_on_cone(FLOAT_OPS, *column, aperture)
            for column, aperture in zip(z.T.tolist(), mu.tolist(), strict=True)
        ]
    ).T
    assert np.array_equal(arrays, floats, equal_nan=True)
    assert np.isnan(arrays[:, 60:80]).any(axis=0).all()  # a NaN stays a NaN


def test_within_cones_scales_only_the_tangential_impulses_outside() -> None:
    # a spatial contact outside its cone by 3e-9 (a solve accepted at its tolerance), a planar
    # one three times outside, a planar one inside, a frictionless one, one bilateral row
    tangents, mu = np.array([2, 1, 1, 0]), np.array([0.5, 0.4, 0.8, 0.0])
    problem = CoulombProblem(np.eye(9), np.zeros(9), mu, tangents, equalities=1)
    spatial = [0.06, np.sqrt((0.1 + 3e-9) ** 2 - 0.06**2)]  # bound 0.5 · 0.2 = 0.1
    P = np.array([0.2, 1.0, 0.5, 3.0, *spatial, -1.2, 0.3, 2.5])
    inside = problem.within_cones(P)
    norms = np.hypot(*problem.tangential(inside).T)
    assert np.all(norms <= mu * inside[:4] * (1.0 + 1e-15))
    assert norms[0] == pytest.approx(0.1, rel=1e-15) and inside[6] == pytest.approx(-0.4, rel=1e-15)
    assert inside[4] / inside[5] == pytest.approx(P[4] / P[5], rel=1e-15)  # the direction kept
    unchanged = [0, 1, 2, 3, 7, 8]  # the normal, inside and bilateral rows
    np.testing.assert_array_equal(inside[unchanged], P[unchanged])
    within = np.array([0.2, 1.0, 0.5, 3.0, 0.06, 0.08, 0.4, -0.4, 2.5])  # on or inside
    assert problem.within_cones(within) is within  # nothing to scale: the same array
