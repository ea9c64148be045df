"""The shortcuts of the closed loop's hot paths give what the general code gives."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.exceptions import SimulationError
from ucontrol.integrators.moreau_jean import _cholesky_solve, _upper_cholesky
from ucontrol.log import Log
from ucontrol.model.compiled_function import CompiledFunction
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate


def test_extra_fields_are_the_arrays_record_extra_writes() -> None:
    log = Log(4, nq=1, nv=1, nu=1, constraint_names=["a"])
    log.add_field("phase", (), np.int64)
    log.add_field("force", (2,))
    phase, force = log.extra_fields(["phase", "force"])
    phase[0], force[0] = 3, (1.0, 2.0)  # row 0 written through the arrays
    log.record_state(0.0, np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), 0.0)
    log.record_step(np.zeros(1), np.zeros(1), np.zeros(1, dtype=bool), 0, 0.0)
    log.record_extra("phase", 5)  # row 1 through record_extra
    assert phase[1] == 5
    assert log.phase.tolist() == [3] and log.force.tolist() == [[1.0, 2.0]]


def test_upper_cholesky_solves_with_the_upper_triangle_only(rng: np.random.Generator) -> None:
    A = rng.normal(size=(5, 5))
    W = A @ A.T + 5.0 * np.eye(5)
    b, B = rng.normal(size=5), rng.normal(size=(5, 3))
    upper = np.triu(W) + np.tril(rng.normal(size=(5, 5)), -1)  # garbage below the diagonal
    factor = _upper_cholesky(upper)
    # Against numpy's dense solve of the symmetric matrix: measured 2e-16 relative.
    np.testing.assert_allclose(_cholesky_solve(factor, b), np.linalg.solve(W, b), rtol=1e-12)
    np.testing.assert_allclose(_cholesky_solve(factor, B), np.linalg.solve(W, B), rtol=1e-12)
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        _upper_cholesky(np.diag([1.0, -1.0]))


def test_free_phase_terms_are_shared_read_only_zeros() -> None:
    controller = load_scene(ROBOTS / "two_link_one_constraint.toml").build_controller()
    machine = controller.machine  # type: ignore[attr-defined]
    first, second = machine.desired(0.1), machine.desired(0.2)
    assert first.force is second.force and not first.force.flags.writeable
    assert not first.constrained.any() and not first.force.any()
    assert first.target[0] is not second.target[0]  # the trajectory itself is fresh per call
    with pytest.raises(ValueError, match="read-only"):
        first.force[0] = 1.0


def test_a_non_finite_controller_output_is_named(two_link_scene: Scene) -> None:
    # The one finiteness check per step covers the held input: a NaN torque is reported
    # as the controller's output, at the step where it was applied.
    def nan_after(t: float, q: np.ndarray, v: np.ndarray, contacts: object) -> np.ndarray:
        return np.full(2, math.nan if t >= 0.0025 else 0.0)

    with pytest.raises(SimulationError, match="controller output u") as raised:
        simulate(two_link_scene, nan_after, duration=0.01, dt=1e-3)
    assert raised.value.step == 3


@pytest.mark.parametrize("compile", [False, True])
def test_inputs_written_in_place_equal_inputs_passed(
    rng: np.random.Generator, compile: bool
) -> None:
    A, b = ca.SX.sym("A", 2, 3), ca.SX.sym("b", 3)
    f = CompiledFunction(
        ca.Function("in_place", [A, b], [ca.vertcat(A @ b, ca.sum1(b))]), compile=compile
    )
    A_value, b_value = rng.normal(size=(2, 3)), rng.normal(size=3)
    expected = np.append(A_value @ b_value, b_value.sum())  # what the function computes
    (passed,) = f(A_value, b_value)
    np.testing.assert_allclose(passed, expected, rtol=1e-14)  # measured: equal
    passed = passed.copy()
    f.input_view(0)[...] = 2.0 * A_value  # the view is the (2, 3) input, column-major
    f.input_view(1)[...] = b_value
    (in_place,) = f()
    np.testing.assert_allclose(in_place[:2], 2.0 * passed[:2], rtol=1e-14)
    assert f.input_view(0).shape == (2, 3)
