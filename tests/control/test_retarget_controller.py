"""A built Brogliato controller given another draw of its believed inertias (no rebuild).

The reference is a controller built for the new draw: a retargeted controller, after
``reset()``, must produce the same closed loop bit for bit, through impacts and the constrained
phase, on both sources of the law's M and h (the law's own ``inertia`` input for the two-link
arm, Pinocchio on the controller's model for the Panda) and on both paths of the law (compiled,
and casadi's virtual machine with ``UCONTROL_NO_COMPILE=1``).
"""

from __future__ import annotations

import dataclasses
import tomllib
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.campaign.overrides import apply_overrides
from ucontrol.control import BrogliatoController, ContactState, FlexibleBrogliatoController
from ucontrol.control.friction_compensation import FrictionCompensation
from ucontrol.control.phase import Phase
from ucontrol.exceptions import NotFoundError, UnknownKeyError
from ucontrol.log import Log
from ucontrol.model.robot_model import SMALL_ROBOT_MAX_NV
from ucontrol.scene import Scene, builtin_scene
from ucontrol.scene.controller_builders import retarget_controller
from ucontrol.simulate import simulate

ROBOTS = builtin_scene().parent
#: Log fields that are not a function of the run's numbers (wall-clock time of a solve).
_CLOCK_FIELDS = {"solver_time"}
#: Simulated time of the runs whose controller is refused a retarget, in [s]: the torques
#: depend on the masses from the first step.
_SHORT = 0.5


def _scene(name: str, overrides: dict[str, Any]) -> Scene:
    """Scene ``name`` of robots/ with the dotted-key ``overrides`` of a campaign run."""
    table = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
    return Scene.from_dict(apply_overrides(table, overrides), base_dir=ROBOTS)


def _assert_same_logs(log: Log, reference: Log) -> None:
    """Every field of ``log`` equal to ``reference``'s, bit for bit, and the same impacts."""
    assert log.fields == reference.fields
    for field in log.fields:
        if field not in _CLOCK_FIELDS:
            assert np.array_equal(getattr(log, field), getattr(reference, field)), field
    assert np.array_equal(log.impacts.t, reference.impacts.t)


#: (scene, dotted key, the value the controller is built for, the value it is retargeted to,
#: duration [s]): the campaign's draw, the [controller] table's own scale (back to the plant's
#: model: the retargeted controller then reads M and h from the plant's evaluation, as a fresh
#: one does), centres of mass, and the Panda (M and h from Pinocchio).
CASES = [
    ("two_link_one_constraint", "controller.model.mass_scale", 0.85, 1.15, 6.0),
    ("two_link_one_constraint", "controller.mass_scale", 1.15, 1.0, 6.0),
    (
        "two_link_one_constraint",
        "controller.model.com_offset",
        {"link1": [0.02, 0.0, 0.0], "link2": [-0.03, 0.01, 0.0]},
        {"link2": [0.03, -0.01, 0.0]},
        6.0,
    ),
    ("panda_table", "controller.model.mass_scale", 0.85, 1.15, 2.5),
]


