"""The generated fast paths of a step against its reference stages, step by step.

From random states and memories (the whole scenes run through both paths in
tests/test_paths_agree.py); the paths are chosen by the public switch ``compiled``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import TRACKING_SCENES, load_experiment, needs_compiled_code

from ucontrol.contact import ConstraintSet
from ucontrol.exceptions import InvalidParameterError
from ucontrol.integrators import MoreauJean
from ucontrol.integrators.compiled_free_step import CompiledFreeStep, ImpactRules
from ucontrol.integrators.step_stages import StepMemory
from ucontrol.model.joint_friction import JointFriction
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.solvers import ProxsuiteLCPSolver

pytestmark = needs_compiled_code  # every test compares a compiled path with the reference

#: (scene, with viscous joint friction): the steps that use the compiled free step.
CASES = [
    ("two_link_flexible_one_constraint", False),
    ("two_link_flexible_two_constraints", False),
    ("two_link_one_constraint", True),
    ("two_link_one_constraint", False),
    ("panda_table", True),
    ("panda_table", False),
]


def _pair(  # type: ignore[no-untyped-def]
    name: str, viscous: bool = False, theta: float | None = None, friction: float | None = None
):
    """Two integrators of scene ``name``: with the compiled free step and without it.

    ``friction``: the Coulomb coefficient of every contact instead of the scene's.
    """
    scene = load_scene(name)
    if friction is not None:
        scene = dataclasses.replace(
            scene,
            contacts=tuple(dataclasses.replace(c, friction=friction) for c in scene.contacts),
        )
    if theta is not None:
        scene = dataclasses.replace(
            scene, integrator=dataclasses.replace(scene.integrator, theta=theta)
        )
    if viscous:
        nv = scene.robot.nv
        friction = JointFriction(viscous=[0.7] * nv, coulomb=[0.0] * nv)
        scene = dataclasses.replace(scene, joint_friction=friction)
    compiled, reference = scene.build_integrator(), scene.build_integrator(compiled=False)
    assert "free step" in compiled.fast_paths and reference.fast_paths == ()
    return scene, compiled, reference


@pytest.mark.parametrize(("name", "viscous"), CASES)
def test_steps_equal_the_numpy_path(name: str, viscous: bool, rng: np.random.Generator) -> None:
    """Steps with no active row, one and several from random states: as the reference's.

    (The compiled call's active set, its one-row steps, the numpy contact step.)
    """
    scene, compiled, reference = _pair(name, viscous)
    q0, v0 = scene.initial_state()
    n = compiled.constraints.size
    seen = set()  # active rows of the steps, 2 for several
    for trial in range(20):
        q = q0 + 0.05 * rng.normal(size=q0.size)
        v = rng.normal(size=v0.size)
        tau = 5.0 * rng.normal(size=v0.size)
        # No constraint active, every one, one row held alone, or as predicted.
        memory = [np.full(n, -1e9), np.full(n, 1e9), np.full(n, -1e9), np.zeros(n)][trial % 4]
        memory[trial % n] = 1e9 if trial % 4 == 2 else memory[trial % n]
        for integrator in (compiled, reference):
            integrator.memory = StepMemory(memory, False)
        a = compiled.step(compiled.evaluate(q, v), tau)
        b = reference.step(reference.evaluate(q, v), tau)
        np.testing.assert_array_equal(a.active, b.active)
        assert a.impacts == b.impacts
        seen.add(min(int(b.active.sum()), 2))
        # Measured: v 3.2e-15 rad/s, q 6.9e-18 rad, impulses 1.8e-15 N s over the cases.
        np.testing.assert_allclose(a.v, b.v, rtol=0, atol=3e-14)
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-16)
        np.testing.assert_allclose(a.impulse, b.impulse, rtol=0, atol=2e-14)
    assert seen == ({0, 1, 2} if n > 1 else {0, 1})


@pytest.mark.parametrize("name", TRACKING_SCENES[:4])
@pytest.mark.parametrize("theta", [0.5, 1.0])
def test_single_row_steps_equal_the_numpy_path(
    name: str, theta: float, rng: np.random.Generator
) -> None:
    """One active row, held or not, restitution or not, the energy guard: as the numpy path.

    Rows other than i are kept out of the active set by a negative persistence memory; row i
    is held (memory 1e9: the closure g/h when it is open) or, where its predicted gap is
    negative, active without being held (memory 0: Newton's law on its closing speed).
    """
    scene, compiled, reference = _pair(name, theta=theta)
    assert compiled.theta == theta and "single row" in compiled.fast_paths
    q0, v0 = scene.initial_state()
    n = compiled.constraints.size
    seen = {"held": 0, "newton": 0, "plastic": 0, "impacts": 0}
    errors = {"v": 0.0, "q": 0.0, "P": 0.0, "w": 0.0}
    for _ in range(300):
        q = q0 + 0.4 * rng.normal(size=q0.size)
        v = 2.0 * rng.normal(size=v0.size)
        # Large forces now and then, for steps whose free velocity closes much faster than
        # the velocity before the step (the energy guard's case at θ = 1).
        tau = rng.choice([40.0, 4e4]) * rng.normal(size=v0.size)
        state_c, state_r = compiled.evaluate(q, v), reference.evaluate(q, v)
        predicted = state_r.gap + 0.5 * compiled.dt * state_r.normal_velocity
        bouncing = compiled.constraints.restitution.nonzero()[0]
        i = int(rng.choice(bouncing if bouncing.size and rng.random() < 0.5 else np.arange(n)))
        held = predicted[i] > 0.0 or rng.random() < 0.5
        memory = np.full(n, -1e9)
        memory[i] = 1e9 if held else 0.0
        for integrator in (compiled, reference):
            integrator.memory = StepMemory(memory, False)
        a = compiled.step(state_c, tau)
        b = reference.step(state_r, tau)
        assert a.active.sum() == 1 and a.active[i] and np.array_equal(a.active, b.active)
        assert a.plastic == b.plastic and a.solution.status == b.solution.status
        assert a.impacts == b.impacts  # the compiled impact rule's, the reference's
        seen["impacts"] += bool(b.impacts)
        seen["held" if held else "newton"] += 1
        seen["plastic"] += b.plastic
        # Errors relative to the step's scale (velocities in [rad/s] or [m/s], impulses in
        # [N s]), the reference with Pinocchio's rows and dynamics; the LCP velocity w
        # (hundreds of m/s with the large forces) measured at most 8.8e-14, a few ulp of w.
        scale_v, scale_p = 1.0 + np.abs(b.v).max(), 1.0 + np.abs(b.impulse).max()
        errors["v"] = max(errors["v"], np.abs(a.v - b.v).max() / scale_v)
        errors["q"] = max(errors["q"], np.abs(a.q - b.q).max() / scale_v)
        errors["P"] = max(errors["P"], np.abs(a.impulse - b.impulse).max() / scale_p)
        errors["w"] = max(
            errors["w"], np.abs(a.solution.velocity - b.solution.velocity).max() / scale_v
        )
    assert errors["v"] <= 1e-13 and errors["q"] <= 3e-16
    assert errors["P"] <= 2e-13 and errors["w"] <= 3e-13
    assert seen["held"] and seen["newton"] and seen["impacts"]
    if theta == 1.0 and compiled.constraints.restitution.any():
        assert seen["plastic"]  # the energy guard acted (never for one row at θ = 1/2)


@pytest.mark.parametrize(
    ("name", "friction"),
    [("table_drop", None), ("quadruped_stand", None), ("quadruped_stand", 0.7),
     ("solo_landing", None)],
)  # fmt: skip
def test_free_flyer_steps_equal_the_numpy_path(
    name: str, friction: float | None, rng: np.random.Generator
) -> None:
    """On a free-flyer root the free step gives the velocity terms (v_free, D, the impact law).

    Every foot pressed into the ground by 1 mm at the lowest, so that several rows are active.
    With friction (``solo_landing``'s four feet, the standing Solo with μ = 0.7) the contact
    steps take the tangential rows from the compiled rows and :math:`M^{-1} [J^T T^T]` and the
    Delassus matrix of all the rows from the free step; the reference from Pinocchio's frame
    Jacobians and Cholesky factor.
    """
    scene, compiled, reference = _pair(name, friction=friction)
    assert "single row" not in compiled.fast_paths  # (its q would not be on SE(3))
    assert ("tangent rows" in compiled.fast_paths) == compiled.constraints.has_friction
    model, (q0, v0) = scene.robot.model, scene.initial_state()
    n, counts = compiled.constraints.size, set()
    for trial in range(20):
        q = pin.integrate(model, q0, 0.05 * rng.normal(size=v0.size))
        q[2] -= reference.evaluate(q, v0).gap.max() + 1e-3  # [m]
        v, tau = 0.1 * rng.normal(size=v0.size), 5.0 * rng.normal(size=v0.size)
        for integrator in (compiled, reference):  # all held, or as predicted
            integrator.memory = StepMemory(np.full(n, 1e9 if trial % 2 else 0.0), False)
        a = compiled.step(compiled.evaluate(q, v), tau)
        b = reference.step(reference.evaluate(q, v), tau)
        np.testing.assert_array_equal(a.active, b.active)
        counts.add(int(np.count_nonzero(a.impulse)))
        # Measured over two seeds: v 4.4e-14 m/s, q 2.2e-16, impulses 6.5e-14 N s (the
        # minimum-norm impulses of redundant feet carry the round-off of D's factorisation).
        np.testing.assert_allclose(a.v, b.v, rtol=0, atol=2e-13)
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-15)
        np.testing.assert_allclose(a.impulse, b.impulse, rtol=0, atol=2e-13)
        if compiled.constraints.has_friction:  # [N s], world coordinates
            np.testing.assert_allclose(a.friction_impulse, b.friction_impulse, rtol=0, atol=2e-13)
    assert max(counts) >= 3  # multi-row problems among them


def test_frictional_steps_keep_the_numpy_free_step_with_viscous_joints() -> None:
    """W = M + hθD: the tangential rows' M⁻¹ [Jᵀ Tᵀ] would need W's factor: refused."""
    scene = load_scene("panda_table_friction")  # e = 0.5: rebounds through the free step
    assert "free step" in scene.build_integrator().fast_paths
    nv = scene.robot.nv
    friction = JointFriction(viscous=[0.7] * nv, coulomb=[0.0] * nv)
    assert dataclasses.replace(scene, joint_friction=friction).build_integrator().fast_paths == (
        "constraint rows", "tangent rows", "active-set start"
    )  # fmt: skip


def test_frictional_steps_with_rebounds_equal_the_numpy_path() -> None:
    """Panda's tool on the table, e = 0.5 and μ = 0.3: impacts, sliding and held steps.

    From the states of the scene's own run around its first contacts (1.65–2 s), the memory
    holding the contact or not: steps with Newton's law (rebounds, measured by the energy
    guard), held closures and open steps, each against the reference stages.
    """
    scene, compiled, reference = _pair("panda_table_friction")
    log = simulate(scene, duration=2.0, progress=False).log
    n, seen = compiled.constraints.size, {"newton": 0, "held": 0, "friction": 0}
    errors = {"v": 0.0, "P": 0.0, "friction": 0.0}
    for k in range(1650, 2000, 5):
        for held in (False, True):
            for integrator in (compiled, reference):
                integrator.memory = StepMemory(np.full(n, 1e9 if held else 0.0), False)
            q, v, t, tau = log.q[k], log.v[k], log.t[k], log.u[k]
            a = compiled.step(compiled.evaluate(q, v, t), tau)
            b = reference.step(reference.evaluate(q, v, t), tau)
            np.testing.assert_array_equal(a.active, b.active)
            assert a.plastic == b.plastic
            np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-15)
            errors["v"] = max(errors["v"], np.abs(a.v - b.v).max())
            errors["P"] = max(errors["P"], np.abs(a.impulse - b.impulse).max())
            errors["friction"] = max(
                errors["friction"], np.abs(a.friction_impulse - b.friction_impulse).max()
            )
            if b.impulse.any():
                seen["held" if held else "newton"] += 1
                seen["friction"] += bool(b.friction_impulse.any())
    # Measured: v 4.1e-13 m/s, impulses 4.7e-13 N s, friction impulses 2.6e-14 N s.
    assert errors["v"] <= 1e-12 and errors["P"] <= 1e-12 and errors["friction"] <= 1e-12
    assert min(seen.values()) >= 5


@pytest.mark.parametrize("rows", ["single_rows", "several_rows"])
def test_a_free_step_without_positions_has_no_one_row_steps(rows: str) -> None:
    """Their q_{k+1} = q_k + h v would not be on a free-flyer's SE(3): refused."""
    rules = ImpactRules(np.zeros(4), 0.0, "closing")
    with pytest.raises(InvalidParameterError, match="positions"):
        CompiledFreeStep(
            np.zeros((6, 6)), np.zeros(6), 4, dt=1e-3, theta=0.5, horizon=5e-4, flexible=None,
            viscous=None, rules=rules, positions=False, **{rows: True},
        )  # fmt: skip


def test_several_row_steps_need_several_constraints() -> None:
    rules = ImpactRules(np.zeros(1), 0.0, "closing")
    with pytest.raises(InvalidParameterError, match="several_rows"):
        CompiledFreeStep(
            np.zeros((6, 6)), np.zeros(6), 1, dt=1e-3, theta=0.5, horizon=5e-4, flexible=None,
            viscous=None, rules=rules, several_rows=True,
        )  # fmt: skip


def test_a_free_step_takes_restitutions_non_zero_where_its_own_are() -> None:
    """Rows without restitution have constant-0 rebound terms: a new one there is refused."""
    rules = ImpactRules(np.array([0.5, 0.0]), 0.0, "closing")
    step = CompiledFreeStep(
        np.zeros((2, 2), order="F"), np.zeros(2), 2, dt=1e-3, theta=0.5, horizon=5e-4,
        flexible=None, viscous=None, rules=rules,
    )  # fmt: skip
    step.use_restitution(np.array([0.9, 0.0]))
    for wrong in ([0.0, 0.0], [0.5, 0.1], [0.5]):
        with pytest.raises(InvalidParameterError, match="restitution"):
            step.use_restitution(np.array(wrong))


def _drawn(scene: Any, draw: dict[str, Any]) -> Any:
    """``scene`` with other numbers, ``draw``: "contacts", "stops" or a surface's name to entries.

    (tests/campaign/test_build_cache.py runs integrators given drawn numbers.)
    """
    contacts = []
    for contact in scene.contacts:
        surface = contact.surface
        if surface.name in draw:
            surface = dataclasses.replace(surface, **draw[surface.name])
        contacts.append(dataclasses.replace(contact, surface=surface, **draw.get("contacts", {})))
    stops = tuple(dataclasses.replace(s, **draw.get("stops", {})) for s in scene.stops)
    return dataclasses.replace(scene, contacts=tuple(contacts), stops=stops)


def test_an_integrator_refuses_constraints_that_differ_in_more_than_numbers() -> None:
    scene = load_scene("two_link_one_constraint")
    integrator = scene.build_integrator()
    plastic = _drawn(scene, {"contacts": {"restitution": 0.0}})  # no rebound terms there
    frictional = _drawn(scene, {"contacts": {"friction": 0.4}})  # tangential rows
    rolling = _drawn(scene, {"contacts": {"radius": 0.01}})
    other = load_scene("two_link_two_constraints")  # another set of contacts
    for constraints in (plastic, frictional, rolling, other):
        assert not integrator.use_constraints(constraints.constraints)
    assert integrator.constraints is scene.constraints  # unchanged
    assert integrator.use_constraints(_drawn(scene, {"contacts": {"restitution": 0.1}}).constraints)


def _panda_on_four_contacts(**options: bool) -> tuple[MoreauJean, Any]:
    """The Panda of experiments/bench_step.py pressing on a table with four contacts.

    ``options``: ``compiled`` of the integrator and ``compiled_start`` of its solver.
    """
    bench_step = load_experiment("bench_step")
    robot, contacts, control = bench_step.panda_setup(4)
    solver = ProxsuiteLCPSolver(compiled_start=options.get("compiled_start", True))
    integrator = MoreauJean(
        robot, ConstraintSet(robot, contacts), dt=1e-3, solver=solver,
        compiled=options.get("compiled", True),
    )  # fmt: skip
    return integrator, (bench_step.Q0, control)


def _several_row_cases(name: str, rng: np.random.Generator) -> Any:
    """(compiled, references, start, control) of :func:`test_several_row_steps_...`.

    The references: the numpy step (``compiled=False``) and, for the Panda, the compiled free
    step with the solver's numpy active-set start (``compiled_start=False``), each with its
    largest relative differences (v, q, P) accepted.
    """
    if name == "panda_four_contacts":
        compiled, (q, control) = _panda_on_four_contacts()
        numpy_start = _panda_on_four_contacts(compiled_start=False)[0]
        reference = _panda_on_four_contacts(compiled=False)[0]
        assert "several rows" not in numpy_start.fast_paths
        # Measured: 6.3e-12, 3.1e-15, 5.4e-12 against the numpy step (its free step's
        # round-off through a Delassus matrix of condition 1e8), 4.5e-15, 6.9e-18, 2.1e-13
        # against the numpy active-set start (Jacobi's eigenvectors against LAPACK's).
        references = ((reference, (2e-11, 1e-14, 2e-11)), (numpy_start, (2e-14, 1e-16, 1e-12)))
        v = 0.05 * rng.normal(size=q.size)
        return compiled, references, (q + 0.002 * rng.normal(size=q.size), v), control
    # The two-link arm dropped onto its two contacts (e = 0.7) and its stops, from before it
    # comes to rest on several of them (from 1.37 s on), without torques (the scene's law).
    scene = load_scene(name)
    log = simulate(scene, duration=1.3, progress=False).log
    compiled, reference = scene.build_integrator(), scene.build_integrator(compiled=False)
    start = np.asarray(log.q)[-1], np.asarray(log.v)[-1] + 0.05 * rng.normal(size=2)
    return compiled, ((reference, (1e-12, 1e-15, 1e-12)),), start, lambda q, v: np.zeros(2)


@pytest.mark.parametrize("name", ["panda_four_contacts", "two_link_drop"])
def test_several_row_steps_equal_the_numpy_path(name: str, rng: np.random.Generator) -> None:
    """Several active rows: the compiled call's solve on the held rows as the numpy paths'.

    Along the first reference's trajectory from a perturbed start (the Panda pressing on four
    contacts under its PD law; the two-link arm coming to rest on its contacts and stops),
    each step is taken by every path from the same state and memory. The compiled call's
    steps report 0 s of solve time: those (the guess right) and the others (rows closing or
    opening, rebounds under the energy guard, more active rows than the call's four slots)
    are counted, and each must occur.
    """
    compiled, references, (q, v), control = _several_row_cases(name, rng)
    assert "several rows" in compiled.fast_paths
    seen = {"compiled": 0, "contact step": 0}
    errors = [[0.0, 0.0, 0.0] for _ in references]
    for _ in range(600):
        memory, tau = references[0][0].memory, control(q, v)
        outcomes = []
        for integrator in (compiled, *(reference for reference, _ in references)):
            integrator.memory = memory
            outcomes.append(integrator.step(integrator.evaluate(q, v), tau))
        a = outcomes[0]
        q, v = outcomes[1].q, outcomes[1].v
        for b, error in zip(outcomes[1:], errors, strict=True):
            np.testing.assert_array_equal(a.active, b.active)
            assert a.impacts == b.impacts and a.plastic == b.plastic
            if b.active.sum() < 2:
                continue
            assert a.solution.status == b.solution.status == "solved"
            # The rows with an impulse are held next; the QP may leave 1e-20 N s where the
            # exact solve has 0.
            held = compiled.memory.activation > 0.0
            np.testing.assert_array_equal(held, a.impulse > 0.0)
            assert np.all(held[b.impulse > 1e-12]), (a.impulse, b.impulse)
            scale_v, scale_p = 1.0 + np.abs(b.v).max(), 1.0 + np.abs(b.impulse).max()
            error[0] = max(error[0], np.abs(a.v - b.v).max() / scale_v)
            error[1] = max(error[1], np.abs(a.q - b.q).max() / scale_v)
            error[2] = max(error[2], np.abs(a.impulse - b.impulse).max() / scale_p)
        if a.active.sum() >= 2:
            seen["compiled" if a.solution.solve_time_s == 0.0 else "contact step"] += 1
    assert seen["compiled"] >= 20 and seen["contact step"] >= 1, seen
    for error, (_, bounds) in zip(errors, references, strict=True):
        assert all(e <= bound for e, bound in zip(error, bounds, strict=True)), (error, bounds)


def _copy(array: np.ndarray | None) -> np.ndarray | None:
    return None if array is None else array.copy()


@pytest.mark.parametrize("name", ["two_link_one_constraint", "panda_table"])
def test_a_state_with_arrays_of_its_own_is_read_as_it_is(
    name: str, rng: np.random.Generator
) -> None:
    """The fast path reads q, v and the rows in place only from the last evaluation's buffers.

    A state carrying arrays of its own (another velocity, copied rows) at the same
    configuration must be stepped from its own values, as the reference does.
    """
    scene, compiled, reference = _pair(name)
    q0, v0 = scene.initial_state()
    for _ in range(5):
        q, v = q0 + 0.05 * rng.normal(size=q0.size), rng.normal(size=v0.size)
        other_v, tau = rng.normal(size=v0.size), rng.normal(size=v0.size)
        states = [integrator.evaluate(q, v) for integrator in (compiled, reference)]
        own = [  # (the reference's state has no rows: Pinocchio's data holds them)
            state._replace(v=other_v, gap=state.gap.copy(), normal_rows=_copy(state.normal_rows))
            for state in states
        ]
        for integrator in (compiled, reference):
            integrator.memory = StepMemory(np.zeros(compiled.constraints.size), False)
        a, b = compiled.step(own[0], tau), reference.step(own[1], tau)
        np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-13)  # measured at most 3e-15
        # The evaluation itself afterwards (its buffers no longer hold the rows of a call).
        for integrator in (compiled, reference):
            integrator.memory = StepMemory(np.zeros(compiled.constraints.size), False)
        a = compiled.step(compiled.evaluate(q, v), tau)
        b = reference.step(reference.evaluate(q, v), tau)
        np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-13)


