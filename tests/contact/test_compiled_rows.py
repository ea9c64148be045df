"""The compiled constraint rows against Pinocchio's per-contact path and finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import needs_compiled_code

from ucontrol.contact import compiled_rows as compiled_rows_module
from ucontrol.contact.compiled_rows import compiled_rows, qualifies
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.model import RobotModel
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate


def _random_state(robot, rng):  # type: ignore[no-untyped-def]
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    return q, rng.normal(size=robot.nv)


@needs_compiled_code
@pytest.mark.parametrize(
    "name",
    [
        "two_link_one_constraint",
        "panda_table",
        "panda_table_friction",  # frictional contacts: their normal rows
        "table_drop",
        "quadruped_stand",
        "solo_landing",
    ],
)  # the last three on a free-flyer root
def test_rows_equal_pinocchio_and_finite_differences(name: str, rng: np.random.Generator) -> None:
    scene = load_scene(name)
    _check_rows_against_pinocchio(scene.constraints, rng)


@needs_compiled_code
def test_rows_of_a_free_flyer_placed_away_from_the_origin(rng: np.random.Generator) -> None:
    """The root joint's placement in the world moves the rows (a URDF's is the identity)."""
    scene = load_scene("table_drop")
    model = pin.Model(scene.robot.model)
    rotation = pin.rpy.rpyToMatrix(0.3, -0.2, 0.5)
    model.jointPlacements[1] = pin.SE3(rotation, np.array([0.1, -0.2, 0.3]))
    robot = RobotModel(model, floating_base=True)
    _check_rows_against_pinocchio(ConstraintSet(robot, scene.constraints.contacts), rng)
    # A free-flyer's M and h are Pinocchio's: its rows never carry the dynamics.
    assert not compiled_rows(scene.constraints, dynamics=True).dynamics


def _check_rows_against_pinocchio(constraints: ConstraintSet, rng: np.random.Generator) -> None:
    """Compiled gaps, velocities and rows against Pinocchio's path and finite differences."""
    robot = constraints.robot
    rows = compiled_rows(constraints)
    assert rows is not None
    model, data = robot.model, pin.Data(robot.model)
    for _ in range(5):
        q, v = _random_state(robot, rng)
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        gap, velocity = constraints.evaluate(data, q, v)
        J = constraints.jacobian(data, np.arange(constraints.size))
        gap_c, velocity_c, J_c = rows(q, v)
        # Measured: 0 m, 5.6e-17 m/s and 2.8e-17 (round-off of two frame compositions).
        np.testing.assert_allclose(gap_c, gap, rtol=0, atol=1e-14)
        np.testing.assert_allclose(velocity_c, velocity, rtol=0, atol=1e-14)
        np.testing.assert_allclose(J_c, J, rtol=0, atol=1e-14)
        # The rows are the derivative of the gaps along v (central differences on the
        # configuration manifold, error ~ eps^2).
        eps = 1e-6
        for j in range(robot.nv):
            step = np.zeros(robot.nv)
            step[j] = eps
            forward, backward = pin.integrate(model, q, step), pin.integrate(model, q, -step)
            derivative = (rows(forward, v)[0] - rows(backward, v)[0]) / (2 * eps)
            np.testing.assert_allclose(derivative, J_c[:, j], rtol=0, atol=1e-8)


