"""The impedance controller refuses contacts and contact phases it cannot honour, by name."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.control.desired_cycle import ContactPhase
from ucontrol.control.impedance_controller import (
    ImpedanceController,
    ImpedanceGains,
    as_gain_matrix,
)
from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.scene import Scene

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out


class _Still:
    """A constant desired point, period 1 s."""

    period = 1.0

    def derivatives(self, t, order):
        return (np.array([0.65, 0.1, 0.0]), *(np.zeros(3) for _ in range(order)))

    def __call__(self, t):
        return self.derivatives(t, 2)


@pytest.fixture(scope="module")
def arm():
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    table["controller"] = {"type": "zero"}
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    return scene.robot, scene.contacts[0]


def _controller(arm, contacts=None, phases=()):
    robot, contact = arm
    return ImpedanceController(
        robot,
        "end_effector",
        _Still(),
        ImpedanceGains(stiffness=100.0, damping=20.0),
        contacts=[contact] if contacts is None else contacts,
        contact_phases=phases,
    )


def test_a_gain_that_is_no_number_is_named():
    with pytest.raises(InvalidParameterError) as caught:
        as_gain_matrix("stiffness", "stiff", positive=True)
    assert caught.value.name == "stiffness" and caught.value.value == "stiff"


def test_a_contact_on_another_frame_is_named(arm):
    other = dataclasses.replace(arm[1], frame="link1")
    with pytest.raises(InvalidParameterError, match="link1") as caught:
        _controller(arm, contacts=[other])
    assert caught.value.value == "link1"


def test_contact_phases_must_name_distinct_known_contacts_within_a_period(arm):
    name = arm[1].name
    phase = ContactPhase(contact=name, start=0.0, end=0.5, force=1.0)
    with pytest.raises(InvalidParameterError, match="one phase per contact") as caught:
        _controller(arm, phases=[phase, phase])
    assert caught.value.value == [name, name]
    with pytest.raises(NotFoundError, match="wall"):
        _controller(arm, phases=[dataclasses.replace(phase, contact="wall")])
    long = dataclasses.replace(phase, end=1.5)  # 1.5 s in a period of 1 s
    with pytest.raises(InvalidParameterError) as caught:
        _controller(arm, phases=[long])
    assert caught.value.value == (0.0, 1.5)