@pytest.mark.parametrize("no_compile", ["", "1"], ids=["compiled", "virtual_machine"])
@pytest.mark.parametrize(("name", "key", "built", "drawn", "duration"), CASES)
def test_a_retargeted_controller_runs_as_one_built_for_the_new_draw(
    name: str,
    key: str,
    built: Any,
    drawn: Any,
    duration: float,
    no_compile: str,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("UCONTROL_NO_COMPILE", no_compile)
    first, scene = _scene(name, {key: built}), _scene(name, {key: drawn})
    controller = first.build_controller()
    assert type(controller) is BrogliatoController
    before = simulate(first, controller, duration=duration, progress=False).log  # a used one
    assert retarget_controller(controller, scene)
    controller.reset()
    log = simulate(scene, controller, duration=duration, progress=False).log
    reference = simulate(scene, scene.build_controller(), duration=duration, progress=False).log
    _assert_same_logs(log, reference)
    # Not a comparison that cannot fail: the draw changes the torques from the first step,
    # and the runs go through impacts into the constrained phase.
    assert not np.array_equal(before.u[0], reference.u[0])
    assert reference.impacts.t.size > 0
    assert np.any(reference.phase == Phase.CONSTRAINED)


def test_a_controller_on_the_plants_data_reads_its_own_once_retargeted() -> None:
    """M and h of the new draw, not the plant's: as a controller built for it, at any state."""
    plant = _scene("panda_table", {})
    controller = plant.build_controller()
    assert controller.use_plant_data(pin.Data(plant.robot.model))  # its model is the plant's
    drawn = _scene("panda_table", {"controller.model.mass_scale": 1.15})
    assert retarget_controller(controller, drawn)
    n = len(drawn.constraints.names)
    contacts = ContactState(
        names=drawn.constraints.names,
        gap=np.full(n, 0.05),
        normal_velocity=np.zeros(n),
        impulse=np.zeros(n),
        active=np.zeros(n, dtype=bool),
        dt=1e-3,
    )
    v = np.random.default_rng(30).uniform(-0.5, 0.5, drawn.robot.nv)
    fresh = drawn.build_controller()
    tau = controller(0.1, drawn.q0, v, contacts)
    assert np.array_equal(tau, fresh(0.1, drawn.q0, v, contacts))
    assert not np.array_equal(tau, plant.build_controller()(0.1, drawn.q0, v, contacts))


def test_the_cases_cover_both_sources_of_m_and_h() -> None:
    """The two-link law takes the inertias as its input, the Panda's reads Pinocchio's M, h."""
    nv = {name: _scene(name, {}).robot.nv for name, *_ in CASES}
    assert nv["two_link_one_constraint"] <= SMALL_ROBOT_MAX_NV < nv["panda_table"]


def _assert_refused(name: str, built: dict[str, Any], drawn: dict[str, Any], kind: type) -> None:
    """The controller of ``name`` with overrides ``built`` refuses ``drawn``'s and is unchanged.

    It then runs as one built for ``built``.
    """
    first = _scene(name, built)
    controller = first.build_controller()
    assert type(controller) is kind
    assert not retarget_controller(controller, _scene(name, drawn))
    _assert_runs_as_built(first, controller)


def _assert_runs_as_built(scene: Scene, controller: Any) -> None:
    """``controller`` runs ``scene`` as the controller the scene builds, bit for bit."""
    log = simulate(scene, controller, duration=_SHORT, progress=False).log
    reference = simulate(scene, scene.build_controller(), duration=_SHORT, progress=False).log
    _assert_same_logs(log, reference)


def test_a_friction_compensated_controller_is_refused() -> None:
    """Its wrapper forwards use_inertias to the law it wraps, but is refused all the same."""
    friction = {"controller.model.joint_friction": {"viscous": 0.5}}
    _assert_refused(
        "two_link_one_constraint",
        {**friction, "controller.model.mass_scale": 0.85},
        {**friction, "controller.model.mass_scale": 1.15},
        FrictionCompensation,
    )


def test_the_flexible_law_is_refused() -> None:
    _assert_refused(
        "two_link_flexible_one_constraint",
        {"controller.mass_scale": 0.85},
        {"controller.mass_scale": 1.15},
        FlexibleBrogliatoController,
    )


def test_another_controller_type_is_refused() -> None:
    from ucontrol.control.impedance_controller import ImpedanceController

    _assert_refused(
        "two_link_one_constraint_impedance",
        {"controller.model.mass_scale": 0.85},
        {"controller.model.mass_scale": 1.15},
        ImpedanceController,
    )


def test_other_believed_surfaces_are_refused() -> None:
    """A surface the controller believes elsewhere (the scene's, or its model's) is refused.

    The plant's surface, where the controller believes one of its own, is not its concern.
    """
    mass = {"controller.model.mass_scale": 0.85}
    _assert_refused(
        "two_link_one_constraint",
        mass,
        {"controller.model.mass_scale": 1.15, "surfaces.ground.point.1": -2e-3},
        BrogliatoController,
    )
    believed = {**mass, "controller.model.surfaces.ground.point": [0.0, 0.0, 0.0]}
    _assert_refused(
        "two_link_one_constraint",
        believed,
        {**believed, "controller.model.surfaces.ground.point": [0.0, -1e-3, 0.0]},
        BrogliatoController,
    )
    controller = _scene("two_link_one_constraint", believed).build_controller()
    plant = {**believed, "surfaces.ground.point.1": -2e-3, "controller.model.mass_scale": 1.1}
    assert retarget_controller(controller, _scene("two_link_one_constraint", plant))


def _longer_forearm(scene: Scene) -> Scene:
    """``scene`` whose elbow is 2 % further from the shoulder (other kinematics)."""
    model = scene.robot.model.copy()
    elbow = model.getJointId("elbow")
    placement = pin.SE3(model.jointPlacements[elbow])
    placement.translation = placement.translation * 1.02
    model.jointPlacements[elbow] = placement
    return dataclasses.replace(scene, robot=scene.robot.with_model(model))


def test_a_believed_robot_of_other_kinematics_or_actuation_is_refused() -> None:
    first = _scene("two_link_one_constraint", {"controller.model.mass_scale": 0.85})
    controller = first.build_controller()
    drawn = _scene("two_link_one_constraint", {"controller.model.mass_scale": 1.15})
    assert not retarget_controller(controller, _longer_forearm(drawn))
    assert not controller.use_inertias(_longer_forearm(drawn).robot)
    assert not controller.use_inertias(drawn.robot.with_actuation(passive=["elbow"]))
    _assert_runs_as_built(first, controller)
    assert controller.use_inertias(drawn.robot)  # the same robot, its own inertias: taken


def test_a_bad_believed_model_table_raises_as_the_builder() -> None:
    controller = _scene("two_link_one_constraint", {}).build_controller()
    scene = _scene("two_link_one_constraint", {})
    for model, error, match in (
        ({"masses": 1.1}, UnknownKeyError, "masses"),
        ({"mass_scale": {"link9": 1.1}}, NotFoundError, "link9.*link1"),
    ):
        bad = dataclasses.replace(scene, controller={**scene.controller, "model": model})
        with pytest.raises(error, match=match):
            retarget_controller(controller, bad)