@needs_compiled_code
@pytest.mark.parametrize(
    "name", ["panda_table_friction", "solo_landing", "block_incline", "block_incline_spatial"]
)  # fixed base, free-flyer root, planar (one tangent each), free body on an incline
def test_tangent_rows_equal_pinocchio_and_finite_differences(
    name: str, rng: np.random.Generator
) -> None:
    """The tangential rows of the compiled call: ConstraintSet.contact_rows' and t · ∂p/∂q."""
    constraints = load_scene(name).constraints
    robot, rows = constraints.robot, compiled_rows(constraints)
    assert rows is not None and rows.tangential == int(constraints.tangent_count.sum()) > 0
    model, data = robot.model, pin.Data(robot.model)
    frames = [robot.frame_id(contact.frame) for contact in constraints.contacts]
    every = np.arange(constraints.size)
    for _ in range(5):
        q, v = _random_state(robot, rng)
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        J, T, tangents = constraints.contact_rows(data, every)
        rows(q, v)
        selected, friction_map = rows.contact_selection(every)
        assert rows.last_contact_rows is not None
        rows_c = rows.last_contact_rows[selected]
        # Measured: 2.8e-17 (the frame compositions' round-off).
        np.testing.assert_allclose(rows_c, np.concatenate((J, T)), rtol=0, atol=1e-14)
        _check_friction_map(constraints, every, friction_map, tangents, rng)
        # Each row t · ∂p_F/∂q along v, by central differences on the manifold (~eps²).
        owners = np.repeat(np.arange(len(frames)), constraints.tangent_count[: len(frames)])
        eps = 1e-6
        for j in range(robot.nv):
            step = np.zeros(robot.nv)
            step[j] = eps
            ends = []
            for sign in (1.0, -1.0):
                pin.framesForwardKinematics(model, data, pin.integrate(model, q, sign * step))
                ends.append(np.array([data.oMf[frames[i]].translation for i in owners]))
            derivative = np.sum(tangents * (ends[0] - ends[1]), axis=1) / (2 * eps)
            np.testing.assert_allclose(derivative, rows_c[constraints.size :, j], atol=1e-8)


@needs_compiled_code
def test_tangent_rows_of_an_active_subset_in_the_order_of_contact_rows(
    rng: np.random.Generator,
) -> None:
    """A subset of the feet, in any order: the rows and tangents ConstraintSet stacks."""
    constraints = load_scene("solo_landing").constraints
    robot, rows = constraints.robot, compiled_rows(constraints)
    assert rows is not None
    model, data = robot.model, pin.Data(robot.model)
    q, v = _random_state(robot, rng)
    pin.computeAllTerms(model, data, q, v)
    rows(q, v)
    assert rows.last_contact_rows is not None
    for indices in ([2], [3, 0], [1, 2, 3], [2, 0, 1]):
        active = np.array(indices, dtype=np.intp)
        J, T, tangents = constraints.contact_rows(data, active)
        selected, friction_map = rows.contact_selection(active)
        np.testing.assert_allclose(
            rows.last_contact_rows[selected], np.concatenate((J, T)), rtol=0, atol=1e-14
        )
        _check_friction_map(constraints, active, friction_map, tangents, rng)


def _check_friction_map(  # type: ignore[no-untyped-def]
    constraints: ConstraintSet, active, friction_map, tangents, rng: np.random.Generator
) -> None:
    """The map of the rows' impulses to friction impulses: Σ P_t t per constraint, by hand."""
    impulses = rng.normal(size=friction_map.shape[1])  # normal rows, then tangential ones
    expected, row = np.zeros((constraints.size, 3)), len(active)
    for i in active:
        for _ in range(constraints.tangent_count[i]):
            expected[i] += impulses[row] * tangents[row - len(active)]
            row += 1
    assert row == impulses.size
    np.testing.assert_allclose(
        (friction_map @ impulses).reshape(-1, 3), expected, rtol=0, atol=1e-15
    )


@needs_compiled_code
def test_contacts_with_a_radius_keep_pinocchios_tangent_rows() -> None:
    """A rolling contact point's rows need the angular Jacobian: the normal rows alone."""
    constraints = load_scene("capsule_arm_points").constraints
    assert constraints.has_friction and any(c.radius > 0.0 for c in constraints.contacts)
    rows = compiled_rows(constraints)
    assert rows is not None and rows.tangential == 0


