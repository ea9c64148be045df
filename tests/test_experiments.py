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


def test_work_precision_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    work_precision = _load("work_precision")
    flags = (
        "--ball-duration 0.5 --arm-duration 0.2 --tracking-duration 0.1 --dts 1e-2 1e-3 "
        "--tolerances 1e-6 --stiffnesses 1e5 --tracking-stiffnesses 1e5 "
        "--hunt-crossley-stiffnesses 1e6 --sample-dt 1e-2 --zeno-velocities 1e-2 "
        "--zeno-sample-dt 1e-3"
    )
    studies = work_precision.main([*flags.split(), "--out", str(tmp_path)])
    assert set(studies) == {"ball_e09", "ball_e05", "two_link_drop", "two_link_tracking"}
    for case, study in studies.items():
        assert (tmp_path / f"work_precision_{case}.png").is_file()
        assert all(np.isfinite(run.error) for run in study.runs)
    for name in ("compliant_stiffness.png", "compliant_stiffness.md", "zeno_threshold.md"):
        assert (tmp_path / name).is_file()
    assert "observed order" in capsys.readouterr().out


def test_see_it_runs(tmp_path: Path) -> None:
    see_it = _load("see_it")
    run, figures = tmp_path / "run", tmp_path / "figures"
    flags = [
        "--duration",
        "0.5",
        "--shot-time",
        "0.2",
        "--out",
        str(run),
        "--figures",
        str(figures),
    ]
    paths = see_it.main(flags)
    assert (tmp_path / "figures" / "see_it_tracking.png").is_file()
    assert paths["replay"].stat().st_size > 500_000  # the viewer is embedded
    assert {"q", "gaps", "forces", "energy", "tracking", "cycle_path", "cycle_time"} <= set(paths)
