"""experiments/hopper.py and the campaign's metrics run briefly (smoke; no time asserted)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.scene import load_scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow


def test_the_experiment_writes_its_figure(tmp_path: Path) -> None:
    hopper = load_experiment("hopper")
    figures = hopper.main(["--hops", "2", "--starts", "2", "--out", str(tmp_path)])
    assert (tmp_path / "hopper_apex.png").is_file()
    assert "multipliers" in (tmp_path / "hopper.md").read_text()
    assert all(error < 0.2 for error in figures["errors"].values())
    assert np.allclose(figures["event_driven"], 0.8, atol=0.01)  # the map is nearly deadbeat


def test_the_campaign_metrics_read_a_run() -> None:
    metrics = load_experiment("hopper_metrics")
    result = simulate(load_scene("hopper"), duration=3.0, progress=False)
    assert metrics.hops(result) == 4
    assert metrics.apex_error(result) < 0.01
    assert not metrics.fell(result)
