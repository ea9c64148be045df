"""The design experiments run briefly (smoke tests; timings are never asserted)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import load_experiment


def test_design_two_link_runs(tmp_path: Path) -> None:
    rows = load_experiment("design_two_link").main(
        ["--substeps", "2", "--intervals", "6", "--out", str(tmp_path)]
    )
    assert rows[2]["success"] == 1.0
    assert np.isfinite(rows[2]["q_defect"])
    # figures are drawn for the task's own substeps (8) only
    assert not (tmp_path / "joints.png").exists()
