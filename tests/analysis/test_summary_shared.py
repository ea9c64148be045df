"""A run's summary derives each array once and shares it: the analyses called alone agree.

The summary written by :func:`ucontrol.simulate` computes the impact mask, the actuators' work
and the cycles' events once and hands them to ``summarize``, ``weak_stability``, ``tracking``
and the physics checks. Here the same log goes through the public analyses one by one, each
computing what it needs, as a user calls them; every figure must be the same float.
"""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.analysis.cycle_table import cycle_table
from ucontrol.analysis.cycles import cycle_events
from ucontrol.analysis.energy_balance import step_work
from ucontrol.analysis.impacts import impact_cells, impact_mask
from ucontrol.analysis.summary import summarize
from ucontrol.analysis.tracking import _row_norms, tracking
from ucontrol.analysis.weak_stability import weak_stability
from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import SimulationResult, _report_physics, simulate

#: Shipped scenes of different kinds: duration of the run in [s], and whether a phase machine
#: logs cycles (then its summary holds ``weak_stability`` and ``tracking``).
SCENES = {
    "two_link_one_constraint": (15.0, True),  # Brogliato, two approaches (4.2 s, 14.2 s)
    "panda_table_friction": (3.0, True),  # Coulomb friction, one cycle
    "solo_landing": (0.5, False),  # a legged robot landing on four feet, with friction
    "two_link_flexible_two_constraints": (6.0, True),  # flexible joints, two constraints
}
#: Entries of a run's summary that the loop adds (not ``summarize``'s nor the checks').
LOOP_KEYS = ("n_events", "n_plastic_steps", "interrupted", "interrupted_by")


@functools.cache
def _run(name: str) -> tuple[Scene, SimulationResult]:
    scene = load_scene(ROBOTS / f"{name}.toml")
    return scene, simulate(scene, duration=SCENES[name][0], progress=False)


@pytest.mark.parametrize("name", SCENES)
def test_run_summary_equals_the_analyses_called_one_by_one(name: str) -> None:
    scene, run = _run(name)
    log, summary = run.log, run.summary
    steps = len(log) - 1
    # the public analyses as a user calls them, with numpy's own reductions
    impacts = impact_mask(log)[:steps]
    assert summary["n_impacts"] == int(impacts.sum()) > 0
    assert summary["n_impacts_per_constraint"] == impacts.sum(axis=0).tolist()
    k = np.flatnonzero(impacts.any(axis=1))
    jumps = log.energy[k + 1] - log.energy[k] - step_work(log)[k]  # [J]
    assert summary["energy_increase_at_impacts"] == max(0.0, float(jumps.max()))
    has_cycles = SCENES[name][1]
    assert ("weak_stability" in summary) is ("tracking" in summary) is has_cycles
    if has_cycles:
        assert summary["weak_stability"]["n_cycles"] >= 1
        assert summary["weak_stability"] == weak_stability(log).to_dict()
        assert summary["tracking"] == tracking(log).to_dict()
    # summarize and the physics checks alone, each computing its arrays: the same floats
    alone = summarize(
        log,
        wall_time_s=summary["wall_time_s"],
        cpu_time_s=summary["cpu_time_s"],
        theta=log.metadata["theta"],
    )
    alone.update({key: summary[key] for key in LOOP_KEYS})
    _report_physics(scene, log, alone)
    assert json.dumps(alone, sort_keys=True) == json.dumps(summary, sort_keys=True)


def test_cycle_table_rows_are_the_analyses_of_each_cycle() -> None:
    _, run = _run("two_link_one_constraint")
    log = run.log
    rows = cycle_table(log).splitlines()[2:]  # below the header and its rule
    cycles = cycle_events(log)
    stability, errors = weak_stability(log).cycles, tracking(log).cycles
    assert len(rows) == len(cycles) == 2  # one declared contact

    def cell(value: float, spec: str) -> str:
        return format(value, spec) if np.isfinite(value) else "–"

    for row, cycle, stable, error in zip(rows, cycles, stability, errors, strict=True):
        times = (cycle.tau0, cycle.first_impact, cycle.accumulation_end, cycle.takeoff)
        expected = [
            str(cycle.index),
            "end_effector/ground",
            *(cell(t[0], ".3f") for t in times),
            cell(stable.V_tau0, ".3e"),
            cell(stable.transition_rise, ".3e"),
            cell(error.free_error_max, ".2e"),
            cell(error.force_error_mid[0], ".2e"),
        ]
        assert [text.strip() for text in row.strip("|").split("|")] == expected
    assert rows[1].count("–") == 4  # the second cycle goes on past 15 s


@pytest.mark.parametrize("shape", [(0, 3), (4, 0), (1, 1), (7, 2), (2000, 5), (300, 40)])
def test_impact_cells_are_numpys_nonzero(shape: tuple[int, int]) -> None:
    mask = np.random.default_rng(sum(shape)).random(shape) < 0.05
    mask[-1:, :1] = True  # at least one impact where the mask has a cell
    rows, columns = impact_cells(mask)
    expected_rows, expected_columns = np.nonzero(mask)
    np.testing.assert_array_equal(rows, expected_rows)
    np.testing.assert_array_equal(columns, expected_columns)
    np.testing.assert_array_equal(np.unique(rows), np.flatnonzero(mask.any(axis=1)))


@pytest.mark.parametrize("m", range(1, 8))
def test_row_norms_are_numpys_norms_float_for_float(m: int) -> None:
    # squares from 1e-12 to 1e6 m^2: sums whose rounding depends on the order of the terms
    rng = np.random.default_rng(m)
    x = rng.standard_normal((5000, m)) * 10.0 ** rng.uniform(-6.0, 3.0, (5000, m))  # [m]
    np.testing.assert_array_equal(_row_norms(x), np.linalg.norm(x, axis=1))


def test_shared_arrays_of_the_wrong_shape_are_refused() -> None:
    _, run = _run("two_link_one_constraint")
    log = run.log
    n = len(log.constraint_names)
    with pytest.raises(ShapeError, match=r"`impacts` must have shape \(15001, 5\), got \(3, 5\)"):
        summarize(log, wall_time_s=1.0, impacts=np.zeros((3, n), dtype=bool))
    with pytest.raises(ShapeError, match=r"`work` must have shape \(15000,\), got \(15001,\)"):
        summarize(log, wall_time_s=1.0, work=np.zeros(len(log)))
    with pytest.raises(ShapeError, match="`impacts`"):
        weak_stability(log, impacts=impact_mask(log)[:, :2])


def test_cycles_of_another_log_are_refused() -> None:
    _, run = _run("two_link_one_constraint")
    log = run.log
    cycles = cycle_events(log)
    assert len(cycles) == 2
    with pytest.raises(InvalidParameterError, match="`cycles` must be cycle_events") as error:
        weak_stability(log, cycles=cycles[:1])  # the cycles of the log's first 14.2 s
    assert error.value.name == "cycles"
    with pytest.raises(InvalidParameterError, match="the last ending at row 15001"):
        tracking(log, cycles=[*cycles[:1], "cycle"])  # type: ignore[list-item]
