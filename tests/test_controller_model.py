"""A controller on its own model of the scene ([controller.model]).

Masses, centres of mass and surfaces as the controller believes them; the plant keeps the
scene's.
"""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.exceptions import NotFoundError, UnknownKeyError
from ucontrol.model.model_uncertainty import perturbed_robot
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.scene.controller_builders import controller_view
from ucontrol.simulate import simulate

ROBOTS = builtin_scene().parent


def test_per_link_mass_scale_and_com_offset_change_only_those_bodies() -> None:
    robot = load_scene("two_link_drop").robot
    changed = perturbed_robot(robot, mass_scale={"link2": 1.5}, com_offset={"link1": [0.1, 0, 0]})
    plant, model = robot.model, changed.model
    assert model.inertias[2].mass == pytest.approx(1.5 * plant.inertias[2].mass)
    np.testing.assert_allclose(model.inertias[2].inertia, 1.5 * plant.inertias[2].inertia)
    np.testing.assert_allclose(
        model.inertias[1].lever, plant.inertias[1].lever + np.array([0.1, 0, 0])
    )
    assert model.inertias[1].mass == plant.inertias[1].mass
    # Gravity torque of the shoulder against an independent sum over the bodies: m g x_com.
    q = np.array([0.3, -0.8])
    data = pin.Data(model)
    pin.forwardKinematics(model, data, q)
    expected = sum(
        model.inertias[j].mass * 9.81 * (data.oMi[j].act(model.inertias[j].lever))[0]
        for j in (1, 2)
    )
    tau = pin.computeGeneralizedGravity(model, data, q)
    assert tau[0] == pytest.approx(expected, rel=1e-12)
    with pytest.raises(NotFoundError, match=r"link 'link9'.*link1"):
        perturbed_robot(robot, mass_scale={"link9": 2.0})


def _one_constraint(**model: Any) -> Scene:
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    table["controller"]["model"] = model
    return Scene.from_dict(table, base_dir=ROBOTS)


def test_controller_believes_its_surfaces_while_the_plant_keeps_the_scenes() -> None:
    # The plant's ground 5 mm higher than the controller believes: a raised ground makes the
    # nominal circle cross it after takeoff, which the controller must not see.
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    table["surfaces"]["ground"]["point"] = [0.0, 0.005, 0.0]
    table["controller"]["model"] = {"surfaces": {"ground": {"point": [0.0, 0.0, 0.0]}}}
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    view = controller_view(scene, table["controller"]["model"])
    np.testing.assert_array_equal(view.contacts[0].surface.point, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(scene.contacts[0].surface.point, [0.0, 0.005, 0.0])
    log = simulate(scene, duration=6.0).log  # landing at ~4.8 s on the raised ground
    landing = int(np.argmax(log.impulse[:, 0] > 0))
    assert 4.0 < log.t[landing] < 6.0
    assert log.gap[landing + 1, 0] > -1e-3  # the plant's gap is measured from its own ground


def test_believed_constraints_are_the_controllers_surfaces_with_the_plants_rows() -> None:
    """The rows the measurement-only observer reports gaps on: the believed ground's."""
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    table["surfaces"]["ground"]["point"] = [0.0, 0.005, 0.0]
    table["controller"]["model"] = {"surfaces": {"ground": {"point": [0.0, 0.0, 0.0]}}}
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    believed = scene.believed_constraints()
    assert believed.names == scene.constraints.names
    q, v = np.array([0.4, -1.1]), np.array([0.3, -0.2])
    data = pin.Data(scene.robot.model)
    pin.forwardKinematics(scene.robot.model, data, q, v)
    pin.updateFramePlacements(scene.robot.model, data)
    seen_gap, seen_speed = believed.evaluate(data, q, v, 0.0)
    true_gap, true_speed = scene.constraints.evaluate(data, q, v, 0.0)
    frame = data.oMf[scene.robot.model.getFrameId(scene.contacts[0].frame)].translation
    assert seen_gap[0] == pytest.approx(frame[1], abs=1e-14)  # height above y = 0 (normal +y)
    assert true_gap[0] == pytest.approx(frame[1] - 0.005, abs=1e-14)
    np.testing.assert_array_equal(seen_speed, true_speed)  # a translated plane: same normal
    plain = load_scene("two_link_one_constraint")  # no [controller.model]: the plant's own
    assert plain.believed_constraints() is plain.constraints


def test_controller_model_table_errors() -> None:
    with pytest.raises(UnknownKeyError, match=r"'inertia' in \[controller.model\]"):
        _one_constraint(inertia=2.0).build_controller()
    with pytest.raises(UnknownKeyError, match=r"'table'"):
        _one_constraint(surfaces={"table": {"point": [0, 0, 0]}}).build_controller()
    with pytest.raises(NotFoundError, match=r"'hand'"):
        _one_constraint(mass_scale={"hand": 1.1}).build_controller()


def test_a_heavier_model_changes_the_torques_by_its_gravity() -> None:
    nominal = load_scene("two_link_drop")
    table = tomllib.loads((ROBOTS / "two_link_drop.toml").read_text())
    table["controller"] = {"type": "joint_pd", "kp": 0.0, "kd": 0.0, "model": {"mass_scale": 1.2}}
    heavier = Scene.from_dict(table, base_dir=ROBOTS)
    table["controller"] = {"type": "joint_pd", "kp": 0.0, "kd": 0.0}
    exact = Scene.from_dict(table, base_dir=ROBOTS)
    q, v = nominal.q0, nominal.v0
    contacts = None
    u_heavy = heavier.build_controller()(0.0, q, v, contacts)
    u_exact = exact.build_controller()(0.0, q, v, contacts)
    np.testing.assert_allclose(u_heavy, 1.2 * u_exact, rtol=1e-12)  # pure gravity compensation
