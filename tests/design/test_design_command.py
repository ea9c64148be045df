"""``ucontrol design``: files written, progress lines, exit status."""

from __future__ import annotations

import argparse
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from two_link_design import COARSE_GRID

from ucontrol.design import DesignedCycle, cycle_transcription
from ucontrol.design.command import add_design_parser, run_design
from ucontrol.exceptions import InfeasibleDesignError

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="ucontrol")
    add_design_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def _write_task(path: Path, **changes: object) -> Path:
    table = tomllib.loads((ROBOTS / "two_link_one_constraint_task.toml").read_text())
    lines = [f'scene = "{ROBOTS / "two_link_one_constraint.toml"}"']
    table.pop("scene")
    table["grid"] = dict(COARSE_GRID)
    table["solver"]["progress_every"] = 5
    for key, value in changes.items():
        table["contact_phases"][0][key] = value
    for key in ("frame", "period", "bounces"):
        lines.append(f"{key} = {json.dumps(table.pop(key))}")
    phase = table.pop("contact_phases")[0]
    lines.append("[[contact_phases]]")
    lines += [f"{key} = {json.dumps(value)}" for key, value in phase.items()]
    for section, entries in table.items():
        lines.append(f"[{section}]")
        lines += [f"{key} = {json.dumps(value)}" for key, value in entries.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow
def test_design_writes_cycle_report_and_figures(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    task = _write_task(tmp_path / "task.toml")
    out = tmp_path / "out"
    assert run_design(_parse(["design", str(task), "--out", str(out)])) == 0
    printed = capsys.readouterr().out
    assert "ipopt iteration    0" in printed and "ipopt iteration    5" in printed
    for name in ("cycle.npz", "cycle.json", "report.json", "report.md", "joints.png", "task.png"):
        assert (out / name).is_file(), name
    report = json.loads((out / "report.json").read_text())
    assert report["success"] and report["period"] == pytest.approx(10.0)
    # one landing, timed or said to be soft (slower than 100 zeno_velocity), never "[nan]"
    (error,) = report["replay"]["impact_time_errors_s"]
    (speed,) = report["replay"]["landing_speeds_m_s"]
    markdown = (out / "report.md").read_text()
    assert "nan" not in markdown.lower()
    if error is None:
        assert f"not timed (soft landing at {speed:.3g} m/s" in markdown
    else:
        assert f"impact time errors: {error:.3g} s" in markdown
    # a coarse grid (3 RK4 steps per interval of 0.5 s and more): measured 1.6e-4 rad
    assert report["replay"]["q_error_rad"] < 1e-3
    cycle = DesignedCycle.load(out / "cycle")
    np.testing.assert_allclose(cycle.phase("flight").position[-1], [0.55, 0.0, 0.0], atol=1e-8)


def test_infeasible_task_exits_with_1_and_names_the_limit(tmp_path, capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # the solve itself is tested in test_cycle_design.py; here only what the command does

    binding = [("torque limit of joint 'shoulder' (|tau| <= 100 N m)", 116.6)]

    def infeasible(task, progress=None):  # type: ignore[no-untyped-def]
        raise InfeasibleDesignError(binding)

    monkeypatch.setattr(cycle_transcription, "design_cycle", infeasible)  # imported on use
    task = _write_task(tmp_path / "task.toml", force_min=400.0, force_max=500.0)
    out = tmp_path / "out"
    assert run_design(_parse(["design", str(task), "--out", str(out), "--no-figures"])) == 1
    assert "torque limit of joint 'shoulder'" in capsys.readouterr().err
    assert not (out / "cycle.npz").exists()


def test_report_words_for_timed_and_soft_landings() -> None:
    from ucontrol.design.command import _impact_time_errors, _timed
    from ucontrol.design.open_loop_replay import ReplayResult

    empty = np.zeros(0)
    replay = ReplayResult(
        t=empty,
        q=empty,
        v=empty,
        q_error=0.0,
        v_error=0.0,
        impact_times=np.array([3.0, np.nan]),
        impact_time_errors=np.array([2.5e-9, np.nan]),
        landing_speeds=np.array([0.3, 1e-4]),
    )
    assert _impact_time_errors(replay, zeno_velocity=1e-5) == (
        "2.5e-09 s; not timed (soft landing at 0.0001 m/s, below 0.001 m/s)"
    )
    assert _timed(replay.impact_time_errors) == [2.5e-9, None]  # JSON null, not NaN


#: Loaded by the figures (matplotlib), the replay (scipy's integrators) and the designed
#: cycle's path (scipy.interpolate), never by ``--no-figures --no-replay``.
_NOT_WITHOUT_FIGURES_AND_REPLAY = ("matplotlib", "scipy", "ucontrol.control.spline_path")

#: Designs in a fresh interpreter, then prints its exit status and the modules it loaded from
#: ``sys.argv[3:]`` (a package's submodules included) as one JSON line.
_PROGRAM = """
import json, sys
from ucontrol.cli import main

code = main(["design", sys.argv[1], "--out", sys.argv[2], "--no-figures", "--no-replay"])
names = sys.argv[3:]
found = [m for m in sys.modules if any(m == n or m.startswith(n + ".") for n in names)]
print(json.dumps({"exit": code, "casadi": "casadi" in sys.modules, "loaded": sorted(found)}))
"""


@pytest.mark.slow
def test_design_without_figures_and_replay_imports_neither(tmp_path: Path) -> None:
    import subprocess
    import sys

    task, out = _write_task(tmp_path / "task.toml"), tmp_path / "out"
    command = [sys.executable, "-c", _PROGRAM, str(task), str(out)]
    completed = subprocess.run(
        [*command, *_NOT_WITHOUT_FIGURES_AND_REPLAY], capture_output=True, text=True, timeout=300
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    result = json.loads(completed.stdout.splitlines()[-1])
    assert result["exit"] == 0 and result["casadi"] and (out / "cycle.npz").is_file()  # designed
    assert result["loaded"] == []
