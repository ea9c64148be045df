"""The experiments of the phase-machine controller run briefly and write their figures."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"


def _load(name: str) -> ModuleType:
    """Import ``experiments/<name>.py`` (the folder is not a package)."""
    module_name = f"experiments_{name}"
    if module_name not in sys.modules:
        spec = importlib.util.spec_from_file_location(module_name, EXPERIMENTS / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module
        spec.loader.exec_module(module)
    return sys.modules[module_name]


@pytest.mark.parametrize(
    "name", ["two_link_one_constraint", "two_link_two_constraints", "panda_table"]
)
def test_experiment_runs_one_cycle(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    if name == "panda_table":
        try:
            example_robot_data_dir()
        except URDFError:
            pytest.skip("example-robot-data is not installed (extra `robots`)")
    result = _load(name).main(["--cycles", "1", "--dt", "2e-3", "--figures", str(tmp_path)])
    stability = result.summary["weak_stability"]
    assert stability["n_cycles"] == stability["n_complete_cycles"] == 1
    for suffix in ("path", "time"):
        figure = tmp_path / f"{name}_{suffix}.png"
        assert figure.stat().st_size > 10_000
    output = capsys.readouterr().out
    assert "| cycle | contact |" in output and "wrote" in output
