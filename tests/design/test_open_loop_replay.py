"""Design model against plant: the designed torques replayed open-loop in the event-driven plant.

The two-link arm under held torques is open-loop unstable (an error grows by about 2.3 per
0.39 s control interval, about 1e7 over the flight), so a replay of the whole cycle from takeoff
reproduces the design only if every shooting interval agrees with the plant to rounding: the
task's order-8 Runge–Kutta steps (8 per interval) and IPOPT's tolerance of 1e-13 on the
defects, the plant's solve_ivp at its floor rtol = 100 machine epsilons.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pinocchio as pin
import pytest
from two_link_design import ROBOTS, TASK, two_link_design, two_link_task

from ucontrol.design import DesignTask, design_cycle
from ucontrol.design.open_loop_replay import replay_open_loop

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out


def _normal_jacobian(task: DesignTask, q: np.ndarray) -> np.ndarray:
    robot, contact = task.scene.robot, task.contact
    model, data = robot.model, pin.Data(robot.model)
    frame = robot.frame_id(contact.frame)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    J = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
    return contact.surface.normal @ J


def test_each_interval_agrees_with_the_plant_to_rounding() -> None:
    task = two_link_task()
    cycle, _ = two_link_design()
    restarted = replay_open_loop(task, cycle, restart=True)
    # measured 2.0e-15 rad and 9.1e-15 rad/s (8 RK8 steps per interval)
    assert restarted.q_error <= 2e-14
    assert restarted.v_error <= 1e-13


def test_the_whole_cycle_replays_open_loop() -> None:
    task = two_link_task()
    cycle, _ = two_link_design()
    run = replay_open_loop(task, cycle)
    # one open-loop run over the 10 s cycle, takeoff to takeoff: measured 1.9e-8 rad (1.5e-7
    # with M and h from SymbolicModel: rounding amplified ~1e7 by the open-loop instability);
    # the bound is the acceptance figure of the design model against the plant
    assert run.q_error <= 1e-6
    assert run.t[-1] == pytest.approx(cycle.period, abs=1e-12)
    # the soft landing (plastic below zeno_velocity) is not timed: its time is ill-conditioned
    assert run.impact_time_errors.size == 1 and np.isnan(run.impact_time_errors[0])


def test_a_bounce_replays_with_its_impact_time() -> None:
    table = tomllib.loads(TASK.read_text())
    table["bounces"] = 1
    table["limits"]["impact_velocity"] = 0.05  # [m/s]
    table["grid"] = {  # the coarsest grid that keeps the replay within 1e-6 rad
        "flight_intervals": 14,
        "bounce_intervals": 8,
        "contact_intervals": 10,
        "substeps": 4,
        "scheme": "rk8",
        "landing_interior": True,
    }
    task = DesignTask.from_dict(table, base_dir=ROBOTS)
    # solved in casadi's virtual machine: no other test compiles this program, whose build
    # costs many times the solve (the compiled path's optimum is the virtual machine's:
    # test_compiled_design.py)
    cycle, report = design_cycle(task, compiled=False)
    assert report.success, report.status
    flight, bounce = cycle.phase("flight"), cycle.phase("bounce_1")
    # Newton's law at the first impact, in Pinocchio terms
    J_n = _normal_jacobian(task, flight.q[-1])
    u_minus, u_plus = J_n @ flight.v[-1], J_n @ bounce.v[0]
    assert u_minus == pytest.approx(-0.05, abs=1e-8)  # the bound is active
    assert u_plus == pytest.approx(-0.7 * u_minus, abs=1e-9)
    run = replay_open_loop(task, cycle)  # the whole cycle, open-loop from takeoff
    # measured 1.3e-8 rad (the soft landing's last interval) and 3.6e-13 s
    assert run.q_error <= 1e-6
    assert run.impact_time_errors[0] <= 1e-11  # [s]
    assert np.isnan(run.impact_time_errors[1])  # the soft landing is not timed
