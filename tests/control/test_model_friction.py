"""Controllers that compensate the joint friction of their model ([controller.model])."""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np
import pytest

from ucontrol.campaign.overrides import apply_overrides
from ucontrol.control.controller import ContactState, LoggingController
from ucontrol.control.friction_compensation import FrictionCompensation
from ucontrol.exceptions import InvalidParameterError, UnknownKeyError
from ucontrol.model.joint_friction import JointFriction
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate

ROBOTS = builtin_scene().parent
PLANT_FRICTION = {"viscous": 0.5, "coulomb": 0.3}  # [N m s/rad], [N m] on both joints


def _table(plant: dict | None, belief: dict | None, duration: float = 3.0) -> dict[str, Any]:
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    table["duration"] = duration
    if plant is not None:
        table["joint_friction"] = plant
    if belief is not None:
        table["controller"]["model"] = {"joint_friction": belief}
    return table


def _free_tracking_error(plant: dict | None, belief: dict | None) -> float:
    """RMS task-space tracking error in [m] on the free circle, t in [1.5, 3] s."""
    scene = Scene.from_dict(_table(plant, belief), base_dir=ROBOTS)
    log = simulate(scene, progress=False).log
    error = np.linalg.norm(log.task_position - log.task_desired, axis=1)
    return float(np.sqrt(np.mean(error[log.t >= 1.5] ** 2)))


@pytest.mark.slow
def test_believed_friction_restores_the_frictionless_tracking() -> None:
    frictionless = _free_tracking_error(None, None)
    believed = _free_tracking_error(PLANT_FRICTION, None)  # the model is the plant's
    blind = _free_tracking_error(PLANT_FRICTION, {"viscous": 0.0, "coulomb": 0.0})
    # Measured: 4.98e-3, 4.16e-3 and 1.62e-2 m.
    assert believed <= 2.0 * frictionless
    assert blind >= 2.0 * believed  # the compensation matters


def test_compensation_adds_the_models_friction_to_the_law(rng: np.random.Generator) -> None:
    scene = Scene.from_dict(
        _table(None, {"viscous": {"shoulder": 0.4}, "coulomb": 0.2, "velocity_band": 0.05}),
        base_dir=ROBOTS,
    )
    assert scene.joint_friction is None  # the plant keeps the scene's: none
    controller = scene.build_controller()
    assert isinstance(controller, FrictionCompensation)
    assert isinstance(controller, LoggingController)  # the wrapped law's log fields
    assert controller.phase == controller.controller.phase
    bare = Scene.from_dict(_table(None, None), base_dir=ROBOTS).build_controller()
    names = list(scene.constraints.names)
    n = len(names)
    contacts = ContactState(names, np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n, bool), 1e-3)
    for v in (rng.normal(size=2), np.array([0.01, -0.2])):
        q = np.array([0.9, -1.6])
        compensation = np.array([0.4 * v[0], 0.0]) + 0.2 * np.clip(v / 0.05, -1.0, 1.0)
        expected = bare(0.0, q, v, contacts) + compensation
        np.testing.assert_allclose(controller(0.0, q, v, contacts), expected, rtol=1e-12)


def test_zero_controller_and_frictionless_belief_are_not_wrapped() -> None:
    table = _table(PLANT_FRICTION, {"viscous": 0.0, "coulomb": 0.0})
    assert not isinstance(
        Scene.from_dict(table, base_dir=ROBOTS).build_controller(), FrictionCompensation
    )
    table = _table(PLANT_FRICTION, None)
    table["controller"] = {"type": "zero"}
    assert not isinstance(
        Scene.from_dict(table, base_dir=ROBOTS).build_controller(), FrictionCompensation
    )


def test_campaign_keys_reach_plant_and_model_friction() -> None:
    table = apply_overrides(
        _table(None, None),
        {"joint_friction.coulomb.elbow": 0.25, "controller.model.joint_friction.viscous": 0.1},
    )
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    np.testing.assert_array_equal(scene.joint_friction.coulomb, [0.0, 0.25])
    friction = scene.build_controller().friction
    np.testing.assert_array_equal(friction.viscous, [0.1, 0.1])


@pytest.mark.parametrize(
    ("belief", "error"),
    [({"viscous": 0.1, "dry": 0.2}, UnknownKeyError), ({"coulomb": -0.1}, InvalidParameterError)],
)
def test_bad_model_friction_is_a_typed_error(belief: dict, error: type) -> None:
    with pytest.raises(error, match=r"controller\.model\] joint_friction"):
        Scene.from_dict(_table(None, belief), base_dir=ROBOTS).build_controller()


def test_model_torque_band() -> None:
    friction = JointFriction(viscous=[0.0], coulomb=[2.0], velocity_band=0.1)
    np.testing.assert_allclose(
        [friction.model_torque(np.array([w]))[0] for w in (-1.0, -0.05, 0.0, 0.05, 1.0)],
        [-2.0, -1.0, 0.0, 1.0, 2.0],
    )
    with pytest.raises(InvalidParameterError, match="velocity_band"):
        JointFriction(viscous=[0.0], coulomb=[0.0], velocity_band=0.0)
