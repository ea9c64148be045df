"""The Brogliato law reading M and h from the plant's evaluation (one Pinocchio pass fewer).

The closed loop lets a controller with the plant's own model and state read the plant's
``computeAllTerms`` instead of running ``crba`` and ``nonLinearEffects`` itself
(:meth:`BrogliatoController.use_plant_data`). Checked here: the law's torques against its
own pass at random states, the runs against runs without sharing, and the cases where the
loop must not share (sensors, a believed model that differs from the plant's).
"""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.control.brogliato_controller import BrogliatoController
from ucontrol.control.controller import ContactState
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import _ClosedLoop, simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

ROBOTS = builtin_scene().parent


def _scene(name: str, **tables: Any) -> Scene:
    table = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
    table.pop("reference", None)
    for key, value in tables.items():
        if isinstance(value, dict) and isinstance(table.get(key), dict):
            table[key] = {**table[key], **value}
        else:
            table[key] = value
    return Scene.from_dict(table, base_dir=ROBOTS)


@pytest.mark.parametrize("name", ["two_link_one_constraint", "panda_table"])
def test_law_on_the_plants_terms_equals_its_own_pass(name: str, rng: np.random.Generator) -> None:
    scene = load_scene(name)
    own, shared = scene.build_controller(), scene.build_controller()
    assert isinstance(own, BrogliatoController) and isinstance(shared, BrogliatoController)
    model = scene.robot.model
    plant = pin.Data(model)
    assert shared.use_plant_data(plant)
    names = list(scene.build_integrator().constraints.names)
    n = len(names)
    contacts = ContactState(names, np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n, bool), 1e-3)
    q0, _ = scene.initial_state()
    largest = 0.0
    for k in range(200):
        q, v = q0 + 0.2 * rng.normal(size=q0.size), rng.normal(size=q0.size)
        pin.computeAllTerms(model, plant, q, v)  # the plant's evaluation at (q, v)
        t = 1e-3 * k
        a, b = own(t, q, v, contacts), shared(t, q, v, contacts)
        largest = max(largest, float(np.abs(a - b).max() / (1.0 + np.abs(a).max())))
        assert np.array_equal(own.X, shared.X)  # the same frame placement
    assert largest <= 1e-14  # measured: 8.5e-16 (two-link), 9.9e-16 (Panda), relative to |τ|


def test_loop_shares_with_the_plants_model_only() -> None:
    def shares(scene: Scene) -> bool:
        integrator, controller = scene.build_integrator(), scene.build_controller()
        loop = _ClosedLoop(scene, integrator, controller, 2, 1, None)
        loop.share_plant_data()
        shared = loop.shares_plant_data
        loop.release()
        assert controller._plant_terms is False  # back on its own data
        return shared

    assert shares(_scene("two_link_one_constraint"))
    assert shares(_scene("two_link_one_constraint", controller={"model": {"mass_scale": 1.0}}))
    assert not shares(_scene("two_link_one_constraint", controller={"model": {"mass_scale": 1.1}}))
    assert not shares(_scene("two_link_one_constraint", sensors={"position_noise": 1e-6}))
    assert not shares(_scene("two_link_flexible_one_constraint"))  # the flexible law's own


def test_runs_with_and_without_sharing_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    scene = load_scene("two_link_one_constraint")
    controller = scene.build_controller()
    shared = simulate(scene, controller, duration=8.0).log
    assert controller._plant_terms is False  # released at the end of the run
    monkeypatch.setattr(BrogliatoController, "use_plant_data", lambda self, data: False)
    own = simulate(scene, duration=8.0).log
    assert np.array_equal(shared.phase, own.phase) and np.array_equal(shared.active, own.active)
    # Measured: q 1.1e-14 rad, u 1.8e-10 N m over the landing, the plateau and the takeoff.
    np.testing.assert_allclose(shared.q, own.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(shared.u, own.u, rtol=0, atol=2e-9)
