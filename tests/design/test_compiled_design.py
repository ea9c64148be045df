"""The design's compiled derivatives: the virtual machine's iterates, cached by definition.

A cache keyed by the program's definition, a notice on the first build, the fallbacks.

The compiled path is the default where a C compiler is present; ``compiled=False``,
``UCONTROL_NO_COMPILE=1`` and a missing compiler solve in the virtual machine.
"""

from __future__ import annotations

import fcntl
import os
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import needs_compiled_code
from two_link_design import ROBOTS, TASK, two_link_design

from ucontrol.design import DesignTask, cycle_transcription, design_cycle
from ucontrol.model import compile_cache
from ucontrol.model.compile_cache import CACHE_ENV, wait_for_builds
from ucontrol.model.compiled_function import NO_COMPILE_ENV

pytestmark = pytest.mark.slow  # designs: seconds each

#: Cost of the two paths on the shipped two-link task, relative: measured 1.1e-15 (22
#: iterations both); states 4e-15 rad apart. The intervals' operations are the same, grouped
#: in substep calls on the compiled path, so only their rounding may differ.
_COST_RTOL = 1e-12
_STATE_ATOL = 1e-10


def _small_task(hessian: str = "exact", **phase: float) -> DesignTask:
    """The two-link task on a coarse grid (4 + 4 intervals of 2 RK4 steps).

    Its C compiles in seconds, its solve takes a fraction of one.
    """
    table = tomllib.loads(TASK.read_text())
    table["grid"] = {"flight_intervals": 4, "contact_intervals": 4, "substeps": 2, "scheme": "rk4"}
    table["contact_phases"][0].update(phase)
    table["solver"]["hessian"] = hessian
    return DesignTask.from_dict(table, base_dir=ROBOTS)


def _libraries(cache: Path) -> list[Path]:
    return sorted((cache / "casadi").glob("design_nlp_*.so"))


def _assert_same_design(a, b) -> None:  # type: ignore[no-untyped-def]
    (cycle_a, report_a), (cycle_b, report_b) = a, b
    assert report_a.success and report_b.success
    assert report_a.iterations == report_b.iterations
    assert report_a.cost == pytest.approx(report_b.cost, rel=_COST_RTOL)
    for phase_a, phase_b in zip(cycle_a.phases, cycle_b.phases, strict=True):
        for name in ("q", "v", "tau"):
            np.testing.assert_allclose(
                getattr(phase_a, name), getattr(phase_b, name), rtol=0, atol=_STATE_ATOL
            )


@needs_compiled_code
def test_the_two_link_design_is_the_same_compiled_and_in_the_virtual_machine() -> None:
    # the default where code compiles (the skip's condition): the design of test_cycle_design.py,
    # solved once per process
    _assert_same_design(two_link_design(), two_link_design(False))


@needs_compiled_code
def test_a_task_compiles_once_says_so_and_a_changed_task_compiles_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.setattr(compile_cache, "_announced", False)  # as in a new process
    reader, writer = os.openpty()  # stderr on a real (pseudo-)terminal
    with os.fdopen(writer, "w") as terminal, os.fdopen(reader, "rb", buffering=0) as screen:
        monkeypatch.setattr("sys.stderr", terminal)
        first = design_cycle(_small_task())
        terminal.flush()
        said = screen.read(4096).decode()  # the one line said, far below a pty's buffer
    assert said.startswith("ucontrol: compiling this design's derivatives"), said
    (library,) = _libraries(tmp_path)
    again = design_cycle(_small_task())  # loaded: nothing built
    assert _libraries(tmp_path) == [library]
    _assert_same_design(first, again)
    _assert_same_design(first, design_cycle(_small_task(), compiled=False))
    # a bound is an argument of the compiled functions: the same library, another optimum
    bounded = design_cycle(_small_task(force_min=6.0))
    assert _libraries(tmp_path) == [library]
    assert bounded[1].cost > first[1].cost * (1 + 1e-6)  # above the 5 N plateau
    _assert_same_design(bounded, design_cycle(_small_task(force_min=6.0), compiled=False))
    design_cycle(_small_task(force=6.0))  # another plateau in the cost: another program
    assert len(_libraries(tmp_path)) == 2
    # IPOPT's own Hessian approximation: no second derivatives to compile, another library
    limited = design_cycle(_small_task("limited-memory"))
    assert len(_libraries(tmp_path)) == 3
    _assert_same_design(limited, design_cycle(_small_task("limited-memory"), compiled=False))


