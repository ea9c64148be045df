"""Bad controller parameters raise typed errors from ucontrol.exceptions, naming the value."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
from brogliato_runs import ROBOTS, scene

from ucontrol.contact import Plane, PointContact
from ucontrol.control import (
    BrogliatoController,
    BrogliatoGains,
    CirclePath,
    ContactPhase,
    ContactState,
    DesiredCycle,
    TaskCoordinates,
)
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    NotFoundError,
    PathThroughSurfaceError,
    SceneError,
    SimulationError,
    UnknownKeyError,
)
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

CASE = "two_link_one_constraint"


def _table() -> dict:
    return tomllib.loads((ROBOTS / f"{CASE}.toml").read_text())


def _from_table(table: dict) -> Scene:
    return Scene.from_dict(table, base_dir=ROBOTS)


def _parts():
    variant = scene(CASE)
    controller = variant.build_controller()
    return variant, controller.task, controller.cycle


@pytest.mark.parametrize(
    ("name", "value", "expected"),
    [
        ("gamma1", 0.0, "> 0"),
        ("gamma1", -8.0, "> 0"),
        ("gamma2", 0.0, "> 0"),
        ("force_gain", 1.0, "in [0, 1)"),
        ("force_gain", -0.1, "in [0, 1)"),
        ("posture_gain", 0.0, "> 0"),
    ],
)
def test_gains_out_of_range(name: str, value: float, expected: str) -> None:
    gains = {"gamma1": 8.0, "gamma2": 7.0, name: value}
    with pytest.raises(InvalidParameterError, match=rf"`{name}` must be") as info:
        BrogliatoGains(**gains)
    assert info.value.name == name and info.value.expected == expected


def test_non_positive_gamma_in_a_scene_is_named() -> None:
    table = _table()
    table["controller"]["gamma1"] = -1.0
    with pytest.raises(InvalidParameterError, match=r"`gamma1` must be > 0, got -1.0"):
        _from_table(table).build_controller()


def test_path_through_the_ground_without_a_contact_phase() -> None:
    _, task, cycle = _parts()
    late = dataclasses.replace(cycle.contact_phases[0], start=6.0)  # path below from 5 s
    with pytest.raises(PathThroughSurfaceError) as info:
        DesiredCycle(path=cycle.path, contact_phases=(late,)).check(task)
    error = info.value
    assert error.constraint == "end_effector/ground"
    assert 5.0 < error.time < 6.0 and error.gap < 0.0
    assert "outside any declared contact phase" in str(error)
    assert isinstance(error, InvalidParameterError)


def test_path_through_an_obstacle_with_no_contact_phase_at_all_in_a_scene() -> None:
    table = _table()
    table["controller"]["path"]["centre"] = [0.65, 0.05, 0.0]
    table["controller"]["path"]["start_angle"] = 0.0
    table["surfaces"]["wall"] = {"type": "plane", "point": [0.7, 0, 0], "normal": [-1, 0, 0]}
    table["contacts"].append({"frame": "end_effector", "surface": "wall", "restitution": 0.7})
    table["controller"]["tangents"] = []  # X = (y, 0.7 - x): two gaps
    with pytest.raises(PathThroughSurfaceError, match=r"end_effector/wall"):
        _from_table(table).build_controller()


def test_frame_missing_from_the_urdf() -> None:
    variant, _, _ = _parts()
    with pytest.raises(FrameNotFoundError, match=r"'tool0'.*end_effector") as info:
        TaskCoordinates(variant.robot, "tool0", [], [[1.0, 0.0, 0.0]])
    assert "end_effector" in info.value.available
    table = _table()
    table["controller"]["frame"] = "tool0"
    with pytest.raises(FrameNotFoundError, match=r"tool0"):
        _from_table(table).build_controller()


@pytest.mark.parametrize(
    ("where", "key"),
    [("controller", "gamma3"), ("path", "center"), ("phase", "lambda_d")],
)
def test_unknown_controller_keys(where: str, key: str) -> None:
    table = _table()
    target = {
        "controller": table["controller"],
        "path": table["controller"]["path"],
        "phase": table["controller"]["contact_phases"][0],
    }[where]
    target[key] = 1.0
    with pytest.raises(UnknownKeyError, match=key) as info:
        _from_table(table).build_controller()
    assert info.value.keys == [key]


def test_missing_controller_keys_and_unknown_contacts() -> None:
    table = _table()
    del table["controller"]["gamma2"]
    with pytest.raises(SceneError, match=r"'gamma2'"):
        _from_table(table).build_controller()
    table = _table()
    table["controller"]["contact_phases"][0]["contact"] = "hand/table"
    with pytest.raises(NotFoundError, match=r"'hand/table'.*end_effector/ground"):
        _from_table(table).build_controller()
    table = _table()
    table["controller"]["contacts"] = ["hand/table"]
    with pytest.raises(NotFoundError, match=r"'hand/table'"):
        _from_table(table).build_controller()
    table = _table()
    table["controller"]["path"]["type"] = "helix"  # the known types are listed
    with pytest.raises(InvalidParameterError, match=r"'circle', 'segment', 'polyline', 'spline'"):
        _from_table(table).build_controller()
    table = _table()
    table["controller"]["path"]["type"] = "spline"  # a spline has no centre
    with pytest.raises(UnknownKeyError, match=r"'centre'.*allowed: period, times, type"):
        _from_table(table).build_controller()


def test_task_directions_must_fit_the_robot() -> None:
    variant, _, _ = _parts()
    ground = variant.contacts[0]
    with pytest.raises(InvalidParameterError, match=r"nv = 2"):
        TaskCoordinates(variant.robot, "end_effector", [ground], [[1, 0, 0], [0, 0, 1]])
    with pytest.raises(InvalidParameterError, match=r"linearly independent"):
        TaskCoordinates(variant.robot, "end_effector", [ground], [[0, 2, 0]])
    other = PointContact(frame="link2", surface=Plane(normal=[0, 1, 0]))
    with pytest.raises(InvalidParameterError, match=r"task frame 'end_effector'"):
        TaskCoordinates(variant.robot, "end_effector", [other])


def test_cycle_parameters_are_checked() -> None:
    _, _, cycle = _parts()
    phase = cycle.contact_phases[0]
    with pytest.raises(InvalidParameterError, match=r"`end` must be > start"):
        ContactPhase(contact="c", start=5.0, end=5.0, force=1.0)
    with pytest.raises(InvalidParameterError, match=r"`force` must be > 0"):
        ContactPhase(contact="c", start=5.0, end=6.0, force=0.0)
    with pytest.raises(InvalidParameterError, match=r"approach_time"):
        DesiredCycle(path=cycle.path, contact_phases=(phase,), approach_time=5.5)
    with pytest.raises(InvalidParameterError, match=r"takeoff that ends before"):
        DesiredCycle(path=cycle.path, contact_phases=(phase,), takeoff_time=4.5)
    with pytest.raises(InvalidParameterError, match=r"`depth_max` must be >= 0.01"):
        DesiredCycle(path=cycle.path, contact_phases=(phase,), depth_max=0.001)
    with pytest.raises(InvalidParameterError, match=r"one phase per contact"):
        DesiredCycle(path=cycle.path, contact_phases=(phase, phase))
    with pytest.raises(InvalidParameterError, match=r"at least one contact phase"):
        DesiredCycle(path=cycle.path, contact_phases=())
    with pytest.raises(InvalidParameterError, match=r"`depth_exponent`"):
        DesiredCycle(path=cycle.path, contact_phases=(phase,), depth_exponent=0.0)
    with pytest.raises(InvalidParameterError, match=r"`radius` must be > 0"):
        CirclePath(centre=[0, 0, 0], radius=0.0, period=1.0)
    with pytest.raises(InvalidParameterError, match=r"orthogonal"):
        CirclePath(centre=[0, 0, 0], radius=1.0, period=1.0, axes=[[1, 0, 0], [1, 1, 0]])


def test_robot_must_be_fully_actuated() -> None:
    _, task, cycle = _parts()
    ball = RobotModel.from_urdf(ROBOTS / "free_ball.urdf", floating_base=True)
    gains = BrogliatoGains(gamma1=8.0, gamma2=7.0)
    with pytest.raises(InvalidParameterError, match=r"fully actuated"):
        BrogliatoController(ball, task, cycle, gains)
    with pytest.raises(InvalidParameterError, match=r"`factor` must be > 0"):
        ball.with_scaled_inertia(0.0)


def test_time_must_not_go_backwards_and_plant_contacts_must_exist() -> None:
    variant = scene(CASE)
    controller = variant.build_controller()
    zeros = np.zeros(1)
    contacts = ContactState(["end_effector/ground"], zeros, zeros, zeros, zeros > 0, 1e-3)
    controller(1.0, variant.q0, variant.v0, contacts)
    with pytest.raises(InvalidParameterError, match=r"reset\(\)"):
        controller(0.5, variant.q0, variant.v0, contacts)
    controller.reset()
    controller(0.5, variant.q0, variant.v0, contacts)
    no_ground = dataclasses.replace(variant, contacts=())
    with pytest.raises(SimulationError, match=r"unknown plant contact 'end_effector/ground'"):
        simulate(no_ground, variant.build_controller(), duration=0.01, dt=1e-3)
