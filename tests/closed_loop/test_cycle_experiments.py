"""The experiments of the phase-machine controller run briefly and write their figures."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import TRACKING_SCENES, load_experiment

from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out


@pytest.mark.parametrize("name", TRACKING_SCENES)
def test_experiment_runs_one_cycle(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    if name == "panda_table":
        try:
            example_robot_data_dir()
        except URDFError:
            pytest.skip("example-robot-data is not installed (extra `robots`)")
    result = load_experiment(name).main(
        ["--cycles", "1", "--dt", "2e-3", "--figures", str(tmp_path)]
    )
    stability = result.summary["weak_stability"]
    assert stability["n_cycles"] == stability["n_complete_cycles"] == 1
    for suffix in ("path", "time"):
        figure = tmp_path / f"{name}_{suffix}.png"
        assert figure.stat().st_size > 10_000
    output = capsys.readouterr().out
    assert "| cycle | contact |" in output and "wrote" in output
