"""Point contacts' rows read together (ConstraintSet.contact_rows), their gaps and velocities."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.contact import ConstraintSet, JointStop, Plane, PointContact
from ucontrol.contact.tangent_basis import tangent_basis
from ucontrol.model import RobotModel

#: Step of the central differences on the manifold [s].
_STEP = 1e-6
#: Their error bound on the rows' velocities [m/s] (O(step²) plus round-off over the step).
_FD_TOLERANCE = 1e-7
#: Gaps against the frame placements of a fresh buffer [m] (the same arithmetic up to order).
_GAP_TOLERANCE = 1e-15

_GROUND = Plane(name="ground")
_TILTED = Plane(point=[0.1, -0.2, 0.05], normal=[0.3, 1.0, 0.5], name="tilted")


def _table() -> tuple[RobotModel, ConstraintSet]:
    """The four-legged table on a free flyer: feet with and without friction, two planes."""
    robot = RobotModel.from_urdf(ROBOTS / "table.urdf", floating_base=True)
    contacts = [
        PointContact(frame="foot_fl", surface=_GROUND, radius=0.02, friction=0.7),
        PointContact(frame="foot_fr", surface=_TILTED, radius=0.03, friction=0.4),
        PointContact(frame="foot_bl", surface=_GROUND),  # frictionless: no tangential row
        PointContact(frame="foot_br", surface=_TILTED, radius=0.01, friction=1.0),
    ]
    return robot, ConstraintSet(robot, contacts)


def _two_link() -> tuple[RobotModel, ConstraintSet]:
    """The planar arm's tip against a tilted plane (spatial friction), and an elbow stop."""
    robot = RobotModel.from_urdf(ROBOTS / "two_link.urdf")
    contacts = [PointContact(frame="end_effector", surface=_TILTED, radius=0.05, friction=0.5)]
    stops = [JointStop(joint="elbow", lower=-3.0, upper=-0.1)]
    return robot, ConstraintSet(robot, contacts, stops)


def _state(robot: RobotModel, seed: int) -> tuple[np.ndarray, np.ndarray, pin.Data]:
    rng = np.random.default_rng(seed)
    q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
    v = rng.standard_normal(robot.nv)
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)
    return q, v, data


def _contact_point_velocity(
    robot: RobotModel, contact: PointContact, q: np.ndarray, v: np.ndarray, data: pin.Data
) -> np.ndarray:
    """Velocity [m/s] of the body's material point at p_F - r n, by central differences."""
    frame = robot.frame_id(contact.frame)
    local = data.oMf[frame].rotation.T @ (-contact.radius * contact.surface.normal)

    def position(step: float) -> np.ndarray:
        moved = pin.Data(robot.model)
        pin.framesForwardKinematics(robot.model, moved, robot.integrate(q, step * v))
        return np.asarray(moved.oMf[frame].act(local))

    return (position(_STEP) - position(-_STEP)) / (2 * _STEP)


@pytest.mark.parametrize(
    ("seed", "indices", "tangential"),
    [(0, [3, 0, 2, 1], 6), (1, [0, 3], 4), (2, [2], 0), (3, [1, 3, 0], 6)],
)
def test_rows_are_velocities_of_the_contact_points(
    seed: int, indices: list[int], tangential: int
) -> None:
    """J v is n·v_c and T v is t·v_c for the material contact point's velocity v_c."""
    robot, constraints = _table()
    q, v, data = _state(robot, seed)
    for _ in range(2):  # the second call reuses the first's selection of rows
        J, T, directions = constraints.contact_rows(data, indices)
    assert J.shape == (len(indices), robot.nv)
    assert T.shape == (tangential, robot.nv) and directions.shape == (tangential, 3)
    start = 0
    for row, i in enumerate(indices):
        contact = constraints.contacts[i]
        velocity = _contact_point_velocity(robot, contact, q, v, data)
        normal = contact.surface.normal
        assert abs(J[row] @ v - normal @ velocity) < _FD_TOLERANCE
        count = int(constraints.tangent_count[i])
        tangents = tangent_basis(normal)[:count]
        end = start + count
        np.testing.assert_allclose(directions[start:end], tangents, atol=1e-15)
        np.testing.assert_allclose(T[start:end] @ v, tangents @ velocity, atol=_FD_TOLERANCE)
        start = end
    assert start == T.shape[0]


