"""Log storage: rows, save and load."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import ball_scene

from ucontrol.log import SAMPLE_FIELDS, Log
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