def test_viscous_step_solves_the_theta_implicit_update() -> None:
    # Free of contacts, M (v+ - v) = -h (h(q, v) + D ((1 - θ) v + θ v+)): the θ-implicit
    # viscous friction of docs/friction.md, written here with numpy.
    _, compiled, _ = _pair("two_link_one_constraint", viscous=True)
    q, v = np.array([1.2, -1.0]), np.array([0.3, -0.2])
    state = compiled.evaluate(q, v)
    step = compiled.step(state, np.zeros(2))
    data = compiled.evaluation_data
    M = np.triu(data.M) + np.triu(data.M, 1).T
    h, theta, D = compiled.dt, compiled.theta, 0.7
    rhs = M @ v - h * (data.nle + (1.0 - theta) * D * v)
    expected = np.linalg.solve(M + h * theta * D * np.eye(2), rhs)
    np.testing.assert_allclose(step.v, expected, rtol=0, atol=1e-15)  # measured 0


def test_without_a_compiler_there_is_no_compiled_step(monkeypatch: pytest.MonkeyPatch) -> None:
    scene = load_scene("two_link_flexible_one_constraint")  # compiled where a compiler is
    compiled = ("constraint rows", "free step", "single row", "several rows", "active-set start")
    assert scene.build_integrator().fast_paths == compiled
    monkeypatch.setenv("UCONTROL_NO_COMPILE", "1")
    integrator = scene.build_integrator()
    assert integrator.fast_paths == ()
    q, v = scene.initial_state()  # and the numpy path steps
    assert np.all(np.isfinite(integrator.step(integrator.evaluate(q, v), np.zeros(v.size)).v))


