"""Run assertions and output locks: free falls, runs without constraints, stale lock files."""

from __future__ import annotations

import os
import textwrap

import pytest

from ucontrol.log import Log
from ucontrol.output_files import LOCK_FILE, OutputLock
from ucontrol.testing import (
    assert_no_energy_gain,
    assert_penetration_below,
    campaign_cases,
)

G = 9.81  # [m/s^2], the ball scene's gravity


def test_a_campaign_case_runs_its_free_fall_alone(tmp_path):
    path = tmp_path / "fall.toml"
    path.write_text(
        textwrap.dedent(
            """
            [campaign]
            scene = "ball.toml"
            duration = 0.1
            [grid]
            "robot.q0.0" = [0.6, 0.9]
            """
        )
    )
    cases = [param.values[0] for param in campaign_cases(path)]
    for case, q0 in zip(cases, (0.6, 0.9), strict=True):
        run = case.simulate()
        # θ = 1/2 integrates a constant acceleration exactly: q(T) = q0 - g T² / 2
        T = float(run.log.t[-1])
        assert T == pytest.approx(0.1, abs=1e-12)
        assert run.log.q[-1, 0] == pytest.approx(q0 - 0.5 * G * T * T, abs=1e-12)
        # no impact, hence no energy gained at an impact; the gap never closes
        assert_no_energy_gain(run)
        # the smallest gap is q(T) - r > 0 [m]: nothing penetrates
        assert float(run.log.gap.min()) == pytest.approx(q0 - 0.5 * G * T * T - 0.1, abs=1e-12)
        assert_penetration_below(run, 0.0)


def test_a_run_without_constraints_penetrates_nothing():
    log = Log(0, nq=1, nv=1, nu=0, constraint_names=[])
    assert_penetration_below(log, 0.0)


def test_a_value_that_is_no_run_is_named():
    with pytest.raises(TypeError, match="got int"):
        assert_penetration_below(42, 1e-3)


@pytest.mark.parametrize("content", ["not a pid", ""])
def test_a_lock_file_without_a_process_id_is_taken_over(tmp_path, content):
    (tmp_path / LOCK_FILE).write_text(content)
    lock = OutputLock(tmp_path)
    with lock.held():
        assert (tmp_path / LOCK_FILE).read_text() == str(os.getpid())
    assert not (tmp_path / LOCK_FILE).exists()
