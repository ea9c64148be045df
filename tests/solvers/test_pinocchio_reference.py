"""Our Moreau–Jean contact step against Pinocchio 4.1's ADMM and PGS constraint solvers.

Each robot case takes one step from a state whose contacts are active and closing and compares
``MoreauJean.step`` (proxsuite) with (a) :class:`PinocchioContactSolver` fed the same Delassus
matrix D and term b, and (b) the whole step written the Pinocchio way
(:func:`pinocchio_step`: ``aba``, ``crba``, ``PointContactConstraintModel``,
``ConstraintCholeskyDecomposition``). Impulses are compared where they are unique (D positive
definite); with redundant contacts (D singular) only the post-step velocities are unique and
are compared, and every solution must satisfy complementarity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.contact import ConstraintSet, Plane, PointContact
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    NonFiniteValueError,
    ShapeError,
    SolverError,
    URDFError,
)
from ucontrol.integrators import MoreauJean
from ucontrol.model import RobotModel, example_robot_data_dir
from ucontrol.plant import PlantEvaluation
from ucontrol.scene import Scene
from ucontrol.solvers import (
    PinocchioContactSolver,
    PinocchioStepper,
    ProxsuiteLCPSolver,
    complementarity_residual,
    pinocchio_step,
    solve_lcp_lemke,
)

_TOLERANCE = 1e-6  # relative agreement of impulses [N s] and velocities [rad/s, m/s]
_RESIDUAL_TOLERANCE = 1e-9  # complementarity residual of Pinocchio's solutions [m/s]
_PIN_TOLERANCE = 1e-12  # tolerance handed to ADMM / PGS [m/s]
#: PGS within a whole step: its 1e-10 Cholesky compliance floors the residual near 1e-11.
_PGS_STEP_TOLERANCE = 1e-10
_METHODS = ("admm", "pgs")
_PANDA_URDF = "panda_description/urdf/panda.urdf"
#: Panda hand pointing down, fingers open [rad] and [m].
_PANDA_Q = np.array([0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.8, 0.04, 0.04])
_PANDA_FRAMES = ("panda_hand_tcp", "panda_leftfinger", "panda_rightfinger", "panda_link7")


def _relative_error(actual: np.ndarray, expected: np.ndarray) -> float:
    """Largest |actual - expected| over max(max |expected|, 1e-12)."""
    scale = max(float(np.max(np.abs(expected), initial=0.0)), 1e-12)
    return float(np.max(np.abs(actual - expected), initial=0.0)) / scale


@dataclass(frozen=True)
class _StepProblem:
    """The contact LCP of one Moreau–Jean step, recomputed as ``MoreauJean.step`` does."""

    indices: np.ndarray  # active constraints, (m,)
    D: np.ndarray  # (m, m) [m/s per N s]
    b: np.ndarray  # (m,) [m/s]
    v_free: np.ndarray  # (nv,)
    Minv_Jt: np.ndarray  # (nv, m)

    def velocity(self, impulses: np.ndarray) -> np.ndarray:
        """Generalized velocity after the step, shape (nv,)."""
        return self.v_free + self.Minv_Jt @ impulses


def _step_problem(integrator: MoreauJean, state: PlantEvaluation, tau: np.ndarray) -> _StepProblem:
    robot, constraints, h = integrator.robot, integrator.constraints, integrator.dt
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, state.q, state.v)
    pin.updateFramePlacements(robot.model, data)
    M = robot.mass_matrix(state.q)
    v_free = state.v + h * np.linalg.solve(M, tau - robot.nonlinear_effects(state.q, state.v))
    active = state.gap + integrator.gamma * h * state.normal_velocity <= 0.0
    indices = np.flatnonzero(active)
    J = constraints.jacobian(data, indices)
    Minv_Jt = np.linalg.solve(M, J.T)
    b = J @ v_free + constraints.restitution[indices] * state.normal_velocity[indices]
    return _StepProblem(indices, J @ Minv_Jt, b, v_free, Minv_Jt)


def _assert_same_step(
    integrator: MoreauJean,
    contacts: tuple[PointContact, ...],
    q: np.ndarray,
    v: np.ndarray,
    tau: np.ndarray,
    method: str,
    *,
    compare_impulses: bool,
) -> None:
    """MoreauJean.step against the Pinocchio adapter on (D, b) and the Pinocchio-way step."""
    state = integrator.evaluate(q, v)
    outcome = integrator.step(state, tau)
    problem = _step_problem(integrator, state, tau)
    n = len(contacts)
    assert problem.indices.size > 0 and np.all(problem.indices < n), "contacts only, active"
    assert np.all(state.normal_velocity[problem.indices] < 0.0), "closing contacts"

    solution = PinocchioContactSolver(method, tolerance=_PIN_TOLERANCE).solve(problem.D, problem.b)
    assert solution.status == "solved"
    assert solution.residual <= _RESIDUAL_TOLERANCE
    assert _relative_error(problem.velocity(solution.impulses), outcome.v) <= _TOLERANCE
    # Constraint velocities D P + b vanish on the active set: compare them on the scale of b.
    velocity_error = np.max(np.abs(solution.velocity - outcome.solution.velocity))
    assert velocity_error <= _TOLERANCE * np.max(np.abs(problem.b))

    reference = pinocchio_step(
        integrator.robot.model,
        pin.Data(integrator.robot.model),
        q,
        v,
        tau,
        integrator.dt,
        contacts,
        method=method,
        tolerance=_PIN_TOLERANCE if method == "admm" else _PGS_STEP_TOLERANCE,
        theta=integrator.theta,
        pgs_until_solved=True,
    )
    assert reference.converged
    np.testing.assert_array_equal(reference.active, outcome.active[:n])
    assert _relative_error(reference.v, outcome.v) <= _TOLERANCE
    assert _relative_error(reference.q, outcome.q) <= _TOLERANCE
    if compare_impulses:
        assert _relative_error(solution.impulses, outcome.impulse[problem.indices]) <= _TOLERANCE
        assert _relative_error(reference.impulse, outcome.impulse[:n]) <= _TOLERANCE


# --- the two-link arm of robots/two_link_drop.toml -------------------------------------------


def _two_link_on_ground() -> tuple[np.ndarray, np.ndarray]:
    """A configuration with the end effector on the ground y = 0, a velocity moving it down."""
    q1 = 0.9  # [rad]
    q = np.array([q1, np.arcsin(-np.sin(q1)) - q1])  # sin(q1) + sin(q1 + q2) = 0
    return q, np.array([-1.0, 0.5])  # [rad/s]


@pytest.mark.parametrize("method", _METHODS)
def test_two_link_impact_matches_pinocchio(two_link_scene: Scene, method: str) -> None:
    integrator = two_link_scene.build_integrator()
    q, v = _two_link_on_ground()
    state = integrator.evaluate(q, v)
    assert abs(state.gap[0]) < 1e-12 and np.all(state.gap[1:] > 0.05)  # ground only, e = 0.7
    _assert_same_step(
        integrator, two_link_scene.contacts, q, v, np.zeros(2), method, compare_impulses=True
    )
    # Newton's law at the impact: u+ = -e u-.
    integrator.reset()  # the step above left the ground contact held
    outcome = integrator.step(state, np.zeros(2))
    model = two_link_scene.robot.model
    reference = pinocchio_step(
        model, pin.Data(model), q, v, np.zeros(2), integrator.dt, two_link_scene.contacts
    )
    ground = two_link_scene.contacts[0]
    J_n = ground.surface.normal @ two_link_scene.robot.frame_jacobian(q, ground.frame)[:3]
    np.testing.assert_allclose(J_n @ reference.v, -0.7 * state.normal_velocity[0], rtol=1e-9)
    np.testing.assert_allclose(J_n @ outcome.v, J_n @ reference.v, rtol=1e-9)


@pytest.mark.parametrize("method", _METHODS)
def test_two_link_free_flight_matches_pinocchio(two_link_scene: Scene, method: str) -> None:
    integrator = two_link_scene.build_integrator()
    q, v = two_link_scene.q0, two_link_scene.v0
    outcome = integrator.step(integrator.evaluate(q, v), np.zeros(2))
    model = two_link_scene.robot.model
    reference = pinocchio_step(
        model, pin.Data(model), q, v, np.zeros(2), integrator.dt, two_link_scene.contacts
    )
    assert not outcome.active.any() and not reference.active.any()
    assert reference.iterations == 0 and reference.converged
    assert _relative_error(reference.v, outcome.v) <= 1e-12
    assert _relative_error(reference.q, outcome.q) <= 1e-12


# --- the Panda against a table ---------------------------------------------------------------


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    try:
        path = example_robot_data_dir() / _PANDA_URDF
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")
    return RobotModel.from_urdf(path)


def _panda_on_table(panda: RobotModel, n_contacts: int) -> tuple[PointContact, ...]:
    """Spheres on the first ``n_contacts`` frames of _PANDA_FRAMES, all touching the table."""
    heights = {f: panda.frame_position(_PANDA_Q, f)[2] for f in _PANDA_FRAMES[:n_contacts]}
    table_z = heights[_PANDA_FRAMES[0]] - 0.01  # [m]
    table = Plane(point=np.array([0.0, 0.0, table_z]), name="table")
    return tuple(
        PointContact(frame=frame, surface=table, radius=height - table_z)
        for frame, height in heights.items()
    )


def _panda_velocity() -> np.ndarray:
    """A seeded velocity moving the hand down onto the table [rad/s, m/s], shape (9,)."""
    v = 0.05 * np.random.default_rng(7).standard_normal(9)
    v[1] += 0.3  # shoulder pitch: the hand moves down
    return v


@pytest.mark.parametrize("method", _METHODS)
def test_panda_one_contact_matches_pinocchio(panda: RobotModel, method: str) -> None:
    contacts = _panda_on_table(panda, 1)
    integrator = MoreauJean(panda, ConstraintSet(panda, contacts), dt=1e-3)
    _assert_same_step(
        integrator,
        contacts,
        _PANDA_Q,
        _panda_velocity(),
        np.zeros(9),
        method,
        compare_impulses=True,
    )


@pytest.mark.parametrize("method", _METHODS)
def test_panda_four_redundant_contacts_match_pinocchio_velocities(
    panda: RobotModel, method: str
) -> None:
    contacts = _panda_on_table(panda, 4)
    integrator = MoreauJean(panda, ConstraintSet(panda, contacts), dt=1e-3)
    state = integrator.evaluate(_PANDA_Q, _panda_velocity())
    problem = _step_problem(integrator, state, np.zeros(9))
    assert problem.indices.size == 4
    assert np.linalg.matrix_rank(problem.D, tol=1e-10) < 4, "redundant contacts"
    _assert_same_step(
        integrator,
        contacts,
        _PANDA_Q,
        _panda_velocity(),
        np.zeros(9),
        method,
        compare_impulses=False,
    )


# --- the adapter on its own ------------------------------------------------------------------


@pytest.mark.parametrize("method", _METHODS)
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("m", [1, 2, 5, 8])
def test_adapter_matches_lemke_and_proxsuite(method: str, seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, m + 2))
    D = A @ A.T / m + 0.1 * np.eye(m)  # positive definite: unique impulses
    b = rng.standard_normal(m)
    solution = PinocchioContactSolver(method).solve(D, b)
    lemke = solve_lcp_lemke(D, b)
    proxsuite = ProxsuiteLCPSolver().solve(D, b)
    assert solution.status == "solved"
    assert solution.residual == pytest.approx(complementarity_residual(D, b, solution.impulses))
    assert solution.residual <= _RESIDUAL_TOLERANCE
    assert _relative_error(solution.impulses, lemke.impulses) <= _TOLERANCE
    assert _relative_error(solution.impulses, proxsuite.impulses) <= _TOLERANCE


def test_adapter_pgs_sweeps_until_solved() -> None:
    # pin 4.1's PGS reports convergence after one sweep here, at P = (0.5, 0.25).
    D = np.array([[2.0, 1.0], [1.0, 2.0]])
    b = np.array([-1.0, -1.0])
    solution = PinocchioContactSolver("pgs").solve(D, b)
    np.testing.assert_allclose(solution.impulses, [1.0 / 3.0, 1.0 / 3.0], rtol=1e-10)
    assert solution.iterations > 1


@pytest.mark.parametrize("method", _METHODS)
def test_adapter_reuses_its_problem_objects(method: str) -> None:
    solver = PinocchioContactSolver(method)
    D = np.array([[2.0, 1.0], [1.0, 2.0]])
    first = solver.solve(D, np.array([-1.0, -1.0]))
    second = solver.solve(D, np.array([-1.0, -1.0]))  # ADMM damped the first operator
    np.testing.assert_allclose(second.impulses, first.impulses, rtol=1e-10)
    empty = solver.solve(np.zeros((0, 0)), np.zeros(0))
    assert empty.impulses.shape == (0,) and empty.residual == 0.0


# --- errors ----------------------------------------------------------------------------------


def test_unknown_method_is_rejected() -> None:
    with pytest.raises(InvalidParameterError, match="method"):
        PinocchioContactSolver("lemke")
    with pytest.raises(InvalidParameterError, match="compliance"):
        PinocchioContactSolver("pgs", compliance=-1.0)


def test_bad_problems_are_rejected() -> None:
    solver = PinocchioContactSolver()
    with pytest.raises(ShapeError, match=r"`D` must have shape \(2, 2\)"):
        solver.solve(np.eye(3), np.ones(2))
    with pytest.raises(NonFiniteValueError, match="`D`"):
        solver.solve(np.array([[1.0, np.nan], [np.nan, 1.0]]), -np.ones(2))
    with pytest.raises(NonFiniteValueError, match="`b`"):
        solver.solve(np.eye(2), np.array([-1.0, np.inf]))


def test_unknown_contact_frame_is_rejected(two_link_scene: Scene) -> None:
    contact = PointContact(frame="no_such_frame", surface=Plane())
    with pytest.raises(FrameNotFoundError, match="end_effector"):
        PinocchioStepper(two_link_scene.robot.model, [contact], dt=1e-3)


class _FailingSolver:
    """Stands in for pin.ADMMConstraintSolver and fails like a backend error."""

    def __init__(self, size: int) -> None:
        self.size = size

    def solve(self, *args: object) -> bool:
        raise RuntimeError("backend failure")


def test_backend_failures_become_solver_errors(
    monkeypatch: pytest.MonkeyPatch, two_link_scene: Scene
) -> None:
    monkeypatch.setattr(pin, "ADMMConstraintSolver", _FailingSolver)
    with pytest.raises(SolverError, match=r"pinocchio-admm failed .*backend failure"):
        PinocchioContactSolver("admm").solve(np.eye(1), -np.ones(1))
    q, v = _two_link_on_ground()
    model = two_link_scene.robot.model
    with pytest.raises(SolverError, match="pinocchio-admm"):
        pinocchio_step(model, pin.Data(model), q, v, np.zeros(2), 1e-3, two_link_scene.contacts)
