"""`ucontrol run` of the default scene imports only what the run uses.

A subprocess runs the command (the default scene, shortened) and lists the modules loaded at
its end: none of the heavy ones that other commands or other scenes need. casadi is loaded only
to build the compiled paths' Functions on a cold compile cache: not with a warm one (the
libraries are found by their definitions and loaded without casadi; the log is the cold run's
bit for bit), nor without a compiled path (``UCONTROL_NO_COMPILE=1``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import needs_compiled_code

from ucontrol.cli import _parser
from ucontrol.model.compile_cache import CACHE_ENV
from ucontrol.model.compiled_function import NO_COMPILE_ENV
from ucontrol.solvers.lapack_routines import FLAPACK

#: Imported by other commands (convergence, design, sweep, plot, view; their parsers too) or
#: by scenes with a Brogliato, walking, impedance, juggling, hopping or pronking controller or
#: a path (the desired cycle, its segments and numpy's polynomials among them), never by a
#: plain run of the default scene; the campaign package (its overrides come with ``--set``,
#: which need not load its runner and spec, dask's side); the cycles' analyses of a summary,
#: for phase-machine controllers; the solvers a proxsuite run does not call (Lemke's pivoting,
#: the rare ill-conditioned case; Pinocchio's adapters) and the analytic bouncing ball; the
#: kinds of constraint the default scene does not declare (bilateral closures and their
#: assembly, clearances, collision pairs, sphere–sphere contacts) and pushes.
HEAVY = (
    "scipy",
    "ucontrol.campaign",
    "ucontrol.convergence",
    "ucontrol.analysis.stability_check",
    "ucontrol.campaign.runner",
    "ucontrol.campaign.spec",
    "ucontrol.campaign.build_cache",
    "ucontrol.campaign.command",
    "ucontrol.campaign.figures",
    "ucontrol.campaign.table",
    "ucontrol.design",
    "ucontrol.control.path_table",
    "ucontrol.control.circle_path",
    "ucontrol.control.polyline_path",
    "ucontrol.control.segment_path",
    "ucontrol.control.brogliato_controller",
    "ucontrol.control.spline_path",
    "ucontrol.design.cycle_transcription",
    "ucontrol.control.hzd_controller",
    "ucontrol.control.impedance_controller",
    "ucontrol.control.juggling_controller",
    "ucontrol.control.raibert_controller",
    "ucontrol.control.path_reach",
    "ucontrol.control.controller_table",
    "ucontrol.control.desired_cycle",
    "ucontrol.control.trajectory_segment",
    "ucontrol.control.task_coordinates",
    "ucontrol.control.pronking_controller",
    "numpy.polynomial",
    "ucontrol.analysis.tracking",
    "ucontrol.analysis.weak_stability",
    "ucontrol.solvers.lemke",
    "ucontrol.solvers.pinocchio_constraint_solver",
    "ucontrol.analysis.bouncing_ball",
    "ucontrol.contact.assembly",
    "ucontrol.contact.bilateral",
    "ucontrol.contact.clearance_joint",
    "ucontrol.contact.collision_pair",
    "ucontrol.contact.sphere_sphere_contact",
    "ucontrol.scene.push",
    "dask",
    "matplotlib",
    "meshcat",
)

PROGRAM = """
import sys
from ucontrol.cli import main

out, duration, *scene = sys.argv[1:]
code = main(["run", *scene, "--out", out, "--duration", duration, "--no-progress"])
print("exit", code)
print("modules", " ".join(sorted(sys.modules)))
"""


#: Simulated time in [s] of the default scene's guarded run: the whole run, whose impacts
#: on two contacts at once reach the exact active-set solves (LAPACK, without scipy.linalg).
DEFAULT_DURATION = 3.0

#: Log entries that are timings (they differ between any two runs).
TIMINGS = ("solver_time",)


def _run(out: Path, env: dict[str, str], *scene: str, duration: float = 0.05) -> set[str]:
    """The command (on ``scene``, or the default) in a new process; the modules it loaded.

    ``duration`` in [s] of simulated time.
    """
    completed = subprocess.run(
        [sys.executable, "-c", PROGRAM, str(out), str(duration), *scene],
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
    return modules


def _loaded(modules: set[str], heavy: tuple[str, ...]) -> list[str]:
    """The modules of ``heavy`` (packages with their submodules) in ``modules``.

    scipy's LAPACK extension module alone is not heavy: loaded without its packages
    (:mod:`ucontrol.solvers.lapack_routines`).
    """
    return sorted(
        m for m in modules - {FLAPACK} if any(m == h or m.startswith(h + ".") for h in heavy)
    )


@pytest.mark.parametrize(
    "cache", ["cold", pytest.param("warm", marks=needs_compiled_code), "no_compile"]
)
def test_run_of_the_default_scene_imports_no_heavy_module(tmp_path: Path, cache: str) -> None:
    env = {key: value for key, value in os.environ.items() if key != NO_COMPILE_ENV}
    env[CACHE_ENV] = str(tmp_path / "cache")
    if cache == "no_compile":
        env[NO_COMPILE_ENV] = "1"
    if cache == "warm":
        cold = _run(tmp_path / "cold", env, duration=DEFAULT_DURATION)
        assert "casadi" in cold  # the cold run built the compiled paths' Functions
    modules = _run(tmp_path / "run", env, duration=DEFAULT_DURATION)
    heavy = HEAVY if cache == "cold" else (*HEAVY, "casadi")
    assert _loaded(modules, heavy) == []
    if cache == "warm":
        _assert_same_logs(tmp_path / "cold", tmp_path / "run")


@needs_compiled_code
def test_warm_run_of_a_brogliato_scene_imports_no_casadi(tmp_path: Path) -> None:
    """The law, the rows and the free step all found by their definitions: no casadi."""
    env = {key: value for key, value in os.environ.items() if key != NO_COMPILE_ENV}
    env[CACHE_ENV] = str(tmp_path / "cache")
    scene = "two_link_one_constraint"
    assert "ucontrol.control.brogliato_controller" in _run(tmp_path / "cold", env, scene)
    modules = _run(tmp_path / "run", env, scene)
    assert "ucontrol.control.brogliato_controller" in modules  # the law ran
    assert _loaded(modules, ("casadi", "ucontrol.model.symbolic_model")) == []
    _assert_same_logs(tmp_path / "cold", tmp_path / "run")


def _assert_same_logs(first: Path, second: Path) -> None:
    """The two runs' logs are equal bit for bit, timings aside."""
    with np.load(first / "log.npz") as a, np.load(second / "log.npz") as b:
        assert a.files == b.files
        for key in a.files:
            if key not in TIMINGS:
                np.testing.assert_array_equal(a[key], b[key], err_msg=key)


