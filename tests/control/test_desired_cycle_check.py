"""`DesiredCycle.check` samples a nominal path once per path content, with the same verdicts.

The reference is the check's definition sampled afresh: the task coordinates of the path at
each of the :data:`PATH_SAMPLES` times, one `TaskCoordinates.of_point` call per time.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ucontrol.control import desired_cycle
from ucontrol.control.circle_path import CirclePath
from ucontrol.control.desired_cycle import (
    PATH_SAMPLES,
    PATH_TOLERANCE,
    ContactPhase,
    DesiredCycle,
    sampled_positions,
)
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.exceptions import PathThroughSurfaceError
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: The reference's task coordinates and the check's agree to this, in [m] (round-off of a
#: 3-term dot product on coordinates below 1 m).
ROUND_OFF = 1e-15


@dataclasses.dataclass(frozen=True)
class CountingCircle:
    """A circle of centre (cx, 0, 0) and radius r in the x-y plane that counts its calls."""

    cx: float
    r: float
    period: float = 10.0
    calls: list[int] = dataclasses.field(default_factory=lambda: [0], compare=False)

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.calls[0] += 1
        phi = 2 * math.pi * t / self.period
        zero = np.zeros(3)
        return np.array([self.cx + self.r * math.cos(phi), self.r * math.sin(phi), 0.0]), zero, zero

    def derivatives(self, t: float, order: int) -> tuple[np.ndarray, ...]:
        return self(t)[: order + 1]


@pytest.fixture(autouse=True)
def _no_samples_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test starts with no path sampled (the samples are kept per process)."""
    monkeypatch.setattr(desired_cycle, "_path_samples", type(desired_cycle._path_samples)())


def _task(ground_y: float = 0.0) -> TaskCoordinates:
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    table["controller"] = {"type": "zero"}
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    contact = scene.contacts[0]
    surface = dataclasses.replace(contact.surface, point=np.array([0.0, ground_y, 0.0]))
    moved = dataclasses.replace(contact, surface=surface)
    return TaskCoordinates(scene.robot, "end_effector", [moved], [[1.0, 0.0, 0.0]])


def _reference_verdict(cycle: DesiredCycle, task: TaskCoordinates) -> tuple[float, float] | None:
    """The first-sampled deepest point outside the phases, (time, gap), or None: the definition."""
    t = np.linspace(0.0, cycle.period, PATH_SAMPLES, endpoint=False)
    gaps = np.array([task.of_point(cycle.path(float(time))[0])[0] for time in t])
    inside = gaps < -PATH_TOLERANCE
    for phase in cycle.contact_phases:
        inside &= ~phase.covers(t, cycle.period)
    if not inside.any():
        return None
    worst = int(np.argmin(np.where(inside, gaps, math.inf)))
    return float(t[worst]), float(gaps[worst])


def _verdict(cycle: DesiredCycle, task: TaskCoordinates) -> tuple[float, float] | None:
    try:
        cycle.check(task)
    except PathThroughSurfaceError as error:
        return error.time, error.gap
    return None


def _assert_same(found: tuple[float, float] | None, expected: tuple[float, float] | None) -> None:
    assert (found is None) == (expected is None)
    if found is not None and expected is not None:
        assert found[0] == expected[0]  # the same sample
        assert found[1] == pytest.approx(expected[1], abs=ROUND_OFF)


def test_equal_paths_are_sampled_once_and_give_the_definitions_verdicts() -> None:
    task = _task()
    first = CountingCircle(cx=0.65, r=0.1)
    # The circle dips 0.1 m below the ground over t in (5, 10) s; the phase covers part of it.
    phase = ContactPhase(contact=task.names[0], start=6.0, end=9.0, force=1.0)
    cycle = DesiredCycle(path=first, contact_phases=(phase,))
    expected = _reference_verdict(cycle, task)
    assert expected is not None and (5.0 < expected[0] < 6.0 or 9.0 < expected[0] < 10.0)
    first.calls[0] = 0
    _assert_same(_verdict(cycle, task), expected)
    assert first.calls[0] == PATH_SAMPLES
    # An equal path (a new object, the same content) is not sampled again.
    second = CountingCircle(cx=0.65, r=0.1)
    _assert_same(_verdict(dataclasses.replace(cycle, path=second), task), expected)
    assert second.calls[0] == 0
    # The verdict follows the task with the path's samples kept: ground 0.2 m lower, no dip.
    lower = _task(ground_y=-0.2)
    assert _reference_verdict(cycle, lower) is None
    _assert_same(_verdict(dataclasses.replace(cycle, path=second), lower), None)
    assert second.calls[0] == 0
    # A different path is sampled anew, and judged on its own samples.
    third = CountingCircle(cx=0.65, r=0.05)
    other = dataclasses.replace(cycle, path=third)
    expected_third = _reference_verdict(other, task)
    assert expected_third is not None and expected_third != expected
    third.calls[0] = 0
    _assert_same(_verdict(other, task), expected_third)
    assert third.calls[0] == PATH_SAMPLES


def test_samples_are_the_paths_positions_and_read_only() -> None:
    path = CirclePath(centre=[0.6, 0.02, 0.0], radius=0.07, period=3.0)
    t = np.linspace(0.0, 3.0, 97, endpoint=False)
    positions = sampled_positions(path, t)
    assert positions.shape == (97, 3)
    np.testing.assert_array_equal(positions, [path(float(time))[0] for time in t])
    assert sampled_positions(CirclePath(centre=[0.6, 0.02, 0.0], radius=0.07, period=3.0), t) is (
        positions
    )
    with pytest.raises(ValueError):
        positions[0, 0] = 1.0
    # Other times of the same path are other samples.
    assert sampled_positions(path, t[:50]).shape == (50, 3)


def test_a_path_that_cannot_be_pickled_is_sampled_at_every_check() -> None:
    task = _task()
    path = CountingCircle(cx=0.65, r=0.05)
    unpicklable = dataclasses.replace(path, calls=[0])
    object.__setattr__(unpicklable, "hook", lambda: None)  # a lambda: pickle refuses it
    phase = ContactPhase(contact=task.names[0], start=6.0, end=9.0, force=1.0)
    cycle = DesiredCycle(path=unpicklable, contact_phases=(phase,))
    expected = _reference_verdict(cycle, task)
    for _ in range(2):
        unpicklable.calls[0] = 0
        _assert_same(_verdict(cycle, task), expected)
        assert unpicklable.calls[0] == PATH_SAMPLES
