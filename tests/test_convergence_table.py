"""The convergence table: runs of equal error merged, no extrapolation beyond the measured range.

The studies are built by hand (no simulation): Moreau–Jean errors on an exact first-order power
law (error = h, wall time = 1e-4 s / h), so the time at equal error inside the range is known in
closed form, and event-driven runs whose errors agree to rounding level or lie outside the range.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from ucontrol.convergence import ERROR_AGREEMENT, ConvergenceRun, ConvergenceStudy

DTS = (1e-2, 1e-3, 1e-4)  # [s]


def _moreau_jean(dt: float) -> ConvergenceRun:
    return ConvergenceRun(
        integrator="moreau_jean",
        parameter="dt",
        value=dt,
        dt=dt,
        error=dt,  # [m] order one, constant one
        wall_time_s=1e-4 / dt,
        steps=round(1.0 / dt),
        n_events=0,
    )


def _event_driven(rtol: float, error: float, wall_time_s: float) -> ConvergenceRun:
    return ConvergenceRun(
        integrator="event_driven",
        parameter="rtol",
        value=rtol,
        dt=1e-3,
        error=error,
        wall_time_s=wall_time_s,
        steps=1000,
        n_events=4,
    )


def _study(event_driven: list[ConvergenceRun]) -> ConvergenceStudy:
    runs = tuple(_moreau_jean(dt) for dt in DTS) + tuple(event_driven)
    return ConvergenceStudy(
        scene="test", duration=1.0, reference="hand-made", error_unit="m", runs=runs
    )


def _table_rows(markdown: str, header_start: str) -> list[list[str]]:
    """The body rows of the markdown table whose header starts with ``header_start``."""
    lines = markdown.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header_start))
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip("|").split("|")])
    return rows


def test_runs_of_equal_error_share_one_row() -> None:
    rng = np.random.default_rng(18)
    error = 5.163e-15  # [m] five tolerances, one error to the last printed digit
    jitter = 1.0 + rng.uniform(-0.2, 0.2, 5) * ERROR_AGREEMENT
    times = rng.uniform(0.6, 0.7, 5)  # [s]
    runs = [
        _event_driven(rtol, error * j, t)
        for rtol, j, t in zip((1e-4, 1e-6, 1e-8, 1e-10, 1e-12), jitter, times, strict=True)
    ]
    rows = _table_rows(_study(runs).to_markdown(), "| integrator | parameter")
    event_rows = [row for row in rows if row[0] == "event_driven"]
    assert len(event_rows) == 1
    assert "5 runs" in event_rows[0][2]
    assert event_rows[0][2].startswith("0.0001 … 1e-12")
    low, high = (float(x) for x in event_rows[0][5].split("–"))
    assert low == pytest.approx(times.min(), rel=2e-3)
    assert high == pytest.approx(times.max(), rel=2e-3)
    # The Moreau–Jean runs, whose errors differ, keep one row each.
    assert [row[0] for row in rows].count("moreau_jean") == len(DTS)


def test_errors_that_differ_beyond_rounding_keep_their_rows() -> None:
    runs = [_event_driven(1e-4, 1e-6, 0.5), _event_driven(1e-6, 1e-6 * (1 + 3e-3), 0.6)]
    rows = _table_rows(_study(runs).to_markdown(), "| integrator | parameter")
    assert [row[0] for row in rows].count("event_driven") == 2


def test_equal_error_inside_the_range_is_the_power_law() -> None:
    # error 1e-3 lies between the runs: Moreau–Jean's time is 1e-4 / 1e-3 = 0.1 s exactly.
    study = _study([_event_driven(1e-6, 1e-3 * 1.7, 0.02)])
    rows = _table_rows(study.to_markdown(), "| error | event_driven")
    assert len(rows) == 1
    expected = 1e-4 / 1.7e-3  # [s] time = 1e-4 / error on this power law
    assert float(rows[0][2]) == pytest.approx(expected, rel=2e-3)
    assert float(rows[0][3]) == pytest.approx(expected / 0.02, rel=2e-3)


def test_below_the_measured_range_says_not_reached() -> None:
    study = _study([_event_driven(r, 5e-15, t) for r, t in ((1e-4, 0.5), (1e-8, 0.4))])
    markdown = study.to_markdown()
    rows = _table_rows(markdown, "| error | event_driven")
    assert len(rows) == 1
    cell = rows[0][2]
    assert cell.startswith("not reached")
    # Only measured figures: the best run's error, step and time; no power-law number.
    numbers = {float(x) for x in re.findall(r"\d+(?:\.\d+)?(?:e[-+]\d+)?", cell)}
    assert numbers == {1e-4, 1.0}  # 1e-4 m error at h = 1e-4 s, took 1 s
    assert "1e+10" not in markdown and "e+1" not in cell
    assert rows[0][3] == f"> {1.0 / 0.5:.3g}"  # its best run's time over the slower run


def test_above_the_measured_range_says_not_reached() -> None:
    study = _study([_event_driven(1e-2, 0.5, 0.3)])
    rows = _table_rows(study.to_markdown(), "| error | event_driven")
    assert rows[0][2].startswith("not reached (its coarsest, 1.000e-02 at h = 0.01 s")
    assert rows[0][3] == f"< {0.01 / 0.3:.3g}"