def test_evaluations_fill_the_whole_data_once_it_is_read(rng: np.random.Generator) -> None:
    """A Panda's evaluations run the step's Pinocchio passes alone until the data is shared.

    Its energies, then (once :attr:`MoreauJean.evaluation_data` is read, as a controller
    sharing the plant's data does) the terms of ``computeAllTerms`` the step does not read
    (centre of mass, joint Jacobians, centroidal momentum matrix), against that pass.
    """
    scene, compiled, _ = _pair("panda_table")
    model = scene.robot.model
    reference = pin.Data(model)
    q0, v0 = scene.initial_state()
    for shared in (False, True):
        data = compiled.evaluation_data if shared else None
        q, v = q0 + 0.1 * rng.normal(size=q0.size), rng.normal(size=v0.size)
        pin.computeAllTerms(model, reference, q, v)
        state = compiled.evaluate(q, v)
        # (the energies equal: the same passes; measured 0 J)
        assert abs(state.kinetic_energy - reference.kinetic_energy) <= 1e-14
        assert abs(state.potential_energy - reference.potential_energy) <= 1e-14
        if data is not None:  # measured 0 apart
            np.testing.assert_allclose(data.com[0], reference.com[0], rtol=0, atol=1e-15)
            np.testing.assert_allclose(data.J, reference.J, rtol=0, atol=1e-15)
            np.testing.assert_allclose(data.Ag, reference.Ag, rtol=0, atol=1e-14)
