"""The ``ucontrol`` command line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.cli import main

SUMMARY_KEYS = {
    "wall_time_s",
    "steps",
    "max_penetration",
    "n_impacts",
    "energy_increase_at_impacts",
}
LOG_KEYS = {"t", "q", "v", "u", "gap", "impulse"}


def test_run_writes_log_and_summary(tmp_path: Path) -> None:
    out = tmp_path / "ball"
    status = main(
        [
            "run",
            str(ROBOTS / "ball.toml"),
            "--out",
            str(out),
            "--dt",
            "5e-4",
            "--duration",
            "1.0",
            "--integrator",
            "moreau_jean",
            "--no-progress",
        ]
    )
    assert status == 0
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["steps"] == 2000 and summary["dt"] == 5e-4 and summary["n_impacts"] == 1
    with np.load(out / "log.npz") as log:
        assert LOG_KEYS <= set(log.files)
        assert log["t"][-1] == pytest.approx(1.0)


def test_run_without_a_scene_runs_the_builtin_default(tmp_path: Path) -> None:
    completed = subprocess.run(
        [sys.executable, "-m", "ucontrol.cli", "run", "--out", str(tmp_path), "--duration", "0.5"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "two_link_drop" in completed.stdout
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["scene"] == "two_link_drop" and summary["steps"] == 500


def test_bad_scene_is_reported_without_a_traceback(tmp_path: Path, capsys) -> None:
    scene = tmp_path / "bad.toml"
    scene.write_text((ROBOTS / "ball.toml").read_text().replace("dt = 1e-3", "dt = -1"))
    (tmp_path / "ball.urdf").write_text((ROBOTS / "ball.urdf").read_text())
    assert main(["run", str(scene), "--out", str(tmp_path / "out")]) == 2
    assert "`dt` must be > 0, got -1" in capsys.readouterr().err
