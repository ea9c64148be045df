"""LZB multiple impacts against independent references.

References: a compliant chain integrated in positions (balls on a line, contact force
k δ^η, no frozen configuration), Newton's law for a single frictionless contact, momentum and
energy balances, the rocking block integrated as a compliant rigid body with its true
kinematics, and Housner's ratio checked against a KKT solve of the sticking impact.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ucontrol.exceptions import InvalidParameterError, ShapeError, SolverError
from ucontrol.integrators.lzb_impact import (
    HERTZ,
    LINEAR,
    LZBImpactLaw,
    lzb_impact,
    lzb_impact_with_friction,
)

#: Agreement asked of LZB against the compliant chain (issue 13).
_CHAIN_TOLERANCE = 1e-6
_ENERGY_TOLERANCE = 1e-10


def chain_jacobian(n: int) -> np.ndarray:
    """Normal Jacobian of a chain of n balls on a line: u_j = v_{j+1} - v_j, shape (n-1, n)."""
    J = np.zeros((n - 1, n))
    for j in range(n - 1):
        J[j, j], J[j, j + 1] = -1.0, 1.0
    return J


def compliant_chain(
    masses: np.ndarray, v0: np.ndarray, stiffness: np.ndarray, exponent: float
) -> np.ndarray:
    """Velocities after the balls of a compliant chain have separated (independent reference).

    Positions x_i (gap x_{j+1} - x_j, zero at the start), force k_j max(-gap_j, 0)^η pushing
    the balls apart; integrated with DOP853 at rtol 1e-13 until every gap is open and opening.
    """
    n = masses.size

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        x, v = y[:n], y[n:]
        force = stiffness * np.maximum(x[:-1] - x[1:], 0.0) ** exponent
        a = np.zeros(n)
        a[:-1] -= force
        a[1:] += force
        return np.concatenate((v, a / masses))

    scale = (np.max(stiffness) / np.min(masses)) ** -0.5  # [s]
    y = np.concatenate((np.zeros(n), v0))
    for _ in range(200):
        y = solve_ivp(rate, (0, 5 * scale), y, method="DOP853", rtol=1e-13, atol=1e-16).y[:, -1]
        gaps, rates = y[1:n] - y[: n - 1], np.diff(y[n:])
        if np.all(gaps > 0) and np.all(rates >= 0):
            return y[n:]
    raise AssertionError("compliant chain did not separate")


@pytest.mark.parametrize("exponent", [LINEAR, HERTZ])
def test_three_ball_cradle_matches_compliant_chain(exponent: float) -> None:
    masses = np.ones(3)
    v0 = np.array([1.0, 0.0, 0.0])
    result = lzb_impact(np.diag(masses), chain_jacobian(3), v0, restitution=1.0, exponent=exponent)
    reference = compliant_chain(masses, v0, np.array([1e6, 1e6]), exponent)
    assert np.max(np.abs(result.v - reference)) <= _CHAIN_TOLERANCE
    # momentum exactly, energy for e = 1
    assert abs(result.v.sum() - 1.0) <= 1e-14
    assert abs(0.5 * result.v @ result.v - 0.5) <= _ENERGY_TOLERANCE
    assert abs(result.kinetic_change) <= _ENERGY_TOLERANCE
    if exponent == LINEAR:
        # dispersion: the striker goes back and the middle ball keeps a velocity
        assert result.v[0] < -0.1 and result.v[1] > 0.1 and result.v[2] < 0.99
    else:
        # Hertz: the last ball takes more than 98.9 % of the energy
        assert result.v[2] ** 2 > 0.989


def test_unequal_ball_hits_chain_matches_compliant_chain(rng: np.random.Generator) -> None:
    masses = np.array([2.0, 1.0, 0.5, 1.5])
    v0 = np.array([1.3, 0.0, 0.0, 0.0])
    stiffness = rng.uniform(0.5, 2.0, size=3) * 1e7
    result = lzb_impact(np.diag(masses), chain_jacobian(4), v0, stiffness=stiffness, exponent=HERTZ)
    reference = compliant_chain(masses, v0, stiffness, HERTZ)
    assert np.max(np.abs(result.v - reference)) <= _CHAIN_TOLERANCE
    assert abs(masses @ result.v - masses @ v0) <= 1e-13
    assert abs(masses @ result.v**2 - masses @ v0**2) <= 2 * _ENERGY_TOLERANCE


def test_stiffness_scale_is_irrelevant_with_equal_exponents() -> None:
    J, M, v0 = chain_jacobian(3), np.eye(3), np.array([1.0, 0.0, 0.0])
    a = lzb_impact(M, J, v0, stiffness=[1.0, 3.0], exponent=HERTZ)
    b = lzb_impact(M, J, v0, stiffness=[1e8, 3e8], exponent=HERTZ)
    assert np.max(np.abs(a.v - b.v)) <= 1e-9


@pytest.mark.parametrize("exponent", [LINEAR, HERTZ])
@pytest.mark.parametrize("e", [0.0, 0.3, 0.8, 1.0])
def test_single_contact_is_newton(exponent: float, e: float) -> None:
    """Two bodies, one frictionless contact: energetic e equals Newton's e."""
    masses = np.array([1.0, 3.0])
    v0 = np.array([2.0, -0.5])
    result = lzb_impact(np.diag(masses), chain_jacobian(2), v0, restitution=e, exponent=exponent)
    u_minus = v0[1] - v0[0]
    assert abs(result.u[0] + e * u_minus) <= 1e-10
    # energy: the contact gives back e^2 of the work it absorbed
    work_back = result.compression_work[0] - result.dissipated[0]
    assert abs(work_back - e**2 * result.compression_work[0]) <= _ENERGY_TOLERANCE
    assert abs(result.compression_work[0] - result.max_potential[0]) <= _ENERGY_TOLERANCE
    assert abs(result.kinetic_change + result.dissipated.sum()) <= _ENERGY_TOLERANCE


