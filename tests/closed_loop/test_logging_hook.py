"""The controller hook of simulate: fields added to the log, zero-order hold, saved metadata."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from brogliato_runs import scene
from conftest import ball_scene

from ucontrol.control import ContactState, Event, LoggingController
from ucontrol.log import Log
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out


class _Counter:
    """Pushes nothing; logs how many times it was called, and a flag only once per call."""

    def __init__(self) -> None:
        self.calls = 0
        self._fresh = False

    def __call__(self, t: float, q, v, contacts: ContactState) -> np.ndarray:
        self.calls += 1
        self._fresh = True
        return np.zeros(1)

    def prepare_log(self, log: Log) -> None:
        log.add_field("calls", (), np.int64)
        log.add_field("fresh", (), bool)
        log.metadata["labels"] = ["a", "b"]

    def record(self, log: Log) -> None:
        log.record_extra("calls", self.calls)
        log.record_extra("fresh", self._fresh)
        self._fresh = False


def test_fields_hold_the_last_call_between_calls(tmp_path: Path) -> None:
    controller = _Counter()
    assert isinstance(controller, LoggingController)
    log = simulate(
        ball_scene(0.9), controller, duration=0.05, dt=1e-3, control_period=1e-2, out=tmp_path
    ).log
    assert len(log) == 51
    np.testing.assert_array_equal(log.calls, np.minimum(np.arange(51) // 10 + 1, 5))
    assert np.flatnonzero(log.fresh).tolist() == [0, 10, 20, 30, 40]
    saved = Log.load(tmp_path / "log.npz")
    np.testing.assert_array_equal(saved.calls, log.calls)
    assert saved.metadata["labels"] == ["a", "b"]  # list metadata survive a round trip
    assert saved.metadata["actuated"] == [0]


def test_plain_functions_are_not_logging_controllers() -> None:
    assert not isinstance(lambda t, q, v, c: np.zeros(1), LoggingController)


def test_events_are_logged_once_with_a_slower_controller() -> None:
    log = simulate(scene("two_link_one_constraint"), duration=6.0, dt=1e-3, control_period=4e-3).log
    for flag in (Event.TAU0, Event.FIRST_IMPACT, Event.ACCUMULATION_END):
        assert np.count_nonzero(log.events[:, 0] & flag) == 1
    calls = np.arange(len(log)) % 4 == 0
    np.testing.assert_array_equal(log.V[1:][~calls[1:]], log.V[:-1][~calls[1:]])