@needs_compiled_code
@pytest.mark.parametrize("armature", [None, (0.3, 0.7)])
def test_rows_with_dynamics_fill_m_and_h_as_pinocchio(armature, rng: np.random.Generator) -> None:
    """A small robot's rows with the dynamics: M, h and the energies of computeAllTerms."""
    scene = load_scene("two_link_one_constraint")
    robot = scene.robot if armature is None else scene.robot.with_armature(np.array(armature))
    constraints = ConstraintSet(robot, scene.constraints.contacts, scene.constraints.stops)
    rows = compiled_rows(constraints, dynamics=True)
    assert rows is not None and rows.dynamics
    model = robot.model
    bound, reference = pin.Data(model), pin.Data(model)
    rows.bind_dynamics(bound)
    for _ in range(10):
        q, v = _random_state(robot, rng)
        gap = rows(q, v)[0]
        pin.computeAllTerms(model, reference, q, v)
        np.testing.assert_allclose(bound.M, reference.M, rtol=0, atol=1e-14)  # both triangles
        np.testing.assert_allclose(bound.nle, reference.nle, rtol=0, atol=1e-13)
        kinetic, potential = rows.energies()
        assert kinetic == pytest.approx(reference.kinetic_energy, rel=1e-14, abs=1e-15)
        assert potential == pytest.approx(reference.potential_energy, rel=1e-14, abs=1e-15)
        np.testing.assert_array_equal(gap, rows(q, v)[0])  # the rows unchanged
    panda = load_scene("panda_table")  # nv = 7: Pinocchio's dynamics, the rows alone
    assert not compiled_rows(panda.constraints, dynamics=True).dynamics


@needs_compiled_code
def test_values_are_fresh_arrays() -> None:
    scene = load_scene("two_link_one_constraint")
    rows = compiled_rows(scene.constraints)
    assert rows is not None
    first = rows(scene.q0, np.zeros(2))
    kept = [value.copy() for value in first]
    rows(scene.q0 + 0.1, np.ones(2))
    for value, copy in zip(first, kept, strict=True):
        np.testing.assert_array_equal(value, copy)


def test_sets_that_do_not_qualify_keep_the_pinocchio_path() -> None:
    stops_only = ConstraintSet(
        load_scene("two_link_one_constraint").robot,
        stops=load_scene("two_link_one_constraint").constraints.stops,
    )
    assert not qualifies(stops_only)
    collision = load_scene("box_drop_collision")  # collision shapes
    assert not qualifies(collision.constraints)
    assert compiled_rows(collision.constraints) is None


@pytest.mark.slow
@needs_compiled_code  # without it both runs would be interpreted
def test_closed_loop_without_compiler_equals_compiled_to_round_off(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    scene = load_scene("two_link_one_constraint")
    compiled = simulate(scene, duration=6.0, progress=False).log
    monkeypatch.setenv("UCONTROL_NO_COMPILE", "1")  # the Pinocchio path (and the casadi laws)
    interpreted = simulate(scene, duration=6.0, progress=False).log
    # 6 s cover the landing at t ~ 4.7 s and a second of sliding, with the same active sets.
    # Measured: q 1.1e-14 rad, impulses 4.1e-11 N s of 1.4 N s (the interpreted laws' round-off).
    np.testing.assert_array_equal(compiled.active, interpreted.active)
    np.testing.assert_allclose(compiled.q, interpreted.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(compiled.impulse, interpreted.impulse, rtol=0, atol=4e-10)


@pytest.mark.parametrize("setting", ["no_compile", "no_compiler"])
def test_rows_are_not_built_where_they_cannot_compile(
    setting: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Built, they would run in casadi's virtual machine, slower than Pinocchio's path: the
    # symbolic rows are not even built (nor casadi imported for them).
    constraints = load_scene("two_link_one_constraint").constraints
    if setting == "no_compile":
        monkeypatch.setenv("UCONTROL_NO_COMPILE", "1")
    else:
        monkeypatch.setenv("CC", "no-such-compiler-ucontrol")
    monkeypatch.setattr(compiled_rows_module, "ConstraintRows", _never_built)
    assert compiled_rows(constraints) is None


def _never_built(constraints: ConstraintSet) -> None:
    raise AssertionError("the rows were built although they cannot compile")
