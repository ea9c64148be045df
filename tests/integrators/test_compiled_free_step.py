"""The compiled free step against the numpy and Pinocchio path it replaces, step by step."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ucontrol.model.joint_friction import JointFriction
from ucontrol.scene import load_scene

#: (scene, with viscous joint friction): the steps that use the compiled free step.
CASES = [
    ("two_link_flexible_one_constraint", False),
    ("two_link_flexible_two_constraints", False),
    ("two_link_one_constraint", True),
    ("panda_table", True),
]


def _pair(name: str, viscous: bool = False):  # type: ignore[no-untyped-def]
    """Two integrators of scene ``name``: with the compiled free step and without it."""
    scene = load_scene(name)
    if viscous:
        nv = scene.robot.nv
        friction = JointFriction(viscous=[0.7] * nv, coulomb=[0.0] * nv)
        scene = dataclasses.replace(scene, joint_friction=friction)
    compiled, reference = scene.build_integrator(), scene.build_integrator()
    assert compiled._free_step is not None
    reference._free_step = None
    return scene, compiled, reference


@pytest.mark.parametrize(("name", "viscous"), CASES)
def test_steps_equal_the_numpy_path(name: str, viscous: bool, rng: np.random.Generator) -> None:
    scene, compiled, reference = _pair(name, viscous)
    q0, v0 = scene.initial_state()
    for trial in range(20):
        q = q0 + 0.05 * rng.normal(size=q0.size)
        v = rng.normal(size=v0.size)
        tau = 5.0 * rng.normal(size=v0.size)
        for integrator in (compiled, reference):
            integrator.reset()
            integrator._first_step = False
            integrator._activation[:] = 1e9 if trial % 2 else 0.0  # every constraint active
        a = compiled.step(compiled.evaluate(q, v), tau)
        b = reference.step(reference.evaluate(q, v), tau)
        np.testing.assert_array_equal(a.active, b.active)
        # Measured: v 3.2e-15 rad/s, q 6.9e-18 rad, impulses 1.8e-15 N s over the cases.
        np.testing.assert_allclose(a.v, b.v, rtol=0, atol=3e-14)
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-16)
        np.testing.assert_allclose(a.impulse, b.impulse, rtol=0, atol=2e-14)


def test_rigid_steps_keep_the_pinocchio_path() -> None:
    # Without flexible joints or viscous friction the numpy path (Pinocchio's Cholesky) is
    # as fast: the compiled free step is not built.
    assert load_scene("two_link_one_constraint").build_integrator()._free_step is None


def test_viscous_step_solves_the_theta_implicit_update() -> None:
    # Free of contacts, M (v+ - v) = -h (h(q, v) + D ((1 - θ) v + θ v+)): the θ-implicit
    # viscous friction of docs/friction.md, written here with numpy.
    _, compiled, _ = _pair("two_link_one_constraint", viscous=True)
    q, v = np.array([1.2, -1.0]), np.array([0.3, -0.2])
    state = compiled.evaluate(q, v)
    step = compiled.step(state, np.zeros(2))
    data = compiled._data
    M = np.triu(data.M) + np.triu(data.M, 1).T
    h, theta, D = compiled.dt, compiled.theta, 0.7
    rhs = M @ v - h * (data.nle + (1.0 - theta) * D * v)
    expected = np.linalg.solve(M + h * theta * D * np.eye(2), rhs)
    np.testing.assert_allclose(step.v, expected, rtol=0, atol=1e-15)  # measured 0


def test_without_a_compiler_there_is_no_compiled_step(monkeypatch: pytest.MonkeyPatch) -> None:
    scene = load_scene("two_link_flexible_one_constraint")  # compiled where a compiler is
    assert scene.build_integrator()._free_step is not None
    monkeypatch.setenv("UCONTROL_NO_COMPILE", "1")
    integrator = scene.build_integrator()
    assert integrator._free_step is None and integrator._rows is None
    q, v = scene.initial_state()  # and the numpy path steps
    assert np.all(np.isfinite(integrator.step(integrator.evaluate(q, v), np.zeros(v.size)).v))
