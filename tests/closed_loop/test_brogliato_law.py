"""The laws themselves: task Jacobians, the book's task-space form, the Lyapunov identity."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from brogliato_runs import scene

from ucontrol.control import BrogliatoController, ContactState, TaskCoordinates
from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

_LWA = pin.LOCAL_WORLD_ALIGNED


def _controller(name: str) -> BrogliatoController:
    if name == "panda_table":
        try:
            example_robot_data_dir()
        except URDFError:
            pytest.skip("example-robot-data is not installed (extra `robots`)")
    controller = scene(name).build_controller()
    assert isinstance(controller, BrogliatoController)
    return controller


def _no_contact(controller: BrogliatoController) -> ContactState:
    n = len(controller.machine.contacts)
    zeros = np.zeros(n)
    return ContactState(controller.machine.contacts, zeros, zeros, zeros, zeros > 0, 1e-3)


def _state_near(
    controller: BrogliatoController, q0: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    q = q0 + 0.05 * rng.standard_normal(q0.shape)
    return q, 0.3 * rng.standard_normal(controller.robot.nv)


def _task(controller: BrogliatoController, q: np.ndarray, v: np.ndarray):
    model = controller.robot.model
    data = pin.Data(model)
    pin.computeAllTerms(model, data, q, v)
    pin.computeJointJacobiansTimeVariation(model, data, q, v)
    pin.updateFramePlacements(model, data)
    return controller.task.evaluate(model, data, v), data


@pytest.mark.parametrize("name", ["two_link_one_constraint", "panda_table"])
def test_task_jacobian_and_its_derivative_match_finite_differences(
    name: str, rng: np.random.Generator
) -> None:
    controller = _controller(name)
    model, task = controller.robot.model, controller.task
    q, v = _state_near(controller, scene(name).q0, rng)
    state, _ = _task(controller, q, v)
    eps = 1e-6

    def X_at(qk: np.ndarray) -> np.ndarray:
        return _task(controller, qk, v)[0].X

    for k in range(model.nv):
        dq = np.zeros(model.nv)
        dq[k] = eps
        column = (X_at(pin.integrate(model, q, dq)) - X_at(pin.integrate(model, q, -dq))) / (
            2 * eps
        )
        np.testing.assert_allclose(state.J[:, k], column, atol=1e-8)
    J_plus = _task(controller, pin.integrate(model, q, eps * v), v)[0].J
    J_minus = _task(controller, pin.integrate(model, q, -eps * v), v)[0].J
    np.testing.assert_allclose(state.dJ, (J_plus - J_minus) / (2 * eps), atol=1e-7)
    np.testing.assert_allclose(state.dX, state.J @ v)
    assert state.X.shape == (task.m,) and task.n_gaps == 1


def test_square_task_law_is_the_book_task_space_slotine_li_law(rng: np.random.Generator) -> None:
    # τ = Jᵀ (M̄ ddX_r + C̄ dX_r + ḡ − γ1 s) with M̄ = J⁻ᵀ M J⁻¹, C̄ = J⁻ᵀ (C − M J⁻¹ J̇) J⁻¹,
    # ḡ = J⁻ᵀ g (Brogliato ch. 8) in free motion.
    controller = _controller("two_link_one_constraint")
    model, gains = controller.robot.model, controller.gains
    t = 1.0  # [s], free phase
    q, v = _state_near(controller, scene("two_link_one_constraint").q0, rng)
    tau = controller(t, q, v, _no_contact(controller))
    state, data = _task(controller, q, v)
    X_d, dX_d, ddX_d = controller.machine.desired(t).target
    M = np.triu(data.M) + np.triu(data.M, 1).T
    C = pin.computeCoriolisMatrix(model, data, q, v)
    g = pin.computeGeneralizedGravity(model, data, q)
    J, dJ = state.J, state.dJ
    J_inv = np.linalg.inv(J)
    M_bar = J_inv.T @ M @ J_inv
    C_bar = J_inv.T @ (C - M @ J_inv @ dJ) @ J_inv
    g_bar = J_inv.T @ g
    X_tilde = state.X - X_d
    s = state.dX - dX_d + gains.gamma2 * X_tilde
    dX_r = dX_d - gains.gamma2 * X_tilde
    ddX_r = ddX_d - gains.gamma2 * (state.dX - dX_d)
    book = J.T @ (M_bar @ ddX_r + C_bar @ dX_r + g_bar - gains.gamma1 * s)
    np.testing.assert_allclose(tau, book, rtol=1e-10, atol=1e-10)
    assert controller.V1 == pytest.approx(0.5 * s @ M_bar @ s, rel=1e-10)
    assert controller.V == pytest.approx(
        controller.V1 + gains.gamma1 * gains.gamma2 * X_tilde @ X_tilde, rel=1e-12
    )


@pytest.mark.parametrize(("name", "t"), [("two_link_one_constraint", 1.0), ("panda_table", 0.5)])
def test_lyapunov_derivative_in_free_motion(name: str, t: float, rng: np.random.Generator) -> None:
    # Along the exact closed loop (acceleration M⁻¹ (τ − h)), the law gives
    # dV/dt = −γ1 (‖dX̃‖² + γ2² ‖X̃‖²) − γ_N ‖N s_q‖²_M, measured here by central differences.
    controller = _controller(name)
    model, gains = controller.robot.model, controller.gains
    q, v = _state_near(controller, scene(name).q0, rng)
    contact = _no_contact(controller)

    def V_after(dt: float, a: np.ndarray) -> float:
        controller.reset()
        q_dt = pin.integrate(model, q, dt * v + 0.5 * dt * dt * a)
        controller(t + dt, q_dt, v + dt * a, contact)
        return controller.V

    controller.reset()
    tau = controller(t, q, v, contact)
    state, data = _task(controller, q, v)
    M = np.triu(data.M) + np.triu(data.M, 1).T
    a = np.linalg.solve(M, tau - data.nle)
    h = 1e-5
    measured = (V_after(h, a) - V_after(-h, a)) / (2 * h)
    X_d, dX_d, _ = controller.machine.desired(t).target
    X_tilde, dX_tilde = state.X - X_d, state.dX - dX_d
    expected = -gains.gamma1 * (dX_tilde @ dX_tilde + gains.gamma2**2 * X_tilde @ X_tilde)
    if controller.task.m < model.nv:  # null-space damping of the posture task
        J = state.J
        N = np.eye(model.nv) - np.linalg.pinv(J) @ J
        dX_r = dX_d - gains.gamma2 * X_tilde
        xi = -gains.posture_gain * pin.difference(model, controller.posture, q)
        s_q = v - np.linalg.pinv(J) @ dX_r - N @ xi
        expected -= gains.null_space_gain * (N @ s_q) @ M @ (N @ s_q)
    assert expected < 0.0
    assert measured == pytest.approx(expected, rel=1e-5, abs=1e-9)


def test_task_coordinates_read_the_gaps_of_the_plant() -> None:
    variant = scene("two_link_two_constraints")
    controller = variant.build_controller()
    q = np.array([1.2, -1.9])
    state, _ = _task(controller, q, np.zeros(2))
    np.testing.assert_allclose(state.X, variant.constraints.gaps(q)[:2], atol=1e-14)
    task = TaskCoordinates(variant.robot, "end_effector", variant.contacts[:1], [[2.0, 0, 0]])
    np.testing.assert_allclose(task.A, [[0, 1, 0], [1, 0, 0]])  # normal, unit tangent
