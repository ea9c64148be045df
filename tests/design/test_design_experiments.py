"""The design experiments run briefly (smoke tests; timings are never asserted)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.model.compiled_function import NO_COMPILE_ENV

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out


def test_design_two_link_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # solved in casadi's virtual machine: no other test compiles this grid's program, whose
    # build costs many times the solve (the compiled path's optimum is the virtual machine's:
    # test_compiled_design.py)
    monkeypatch.setenv(NO_COMPILE_ENV, "1")
    rows = load_experiment("design_two_link").main(
        ["--substeps", "2", "--intervals", "6", "--out", str(tmp_path)]
    )
    assert rows[2]["success"] == 1.0
    assert np.isfinite(rows[2]["q_defect"])
    # figures are drawn for the task's own substeps (8) only
    assert not (tmp_path / "joints.png").exists()


def test_design_closed_loop_runs_on_a_saved_cycle(tmp_path: Path) -> None:
    from two_link_design import two_link_design

    cycle = two_link_design()[0].save(tmp_path / "cycle")
    results = load_experiment("design_closed_loop").main(
        ["--cycle-file", str(cycle), "--cycles", "1", "--figures", str(tmp_path / "figures")]
    )
    assert results["designed"]["complete_cycles"] == 1
    assert results["hand-made"]["complete_cycles"] == 1
    assert 0.0 < results["ratios"]["first_impact_impulse"] < 1.0
    assert (tmp_path / "figures" / "task.png").is_file()
