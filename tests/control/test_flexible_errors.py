"""Bad parameters of the flexible-joint law raise typed errors naming the value."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from flexible_arm import (
    GAINS,
    MOTOR_INERTIA,
    Q0,
    STIFFNESS,
    contact_state,
    controller,
    cycle,
    ground,
    robot,
    task,
)

from ucontrol.control import (
    BrogliatoGains,
    CirclePath,
    DesiredCycle,
    FlexibleBrogliatoController,
    TaskCoordinates,
)
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    ShapeError,
    SolverError,
)
from ucontrol.model import FlexibleJoints


def _flexible(**changes) -> FlexibleJoints:
    parameters = {"stiffness": STIFFNESS, "motor_inertia": MOTOR_INERTIA, **changes}
    return FlexibleJoints.from_robot(robot(), ["shoulder", "elbow"], **parameters)


@pytest.mark.parametrize("name", ["gamma1", "gamma2"])
def test_non_positive_gamma(name: str) -> None:
    with pytest.raises(InvalidParameterError, match=rf"`{name}` must be > 0, got 0.0"):
        BrogliatoGains(**{"gamma1": 10.0, "gamma2": 5.0, name: 0.0})


def test_missing_task_frame() -> None:
    with pytest.raises(FrameNotFoundError, match="unknown frame 'tool'"):
        TaskCoordinates(robot(), "tool", [], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def test_redundant_task_is_refused() -> None:
    arm = robot()
    gap_only = TaskCoordinates(arm, "end_effector", [ground()])
    with pytest.raises(InvalidParameterError, match=r"`task` must be a square task of m = nv = 2"):
        FlexibleBrogliatoController(arm, _flexible(), gap_only, cycle(), GAINS)


def test_transmission_damping_is_refused() -> None:
    arm = robot()
    flexible = _flexible(damping=[0.0, 0.1])
    with pytest.raises(InvalidParameterError, match=r"`damping` must be 0 on every") as info:
        FlexibleBrogliatoController(arm, flexible, task(arm), cycle(), GAINS)
    assert info.value.value == [0.0, 0.1]


def test_flexible_joints_of_another_robot() -> None:
    arm = robot()
    other = dataclasses.replace(_flexible(), nq=3, nv=3)
    with pytest.raises(InvalidParameterError, match=r"`flexible` must be flexible joints of a"):
        FlexibleBrogliatoController(arm, other, task(arm), cycle(), GAINS)


def test_state_of_the_wrong_size() -> None:
    law = controller()
    with pytest.raises(ShapeError, match=r"`extended configuration q` must have shape \(4,\)"):
        law(0.0, Q0, np.zeros(4), contact_state())


def test_unreachable_target() -> None:
    arm = robot()
    far = CirclePath(centre=np.array([2.0, 0.5, 0.0]), radius=0.1, period=10.0)  # reach: 1 m
    unreachable = DesiredCycle(path=far, contact_phases=cycle().contact_phases)
    law = FlexibleBrogliatoController(arm, _flexible(), task(arm), unreachable, GAINS)
    with pytest.raises(SolverError, match="Newton's method for the link reference"):
        law(0.0, np.concatenate([Q0, Q0]), np.zeros(4), contact_state())
