"""The designed cycle of the two-link task.

KKT residuals, constraints checked with Pinocchio, open-loop replay in the event-driven plant,
infeasible tasks, the cycle file and its nominal path.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.design import DesignedCycle, DesignTask, design_cycle
from ucontrol.design.open_loop_replay import replay_open_loop
from ucontrol.exceptions import InfeasibleDesignError

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
TASK = ROBOTS / "two_link_one_constraint_task.toml"


@pytest.fixture(scope="module")
def task() -> DesignTask:
    return DesignTask.from_toml(TASK)


@pytest.fixture(scope="module")
def designed(task: DesignTask):  # type: ignore[no-untyped-def]
    return design_cycle(task)


def _terms(task: DesignTask, q: np.ndarray, v: np.ndarray):  # type: ignore[no-untyped-def]
    """M, h, J_n and J̇_n v of the contact from Pinocchio (not the casadi model)."""
    robot, contact = task.scene.robot, task.contact
    model, data = robot.model, robot.model.createData()
    frame = robot.frame_id(contact.frame)
    M = pin.crba(model, data, q, pin.Convention.WORLD)
    M = np.triu(M) + np.triu(M, 1).T
    h = pin.nonLinearEffects(model, data, q, v)
    pin.forwardKinematics(model, data, q, v, np.zeros(robot.nv))
    pin.updateFramePlacements(model, data)
    J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
    drift = pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED).linear
    n = contact.surface.normal
    gap = n @ (data.oMf[frame].translation - contact.surface.point) - contact.radius
    return M, h, n @ J, n @ drift, gap


def test_ipopt_converged_with_small_kkt_residuals(designed) -> None:  # type: ignore[no-untyped-def]
    _, report = designed
    assert report.success, report.status
    assert report.inf_pr <= 1e-8
    assert report.inf_du <= 1e-6
    # stationarity recomputed from casadi's Jacobians and IPOPT's multipliers
    assert report.stationarity <= 1e-6
    assert report.complementarity <= 1e-6
    assert report.multiplier_sign_error <= 1e-8
    assert report.max_violation <= 1e-6


def test_constraints_hold_in_pinocchio_terms(task, designed) -> None:  # type: ignore[no-untyped-def]
    cycle, _ = designed
    flight, contact = cycle.phase("flight"), cycle.phase("contact")
    spec = task.contact_phase
    # periodicity, torque and joint limits
    np.testing.assert_allclose(flight.q[0], contact.q[-1], atol=1e-9)
    np.testing.assert_allclose(flight.v[0], contact.v[-1], atol=1e-9)
    for phase in cycle.phases:
        assert np.all(np.abs(phase.tau) <= task.torque_limit + 1e-6)
        assert np.all(phase.q >= task.joint_limits[0] - 1e-6)
        assert np.all(phase.q <= task.joint_limits[1] + 1e-6)
    # landing on the surface, at the task's point, then the impact map M (v+ - v-) = J^T P
    q_land, v_minus, v_plus = flight.q[-1], flight.v[-1], contact.v[0]
    M, _, J_n, _, gap = _terms(task, q_land, v_minus)
    assert abs(gap) <= 1e-9
    np.testing.assert_allclose(flight.position[-1], spec.landing, atol=1e-9)
    np.testing.assert_allclose(M @ (v_plus - v_minus), J_n * cycle.impulses[0], atol=1e-8)
    assert abs(J_n @ v_plus) <= 1e-9  # plastic: the plant's threshold for e = 0.7
    assert -(J_n @ v_minus) <= 0.5 * task.zeno_velocity / 0.7 + 1e-8
    # contact forces from Pinocchio's dynamics: lambda = -(J a_free + J̇v) / (J M^-1 J^T)
    for k in range(len(contact.t) - 1):
        M, h, J_n, drift, gap = _terms(task, contact.q[k], contact.v[k])
        a_free = np.linalg.solve(M, contact.tau[k] - h)
        force = -(J_n @ a_free + drift) / (J_n @ np.linalg.solve(M, J_n))
        assert force == pytest.approx(contact.force[k], abs=1e-7)
        assert abs(gap) <= 1e-7
        if k < len(contact.t) - 1 - max(2, (len(contact.t) - 1) // 5):
            assert force >= spec.force_min - 1e-6
        assert force <= spec.force_max + 1e-6
    assert abs(contact.force[-1]) <= 1e-8  # takeoff: the force has fallen to 0
    assert cycle.period == pytest.approx(task.period, abs=1e-9)


def test_open_loop_replay_in_the_event_driven_plant(task, designed) -> None:  # type: ignore[no-untyped-def]
    cycle, _ = designed
    restarted = replay_open_loop(task, cycle, restart=True)
    assert restarted.q_error <= 1e-6  # [rad], one control interval from each design node
    # the soft landing (plastic below zeno_velocity) is not timed: its time is ill-conditioned
    assert restarted.impact_time_errors.size == 1 and np.isnan(restarted.impact_time_errors[0])
    # one open-loop run from takeoff: the same defect, amplified by the open-loop
    # instability of the arm under held torques, stays small over the first intervals
    run = replay_open_loop(task, cycle)
    flight = cycle.phase("flight")
    np.testing.assert_allclose(run.q[:3], flight.q[:3], atol=1e-5)


def test_a_force_beyond_the_torque_limits_is_infeasible_and_names_the_limit() -> None:
    table = tomllib.loads(TASK.read_text())
    table["contact_phases"][0]["force_min"] = (
        400.0  # [N]: needs about 0.55 m x 400 N at the shoulder
    )
    table["contact_phases"][0]["force_max"] = 500.0
    table["solver"]["max_iter"] = 200
    table["grid"] = {"flight_intervals": 10, "contact_intervals": 10, "substeps": 2}
    task = DesignTask.from_dict(table, base_dir=ROBOTS)
    with pytest.raises(InfeasibleDesignError, match="torque limit of joint 'shoulder'") as error:
        design_cycle(task)
    name, violation = error.value.binding[0]
    assert "shoulder" in name
    assert violation > 50.0  # [N m] beyond the 100 N m limit
    assert error.value.best is not None
    assert not error.value.report.success


def test_cycle_file_round_trip_and_nominal_path(task, designed, tmp_path) -> None:  # type: ignore[no-untyped-def]
    cycle, _ = designed
    path = cycle.save(tmp_path / "cycle")
    loaded = DesignedCycle.load(path)
    assert loaded.contact == cycle.contact and loaded.period == cycle.period
    for a, b in zip(loaded.phases, cycle.phases, strict=True):
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.tau, b.tau)
    nominal = cycle.nominal_path()
    times, positions = cycle.nodes()
    for t, p in zip(times, positions, strict=True):
        np.testing.assert_allclose(nominal(float(t))[0], p, atol=1e-12)
        np.testing.assert_allclose(nominal(float(t) + cycle.period)[0], p, atol=1e-12)
    rng = np.random.default_rng(11)
    step = 1e-4  # [s]
    for t in rng.uniform(0.0, cycle.period, 5):
        d = nominal.derivatives(float(t), 4)
        for k in range(1, 5):
            lower = nominal.derivatives(float(t) - step, k - 1)[k - 1]
            upper = nominal.derivatives(float(t) + step, k - 1)[k - 1]
            scale = max(1.0, float(np.max(np.abs(d[k]))))
            assert np.max(np.abs((upper - lower) / (2 * step) - d[k])) <= 1e-4 * scale
    desired = loaded.desired_cycle()
    assert desired.contact_phases[0].start == pytest.approx(cycle.landing_time)
    coordinates = TaskCoordinates(task.scene.robot, cycle.frame, [task.contact], [[1.0, 0.0, 0.0]])
    desired.check(coordinates)  # no path through the ground outside the contact phase


def test_a_bounce_replays_with_its_impact_time() -> None:
    table = tomllib.loads(TASK.read_text())
    table["bounces"] = 1
    table["limits"]["impact_velocity"] = 0.05  # [m/s]
    table["grid"] = {
        "flight_intervals": 14,
        "bounce_intervals": 8,
        "contact_intervals": 10,
        "substeps": 6,
    }
    task = DesignTask.from_dict(table, base_dir=ROBOTS)
    cycle, report = design_cycle(task)
    assert report.success, report.status
    flight, bounce = cycle.phase("flight"), cycle.phase("bounce_1")
    # Newton's law at the first impact, in Pinocchio terms
    M, _, J_n, _, _ = _terms(task, flight.q[-1], flight.v[-1])
    u_minus, u_plus = J_n @ flight.v[-1], J_n @ bounce.v[0]
    assert u_minus == pytest.approx(-0.05, abs=1e-8)  # the bound is active
    assert u_plus == pytest.approx(-0.7 * u_minus, abs=1e-9)
    np.testing.assert_allclose(M @ (bounce.v[0] - flight.v[-1]), J_n * cycle.impulses[0], atol=1e-8)
    replay = replay_open_loop(task, cycle, restart=True)
    assert replay.q_error <= 1e-5  # a coarse grid (h up to 0.5 s); 1e-6 on the shipped grid
    assert replay.impact_time_errors[0] <= 1e-6  # [s]
    assert np.isnan(replay.impact_time_errors[1])  # the soft landing is not timed
