"""The stability check's bounds after a run: in summary.json and on the cycle figure.

The bounds are those of ``ucontrol check`` (docs/stability_check.md); here they must reach the
run's outputs and hold against what the run measured over its second cycle, the first tracked
one (the first cycle starts off the desired path, which the check does not bound).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from matplotlib.collections import LineCollection

from ucontrol.analysis.stability_check import check_scene
from ucontrol.cli import main
from ucontrol.saved_run import SavedRun
from ucontrol.scene import load_scene
from ucontrol.viz.cycle_figures import _time_figure


@pytest.mark.slow
def test_run_writes_the_bounds_beside_the_measured_cycles_and_draws_them(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["run", "two_link_one_constraint", "--duration", "20", "--out", str(out)]
    assert main([*args, "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    check = summary["stability_check"]
    assert check["holds"] is True
    (contact,) = check["measured"]
    assert len(contact["cycles"]) == 2
    tracked = contact["cycles"][1]
    # Measured 0.00991 J and 1.03 s against 0.01017 J and 1.219 s (docs/stability_check.md).
    assert 0.0 < tracked["impact_jumps"] <= contact["jump_bound"]
    assert tracked["accumulation_time"] <= contact["accumulation_time_bound"]
    assert tracked["jump_bound_holds"] and tracked["accumulation_bound_holds"]

    run = SavedRun.load(out, load_scene("two_link_one_constraint").source)
    scene = run.scene
    controller = scene.build_controller()
    figure = _time_figure(run.log, controller, check_scene(scene))
    gaps, lyapunov = figure.axes[0], figure.axes[1]
    bounds = [c for c in lyapunov.collections if isinstance(c, LineCollection)]
    assert len(bounds) == 2  # one dashed bound per cycle
    segment = bounds[1].get_segments()[0]
    assert segment[0][1] == pytest.approx(
        run.log.V[run.log.row_at(segment[0][0])] + contact["jump_bound"], rel=1e-12
    )
    (end,) = [line for line in gaps.lines if line.get_label() == "t0 + accumulation bound"]
    first = check["contacts"][0]["first_impact"]
    bound = first + contact["accumulation_time_bound"]
    assert end.get_xdata()[0] == pytest.approx(bound, rel=1e-12)
