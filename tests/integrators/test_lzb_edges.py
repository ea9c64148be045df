"""LZB impact law: malformed inputs, fixed impulse steps, friction without approach.

References: momentum conservation of a chain (internal impulses), the adaptive solution,
Newton's law for one frictionless contact, and the unchanged velocity without approach.
"""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.exceptions import InvalidParameterError, ShapeError, SolverError
from ucontrol.integrators.lzb_impact import (
    LINEAR,
    LZBImpactLaw,
    lzb_impact,
    lzb_impact_with_friction,
)


def _chain(n: int) -> np.ndarray:
    """Normal rows of a chain of n balls on a line, u_j = v_{j+1} - v_j, shape (n-1, n)."""
    J = np.zeros((n - 1, n))
    for j in range(n - 1):
        J[j, j], J[j, j + 1] = -1.0, 1.0
    return J


def test_a_step_cap_below_one_is_named():
    with pytest.raises(InvalidParameterError, match="max_steps") as caught:
        LZBImpactLaw(max_steps=0)
    assert caught.value.value == 0


@pytest.mark.parametrize("kind", ["adaptive", "fixed", "friction", "function"])
def test_max_steps_caps_every_integration_of_the_law(kind: str) -> None:
    # three equal balls, the first at 1 m/s: a chain impact of several steps; with friction
    # the tangential rows are those of a fourth coordinate, decoupled (M diagonal), at rest
    M, J, v_minus = np.eye(4), np.hstack((_chain(3), np.zeros((2, 1)))), np.eye(4)[0]
    J_t = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]])

    def solve(max_steps: int) -> tuple[np.ndarray, int]:
        if kind == "function":
            result = lzb_impact(M, J, v_minus, restitution=0.9, max_steps=max_steps)
            return result.v, result.steps
        law = LZBImpactLaw(
            restitution=0.9,
            impulse_step=1e-3 if kind == "fixed" else None,
            max_steps=max_steps,
        )
        if kind == "friction":
            friction = lzb_impact_with_friction(law, M, J, J_t, v_minus, 0.0)
            return friction.v, friction.steps
        result = law.solve(M, J, v_minus)
        return result.v, result.steps

    v, steps = solve(100_000)
    assert steps > 2
    assert sum(v) == pytest.approx(1.0, abs=1e-9)  # momentum of equal masses, v[3] = 0
    np.testing.assert_array_equal(solve(steps)[0], v)  # the cap itself is allowed
    with pytest.raises(SolverError, match=r"max_steps = 2|after 2 impulse steps"):
        solve(2)


@pytest.mark.parametrize(
    ("M", "J", "name", "shape"),
    [
        (np.ones((2, 3)), np.ones((1, 2)), "M", (2, 3)),
        (np.eye(2), np.ones((1, 3)), "J", (1, 3)),
    ],
)
def test_inertia_and_jacobian_of_the_wrong_shape_are_named(M, J, name, shape):
    with pytest.raises(ShapeError) as caught:
        LZBImpactLaw().solve(M, J, np.zeros(2))
    assert caught.value.name == name and caught.value.shape == shape


def test_a_singular_inertia_matrix_is_named():
    with pytest.raises(InvalidParameterError, match="singular") as caught:
        LZBImpactLaw().solve(np.zeros((2, 2)), np.ones((1, 2)), np.array([0.0, -1.0]))
    assert caught.value.name == "M"


def test_a_delassus_matrix_of_the_wrong_shape_is_named():
    with pytest.raises(ShapeError) as caught:
        LZBImpactLaw().solve_contact_space(np.eye(3), np.array([-1.0, 0.0]))
    assert caught.value.name == "D" and caught.value.shape == (3, 3)


def test_fixed_steps_fly_across_an_opening_and_conserve_momentum():
    """Four balls, the last three times heavier: a contact opens and closes again."""
    M, J, v_minus = np.diag([1.0, 1.0, 1.0, 3.0]), _chain(4), np.array([1.0, 0.0, 0.0, 0.0])
    adaptive = LZBImpactLaw(restitution=0.9, exponent=LINEAR).solve(M, J, v_minus)
    fixed = LZBImpactLaw(restitution=0.9, exponent=LINEAR, impulse_step=5e-4).solve(M, J, v_minus)
    # internal impulses: the momentum is kept to round-off (measured 0)
    assert abs(np.sum(M @ fixed.v) - 1.0) < 1e-14
    # the fixed step against the adaptive solution: measured 3.8e-6
    assert np.max(np.abs(fixed.v - adaptive.v)) < 4e-5


def test_fixed_steps_without_gaps_give_newtons_rebound_on_one_contact():
    law = LZBImpactLaw(restitution=0.5, gaps=False, impulse_step=1e-3)
    result = law.solve(np.eye(1), np.eye(1), np.array([-1.0]))
    # one frictionless contact: u+ = -e u- = 0.5; measured error 1.5e-4 (first order in ΔP)
    assert abs(result.v[0] - 0.5) < 1.5e-3


def test_friction_with_tangent_rows_of_the_wrong_shape_is_named():
    with pytest.raises(ShapeError) as caught:
        lzb_impact_with_friction(
            LZBImpactLaw(), np.eye(2), np.ones((1, 2)), np.ones((2, 2)), np.zeros(2), 0.5
        )
    assert caught.value.name == "J_t" and caught.value.shape == (2, 2)


def test_friction_without_an_approaching_contact_leaves_the_velocity():
    rng = np.random.default_rng(16)
    A = rng.normal(size=(3, 3))
    M = A @ A.T + 3.0 * np.eye(3)
    J, J_t = np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]])
    v_minus = np.array([0.3, 0.2, -0.1])  # u_n = 0.2 > 0: separating
    result = lzb_impact_with_friction(LZBImpactLaw(), M, J, J_t, v_minus, 0.4)
    assert result.v.tolist() == v_minus.tolist()
    assert result.u.tolist() == [0.2] and result.u_t.tolist() == [0.3]
    assert result.impulse.tolist() == [0.0] and result.impulse_t.tolist() == [0.0]
