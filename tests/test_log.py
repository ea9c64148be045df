"""Log storage: rows, save and load."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import ball_scene

from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.log import SAMPLE_FIELDS, Log
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate


def test_log_round_trip(tmp_path: Path) -> None:
    log = simulate(ball_scene(0.9), duration=0.5, dt=1e-3).log
    loaded = Log.load(log.save(tmp_path / "log.npz"))
    assert len(loaded) == len(log) == 501
    assert loaded.constraint_names == ["ball/ground"]
    assert loaded.metadata["integrator"] == "moreau_jean"
    assert loaded.metadata["dt"] == 1e-3
    for name in SAMPLE_FIELDS:
        np.testing.assert_array_equal(getattr(loaded, name), getattr(log, name))


def test_log_rows_follow_the_step_convention() -> None:
    log = simulate(ball_scene(0.0), duration=0.6, dt=1e-3).log
    np.testing.assert_allclose(np.diff(log.t), 1e-3)
    assert log.impulse[-1, 0] == 0.0 and not log.active[-1, 0]  # no step after the last row
    hit = int(np.flatnonzero(log.impulse[:, 0] > 0)[0])
    # The impulse of row k acts over the step from t[k]: it turns v[k] into v[k + 1].
    assert log.v[hit, 0] < -4.0 and log.v[hit + 1, 0] == 0.0


def test_extra_fields(tmp_path: Path) -> None:
    log = Log(3, nq=1, nv=1, nu=1, constraint_names=[])
    log.add_field("phase", (), dtype=np.int64)
    for k in range(3):
        log.record_state(0.1 * k, [0.0], [0.0], [], [], 0.0)
        log.record_extra("phase", k)
        log.record_step([0.0], [], [], 0, 0.0)
    loaded = Log.load(log.save(tmp_path / "log.npz"))
    np.testing.assert_array_equal(loaded.phase, [0, 1, 2])


def test_accessors_by_constraint_name_and_time() -> None:
    """The mean ground force over a run closes the ball's momentum balance."""
    log = simulate(load_scene("ball"), duration=3.0).log
    name = "ball/ground"
    assert log.constraint_index(name) == 0
    np.testing.assert_array_equal(log.gap_of(name), log.gap[:, 0])
    np.testing.assert_array_equal(log.impulse_of(name), log.impulse[:, 0])
    force, times = log.force_of(name)
    assert force.shape == times.shape == (len(log) - 1,)
    # m (v_end - v_0) = mean(force) T - m g T (m = 1 kg, g = 9.81 m/s², T = 3 s): the last
    # row's zero impulse, which has no step, is not averaged in.
    duration = log.t[-1] - log.t[0]
    momentum = 1.0 * (log.v[-1, 0] - log.v[0, 0])
    assert np.mean(force) * duration == pytest.approx(momentum + 9.81 * duration, rel=1e-9)
    assert log.row_at(1.0005) == 1000 and log.row_at(1.0) == 1000
    np.testing.assert_array_equal(log.at("q", 1.0), log.q[1000])
    with pytest.raises(NotFoundError, match=r"constraint 'ball/table'.*ball/ground"):
        log.force_of("ball/table")
    with pytest.raises(InvalidParameterError, match=r"`t`.*4"):
        log.row_at(4.0)
    with pytest.raises(NotFoundError, match=r"log field 'phase'"):
        log.at("phase", 1.0)
