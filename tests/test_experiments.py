"""Every experiment runs briefly (smoke tests; timings are never asserted)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def _load(name: str) -> ModuleType:
    """Import ``experiments/<name>.py`` (the folder is not a package) as ``experiments_<name>``."""
    module_name = f"experiments_{name}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    spec = importlib.util.spec_from_file_location(module_name, EXPERIMENTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses look their module up while being created
    spec.loader.exec_module(module)
    return module


def _require_example_robot_data() -> None:
    try:
        example_robot_data_dir()
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")


def test_bench_step_runs(capsys: pytest.CaptureFixture[str]) -> None:
    _require_example_robot_data()
    bench = _load("bench_step")
    rows = bench.main(["--steps", "5", "--repeats", "1", "--warmup", "2"])
    assert [row.contacts for row in rows] == [1, 4]
    for row in rows:
        assert set(row.time_us) == set(bench.LOOPS)
        assert all(np.isfinite(value) for value in row.time_us.values())
        assert set(row.max_dv) == set(bench.LOOPS)
        assert row.active_fraction > 0.0
    output = capsys.readouterr().out
    assert "| contacts |" in output and "Target ucontrol" in output
