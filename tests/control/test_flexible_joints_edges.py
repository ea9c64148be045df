"""Flexible joints declared on the two-link arm: joint lists, parameters and state shapes."""

from __future__ import annotations

import numpy as np
import pytest
from flexible_arm import MOTOR_INERTIA, STIFFNESS, robot

from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.model import FlexibleJoints


def _flexible(joints=("shoulder", "elbow"), **changes) -> FlexibleJoints:
    parameters = {"stiffness": STIFFNESS, "motor_inertia": MOTOR_INERTIA, **changes}
    return FlexibleJoints.from_robot(robot(), list(joints), **parameters)


def test_a_joint_listed_twice_is_named():
    with pytest.raises(InvalidParameterError, match="distinct") as caught:
        _flexible(("elbow", "shoulder", "elbow"))
    assert caught.value.value == ["elbow", "shoulder", "elbow"]


def test_a_parameter_that_is_no_number_is_named():
    with pytest.raises(InvalidParameterError) as caught:
        _flexible(damping={"shoulder": 1.0})
    assert caught.value.name == "damping" and caught.value.value == {"shoulder": 1.0}


def test_the_extended_state_is_split_into_views_and_its_shape_checked():
    flexible = _flexible()
    rng = np.random.default_rng(8)
    q, v = rng.normal(size=4), rng.normal(size=4)
    q1, dq1, q2, dq2 = flexible.split(q, v)
    assert q1.tolist() == q[:2].tolist() and q2.tolist() == q[2:].tolist()
    assert dq1.tolist() == v[:2].tolist() and dq2.tolist() == v[2:].tolist()
    q2[0] = 7.0  # a view: the extended configuration changes with it
    assert q[2] == 7.0
    with pytest.raises(ShapeError) as caught:
        flexible.split(q, v[:3])
    assert caught.value.name == "extended velocity v" and caught.value.shape == (3,)


def test_an_empty_joint_list_is_named():
    with pytest.raises(InvalidParameterError, match="at least one joint") as caught:
        _flexible(())
    assert caught.value.value == []
