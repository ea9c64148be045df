"""The seven-joint case: the Panda lands on a table, slides under force control, takes off."""

from __future__ import annotations

import numpy as np
import pytest
from brogliato_runs import run, scene

from ucontrol.analysis.cycles import cycle_events
from ucontrol.control import BrogliatoController, Phase
from ucontrol.exceptions import URDFError
from ucontrol.log import Log
from ucontrol.model import example_robot_data_dir

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

CYCLES = 2


@pytest.fixture(scope="module")
def panda() -> tuple[BrogliatoController, Log]:
    try:
        example_robot_data_dir()
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")
    controller, result = run("panda_table", CYCLES)
    return controller, result.log


def test_the_task_is_redundant(panda) -> None:
    controller, _ = panda
    assert (controller.task.m, controller.robot.nv) == (3, 9)


def test_every_cycle_lands_slides_and_takes_off(panda) -> None:
    _controller, log = panda
    cycles = cycle_events(log)
    assert len(cycles) == CYCLES and all(cycle.complete for cycle in cycles)
    for cycle in cycles:
        t_f, t_d = cycle.accumulation_end[0], cycle.takeoff[0]
        held = (log.t >= t_f) & (log.t < t_d)
        assert np.all(log.contact_phase[held, 0] == Phase.CONSTRAINED)
        assert np.all(np.abs(log.gap[held, 0]) < 1e-3)  # [m] on the table
        x = log.task_position[held, 1]
        assert x.max() - x.min() > 0.15  # [m] it slides along the table
        middle = (log.t > t_f + (t_d - t_f) / 3) & (log.t < t_d - (t_d - t_f) / 3)
        mean = log.contact_force[middle, 0].mean()
        assert mean == pytest.approx(log.lambda_d[middle, 0].mean(), rel=0.02)
        after = (log.t > t_d + 0.5) & (log.t < t_d + 1.0)
        assert np.all(log.gap[after, 0] > 0.01)  # [m] it took off


def test_free_motion_tracking_and_the_null_space_posture(panda) -> None:
    _controller, log = panda
    free = ((log.phase == Phase.FREE) | (log.phase == Phase.TAKEOFF)) & (log.t >= 4.0)
    error = np.linalg.norm(log.task_position - log.task_desired, axis=1)
    assert error[free].max() < 2e-4  # [m], the hold bound dt a_max / γ2 = 1e-3 · 1 / 10
    q0 = scene("panda_table").q0
    arm = slice(0, 7)
    assert np.abs(log.q[:, arm] - q0[arm]).max() < 0.5  # [rad] the posture holds the arm
    fingers = log.q[:, 7:]
    assert np.all(np.abs(fingers - q0[7:]) < 2e-3)  # [m] the fingers keep their opening