def test_dissipation_balances_kinetic_energy_in_chain(rng: np.random.Generator) -> None:
    e = rng.uniform(0.2, 0.9, size=4)
    masses = rng.uniform(0.5, 2.0, size=5)
    v0 = np.array([1.0, 0.0, 0.0, 0.0, -0.2])
    result = lzb_impact(np.diag(masses), chain_jacobian(5), v0, restitution=e, exponent=HERTZ)
    kinetic = 0.5 * masses @ result.v**2 - 0.5 * masses @ v0**2
    assert abs(kinetic - result.kinetic_change) <= _ENERGY_TOLERANCE
    assert abs(kinetic + result.dissipated.sum()) <= _ENERGY_TOLERANCE
    assert np.all(result.dissipated >= -_ENERGY_TOLERANCE)
    assert abs(masses @ result.v - masses @ v0) <= 1e-13
    assert np.all(result.u >= -1e-12)  # every contact separates


def test_fixed_impulse_step_converges_to_adaptive() -> None:
    J, M, v0 = chain_jacobian(3), np.eye(3), np.array([1.0, 0.0, 0.0])
    reference = lzb_impact(M, J, v0, restitution=0.9).v
    errors = [
        np.max(np.abs(lzb_impact(M, J, v0, restitution=0.9, impulse_step=dP).v - reference))
        for dP in (4e-3, 1e-3)
    ]
    assert errors[1] < errors[0] / 2.5  # at least first order in the impulse step
    assert errors[1] < 2e-3


# --- rocking block ------------------------------------------------------------------------

_MASS = 2.0  # [kg]
_SLENDER = (0.1, 0.4)  # half-width b, half-height h [m]: sin²α = 1/17 < 1/3
_SQUAT = (0.4, 0.2)  # sin²α = 0.8 > 1/3: the impact at B presses A down


def block_inertia(b: float, h: float) -> np.ndarray:
    """Inertia of the planar block in (x, z, θ): m, m, m (b² + h²) / 3, shape (3, 3)."""
    return np.diag([_MASS, _MASS, _MASS * (b**2 + h**2) / 3.0])


