"""``ucontrol design`` on a gait task, and the designed gait tracked by the HZD controller."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import load_experiment
from test_design_command import _parse

from ucontrol.cli import main
from ucontrol.design.command import run_design
from ucontrol.exceptions import InvalidParameterError

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


def _write_task(path: Path, **changes: object) -> Path:
    text = (ROBOTS / "rabbit_gait_task.toml").read_text()
    text = text.replace('urdf = "rabbit.urdf"', f'urdf = "{ROBOTS / "rabbit.urdf"}"')
    text = text.replace("intervals = 30", "intervals = 8")
    for key, value in changes.items():
        text = text.replace(f"\n{key} = ", f"\n{key} = {json.dumps(value)}\n#", 1)
    path.write_text(text)
    return path


@pytest.mark.slow
def test_design_writes_the_step_the_scene_and_the_figure(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "out"
    assert (
        run_design(_parse(["design", str(_write_task(tmp_path / "t.toml")), "--out", str(out)]))
        == 0
    )
    assert "designed step: Solve_Succeeded" in capsys.readouterr().out
    summary = json.loads((out / "gait.json").read_text())
    assert summary["success"] and summary["step_length_m"] == 0.4
    assert summary["residuals"]["impact_velocity"] < 1e-7
    scene = tomllib.loads((out / "scene.toml").read_text())
    assert scene["controller"]["type"] == "hzd"
    assert (out / scene["robot"]["urdf"]).resolve() == (ROBOTS / "rabbit.urdf").resolve()
    assert (out / "gait.png").is_file() and (out / "gait.npz").is_file()


def test_bad_gait_task_is_a_typed_error_before_the_solve(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    task = _write_task(tmp_path / "t.toml", step_length=-0.4)
    with pytest.raises(InvalidParameterError, match="step_length"):
        run_design(_parse(["design", str(task), "--out", str(tmp_path / "out")]))
    assert not (tmp_path / "out").exists()
    # the command line: one line naming the key, exit status 2
    assert main(["design", str(task), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert "step_length" in error and "-0.4" in error and len(error.splitlines()) == 1


@pytest.mark.slow
def test_designed_gait_is_tracked_in_closed_loop(tmp_path: Path) -> None:
    """The HZD controller on the fitted constraints walks the designed steps (Moreau–Jean)."""
    result = load_experiment("biped_gait_ocp").main(
        [
            "--intervals", "12",
            "--steps", "4",
            "--scene", str(tmp_path / "walk.toml"),
            "--no-figure",
        ]
    )  # fmt: skip
    design = result["design"]
    steps = result["closed_loop"]
    assert len(steps["lengths"]) >= 4
    # every step of the run within 2 % of the designed length and 5 % of its period (the
    # closed loop's period is its zero dynamics', 3 % longer on the shipped grid)
    np.testing.assert_allclose(steps["lengths"], design["step_length_m"], rtol=0.02)
    np.testing.assert_allclose(steps["periods"][:4], design["step_time_s"], rtol=0.05)
