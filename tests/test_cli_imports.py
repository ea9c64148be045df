"""`ucontrol run` of the default scene imports only what the run uses.

A subprocess runs the command (the default scene, shortened) and lists the modules loaded at
its end: none of the heavy ones that other commands or other scenes need. Without a compiled
path (``UCONTROL_NO_COMPILE=1``), casadi is not loaded either: only the compiled constraint
rows import it, to build their C code.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ucontrol.model.compiled_function import NO_COMPILE_ENV

#: Imported by other commands (convergence, design, sweep, plot, view) or by scenes with a
#: Brogliato controller or a spline path, never by a plain run of the default scene; the
#: campaign package's runner and spec (dask's side), which the parser of ``ucontrol sweep``
#: and ``--set`` need not load.
HEAVY = (
    "scipy",
    "ucontrol.convergence",
    "ucontrol.analysis.stability_check",
    "ucontrol.campaign.runner",
    "ucontrol.campaign.spec",
    "ucontrol.campaign.build_cache",
    "ucontrol.control.brogliato_controller",
    "ucontrol.control.spline_path",
    "ucontrol.design.cycle_transcription",
    "dask",
    "matplotlib",
    "meshcat",
)

PROGRAM = """
import sys
from ucontrol.cli import main

code = main(["run", "--out", sys.argv[1], "--duration", "0.05", "--no-progress"])
print("exit", code)
print("modules", " ".join(sorted(sys.modules)))
"""


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "no_compile"])
def test_run_of_the_default_scene_imports_no_heavy_module(tmp_path: Path, compiled: bool) -> None:
    env = {key: value for key, value in os.environ.items() if key != NO_COMPILE_ENV}
    if not compiled:
        env[NO_COMPILE_ENV] = "1"
    completed = subprocess.run(
        [sys.executable, "-c", PROGRAM, str(tmp_path / "run")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    lines = dict(line.split(" ", 1) for line in completed.stdout.splitlines() if " " in line)
    assert lines["exit"] == "0"
    modules = set(lines["modules"].split())
    assert "ucontrol.simulate" in modules  # the run did run
    heavy = HEAVY if compiled else (*HEAVY, "casadi")
    loaded = sorted(m for m in modules if any(m == h or m.startswith(h + ".") for h in heavy))
    assert loaded == []