def block_rows(b: float, h: float, theta: float) -> np.ndarray:
    """Rows d z_corner / d(x, z, θ) of the corners A = (-b, -h) and B = (b, -h), shape (2, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[0.0, 1.0, c * px - s * pz] for px, pz in ((-b, -h), (b, -h))])


def pre_impact_velocity(b: float, h: float, omega: float) -> np.ndarray:
    """(vx, vz, ω) of the block rotating about corner A, flat (θ = 0), B landing."""
    return np.array([-h * omega, b * omega, omega])


def compliant_block(b: float, h: float, v0: np.ndarray, k: float, exponent: float) -> np.ndarray:
    """Velocity after the compliant corners (force k δ^η at each) release; true kinematics."""
    M = block_inertia(b, h)
    corners = np.array([[-b, -h], [b, -h]])

    def corner_heights(q: np.ndarray) -> np.ndarray:
        c, s = np.cos(q[2]), np.sin(q[2])
        return q[1] + s * corners[:, 0] + c * corners[:, 1]

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        q, v = y[:3], y[3:]
        force = k * np.maximum(-corner_heights(q), 0.0) ** exponent
        return np.concatenate((v, np.linalg.solve(M, block_rows(b, h, q[2]).T @ force)))

    y = np.concatenate(([0.0, h, 0.0], v0))
    T = (k / _MASS) ** -0.5
    for _ in range(200):
        y = solve_ivp(rate, (0, 10 * T), y, method="DOP853", rtol=1e-13, atol=1e-18).y[:, -1]
        q, v = y[:3], y[3:]
        if np.all(corner_heights(q) > 0) and np.all(block_rows(b, h, q[2]) @ v >= 0):
            return v
    raise AssertionError("compliant block did not release")


@pytest.mark.slow
@pytest.mark.parametrize("exponent", [LINEAR, HERTZ])
def test_squat_rocking_block_matches_compliant_block(exponent: float) -> None:
    """Frictionless LZB with two corners (both loaded), e = 1, against the compliant block."""
    b, h = _SQUAT
    v0 = pre_impact_velocity(b, h, -1.0)
    M = block_inertia(b, h)
    result = lzb_impact(M, block_rows(b, h, 0.0), v0, restitution=1.0, exponent=exponent)
    assert result.impulse[0] > 0.1 * result.impulse[1]  # a genuine double impact
    stiffness = (1e10, 1e12) if exponent == LINEAR else (1e13, 1e16)
    errors = [np.max(np.abs(compliant_block(b, h, v0, k, exponent) - result.v)) for k in stiffness]
    # the compliant block tends to LZB as its rotation during the impact vanishes
    assert errors[1] < errors[0] / 5.0
    assert errors[1] < 1e-5
    assert abs(result.kinetic_change) <= _ENERGY_TOLERANCE
    assert abs(result.v[0] - v0[0]) <= 1e-14  # frictionless: horizontal momentum unchanged


def sin2_alpha(b: float, h: float) -> float:
    return b**2 / (b**2 + h**2)


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_slender_rocking_block_ratio(e: float) -> None:
    """Slender block, frictionless: A lifts at once, LZB is Newton's law at B alone.

    Independent computation (docs/multiple_impacts.md): D_AB = (1 - 3 sin²α)/m > 0 and
    ω+/ω- = 1 - (1 + e) 6 sin²α / (1 + 3 sin²α).
    """
    b, h = _SLENDER
    v0 = pre_impact_velocity(b, h, -1.0)
    result = lzb_impact(block_inertia(b, h), block_rows(b, h, 0.0), v0, restitution=e)
    s2 = sin2_alpha(b, h)
    assert abs(result.v[2] / v0[2] - (1.0 - (1.0 + e) * 6.0 * s2 / (1.0 + 3.0 * s2))) <= 1e-10
    assert result.impulse[0] == 0.0


def housner_ratio(b: float, h: float) -> float:
    """Housner (1963): ω+/ω- = 1 - (3/2) sin²α, α = atan(b/h), rectangular block."""
    return 1.0 - 1.5 * sin2_alpha(b, h)


@pytest.mark.parametrize("dimensions", [_SLENDER, _SQUAT])
def test_housner_ratio_against_sticking_plastic_impact(dimensions: tuple[float, float]) -> None:
    """Housner's formula against a KKT solve: B plastic and sticking (x and z), A released."""
    b, h = dimensions
    v0 = pre_impact_velocity(b, h, -1.0)
    M = block_inertia(b, h)
    J_B = np.array([[1.0, 0.0, h], [0.0, 1.0, b]])  # d(x_B, z_B)/d(x, z, θ) at θ = 0
    kkt = np.block([[M, -J_B.T], [J_B, np.zeros((2, 2))]])
    v_plus = np.linalg.solve(kkt, np.concatenate((M @ v0, np.zeros(2))))[:3]
    assert abs(v_plus[2] / v0[2] - housner_ratio(b, h)) <= 1e-14