@pytest.mark.parametrize(("variable", "value"), [(NO_COMPILE_ENV, "1"), ("CC", "no-such-compiler")])
def test_without_compilation_the_virtual_machine_finds_the_same_optimum(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, variable: str, value: str
) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    reference = design_cycle(_small_task(), compiled=False)
    monkeypatch.setenv(variable, value)
    _assert_same_design(design_cycle(_small_task()), reference)
    assert _libraries(tmp_path) == []


@pytest.fixture
def large(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The two-link task taken for a large model (MX intervals: built in the background).

    Returns the cache directory (fresh), nothing said on the terminal.
    """
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.setattr(cycle_transcription, "INLINE_JOINTS", 1)  # two joints are "many"
    monkeypatch.setattr(compile_cache, "_announced", True)
    assert wait_for_builds(0.0) == []  # none left by another test
    return tmp_path / "cache"


def _gated_compiler(tmp_path: Path) -> tuple[str, Path]:
    """A compiler command that runs ``cc`` once the returned gate file's lock is free."""
    gate, script = tmp_path / "gate", tmp_path / "gated-cc"
    gate.touch()
    script.write_text(
        f"#!{sys.executable}\n"
        "import fcntl, os, sys\n"
        f"with open({str(gate)!r}) as gate:\n"
        "    fcntl.flock(gate, fcntl.LOCK_EX)\n"
        "os.execvp('cc', ['cc', *sys.argv[1:]])\n"
    )
    script.chmod(0o755)
    return str(script), gate


def _leftovers(cache: Path) -> list[str]:
    """What the cache directory holds besides libraries: lock files, work directories."""
    return sorted(path.name for path in (cache / "casadi").iterdir() if path.suffix != ".so")


@needs_compiled_code
def test_a_large_program_is_built_in_the_background_then_loaded_with_the_same_optimum(
    large: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    compiler, gate = _gated_compiler(tmp_path)
    monkeypatch.setenv("CC", compiler)
    reference = design_cycle(_small_task(), compiled=False)
    with open(gate) as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # the build's compiler waits until released
        reader, writer = os.openpty()  # stderr on a real (pseudo-)terminal
        with (
            os.fdopen(writer, "w") as terminal,
            os.fdopen(reader, "rb", buffering=0) as screen,
            monkeypatch.context() as on_terminal,
        ):
            on_terminal.setattr("sys.stderr", terminal)
            first = design_cycle(_small_task())  # returns without the library, build started
            terminal.flush()
            said = screen.read(4096).decode()  # the one line said, far below a pty's buffer
        assert said.count("\n") == 1, said
        assert said.startswith("ucontrol: compiling this design's derivatives (a large"), said
        assert "in the background" in said and "later runs of this task load them" in said
        assert _libraries(large) == []
        (lock,) = (large / "casadi").glob("design_nlp_*.so.lock")
        with open(lock) as probe, pytest.raises(BlockingIOError):
            fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)  # held by the build
        second = design_cycle(_small_task())  # neither waits nor builds again
    assert wait_for_builds(120.0) == [0]  # one build, finished
    (library,) = _libraries(large)
    assert _leftovers(large) == [lock.name]  # its work directory removed
    loaded = design_cycle(_small_task())
    assert wait_for_builds(0.0) == []  # loaded: nothing built
    assert _libraries(large) == [library]
    for design in (first, second, loaded):
        _assert_same_design(design, reference)


@needs_compiled_code
def test_a_failed_background_build_leaves_its_marker_alone_and_is_not_started_again(
    large: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    reference = design_cycle(_small_task(), compiled=False)
    monkeypatch.setenv("CC", "false")  # a compiler that fails
    _assert_same_design(design_cycle(_small_task()), reference)
    assert wait_for_builds(120.0) == [1]  # tried, failed
    (marker,) = _leftovers(large)  # no lock file, no work directory: the marker alone
    assert marker.endswith(".so.failed") and _libraries(large) == []
    _assert_same_design(design_cycle(_small_task()), reference)
    assert wait_for_builds(0.0) == []  # not started again
    (large / "casadi" / marker).unlink()  # removed: the next run tries again
    _assert_same_design(design_cycle(_small_task()), reference)
    assert wait_for_builds(120.0) == [1]
    (large / "casadi" / marker).unlink()
    assert _libraries(large) == [] and _leftovers(large) == []
    monkeypatch.setenv("CC", "no-such-compiler")  # nothing to try
    _assert_same_design(design_cycle(_small_task()), reference)
    assert wait_for_builds(0.0) == []
    assert _libraries(large) == [] and _leftovers(large) == []