@pytest.mark.parametrize("build", [_table, _two_link])
def test_rows_read_together_equal_the_rows_read_apart(build) -> None:
    """contact_rows equals jacobian and tangent_rows, with or without other constraints."""
    robot, constraints = build()
    _, _, data = _state(robot, 7)
    every = list(range(constraints.size))
    for indices in (every, every[::-1], every[:1]):
        J, T, directions = constraints.contact_rows(data, indices)
        np.testing.assert_array_equal(J, constraints.jacobian(data, indices))
        T_apart, directions_apart = constraints.tangent_rows(data, indices)
        np.testing.assert_array_equal(T, T_apart)
        np.testing.assert_array_equal(directions, directions_apart)
        rows = np.vstack((J, T))
        assert np.all(np.isfinite(rows))
        # Each point contact's normal row against the frame's Jacobian, read on its own.
        for row, i in enumerate(indices):
            if i < len(constraints.contacts):
                contact = constraints.contacts[i]
                frame_jacobian = pin.getFrameJacobian(
                    robot.model, data, robot.frame_id(contact.frame), pin.LOCAL_WORLD_ALIGNED
                )
                np.testing.assert_allclose(
                    J[row], contact.surface.normal @ frame_jacobian[:3], atol=1e-15
                )


def _gaps_and_rates(
    robot: RobotModel, constraints: ConstraintSet, q: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Gaps n·(p_F - p0) - r on a fresh buffer, and their rates by central differences on q."""

    def gaps(step: float) -> np.ndarray:
        data = pin.Data(robot.model)
        pin.framesForwardKinematics(robot.model, data, robot.integrate(q, step * v))
        return np.array(
            [
                contact.surface.normal
                @ (data.oMf[robot.frame_id(contact.frame)].translation - contact.surface.point)
                - contact.radius
                for contact in constraints.contacts
            ]
        )

    return gaps(0.0), (gaps(_STEP) - gaps(-_STEP)) / (2.0 * _STEP)


def _move(robot: RobotModel, data: pin.Data, q: np.ndarray, v: np.ndarray) -> None:
    """What ConstraintSet.evaluate reads, computed on ``data`` at (q, v)."""
    pin.computeAllTerms(robot.model, data, q, v)
    pin.updateFramePlacements(robot.model, data)


def test_gaps_and_velocities_against_placements_and_differences() -> None:
    robot, constraints = _table()
    for seed in range(3):
        q, v, data = _state(robot, seed)
        gap, velocity = constraints.evaluate(data, q, v)
        gap_ref, velocity_ref = _gaps_and_rates(robot, constraints, q, v)
        assert np.max(np.abs(gap - gap_ref)) / _GAP_TOLERANCE <= 1.0
        assert np.max(np.abs(velocity - velocity_ref)) / _FD_TOLERANCE <= 1.0


def test_buffers_read_in_turn_give_each_its_own_state() -> None:
    """The frame origins are read from views on the last buffer: another buffer is read anew."""
    robot, constraints = _table()
    states = [_state(robot, seed) for seed in (10, 11)]
    references = [_gaps_and_rates(robot, constraints, q, v)[0] for q, v, _ in states]
    for _ in range(2):
        for (q, v, data), gap_ref in zip(states, references, strict=True):
            gap, _ = constraints.evaluate(data, q, v)
            assert np.max(np.abs(gap - gap_ref)) / _GAP_TOLERANCE <= 1.0
    # The first buffer moved to the second state: the views follow it.
    (_, _, data), (q, v, _) = states
    _move(robot, data, q, v)
    gap, _ = constraints.evaluate(data, q, v)
    assert np.max(np.abs(gap - references[1])) / _GAP_TOLERANCE <= 1.0


@pytest.mark.parametrize("duplicate", [copy.deepcopy, lambda x: pickle.loads(pickle.dumps(x))])
def test_a_copied_set_reads_its_copied_buffer(duplicate) -> None:
    """A copy of a set and of the buffer it read does not read the original buffer's memory."""
    robot, constraints = _table()
    (q, v, data), (q_other, v_other, _) = _state(robot, 20), _state(robot, 21)
    constraints.evaluate(data, q, v)  # views on ``data`` taken
    copied, copied_data = duplicate((constraints, data))
    _move(robot, copied_data, q_other, v_other)
    gap, _ = copied.evaluate(copied_data, q_other, v_other)
    gap_ref = _gaps_and_rates(robot, constraints, q_other, v_other)[0]
    assert np.max(np.abs(gap - gap_ref)) / _GAP_TOLERANCE <= 1.0
