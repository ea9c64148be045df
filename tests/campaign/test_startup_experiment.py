"""experiments/campaign_startup.py runs briefly (a smoke test; no time is asserted)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import load_experiment

pytestmark = pytest.mark.slow  # two local clusters


def test_campaign_startup_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    startup = load_experiment("campaign_startup")
    flags = "--campaigns sensors --runs 2 --duration 0.3 --workers 1 --seed 5"
    figures = startup.main([*flags.split(), "--out", str(tmp_path)])
    for label in ("sensors_fresh", "sensors_reused"):
        assert figures[f"{label}_runs"] == 2 and figures[f"{label}_failed"] == 0
        assert 0.0 < figures[f"{label}_startup_share"] < 1.0
        assert figures[f"{label}_efficiency"] > 0.0
    builds = [
        json.loads(path.read_text())["build"]
        for path in sorted((tmp_path / "sensors_reused" / "runs").glob("*.json"))
    ]
    # the worker was prepared with the first run's builds (sensors only differ): both reuse them
    assert [build["integrator"] for build in builds] == ["reused", "reused"]
    assert "| sensors | reused |" in capsys.readouterr().out