#: Prints, after ``ucontrol run`` of the default scene in this process (numpy not loaded
#: before), the thread count of each OpenBLAS library loaded and the variable it reads.
BLAS_PROGRAM = """
import ctypes, os, sys
from ucontrol.cli import main

out, duration = sys.argv[1:]
assert main(["run", "--out", out, "--duration", duration, "--no-progress"]) == 0
libraries = {line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line.lower()}
for path in sorted(libraries):
    library = ctypes.CDLL(path)
    names = ("openblas_get_num_threads", "scipy_openblas_get_num_threads64_",
             "scipy_openblas_get_num_threads")
    name = next(name for name in names if hasattr(library, name))
    print("threads", getattr(library, name)())
print("variable", os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
@pytest.mark.parametrize("chosen", [None, "2"])
def test_run_loads_openblas_single_threaded_unless_the_user_chose(
    tmp_path: Path, chosen: str | None
) -> None:
    """Without a thread count of the user's, OpenBLAS runs one thread; the variable is reset.

    A count the user chose (here 2, or the cores there are) is OpenBLAS's, untouched.
    """
    variables = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")
    env = {key: value for key, value in os.environ.items() if key not in variables}
    if chosen is not None:
        env["OPENBLAS_NUM_THREADS"] = chosen
    completed = subprocess.run(
        [sys.executable, "-c", BLAS_PROGRAM, str(tmp_path / "run"), "0.05"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    words = [line.split(" ", 1) for line in completed.stdout.splitlines()]
    threads = [int(value) for key, value in words if key == "threads"]
    assert threads  # numpy's OpenBLAS at least
    expected = 1 if chosen is None else min(int(chosen), os.cpu_count() or 1)
    assert threads == [expected] * len(threads)
    assert dict(words)["variable"] == str(chosen)


#: ``ucontrol run`` called from Python with its words, then as the process's command (its
#: words in ``sys.argv``); the objects the collector holds frozen after each.
FREEZE_PROGRAM = """
import gc, sys
from ucontrol.cli import main

words = ["run", "--out", sys.argv[1], "--duration", "0.01", "--no-progress"]
assert main(words) == 0
print("called", gc.get_freeze_count())
sys.argv = ["ucontrol", *words]
assert main() == 0
print("command", gc.get_freeze_count())
print("enabled", int(gc.isenabled()))
"""


def test_only_the_process_command_freezes_the_collector(tmp_path: Path) -> None:
    """The command's process ends freezing its objects (a quicker exit); a caller's does not."""
    completed = subprocess.run(
        [sys.executable, "-c", FREEZE_PROGRAM, str(tmp_path / "run")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    counts = {
        key: int(value)
        for key, value in (
            line.split(" ", 1)
            for line in completed.stdout.splitlines()
            if line.startswith(("called ", "command ", "enabled "))
        )
    }
    assert counts["called"] == 0
    assert counts["command"] > 1000  # the modules' objects, among them
    assert counts["enabled"] == 1  # the collector still runs for what comes after
    assert (tmp_path / "run" / "summary.json").is_file()


#: Every command of ``ucontrol``.
COMMANDS = ("scenes", "run", "check", "convergence", "bench", "view", "plot", "sweep", "design")


@pytest.mark.parametrize("command", COMMANDS)
def test_parser_of_a_command_holds_that_command(command: str) -> None:
    """The parser built for a command line knows its command; without one, it knows them all."""
    assert command in _commands(_parser([command, "--help"]))
    assert _commands(_parser([])) == set(COMMANDS)
    assert _commands(_parser(["--version"])) == set(COMMANDS)


def _commands(parser: argparse.ArgumentParser) -> set[str]:
    (subparsers,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return set(subparsers.choices)
