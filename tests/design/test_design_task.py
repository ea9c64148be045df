"""Task files: the shipped task parses; malformed ones get typed errors naming key and value."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from ucontrol.design import DesignTask
from ucontrol.design.design_task import FlightSpec
from ucontrol.exceptions import InvalidParameterError, NotFoundError, SceneError, UnknownKeyError

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
TASK = ROBOTS / "two_link_one_constraint_task.toml"


def _table() -> dict:
    return tomllib.loads(TASK.read_text())


def test_shipped_task_reads_limits_from_the_urdf_and_the_task() -> None:
    task = DesignTask.from_toml(TASK)
    assert task.contact.name == "end_effector/ground"
    assert task.contact.restitution == 0.7
    np.testing.assert_array_equal(task.torque_limit, [100.0, 100.0])  # URDF effort
    np.testing.assert_array_equal(task.joint_limits, [[0.0, -2.6], [3.1, -0.3]])
    assert task.period == 10.0
    assert task.zeno_velocity == 1e-5


def test_unknown_key_is_named() -> None:
    table = _table()
    table["cost"]["efort"] = 1.0
    with pytest.raises(UnknownKeyError, match="efort"):
        DesignTask.from_dict(table, base_dir=ROBOTS)


def test_bad_values_are_named() -> None:
    table = _table()
    table["contact_phases"][0]["force_max"] = 0.5  # below force_min = 1
    with pytest.raises(InvalidParameterError, match="force_max") as error:
        DesignTask.from_dict(table, base_dir=ROBOTS)
    assert error.value.value == 0.5
    table = _table()
    table["grid"]["substeps"] = 1
    with pytest.raises(InvalidParameterError, match="substeps"):
        DesignTask.from_dict(table, base_dir=ROBOTS)
    table = _table()
    table["limits"]["torque"] = [100.0]
    with pytest.raises(InvalidParameterError, match="torque"):
        DesignTask.from_dict(table, base_dir=ROBOTS)
    table = _table()
    table["cost"] = {"effort": 0.0, "smoothness": 0.0}
    with pytest.raises(InvalidParameterError, match="cost"):
        DesignTask.from_dict(table, base_dir=ROBOTS)


def test_unknown_contact_missing_scene_and_bounces_on_a_plastic_contact() -> None:
    table = _table()
    table["contact_phases"][0]["contact"] = "hand/wall"
    with pytest.raises(NotFoundError, match="hand/wall"):
        DesignTask.from_dict(table, base_dir=ROBOTS)
    table = _table()
    del table["scene"]
    with pytest.raises(SceneError, match="scene"):
        DesignTask.from_dict(table, base_dir=ROBOTS)
    with pytest.raises(SceneError, match="does not exist"):
        DesignTask.from_toml(ROBOTS / "no_such_task.toml")
    table = _table()
    table["contact_phases"].append(dict(table["contact_phases"][0]))
    with pytest.raises(InvalidParameterError, match="contact_phases"):
        DesignTask.from_dict(table, base_dir=ROBOTS)


def test_locked_joints_reduce_the_design_model() -> None:
    table = tomllib.loads((ROBOTS / "panda_table_task.toml").read_text())
    task = DesignTask.from_dict(table, base_dir=ROBOTS)
    assert task.scene.robot.nv == 7  # the two fingers held at q0
    np.testing.assert_array_equal(task.torque_limit, [87.0] * 4 + [12.0] * 3)  # URDF effort
    full = task.scene.source
    assert full is not None and full.name == "panda_table.toml"
    table["locked_joints"] = ["panda_finger_joint3"]
    with pytest.raises(NotFoundError, match="panda_finger_joint3"):
        DesignTask.from_dict(table, base_dir=ROBOTS)
    table["locked_joints"] = "panda_finger_joint1"
    with pytest.raises(InvalidParameterError, match="locked_joints"):
        DesignTask.from_dict(table, base_dir=ROBOTS)


@pytest.mark.parametrize(("key", "value"), [("hessian", "bfgs"), ("warm_start", "yes")])
def test_bad_solver_setting_is_named(key: str, value: str) -> None:
    table = _table()
    table["solver"][key] = value
    with pytest.raises(InvalidParameterError, match=key) as error:
        DesignTask.from_dict(table, base_dir=ROBOTS)
    assert error.value.value == value


@pytest.mark.parametrize(
    ("low", "high", "off"),
    [(0.5, 0.4, "duration_max"), (0.0, 1.0, "duration_min"), (0.5, float("inf"), "duration_max")],
)
def test_flight_durations_out_of_order_or_not_positive_are_refused(low, high, off) -> None:
    with pytest.raises(InvalidParameterError, match=f"`{off}`"):
        FlightSpec(duration_min=low, duration_max=high)
    assert (FlightSpec(duration_min=0.5, duration_max=0.5).duration_max) == 0.5  # equal bounds
