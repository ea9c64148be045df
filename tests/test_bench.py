"""``ucontrol bench``: the loops, their ratios, the reference check and the command.

Timings are never asserted: only what the report must hold whatever the machine.
"""

from __future__ import annotations

import resource
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.bench import (
    REFERENCES,
    UCONTROL,
    BenchReport,
    bench_scene,
    integrator_step,
    peak_allocation_kb,
    recorded_forces,
    trajectory,
)
from ucontrol.cli import main
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import load_scene

#: 0.6 s at dt = 1 ms: the ball falls for 0.45 s and hits the ground once.
STEPS = 600
#: Largest velocity difference between loops doing the same physics, in [m/s] or [rad/s].
SAME_PHYSICS = 1e-6
#: Replaying the recorded forces must reproduce the closed loop to round-off, in [m/s].
REPLAY_TOLERANCE = 1e-12


@pytest.fixture(scope="module")
def free_ball_report() -> BenchReport:
    return bench_scene(load_scene(ROBOTS / "free_ball.toml"), steps=STEPS, repeats=2, warmup=10)


def test_a_qualifying_scene_has_the_reference_loops(free_ball_report: BenchReport) -> None:
    assert [loop.name for loop in free_ball_report.loops] == [UCONTROL, *REFERENCES]
    assert free_ball_report.no_reference is None
    assert free_ball_report.steps == STEPS and free_ball_report.dt == 1e-3


def test_ratios_are_given_for_every_reference_loop(free_ball_report: BenchReport) -> None:
    # Their values are timings (never asserted); recomputing them with the report's own
    # formula could not fail, so only their keys are checked.
    assert set(free_ball_report.ratios) == set(REFERENCES)


def test_reference_loops_do_the_same_physics(free_ball_report: BenchReport) -> None:
    ucontrol = free_ball_report.loop(UCONTROL)
    assert ucontrol.max_dv == 0.0 and ucontrol.active_fraction > 0.0  # the impact is in
    for name in REFERENCES:
        loop = free_ball_report.loop(name)
        assert loop.max_dv / SAME_PHYSICS <= 1.0, name
        assert loop.active_fraction == ucontrol.active_fraction, name


