"""The flexible-joint law: references and their exact derivatives, the closed-loop identity."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest
from flexible_arm import (
    GAINS,
    GROUND,
    MOTOR_INERTIA,
    Q0,
    TAU0,
    contact_state,
    controller,
    free_motion_input,
    initial_state,
    plant,
    task_position,
)
from scipy.integrate import solve_ivp

from ucontrol.control import FlexibleBrogliatoController, Phase
from ucontrol.control.brogliato_controller import LOG_FIELDS
from ucontrol.control.flexible_brogliato_controller import FLEXIBLE_LOG_FIELDS
from ucontrol.log import Log

#: Both joints flexible (the reference cases), or the elbow only (the shoulder is rigid).
JOINTS = [("shoulder", "elbow"), ("elbow",)]


def _references(law: FlexibleBrogliatoController, times, x: np.ndarray, contacts=None):
    """(link_desired, motor_desired) after a call at each of ``times`` at state ``x``."""
    nq = law.robot.nq + law.flexible.nf
    out = []
    for t in times:
        law(t, x[:nq], x[nq:], contacts or contact_state())
        out.append((law.link_desired, law.motor_desired))
    return out


def _assert_derivative(derivative: np.ndarray, samples: list, h: float, rtol: float) -> None:
    """``derivative`` is the 4th-order central difference of f(t - 2h), ..., f(t + 2h)."""
    difference = (samples[0] - 8 * samples[1] + 8 * samples[3] - samples[4]) / (12 * h)
    scale = max(1.0, float(np.max(np.abs(derivative))))
    np.testing.assert_allclose(derivative, difference, rtol=0.0, atol=rtol * scale)


def _rigid_law(law: FlexibleBrogliatoController, x: np.ndarray) -> np.ndarray:
    """U_R in free motion from Pinocchio: M ddq1r + C dq1r + g - γ1 s1, shape (nv,)."""
    arm, nv = law.robot, law.robot.nv
    q1, dq1 = x[:nv], x[nv + law.flexible.nf : 2 * nv + law.flexible.nf]
    q1d, dq1d, ddq1d = law.link_desired[:3]
    data = pin.Data(arm.model)
    M = pin.crba(arm.model, data, q1)
    M = np.triu(M) + np.triu(M, 1).T
    C = pin.computeCoriolisMatrix(arm.model, data, q1, dq1)
    g = pin.computeGeneralizedGravity(arm.model, data, q1)
    g1, g2 = GAINS.gamma1, GAINS.gamma2
    s1 = dq1 - dq1d + g2 * (q1 - q1d)
    return M @ (ddq1d - g2 * (dq1 - dq1d)) + C @ (dq1d - g2 * (q1 - q1d)) + g - g1 * s1


@pytest.mark.parametrize("t", [1.0, TAU0 + 0.3])
def test_link_reference_inverts_the_task_map_with_exact_derivatives(t: float) -> None:
    # Free motion, then the approach (virtual target below the ground, frozen tangent).
    law = controller()
    x = np.concatenate([Q0, Q0, np.zeros(4)])
    h = 1e-4
    _references(law, np.arange(0.0, t - 0.01, 0.05), x)
    link = [sample[0] for sample in _references(law, t + h * np.arange(-2, 3), x)]
    assert law.phase is (Phase.FREE if t < TAU0 else Phase.APPROACH)
    target = law.machine.desired(t).target
    np.testing.assert_allclose(task_position(law.robot, law, link[2][0]), target[0], atol=1e-12)
    for k in range(4):
        _assert_derivative(link[2][k + 1], [sample[k] for sample in link], h, 1e-7)


def test_motor_reference_and_its_derivatives_along_the_closed_loop(
    rng: np.random.Generator,
) -> None:
    # q2d = S q1d + K⁻¹ S U_R, and dq2d, ddq2d are its time derivatives along the smooth
    # closed loop (integrated by scipy at rtol = 1e-12, free motion).
    law = controller()
    input_of = free_motion_input(law)
    rhs = plant(law, input_of)
    t0, h = 1.0, 1e-4
    states = [initial_state(law, rng)]
    for k in range(4):
        span = (t0 + k * h, t0 + (k + 1) * h)
        solution = solve_ivp(rhs, span, states[-1], method="DOP853", rtol=1e-12, atol=1e-14)
        states.append(solution.y[:, -1])
    motor = []
    for k, x in enumerate(states):
        input_of(t0 + k * h, x)
        motor.append(law.motor_desired)
        U_R = _rigid_law(law, x)
        np.testing.assert_allclose(
            law.flexible.stiffness * (law.motor_desired[0] - law.link_desired[0]), U_R, rtol=1e-12
        )
    for k in range(2):
        _assert_derivative(motor[2][k + 1], [sample[k] for sample in motor], h, 1e-6)


def test_motor_reference_derivatives_with_a_contact_force(rng: np.random.Generator) -> None:
    # Constrained phase, desired force falling to 0 at t_d = 10 s, the ground pushing with
    # λ(t) = 4 N + λ_d(t) - λ_d(9.7 s), which falls as λ_d does, as the law assumes of the
    # measured force (its value is used, its derivatives are those of λ_d): the derivatives of
    # q2d hold those of λ_d and of J_c. The law is stateful, so the plant is integrated by RK4
    # (non-decreasing call times), and it is given the ground force of each call time.
    law = controller()
    x = np.concatenate([Q0, Q0, np.zeros(4)])
    _references(law, np.arange(0.0, 5.0, 0.01), x)
    _references(law, np.arange(5.0, 9.7, 0.01), x, contact_state(4.0))
    assert law.phase is Phase.CONSTRAINED and law.desired.force_derivatives[0][0] < 0.0
    phase = law.cycle.contact_phases[0]

    def force(t: float) -> float:
        """The ground force at ``t`` [s], in [N]."""
        desired = law.cycle.desired_force(phase, t, 10.0)
        return 4.0 + desired - law.cycle.desired_force(phase, 9.7, 10.0)

    nq = law.robot.nq + law.flexible.nf
    rhs = plant(law, lambda t, y: law(t, y[:nq], y[nq:], contact_state(force(t))), force)
    h, steps = 5e-5, 5  # [s], RK4 steps per difference step
    times = 9.7 + h / steps * np.arange(4 * steps + 1)
    x = initial_state(law, rng)
    motor = []
    for i, (t, t_next) in enumerate(itertools.pairwise(times)):
        if i % steps == 0:
            motor.append(_references(law, [t], x, contact_state(force(t)))[0][1])
        step = t_next - t
        k1 = rhs(t, x)
        k2 = rhs(t + step / 2, x + step / 2 * k1)
        k3 = rhs(t + step / 2, x + step / 2 * k2)
        k4 = rhs(t_next, x + step * k3)
        x = x + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    motor.append(_references(law, [times[-1]], x, contact_state(force(times[-1])))[0][1])
    for k in range(2):
        _assert_derivative(motor[2][k + 1], [sample[k] for sample in motor], h, 1e-6)


@pytest.mark.parametrize("joints", JOINTS)
def test_lyapunov_derivative_in_free_motion(
    joints: tuple[str, ...], rng: np.random.Generator
) -> None:
    # dV/dt along the exact closed loop (central difference along the vector field) is
    # -γ1 (|dq̃1|² + γ2²|q̃1|² + |dq̃2|² + γ2²|q̃2|²) - γ2 eᵀ K e, e = S q̃1 - q̃2.
    law = controller(joints)
    input_of = free_motion_input(law)
    rhs = plant(law, input_of)
    g1, g2 = GAINS.gamma1, GAINS.gamma2
    nv, nf = law.robot.nv, law.flexible.nf
    K, h = law.flexible.stiffness, 1e-5
    for t in (0.3, 1.7, 3.1):
        x = initial_state(law, rng)
        dx = rhs(t, x)
        q1_error = x[:nv] - law.link_desired[0]
        dq1_error = x[nv + nf : 2 * nv + nf] - law.link_desired[1]
        q2_error = x[nv : nv + nf] - law.motor_desired[0]
        dq2_error = x[2 * nv + nf :] - law.motor_desired[1]
        e = q1_error[law.flexible.v_index] - q2_error
        expected = -g1 * (
            dq1_error @ dq1_error
            + g2**2 * q1_error @ q1_error
            + dq2_error @ dq2_error
            + g2**2 * q2_error @ q2_error
        ) - g2 * e @ (K * e)
        input_of(t + h, x + h * dx)
        V_plus = law.V
        input_of(t - h, x - h * dx)
        measured = (V_plus - law.V) / (2 * h)
        assert expected < 0.0
        assert measured == pytest.approx(expected, rel=1e-6)


@pytest.mark.slow
def test_closed_loop_tracks_the_circle_with_v_decreasing() -> None:
    # DESIGN's flexible case from q0 = (0.9, -1.5, 0.9, -1.5) at rest, free motion until τ0.
    law = controller()
    input_of = free_motion_input(law)
    rhs = plant(law, input_of)
    x0 = np.concatenate([Q0, Q0, np.zeros(4)])
    duration = 2.0  # [s]
    solution = solve_ivp(
        rhs, (0.0, duration), x0, method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True
    )
    assert solution.success
    times = np.linspace(0.0, duration, 201)
    V, errors = [], []
    for t in times:
        x = solution.sol(t)
        input_of(t, x)
        V.append(law.V)
        X = task_position(law.robot, law, x[:2])
        errors.append(np.linalg.norm(X - law.machine.desired(t).target[0]))
    V = np.array(V)
    assert np.all(np.diff(V) <= 1e-12 * V[0])  # non-increasing between samples
    assert V[-1] < 1e-8 * V[0]
    assert errors[0] > 0.1 and errors[-1] < 1e-5  # [m]


def test_stiff_joints_limit_is_the_rigid_law_with_motor_inertia(rng: np.random.Generator) -> None:
    # With q2 = S q1 + K⁻¹ U_R and dq2 = S dq1, u(K) -> (M + B) ddq1r + C dq1r + g - 2 γ1 s1
    # as K -> ∞ (the rigid joint-space law for the links plus the motors), with an O(1/K) gap.
    x = initial_state(controller(), rng)
    t, nv = 1.0, 2
    stiffnesses = np.array([1e3, 1e4, 1e5, 1e6])  # [N m/rad]
    gaps = []
    for stiffness in stiffnesses:
        law = controller(stiffness=stiffness)
        input_of = free_motion_input(law)
        input_of(t, x)  # the link reference does not depend on q2
        U_R = _rigid_law(law, x)
        x[nv : 2 * nv] = x[:nv] + U_R / stiffness
        x[3 * nv :] = x[2 * nv : 3 * nv]
        u = input_of(t, x)
        q1, dq1 = x[:nv], x[2 * nv : 3 * nv]
        q1d, dq1d, ddq1d = law.link_desired[:3]
        s1 = dq1 - dq1d + GAINS.gamma2 * (q1 - q1d)
        ddq1_r = ddq1d - GAINS.gamma2 * (dq1 - dq1d)
        rigid = U_R + MOTOR_INERTIA * ddq1_r - GAINS.gamma1 * s1
        gaps.append(np.linalg.norm(u - rigid) / np.linalg.norm(rigid))
    assert gaps[-1] < 1e-3
    np.testing.assert_allclose(gaps * stiffnesses, gaps[-1] * stiffnesses[-1], rtol=0.01)


def test_log_fields_of_the_flexible_law() -> None:
    law = controller()
    log = Log(2, nq=2, nv=2, nu=2, constraint_names=[GROUND])  # links only, as simulate
    law.prepare_log(log)
    u = law(0.0, np.concatenate([Q0, Q0]), np.zeros(4), contact_state())
    law.record(log)
    log.record_step(u, np.zeros(1), np.zeros(1, dtype=bool), 0, 0.0)
    assert set(LOG_FIELDS) | set(FLEXIBLE_LOG_FIELDS) <= set(log.fields)
    np.testing.assert_array_equal(log.motor_desired[0], law.motor_desired[0])
    np.testing.assert_array_equal(log.link_desired[0], law.link_desired[0])
    assert log.V[0] == law.V > log.V1[0] == law.V1 > 0.0
    np.testing.assert_allclose(log.task_position[0], task_position(law.robot, law, Q0))
    assert log.metadata["controller"] == "flexible_brogliato"
