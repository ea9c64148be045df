"""Saved runs: the log and the scene it recorded, for replays and figures."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import pytest
from conftest import ROBOTS

from ucontrol.cli import main
from ucontrol.exceptions import InvalidParameterError, RunNotFoundError, SceneError
from ucontrol.saved_run import SavedRun
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate


def test_a_run_records_its_scene_file(tmp_path: Path) -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    assert scene.source == (ROBOTS / "ball.toml").resolve()
    simulate(scene, duration=0.05, out=tmp_path)
    run = SavedRun.load(tmp_path)
    assert run.log.metadata["scene_path"] == str(scene.source)
    assert run.scene is not None and run.require_scene().name == "ball"
    assert run.scene.robot.urdf_path == (ROBOTS / "ball.urdf").resolve()


def test_a_directory_without_log_is_not_a_run(tmp_path: Path, capsys) -> None:
    with pytest.raises(RunNotFoundError) as info:
        SavedRun.load(tmp_path)
    assert info.value.directory == str(tmp_path)
    for command in ("view", "plot"):
        assert main([command, str(tmp_path)]) == 2
        assert "no log.npz in" in capsys.readouterr().err


def test_an_unknown_scene_is_none_until_required(tmp_path: Path, capsys) -> None:
    for name in ("ball.toml", "ball.urdf"):
        shutil.copy(ROBOTS / name, tmp_path / name)
    simulate(load_scene(tmp_path / "ball.toml"), duration=0.05, out=tmp_path / "run")
    (tmp_path / "ball.toml").unlink()  # the scene file has moved
    run = SavedRun.load(tmp_path / "run")
    assert run.scene is None
    with pytest.raises(SceneError, match="no longer exists; pass the scene file"):
        run.require_scene()
    assert main(["view", str(tmp_path / "run"), "--html", str(tmp_path / "x.html")]) == 2
    assert "--scene FILE" in capsys.readouterr().err
    assert SavedRun.load(tmp_path / "run", ROBOTS / "ball.toml").require_scene().name == "ball"
    code_scene = dataclasses.replace(load_scene(ROBOTS / "ball.toml"), source=None)
    simulate(code_scene, duration=0.05, out=tmp_path / "code")
    with pytest.raises(SceneError, match="does not name its scene file"):
        SavedRun.load(tmp_path / "code").require_scene()


def test_a_scene_that_does_not_match_the_log_is_refused(tmp_path: Path) -> None:
    simulate(load_scene(ROBOTS / "ball.toml"), duration=0.05, out=tmp_path)
    with pytest.raises(InvalidParameterError, match=r"nq = 1, constraints \['ball/ground'\]"):
        SavedRun.load(tmp_path, ROBOTS / "two_link_drop.toml")