def test_memory_figures_measure_known_allocations(free_ball_report: BenchReport) -> None:
    # A step that holds one array of 100 000 doubles (781.25 kB) while it runs: the peak
    # is that array plus the step's own small objects (measured 781.8 to 782.1 kB).
    def step(q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        held = np.ones(100_000)
        return q + held[:1], v, False

    zero = np.zeros(1)
    peak = peak_allocation_kb(step, lambda k, q, v: zero, zero, zero, steps=3)
    assert 781.25 <= peak < 781.25 + 8.0  # [kB]
    # The process's peak resident set, in MB: at most the peak now, and at least what
    # Python with Pinocchio and numpy loaded occupies (> 10 MB; a unit slip would be 1024x).
    now_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    assert 10.0 < free_ball_report.peak_rss_mb <= now_mb


def test_markdown_holds_every_loop_and_the_memory(free_ball_report: BenchReport) -> None:
    table = free_ball_report.markdown()
    assert table.count("\n| ") == 1 + len(free_ball_report.loops)  # header + one row per loop
    assert "| pin PGS |" in table and "Peak resident set size" in table
    assert "No Pinocchio reference" not in table


def test_joint_stops_leave_ucontrol_alone() -> None:
    report = bench_scene(load_scene(ROBOTS / "two_link_drop.toml"), steps=50, repeats=1, warmup=5)
    assert [loop.name for loop in report.loops] == [UCONTROL] and report.ratios == {}
    assert (
        report.no_reference is not None and "joint stops (shoulder, elbow)" in report.no_reference
    )
    assert f"No Pinocchio reference: {report.no_reference}." in report.markdown()


def test_the_cpu_clock_times_the_loops_and_says_so() -> None:
    report = bench_scene(load_scene(ROBOTS / "ball.toml"), steps=50, repeats=1, clock="cpu")
    assert report.clock == "cpu" and "cpu clock" in report.markdown().splitlines()[0]
    assert all(loop.time_us > 0.0 for loop in report.loops)


def test_one_velocity_coordinate_ball_is_compared_with_pinocchio() -> None:
    report = bench_scene(load_scene(ROBOTS / "ball.toml"), steps=600, repeats=1, warmup=0)
    assert [loop.name for loop in report.loops] == [UCONTROL, "pin ADMM", "pin PGS"]
    for loop in report.loops[1:]:
        assert loop.max_dv < 1e-6  # [m/s]: the ball's first impact, the same physics


@pytest.mark.parametrize(
    "scene_file", ["two_link_one_constraint.toml", "two_link_flexible_one_constraint.toml"]
)
def test_replayed_forces_reproduce_the_closed_loop(scene_file: str) -> None:
    """The open-loop replay of the recorded forces retraces the run of the scene's controller."""
    from ucontrol.simulate import simulate

    scene, steps = load_scene(ROBOTS / scene_file), 200
    tau = recorded_forces(scene, steps)
    assert np.abs(tau).max() > 0.0  # the controller acts (on the motors with flexible joints)
    log = simulate(scene, duration=steps * scene.integrator.dt, progress=False).log
    expected = log.v[1:]
    if scene.flexible is not None:
        expected = np.hstack((expected, log.motor_v[1:]))
    q0, v0 = scene.initial_state()
    velocities, _ = trajectory(
        integrator_step(scene.build_integrator()), lambda k, q, v: tau[k], q0, v0, steps
    )
    assert np.max(np.abs(velocities - expected)) / REPLAY_TOLERANCE <= 1.0


@pytest.mark.parametrize(
    ("argument", "value"),
    [
        ("steps", 0),
        ("steps", 1.5),
        ("repeats", 0),
        ("warmup", -1),
        ("warmup", True),
        ("dt", -1.0),
        ("clock", "sundial"),
    ],
)
def test_bad_arguments_raise_a_typed_error(argument: str, value: object) -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    with pytest.raises(InvalidParameterError) as caught:
        bench_scene(scene, **{argument: value})
    assert caught.value.name == argument and caught.value.value == value


def test_command_prints_the_table_and_writes_it(tmp_path: Path, capsys) -> None:
    out = tmp_path / "bench" / "free_ball.md"
    flags = ["--steps", "50", "--repeats", "1", "--warmup", "5", "--out", str(out)]
    assert main(["bench", str(ROBOTS / "free_ball.toml"), *flags]) == 0
    printed = capsys.readouterr().out
    assert "| loop | time [µs/step] |" in printed and "| pin ADMM |" in printed
    assert out.read_text().strip() in printed


def test_command_without_a_scene_benches_the_default(capsys) -> None:
    assert main(["bench", "--steps", "20", "--repeats", "1", "--warmup", "0"]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("benchmarking the built-in scene table_drop")
    assert "table_drop: dt = 0.001 s, 20 steps" in printed and "| pin PGS |" in printed


def test_command_reports_a_bad_argument_in_one_line(capsys) -> None:
    assert main(["bench", str(ROBOTS / "ball.toml"), "--steps", "0"]) == 2
    error = capsys.readouterr().err
    assert error == "ucontrol: error: `steps` must be an integer >= 1, got 0\n"


# --- closed loop (bench_closed_loop) ------------------------------------------------------

#: 0.3 s of the two-link tracking scene: 300 steps of the rigid law in its free phase.
CLOSED_LOOP_DURATION = 0.3


@pytest.fixture(scope="module")
def two_link_closed_loop():
    from ucontrol.bench import bench_closed_loop

    scene = load_scene(ROBOTS / "two_link_one_constraint.toml")
    return scene, bench_closed_loop(scene, duration=CLOSED_LOOP_DURATION, repeats=2)


def test_closed_loop_split_sums_to_the_total(two_link_closed_loop) -> None:
    _, result = two_link_closed_loop
    parts = (result.controller_us, result.plant_us, result.solver_us, result.loop_us)
    assert sum(parts) == pytest.approx(result.total_us, rel=1e-9)
    assert result.total_us > 0.0 and result.controller_us > 0.0 and result.plant_us > 0.0
    assert result.solver_us >= 0.0


def test_closed_loop_counts_and_real_time_factor(two_link_closed_loop) -> None:
    scene, result = two_link_closed_loop
    assert result.scene == scene.name
    assert result.dt == scene.integrator.dt
    assert result.steps == round(CLOSED_LOOP_DURATION / scene.integrator.dt) - 1  # step 0 out
    assert result.clock == "wall"
    assert (result.nv, result.n_constraints, result.repeats) == (2, 5, 2)  # 1 contact, 4 stops
    assert result.untimed_us > 0.0  # the runs without stage timers give the real-time factor
    assert result.real_time_factor == pytest.approx(1e6 * result.dt / result.untimed_us)


def test_closed_loop_solver_time_is_the_logs(two_link_closed_loop) -> None:
    """The contact-solve share is the log's own solver_time: a run with contacts has some."""
    from ucontrol.bench import bench_closed_loop

    result = bench_closed_loop(load_scene(ROBOTS / "table_drop.toml"), duration=0.2, repeats=1)
    assert result.solver_us > 0.0
    parts = (result.controller_us, result.plant_us, result.solver_us, result.loop_us)
    assert sum(parts) == pytest.approx(result.total_us, rel=1e-9)


def test_closed_loop_markdown_has_one_row_per_result(two_link_closed_loop) -> None:
    from ucontrol.bench import CLOSED_LOOP_HEADER, closed_loop_markdown

    _, result = two_link_closed_loop
    text = closed_loop_markdown([result, result])
    assert text.startswith(CLOSED_LOOP_HEADER)
    rows = text.splitlines()[2:]
    assert len(rows) == 2 and rows[0].startswith(f"| {result.scene} | 2 | 5 |")
    assert rows[0].count("|") == CLOSED_LOOP_HEADER.splitlines()[0].count("|")


def test_closed_loop_bad_arguments_raise_a_typed_error() -> None:
    from ucontrol.bench import bench_closed_loop

    with pytest.raises(InvalidParameterError, match="repeats"):
        bench_closed_loop(load_scene(ROBOTS / "ball.toml"), repeats=0)
    with pytest.raises(InvalidParameterError, match="clock"):
        bench_closed_loop(load_scene(ROBOTS / "ball.toml"), clock="sundial")


def test_closed_loop_cpu_clock_splits_the_same_way() -> None:
    from ucontrol.bench import bench_closed_loop

    result = bench_closed_loop(
        load_scene(ROBOTS / "two_link_flexible_one_constraint.toml"),
        duration=0.05,
        repeats=1,
        clock="cpu",
    )
    parts = (result.controller_us, result.plant_us, result.solver_us, result.loop_us)
    assert result.clock == "cpu" and (result.nv, result.n_constraints) == (4, 5)  # + 2 motors
    assert sum(parts) == pytest.approx(result.total_us, rel=1e-9)


@pytest.mark.slow
def test_closed_loop_experiment_prints_one_row_per_scene(capsys) -> None:
    """experiments/bench_closed_loop.py, briefly: the table's rows and columns."""
    module = _experiment("bench_closed_loop")
    names = ["two_link_one_constraint", "quadruped_stand"]
    text = module.main(["--scenes", *names, "--duration", "0.02", "--repeats", "1", "--no-scaling"])
    rows = [line for line in text.splitlines() if line.startswith("| ") and "µs" not in line]
    assert [row.split(" | ")[0][2:] for row in rows] == names
    assert rows[1].split(" | ")[1:3] == ["18", "4"]  # Solo-12: nv = 6 + 12, four feet


def test_compare_logs_passes_equal_logs_and_fails_a_perturbed_one(tmp_path: Path) -> None:
    module = _experiment("compare_logs")
    rng = np.random.default_rng(3)
    log = {name: rng.standard_normal((5, 2)) for name in ("q", "v", "u", "impulse")}
    log["t"] = np.arange(5) * 1e-3
    for directory in ("a", "b", "c"):
        (tmp_path / directory / "scene").mkdir(parents=True)
    np.savez(tmp_path / "a" / "scene" / "log.npz", **log)
    np.savez(tmp_path / "b" / "scene" / "log.npz", **log)
    log["u"] = log["u"] + 1e-9
    np.savez(tmp_path / "c" / "scene" / "log.npz", **log)
    assert module.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    assert module.main([str(tmp_path / "a"), str(tmp_path / "c")]) == 1
    (comparison,) = module.compare_directories(tmp_path / "a", tmp_path / "c")
    assert comparison.max_diff["u"] == pytest.approx(1e-9, rel=1e-6)
    assert comparison.max_diff["q"] == 0.0 and comparison.rows == (5, 5)


def _experiment(name: str):
    """The module experiments/<name>.py."""
    import importlib.util
    import sys

    path = ROBOTS.parent / "experiments" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"_{name}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_closed_loop_cpu_clock_keeps_the_solver_inside_the_plant() -> None:
    """With the CPU clock the solver's wall time is scaled to the step's CPU time: plant >= 0."""
    from ucontrol.bench import bench_closed_loop

    scene = load_scene(ROBOTS / "table_drop.toml")
    result = bench_closed_loop(scene, duration=0.2, repeats=1, clock="cpu")
    assert result.solver_us > 0.0 and result.plant_us >= 0.0
    parts = (result.controller_us, result.plant_us, result.solver_us, result.loop_us)
    assert sum(parts) == pytest.approx(result.total_us, rel=1e-9)
