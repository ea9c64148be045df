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
from ucontrol.log import Log

SUMMARY_KEYS = {
    "wall_time_s",
    "cpu_time_s",
    "steps",
    "max_penetration",
    "n_impacts",
    "energy_increase_at_impacts",
}
LOG_KEYS = {"t", "q", "v", "u", "gap", "impulse"}


def test_run_writes_log_and_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
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
    assert summary["cpu_time_s"] > 0.0  # the loop's CPU time, and both real-time factors:
    wall, cpu = summary["wall_time_s"], summary["cpu_time_s"]
    assert (
        f"({1.0 / wall:.3g}× real time; CPU {cpu:.3g} s, {1.0 / cpu:.3g}×)"
        in capsys.readouterr().out
    )
    with np.load(out / "log.npz") as log:
        assert LOG_KEYS <= set(log.files)
        assert log["t"][-1] == pytest.approx(1.0)


@pytest.mark.slow
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


@pytest.mark.slow
def test_builtin_scenes_by_name_from_any_folder(tmp_path: Path) -> None:
    """`ucontrol run ball`, `ucontrol scenes` and `--version` outside the repository."""

    def ucontrol(*args: str) -> str:
        return subprocess.run(
            [sys.executable, "-m", "ucontrol.cli", *args],
            capture_output=True,
            text=True,
            check=True,
            cwd=tmp_path,
            timeout=300,
        ).stdout

    assert ucontrol("--version").strip() == "ucontrol 0.1.0"
    listing: dict[str, str] = {}
    for line in ucontrol("scenes").splitlines():
        assert len(line) <= 100, line
        if line.startswith(" "):  # a long description wraps under itself
            last = list(listing)[-1]
            listing[last] += " " + line.strip()
        else:
            scene, text = line.split(maxsplit=1)
            listing[scene] = text
    assert {"ball", "two_link_drop", "panda_table", "two_link_mjcf_one_constraint"} <= set(listing)
    assert listing["ball"].startswith("A 1 kg ball dropped")
    assert "…" not in "".join(listing.values())  # never cut: the whole first sentence
    assert listing["ball_mesh_wedge"].endswith("onto the ground halfspace")
    assert "ucontrol run NAME" in " ".join(ucontrol("scenes", "--help").split())
    assert not any(name.endswith("_task") for name in listing)  # design tasks are no scenes
    ucontrol("run", "ball", "--duration", "0.5", "--no-progress")
    summary = json.loads((tmp_path / "runs" / "ball" / "summary.json").read_text())
    assert summary["scene"] == "ball" and summary["steps"] == 500


def test_unknown_scene_name_lists_the_builtin_ones(capsys) -> None:
    assert main(["run", "no_such_scene"]) == 2
    error = capsys.readouterr().err
    assert "built-in scene 'no_such_scene'" in error and "two_link_drop" in error


def test_set_overrides_scene_keys(tmp_path: Path, capsys) -> None:
    """--set changes the scene: half the restitution, a lower rebound (e² of the height)."""
    out = tmp_path / "half"
    args = ["run", "ball", "--duration", "1.0", "--out", str(out), "--no-progress"]
    assert main([*args, "--set", "contacts.0.restitution=0.5"]) == 0
    log = Log.load(out / "log.npz")
    first = int(np.argmax(log.impulse[:, 0] > 0))
    rebound = log.v[first + 1, 0] / -log.v[first, 0]
    assert rebound == pytest.approx(0.5, abs=0.01)
    assert main([*args, "--set", "contacts.0.restitution='x'"]) == 2
    assert "'x'" in capsys.readouterr().err
