"""The two-link task's designed cycle, solved once per test session (the solve takes seconds)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pinocchio as pin

from ucontrol.design import DesignedCycle, DesignReport, DesignTask, design_cycle

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
TASK = ROBOTS / "two_link_one_constraint_task.toml"
#: A coarse grid of the task (6 + 6 intervals of 3 RK4 steps) for the tests that need a solve
#: but not the shipped grid's optimum: the same program for them all (bounds and IPOPT's
#: options are not part of it), compiled once per cache instead of once per test.
COARSE_GRID = {"flight_intervals": 6, "contact_intervals": 6, "substeps": 3}


@functools.cache
def two_link_task() -> DesignTask:
    """The shipped two-link one-constraint task."""
    return DesignTask.from_toml(TASK)


@functools.cache
def two_link_design(compiled: bool | None = None) -> tuple[DesignedCycle, DesignReport]:
    """Its designed cycle and report (``compiled``: the switch of :func:`design_cycle`)."""
    return design_cycle(two_link_task(), compiled=compiled)


def pinocchio_terms(task: DesignTask, q: np.ndarray, v: np.ndarray):  # type: ignore[no-untyped-def]
    """M, h, J_n and J̇_n v of the contact from Pinocchio (not the casadi model)."""
    robot, contact = task.scene.robot, task.contact
    model, data = robot.model, pin.Data(robot.model)
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