# --- bad input ----------------------------------------------------------------------------


def test_restitution_outside_unit_interval_is_refused() -> None:
    with pytest.raises(InvalidParameterError, match="restitution") as error:
        LZBImpactLaw(restitution=[0.5, 1.2])
    assert error.value.value == 1.2


def test_zero_stiffness_is_refused() -> None:
    with pytest.raises(InvalidParameterError, match="stiffness") as error:
        LZBImpactLaw(stiffness=[1.0, 0.0])
    assert error.value.value == 0.0


def test_parameter_length_must_match_contacts() -> None:
    law = LZBImpactLaw(restitution=[0.5, 0.5, 0.5])
    with pytest.raises(ShapeError):
        law.solve(np.eye(3), chain_jacobian(3), [1.0, 0.0, 0.0])


def test_step_cap_raises_solver_error() -> None:
    law = LZBImpactLaw(impulse_step=1e-3, max_steps=10)
    with pytest.raises(SolverError, match="impulse steps"):
        law.solve(np.eye(2), chain_jacobian(2), [1.0, 0.0])


def test_no_approach_no_impulse() -> None:
    result = lzb_impact(np.eye(2), chain_jacobian(2), [0.0, 1.0])
    assert np.all(result.impulse == 0.0) and result.steps == 0


def test_newton_cradle_scene_jacobians_give_the_chain_result() -> None:
    """robots/newton_cradle.toml: M and J from Pinocchio, as the event-driven integrator has."""
    import pinocchio as pin

    from tests.conftest import ROBOTS
    from ucontrol.plant import evaluate_plant
    from ucontrol.scene import Scene

    scene = Scene.from_toml(ROBOTS / "newton_cradle.toml")
    q, v = scene.initial_state()
    data = pin.Data(scene.robot.model)
    state = evaluate_plant(data, scene.constraints, None, q, v)
    J = scene.constraints.jacobian(data, [0, 1])
    M = scene.robot.mass_matrix(q)
    assert np.max(np.abs(J @ v - state.normal_velocity)) <= 1e-14
    result = LZBImpactLaw(restitution=1.0, exponent=HERTZ).solve(M, J, v)
    chain = lzb_impact(0.1 * np.eye(3), chain_jacobian(3), v, restitution=1.0, exponent=HERTZ)
    assert np.max(np.abs(result.v - chain.v)) <= 1e-12
    reference = compliant_chain(0.1 * np.ones(3), v, np.array([1e6, 1e6]), HERTZ)
    assert np.max(np.abs(result.v - reference)) <= _CHAIN_TOLERANCE


def test_contact_at_rest_with_rounding_noise_terminates() -> None:
    """A contact at rest whose velocity rounds to -1e-17 m/s (a block landing flat) is at rest.

    Independent computation: with A lifting (D_AB > 0), LZB with e = 0 is the plastic impact at
    B alone, P_B = -u_B / D_BB, and A takes no impulse.
    """
    D = np.array([[10.0, 7.0], [7.0, 10.0]]) / 17.0  # slender rocking block, m = 2 kg [1/kg]
    u_minus = np.array([-0.2301102, -1.59e-17])
    result = LZBImpactLaw(restitution=0.0).solve_contact_space(D, u_minus)
    assert abs(result.impulse[0] + u_minus[0] / D[0, 0]) <= 1e-12
    assert result.impulse[1] <= 1e-15


def test_lzb_cases_experiment_runs(tmp_path) -> None:
    from tests.conftest import load_experiment

    written = load_experiment("lzb_cases").main(["--out", str(tmp_path), "--max-balls", "3"])
    assert all(path.exists() for path in written)
    assert "Newton's cradle" in (tmp_path / "lzb_cases.md").read_text()


#: Siconos' published LZB run of a monodisperse chain of 10 steel balls (Hertz, e = 1, striker
#: at 1 m/s, fixed impulse step 1e-6 N s): velocities after the impact, from
#: siconos/siconos examples/Mechanics/ChainOfBalls/MonodisperseChainOfBalls-LZBModel.ref
#: (row t = 0.2 s; Apache-2.0).
_SICONOS_CHAIN = np.array(
    [
        -7.105929287758861e-02,
        -3.018624045788600e-02,
        -1.574960308766378e-02,
        -8.808055289868551e-03,
        -5.062343781337067e-03,
        -2.936631945849190e-03,
        -1.701856524055756e-03,
        2.624517363818925e-03,
        1.469233855937676e-01,
        9.859561210066624e-01,
    ]
)


