"""A run without a viewer never imports meshcat (nor Pinocchio's meshcat visualizer)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROBOTS = Path(__file__).resolve().parents[2] / "robots"

PROGRAM = """
import sys
import ucontrol, ucontrol.simulate
from ucontrol import load_scene
from ucontrol.simulate import simulate  # the function (ucontrol.simulate is also a module)
from ucontrol.cli import main

simulate(load_scene(sys.argv[1]), duration=0.05)
assert main(["run", sys.argv[1], "--out", sys.argv[2], "--duration", "0.05"]) == 0
assert main(["plot", sys.argv[2]]) == 0
loaded = sorted(m for m in sys.modules if "meshcat" in m)
print("meshcat modules:", loaded)
sys.exit(1 if loaded else 0)
"""


@pytest.mark.slow
def test_run_and_plot_without_viewer_never_import_meshcat(tmp_path: Path) -> None:
    completed = subprocess.run(
        [sys.executable, "-c", PROGRAM, str(ROBOTS / "two_link_drop.toml"), str(tmp_path)],
        capture_output=True,
        text=True,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    assert "meshcat modules: []" in completed.stdout
