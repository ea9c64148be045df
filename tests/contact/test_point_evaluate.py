"""Point contacts' gaps and normal velocities (ConstraintSet.evaluate), on any data buffer."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.contact import ConstraintSet, Plane, PointContact
from ucontrol.model import RobotModel

#: Step of the central differences on the manifold [s].
_STEP = 1e-6
#: Their error bound on the normal velocities [m/s] (O(step²) plus round-off over the step).
_FD_TOLERANCE = 1e-7
#: Gaps against the frame placements of a fresh buffer [m] (the same arithmetic up to order).
_GAP_TOLERANCE = 1e-15

_GROUND = Plane(name="ground")
_TILTED = Plane(point=[0.1, -0.2, 0.05], normal=[0.3, 1.0, 0.5], name="tilted")


def _table() -> tuple[RobotModel, ConstraintSet]:
    """The four-legged table on a free flyer, its feet against two planes."""
    robot = RobotModel.from_urdf(ROBOTS / "table.urdf", floating_base=True)
    contacts = [
        PointContact(frame="foot_fl", surface=_GROUND, radius=0.02, friction=0.7),
        PointContact(frame="foot_fr", surface=_TILTED, radius=0.03),
        PointContact(frame="foot_bl", surface=_GROUND),
        PointContact(frame="foot_br", surface=_TILTED, radius=0.01, friction=1.0),
    ]
    return robot, ConstraintSet(robot, contacts)


def _state(robot: RobotModel, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    return q, rng.standard_normal(robot.nv)


def _evaluated(robot: RobotModel, q: np.ndarray, v: np.ndarray) -> pin.Data:
    """A buffer holding what :meth:`ConstraintSet.evaluate` reads at (q, v)."""
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    return data


def _reference(
    robot: RobotModel, constraints: ConstraintSet, q: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Gaps n·(p_F - p0) - r and their time derivatives by central differences on q."""

    def gaps(step: float) -> np.ndarray:
        data = pin.Data(robot.model)
        pin.framesForwardKinematics(robot.model, data, pin.integrate(robot.model, q, step * v))
        return np.array(
            [
                contact.surface.normal
                @ (data.oMf[robot.frame_id(contact.frame)].translation - contact.surface.point)
                - contact.radius
                for contact in constraints.contacts
            ]
        )

    return gaps(0.0), (gaps(_STEP) - gaps(-_STEP)) / (2.0 * _STEP)


def test_gaps_and_velocities_against_placements_and_differences() -> None:
    robot, constraints = _table()
    for seed in range(3):
        q, v = _state(robot, seed)
        gap, velocity = constraints.evaluate(_evaluated(robot, q, v), q, v)
        gap_ref, velocity_ref = _reference(robot, constraints, q, v)
        assert np.max(np.abs(gap - gap_ref)) / _GAP_TOLERANCE <= 1.0
        assert np.max(np.abs(velocity - velocity_ref)) / _FD_TOLERANCE <= 1.0


def test_buffers_read_in_turn_give_each_its_own_state() -> None:
    """The frame origins are read from views on the last buffer: a new buffer is read anew."""
    robot, constraints = _table()
    states = [_state(robot, seed) for seed in (10, 11)]
    buffers = [_evaluated(robot, q, v) for q, v in states]
    references = [_reference(robot, constraints, q, v)[0] for q, v in states]
    for _ in range(2):
        for (q, v), data, gap_ref in zip(states, buffers, references, strict=True):
            gap, _ = constraints.evaluate(data, q, v)
            assert np.max(np.abs(gap - gap_ref)) / _GAP_TOLERANCE <= 1.0
    # The same buffer moved to another state: the views follow it.
    (q, v), data = states[1], buffers[0]
    pin.computeAllTerms(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    gap, _ = constraints.evaluate(data, q, v)
    assert np.max(np.abs(gap - references[1])) / _GAP_TOLERANCE <= 1.0


@pytest.mark.parametrize("duplicate", [copy.deepcopy, lambda x: pickle.loads(pickle.dumps(x))])
def test_a_copied_set_reads_its_copied_buffer(duplicate) -> None:
    """A copy of a set and of the buffer it read does not read the original buffer's memory."""
    robot, constraints = _table()
    (q, v), (q_other, v_other) = _state(robot, 20), _state(robot, 21)
    data = _evaluated(robot, q, v)
    constraints.evaluate(data, q, v)  # views on ``data`` taken
    copied, copied_data = duplicate((constraints, data))
    pin.computeAllTerms(robot.model, copied_data, q_other, v_other)
    pin.updateFramePlacements(robot.model, copied_data)
    gap, _ = copied.evaluate(copied_data, q_other, v_other)
    gap_ref = _reference(robot, constraints, q_other, v_other)[0]
    assert np.max(np.abs(gap - gap_ref)) / _GAP_TOLERANCE <= 1.0