def test_ten_ball_chain_against_siconos_reference() -> None:
    """Agreement with Siconos to its own discretization error (its energy is off by 2.6e-5)."""
    v0 = np.zeros(10)
    v0[0] = 1.0
    result = lzb_impact(np.eye(10), chain_jacobian(10), v0, restitution=1.0, exponent=HERTZ)
    siconos_energy_error = abs(_SICONOS_CHAIN @ _SICONOS_CHAIN - 1.0)
    assert siconos_energy_error > 1e-5
    assert np.max(np.abs(result.v - _SICONOS_CHAIN)) <= 1e-3
    assert abs(result.v @ result.v - 1.0) <= 1e-11  # ours conserves energy


# --- Coulomb friction -------------------------------------------------------------------------


@pytest.mark.parametrize(("mu", "e"), [(0.1, 0.5), (0.05, 0.9), (0.5, 0.5), (2.0, 0.0)])
def test_particle_oblique_impact_slides_or_sticks(mu: float, e: float) -> None:
    """A point mass hits a plane at (u_t, u_n) = (0.3, -1) m/s.

    Newton's law normally; the tangential impulse is -μ P_n while it slides, or stops the slip
    (Coulomb, analytic).
    """
    m = 2.0
    M, J, J_t = m * np.eye(2), np.array([[0.0, 1.0]]), np.array([[1.0, 0.0]])
    result = lzb_impact_with_friction(LZBImpactLaw(restitution=e), M, J, J_t, [0.3, -1.0], mu)
    P_n = m * (1.0 + e)
    assert abs(result.impulse[0] - P_n) <= 1e-10
    slip = max(0.3 - mu * P_n / m, 0.0)
    assert abs(result.u_t[0] - slip) <= 1e-10
    assert abs(result.friction_dissipated[0] - 0.5 * m * (0.3**2 - slip**2)) <= 1e-10
    normal_loss = 0.5 * m * (1.0 - e**2)
    assert abs(result.kinetic_change + normal_loss + result.friction_dissipated[0]) <= 1e-10


@pytest.mark.parametrize("dimensions", [_SLENDER, (0.15, 0.4)])
def test_rocking_block_with_sticking_friction_is_housner(dimensions: tuple[float, float]) -> None:
    """A plastic corner that sticks: LZB with Coulomb friction gives Housner's ratio."""
    b, h = dimensions
    v0 = pre_impact_velocity(b, h, -1.0)
    J_t = np.array([[1.0, 0.0, h], [1.0, 0.0, h]])  # d x_corner / d(x, z, θ) at θ = 0
    result = lzb_impact_with_friction(
        LZBImpactLaw(restitution=0.0), block_inertia(b, h), block_rows(b, h, 0.0), J_t, v0, 1.0
    )
    assert abs(result.v[2] / v0[2] - housner_ratio(b, h)) <= 1e-10
    assert abs(result.u_t[1]) <= 1e-12 and result.impulse[0] == 0.0


def test_frictionless_limit_equals_the_frictionless_law() -> None:
    b, h = _SQUAT
    v0 = pre_impact_velocity(b, h, -1.0)
    law = LZBImpactLaw(restitution=0.5)
    M, J = block_inertia(b, h), block_rows(b, h, 0.0)
    J_t = np.array([[1.0, 0.0, h], [1.0, 0.0, h]])
    with_friction = lzb_impact_with_friction(law, M, J, J_t, v0, 0.0)
    assert np.max(np.abs(with_friction.v - law.solve(M, J, v0).v)) <= 1e-10


def test_bad_friction_inputs_are_refused() -> None:
    M, J, J_t = np.eye(2), np.array([[0.0, 1.0]]), np.array([[1.0, 0.0]])
    with pytest.raises(InvalidParameterError, match="friction"):
        lzb_impact_with_friction(LZBImpactLaw(), M, J, J_t, [0.3, -1.0], -0.1)
    with pytest.raises(InvalidParameterError, match="impulse_step"):
        lzb_impact_with_friction(LZBImpactLaw(impulse_step=1e-3), M, J, J_t, [0.3, -1.0], 0.1)
