"""The two-link task's designed cycle, solved once per test session (the solve takes seconds)."""

from __future__ import annotations

import functools
from pathlib import Path

from ucontrol.design import DesignedCycle, DesignReport, DesignTask, design_cycle

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
TASK = ROBOTS / "two_link_one_constraint_task.toml"


@functools.cache
def two_link_task() -> DesignTask:
    """The shipped two-link one-constraint task."""
    return DesignTask.from_toml(TASK)


@functools.cache
def two_link_design() -> tuple[DesignedCycle, DesignReport]:
    """Its designed cycle and report."""
    return design_cycle(two_link_task())
