"""Runs that write their log while they go, and runs whose plant leaves the finite numbers.

With an output directory, :func:`ucontrol.simulate.simulate` rewrites ``log.npz`` every
``CHECKPOINT_PERIOD_S`` of wall time (checked every 1000 steps): a run killed part-way
leaves its samples up to the last checkpoint. The period is set to -1 s here, so that every
check is due whatever the clock says; an observer (called after every step) reads the
file while the run goes on.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import ucontrol.simulate
from ucontrol.exceptions import SimulationError
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

#: Steps after which the observer reads the file (around the checks of steps 0, 1000, 2000).
READ_AT = (0, 1, 1000, 1001, 1500, 2000, 2001)


def _reader(path: Path, seen: dict[int, int | None]) -> object:
    """Observer that records how many rows the file on disk holds (None: no file yet)."""

    def observer(log: Log) -> None:
        step = len(log) - 1
        if not path.exists():
            seen[step] = None
            return
        if step not in READ_AT:
            return
        saved = Log.load(path)
        seen[step] = len(saved)
        if step in (1500, 2001):  # mid-run and at the end: the file holds the run's rows
            np.testing.assert_array_equal(saved.t, log.t[: len(saved)])
            np.testing.assert_array_equal(saved.q, log.q[: len(saved)])
            np.testing.assert_array_equal(saved.v, log.v[: len(saved)])

    return observer


def test_a_checkpoint_is_written_every_1000_steps_when_due(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, two_link_scene: Scene
) -> None:
    monkeypatch.setattr(ucontrol.simulate, "CHECKPOINT_PERIOD_S", -1.0)  # always due
    path = tmp_path / "log.npz"
    seen: dict[int, int | None] = {}
    simulate(two_link_scene, duration=2.5, dt=1e-3, out=tmp_path, observer=_reader(path, seen))
    # Rows 0..k are complete after step k; the checkpoint of step k follows its observer call.
    assert seen[0] is None  # nothing written before the first check
    assert seen[1] == seen[1000] == 1  # written at step 0: its one complete row
    assert seen[1001] == seen[2000] == 1001  # written at step 1000
    assert seen[2001] == 2001
    assert len(Log.load(path)) == 2501  # the final save: every row


def test_no_checkpoint_is_written_before_its_period(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, two_link_scene: Scene
) -> None:
    monkeypatch.setattr(ucontrol.simulate, "CHECKPOINT_PERIOD_S", 1e9)  # [s], never due
    path = tmp_path / "log.npz"
    seen: dict[int, int | None] = {}
    simulate(two_link_scene, duration=1.5, dt=1e-3, out=tmp_path, observer=_reader(path, seen))
    assert len(seen) == 1501 and set(seen.values()) == {None}  # only the final save writes
    assert len(Log.load(path)) == 1501


def test_a_state_that_overflows_stops_the_run_with_its_finite_samples(
    tmp_path: Path, two_link_scene: Scene
) -> None:
    # A torque of 1e308 N m on the arm: the velocity update h M^-1 tau exceeds the largest
    # double (1.8e308) at the first step. The run stops there; the log keeps the initial
    # sample, saved to the output directory.
    def overflowing(t: float, q: np.ndarray, v: np.ndarray, contacts: object) -> np.ndarray:
        return np.full(2, 1e308)  # [N m], finite

    with np.errstate(over="ignore", invalid="ignore"), pytest.raises(SimulationError) as raised:
        simulate(two_link_scene, overflowing, duration=0.05, dt=1e-3, out=tmp_path)
    error = raised.value
    assert error.step == 0 and error.time == 0.0
    assert "the state became non-finite at t = 0.001 s" in error.reason
    assert isinstance(error.__cause__, ArithmeticError)
    assert len(error.log) == 1 and np.all(np.isfinite(error.log.q))
    np.testing.assert_array_equal(error.log.q[0], two_link_scene.q0)
    saved = Log.load(error.log_path)
    np.testing.assert_array_equal(saved.q, error.log.q)
