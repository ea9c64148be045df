"""Every experiment runs briefly (smoke tests; timings are never asserted)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

_load = load_experiment


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
        "--ball-duration 0.5 --arm-duration 0.2 --tracking-duration 0.1 --flexible-duration 0.2 "
        "--dts 1e-2 1e-3 --tolerances 1e-6 --stiffnesses 1e5 --tracking-stiffnesses 1e5 "
        "--hunt-crossley-stiffnesses 1e6 --sample-dt 1e-2 --zeno-velocities 1e-2 "
        "--zeno-sample-dt 1e-3"
    )
    studies = work_precision.main([*flags.split(), "--out", str(tmp_path)])
    assert set(studies) == {
        "ball_e09",
        "ball_e05",
        "two_link_drop",
        "two_link_tracking",
        "two_link_flexible_drop",
    }
    assert "moreau_jean midpoint" in studies["two_link_flexible_drop"].curves()
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


def test_bench_contacts_peak_memory(capsys: pytest.CaptureFixture[str]) -> None:
    bench = _load("bench_contacts")
    assert bench.main(["--peak-memory", "3"]) == []
    line = capsys.readouterr().out.strip()
    assert line.startswith("peak RSS, 3 beads: ") and line.endswith(" MB")
    assert float(line.split(": ")[1].split()[0]) > 0.0
    with pytest.raises(SystemExit):
        bench.main(["--peak-memory", "0"])
    assert "--peak-memory: 0 beads" in capsys.readouterr().err


def test_bench_contacts_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bench = _load("bench_contacts")
    flags = "--sizes 1 3 --steps 3 --repeats 1 --warmup 1 --fit-from 1"
    rows = bench.main([*flags.split(), "--out", str(tmp_path)])
    assert [row.contacts for row in rows] == [1, 3]
    for row in rows:
        assert row.active == row.contacts  # the column rests on every contact
        assert set(row.step_us) == set(row.solve_us) == set(bench.SOLVERS)
        assert max(row.residual.values()) <= 1e-8
    assert (tmp_path / "bench_contacts.png").is_file()
    assert "Fitted growth" in (tmp_path / "bench_contacts.md").read_text()
    assert "| contacts |" in capsys.readouterr().out


def test_bench_friction_runs(capsys: pytest.CaptureFixture[str]) -> None:
    bench = _load("bench_friction")
    flags = "--scenes block_incline_spatial painleve_rod --duration 0.02 --rounds 1"
    results = bench.main(flags.split())
    assert [result["scene"] for result in results] == ["block_incline_spatial", "painleve_rod"]
    for result in results:
        assert result["solves"] > 0
        assert result["ucontrol"]["residual"] <= bench.TOLERANCE
        assert result["ucontrol"]["unsolved"] == 0
        assert result["ucontrol numpy"]["residual"] <= bench.TOLERANCE
        assert result["pin ADMM"]["residual"] >= 0.0  # ran (PGS may stall on the rod)
    spatial = results[0]
    assert spatial["ucontrol"]["qp_free"] == spatial["solves"] - 1  # warm starts after the first
    assert "| scene |" in capsys.readouterr().out


def test_beads_urdf_is_generated(robots_dir: Path) -> None:
    bench = _load("bench_contacts")
    assert (robots_dir / "beads.urdf").read_text() == bench.beads_urdf(10)


def test_friction_cases_run(tmp_path: Path) -> None:
    cases = _load("friction_cases")
    flags = "--duration 0.05 --angles 20 45 --dts 1e-2 --problems 3 --seeds 0 --beads-duration 0.5"
    tables = cases.main([*flags.split(), "--out", str(tmp_path)])
    assert set(tables) == {"incline", "stop", "admm", "painleve", "beads"}
    assert (tmp_path / "friction_cases.md").is_file()
    assert (tmp_path / "painleve_rod.png").is_file()
    # Values against their references, tolerances 10x the measured errors (in brackets).
    for row in tables["incline"]:  # g (sin a - mu cos a) when sliding, rest when sticking
        if row["sticks"]:
            assert row["max_speed_if_stuck"] <= 6e-14  # [6.0e-15 m/s]
        else:
            assert row["relative_error"] <= 5e-14  # [5.1e-15]
        assert row["max_residual"] <= 3e-13  # [3.1e-14 m/s]
    assert tables["stop"][0]["d_error"] <= 6e-4  # [5.8e-5 m] at dt = 1e-2 s
    for row in tables["admm"]:  # Pinocchio's ADMM on the same problems
        assert row["above_1e-6"] == 0 and row["max_difference"] <= 1.2e-10  # [1.2e-11]
    assert tables["painleve"][0]["impulse_over_mgh"] > 1.0  # mu = 1.5: a tangential impact
    for row in tables["beads"]:  # a vertical column: no impact gains energy, none moves aside
        assert row["energy_increase_at_impacts"] == 0.0 and row["max_lateral_position"] == 0.0


def test_midpoint_order_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    midpoint_order = _load("midpoint_order")
    flags = "--duration 0.2 --drop-duration 0.05 --dts 2e-3 1e-3 --reference-tolerance 1e-10"
    studies = midpoint_order.main([*flags.split(), "--out", str(tmp_path)])
    assert set(studies) == set(midpoint_order.CASES)
    for study in studies.values():
        assert set(study.curves()) == set(midpoint_order.CURVES)
        assert all(np.isfinite(run.error) and run.error > 0.0 for run in study.runs)
    for name in ("midpoint_order.png", "midpoint_order.md", "midpoint_order.csv"):
        assert (tmp_path / name).is_file()
    assert "| slope |" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        ("--cases two_link_drop --drop-duration 0.3 --dts 2e-3", "reaches the drop's first impact"),
        ("--cases four_bar --duration 0 --dts 2e-3", "`duration` must be > 0, got 0.0"),
        ("--cases four_bar --dts 1e-3 7e-4", "a step that divides the largest step"),
        ("--cases four_bar --reference-tolerance 0 --dts 2e-3", "`rtol` must be > 0, got 0.0"),
    ],
)
def test_midpoint_order_refuses_bad_flags(
    flags: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    midpoint_order = _load("midpoint_order")
    with pytest.raises(SystemExit) as exit_info:
        midpoint_order.main(["--duration", "0.01", "--out", str(tmp_path), *flags.split()])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_momentum_observer_runs(capsys: pytest.CaptureFixture[str]) -> None:
    rows = _load("momentum_observer").main(
        ["--duration", "6.5", "--scenes", "two_link_one_constraint"]
    )
    assert len(rows) == 8 and rows[0].startswith("| two_link_one_constraint | oracle |")
    assert "0 false" in rows[1]  # the default observer flags no impact the plant did not make
    assert "| run |" in capsys.readouterr().out


def test_biped_walk_runs(tmp_path: Path) -> None:
    flags = ["--steps", "2", "--robustness-duration", "0.3", "--out", str(tmp_path)]
    result = _load("biped_walk").main(flags)
    assert result["gait"].stable
    assert result["walked"]["swaps"].size >= 2
    assert (tmp_path / "biped_walk.png").is_file() and (tmp_path / "biped_walk.md").is_file()


def test_biped_gait_design_runs(capsys: pytest.CaptureFixture[str]) -> None:
    _load("biped_gait_design").main(["--iterations", "2"])
    assert "bezier = [" in capsys.readouterr().out


def test_bench_alternating_runs(capsys: pytest.CaptureFixture[str]) -> None:
    bench = _load("bench_alternating")
    flags = "--scenes block_incline --beads 2 --duration 0.01 --steps 2 --runs 2 --rounds 2"
    rows = bench.main(flags.split())
    assert [row["item"] for row in rows] == ["scene:block_incline", "beads:2"]
    for row in rows:
        smallest, median = row["after"]
        # two rounds of two runs each, ordered; the scene's cost is a difference of two CPU
        # times of runs this short, whose sign the machine's noise decides: finite, not positive
        assert math.isfinite(smallest) and math.isfinite(median) and smallest <= median
    assert "| beads:2 |" in capsys.readouterr().out


def test_bench_alternating_counts_instructions(capsys: pytest.CaptureFixture[str]) -> None:
    import shutil

    if shutil.which("valgrind") is None or shutil.which("callgrind_control") is None:
        pytest.skip("valgrind's callgrind is not installed")
    [row] = _load("bench_alternating").main("--beads 2 --steps 2 --instructions".split())
    # A step of two beads with friction: hundreds of thousands of instructions (about
    # 1.5 million measured), never the set-up's billions.
    assert row["item"] == "beads:2" and 1e5 < float(row["after"]) < 1e8
    assert "| beads:2 |" in capsys.readouterr().out


def test_instructions_per_step_runs(capsys: pytest.CaptureFixture[str]) -> None:
    import shutil

    if shutil.which("valgrind") is None or shutil.which("callgrind_control") is None:
        pytest.skip("valgrind's callgrind is not installed")
    flags = "--scenes two_link_drop --duration 0.004".split()
    [(name, instructions)] = _load("instructions_per_step").main(flags)
    # A step of the two-link arm in free fall: the plant and the log's Python calls, at least
    # tens of thousands of instructions (about 170 000 measured), never the set-up's millions.
    assert name == "two_link_drop" and 1e4 < instructions < 1e6
    assert "| two_link_drop |" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("contacts", [1, 4])
def test_instructions_per_step_counts_a_bench_loop(
    capsys: pytest.CaptureFixture[str], contacts: int
) -> None:
    import shutil

    if shutil.which("valgrind") is None or shutil.which("callgrind_control") is None:
        pytest.skip("valgrind's callgrind is not installed")
    flags = ["--bench-loops", "ucontrol", "--steps", "60", "--contacts", str(contacts)]
    [(name, instructions)] = _load("instructions_per_step").main(flags)
    # A Panda step with its control law: about 120 000 instructions measured with one
    # contact, 240 000 with four, never the set-up's millions (the 50-step run subtracted).
    assert name == "ucontrol" and 3e4 < instructions < 1e6
    output = capsys.readouterr().out
    assert "| ucontrol |" in output and f"{contacts} contact(s)" in output
