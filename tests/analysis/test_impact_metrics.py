"""Figures of a landing against hand-computed logs (ucontrol.analysis.impact_metrics)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.analysis import impact_metrics as im
from ucontrol.exceptions import NotFoundError
from ucontrol.log import Log

H = 0.01  # [s] the rows' spacing
N = 101  # rows, t = 0 ... 1 s


def _log(
    u: np.ndarray,
    impulse: np.ndarray,
    normal_velocity: np.ndarray,
    impacts: list[float],
    lambda_d: float = 6.0,
    target: np.ndarray | None = None,
) -> Log:
    """A one-constraint log ``c`` with the given rows (q = v = 0) and impact times."""
    log = Log(N, nq=1, nv=1, nu=1, constraint_names=["c"])
    log.add_field("lambda_d", (1,))
    if target is not None:
        log.add_field("task_target", (target.shape[1],))
    for k in range(N):
        log.record_state(k * H, np.zeros(1), np.zeros(1), np.zeros(1), normal_velocity[k], 0.0)
        log.record_extra("lambda_d", [lambda_d])
        if target is not None:
            log.record_extra("task_target", target[k])
        log.record_step_without_solve(u[k], impulse[k], impulse[k] > 0.0)
    log.record_impacts([(0, t) for t in impacts])
    return log


def _landing_log() -> tuple[Log, np.ndarray, np.ndarray]:
    """First impact at row 30 (t = 0.3 s), a second at 0.35 s, a third outside the window."""
    u = np.zeros((N, 1))
    u[33:] = 1.0  # a 1 N m jump at row 33, inside [t_1, t_1 + 0.1]
    u[55:] = 11.0  # a 10 N m jump at row 55, outside it
    impulse = np.zeros((N, 1))
    normal_velocity = np.zeros((N, 1))
    impulse[31:] = 5.0 * H  # 5 N held after the impact
    impulse[30], normal_velocity[30] = 1.0, -0.3  # the impact steps: no force figure
    impulse[35], normal_velocity[35] = 0.3, -0.2
    impulse[36] = 8.0 * H  # 8 N against lambda_d = 6 N: overshoot 2 N
    impulse[90] = 50.0 * H  # 50 N after t_1 + 0.5 s: outside the force window
    log = _log(u, impulse, normal_velocity, impacts=[0.3, 0.35, 0.95])
    velocities = np.zeros((N, 3))
    references = np.zeros((N, 3))
    velocities[29] = (0.0, 0.0, 3.0)  # before t_1: not counted
    velocities[32] = (0.3, 0.0, 0.4)  # error 0.5 m/s
    references[34] = (0.0, 0.2, 0.0)  # error 0.2 m/s
    velocities[45] = (0.0, 0.0, 2.0)  # after t_1 + 0.1 s: not counted
    return log, velocities, references


def test_landing_figures_match_the_hand_computed_ones() -> None:
    log, velocities, references = _landing_log()
    window = im.landing_window(start=0.4, end=0.8, period=1.0, k=0)
    assert window == pytest.approx((0.1, 0.8))  # half the 0.6 s of free flight before
    landing = im.landing(log, velocities, references, "c", window)
    assert landing.t_1 == pytest.approx(0.3)
    assert landing.velocity_error == pytest.approx(0.5, rel=1e-12)
    assert landing.torque_jump == pytest.approx(1.0, rel=1e-12)
    assert landing.force_overshoot == pytest.approx(2.0, rel=1e-9)
    assert landing.impacts == 2  # 0.95 s is after the window


def test_force_below_the_desired_one_is_no_overshoot() -> None:
    log, velocities, references = _landing_log()
    log.impulse[36] = 5.0 * H
    landing = im.landing(log, velocities, references, "c", (0.1, 0.8))
    assert landing.force_overshoot == 0.0


def test_landing_without_an_impact_in_its_window_has_no_figures() -> None:
    log, velocities, references = _landing_log()
    landing = im.landing(log, velocities, references, "c", (0.4, 0.9))  # 0.35 and 0.95 outside
    assert landing.impacts == 0 and math.isnan(landing.t_1)
    assert math.isnan(landing.velocity_error) and math.isnan(landing.force_overshoot)


def test_an_unknown_contact_is_named() -> None:
    log, velocities, references = _landing_log()
    with pytest.raises(NotFoundError, match="'d'"):
        im.landing(log, velocities, references, "d", (0.1, 0.8))


def test_landing_window_of_a_later_cycle() -> None:
    # phase [5, 10] s of a 10 s cycle: 5 s of free flight, the window opens 2.5 s before
    assert im.landing_window(5.0, 10.0, 10.0, 1) == pytest.approx((12.5, 20.0))


def test_contact_held_needs_a_positive_impulse_on_every_step() -> None:
    log, _, _ = _landing_log()
    assert im.contact_held(log, "c", (0.5, 0.8))
    log.impulse[60] = 0.0  # one open step
    assert not im.contact_held(log, "c", (0.5, 0.8))
    assert im.contact_held(log, "c", (0.61, 0.8))
    assert not im.contact_held(log, "c", (0.9, 1.2))  # the run ended before the interval
    assert not im.contact_held(log, "c", (0.1, 0.2))  # before the landing: open


def test_settled_error_is_the_percentile_of_the_error() -> None:
    log, _, _ = _landing_log()
    velocities = np.zeros((N, 3))
    velocities[:, 0] = np.arange(N) * 0.001  # error 0.001 k m/s at row k
    references = np.zeros((N, 3))
    # rows 50 ... 70: errors 0.050 ... 0.070 m/s
    assert im.settled_error(log, velocities, references, (0.495, 0.705), 100.0) == pytest.approx(
        0.070
    )
    assert im.settled_error(log, velocities, references, (0.495, 0.705)) == pytest.approx(
        np.percentile(np.arange(50, 71) * 0.001, 95)
    )
    assert math.isnan(im.settled_error(log, velocities, references, (0.9, 1.1)))


def test_target_velocities_differentiate_and_skip_a_switch() -> None:
    a, b = 0.6, 0.25  # X = (a t^2, b t) [m], a jump of 5 mm of X_0 between rows 49 and 50
    t = np.arange(N) * H
    target = np.column_stack([a * t**2, b * t])
    target[50:, 0] += 5e-3
    log = _log(np.zeros((N, 1)), np.zeros((N, 1)), np.zeros((N, 1)), [], target=target)
    directions = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # X_0 along z, X_1 along x
    world = im.target_velocities(log, directions)
    exact = np.column_stack([np.full(N, b), np.zeros(N), 2 * a * t])
    error = np.abs(world - exact).max(axis=1)
    inner = np.r_[1:49, 51 : N - 1]
    assert error[inner].max() < 1e-12  # central differences are exact on a parabola
    # one-sided at the ends and at the switch: error a h, without the jump's 0.5 m/s
    assert error[[0, 49, 50, N - 1]].max() == pytest.approx(a * H, rel=1e-9)


def test_frame_velocities_of_a_prismatic_joint() -> None:
    model = pin.Model()
    joint = model.addJoint(
        0, pin.JointModelPrismaticUnaligned(np.array([0.6, 0.0, 0.8])), pin.SE3.Identity(), "slide"
    )
    model.addFrame(pin.Frame("tip", joint, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    log = Log(3, nq=1, nv=1, nu=1, constraint_names=[])
    for k, v in enumerate([0.0, 1.0, -2.0]):
        log.record_state(k * H, np.array([0.1 * k]), np.array([v]), np.zeros(0), np.zeros(0), 0.0)
        log.record_step_without_solve(np.zeros(1), np.zeros(0), np.zeros(0, bool))
    velocities = im.frame_velocities(log, model, "tip")
    expected = np.outer([0.0, 1.0, -2.0], [0.6, 0.0, 0.8])
    np.testing.assert_allclose(velocities, expected, atol=1e-15)
