"""Compiled libraries found by their definition: loaded without building the Function.

References: the casadi Function itself (its outputs on random inputs, its names and shapes)
and an analytic reference of its expressions.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import needs_compiled_code

from ucontrol.model import compile_cache
from ucontrol.model.compile_cache import (
    CACHE_ENV,
    build_library,
    definition_key,
    find_library,
    library_path,
)
from ucontrol.model.compiled_function import NO_COMPILE_ENV, CompiledFunction

#: Compiled C against the analytic expressions: the same arithmetic to round-off.
_TOLERANCE = 1e-12
#: The modules of a definition in these tests (any source files do).
_MODULES = ("ucontrol.model.compile_cache",)


class _Builder:
    """Builds the probe Function of a given name and counts its builds."""

    def __init__(self, name: str) -> None:
        self.name, self.builds = name, 0

    def __call__(self) -> ca.Function:
        self.builds += 1
        x, A = ca.SX.sym("x", 3), ca.SX.sym("A", 2, 3)  # a matrix input, column-major
        return ca.Function(
            self.name,
            [x, A],
            [ca.vertcat(ca.sin(x[0]) * x[1], A @ x), x[2] ** 2],
            ["x", "A"],
            ["first", "second"],
        )


def _reference(x: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.concatenate([[math.sin(x[0]) * x[1]], A @ x]), np.array([x[2] ** 2])


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    monkeypatch.setattr(compile_cache, "_announced", True)  # no notice in the tests' output
    return tmp_path


def _assert_probe_outputs(function: CompiledFunction, rng: np.random.Generator) -> None:
    for _ in range(5):
        x, A = rng.standard_normal(3), rng.standard_normal((2, 3))
        outputs = function(x, A)
        for out, ref in zip(outputs, _reference(x, A), strict=True):
            np.testing.assert_allclose(out, ref, rtol=0.0, atol=_TOLERANCE)


@needs_compiled_code
def test_a_recorded_definition_loads_the_library_without_building(cache: Path) -> None:
    builder = _Builder("probe_definition")
    definition = definition_key(["probe", 3], _MODULES)
    assert find_library(builder.name, definition) is None
    first = CompiledFunction.cached(builder.name, definition, builder)
    assert first.compiled and builder.builds == 1
    found = find_library(builder.name, definition)
    assert found is not None
    assert os.stat(found).st_ino == os.stat(first.library_path).st_ino  # one file, two names
    second = CompiledFunction.cached(builder.name, definition, builder)
    assert second.compiled and builder.builds == 1  # loaded: not built
    assert second.library_path == found
    # The signature read from the library is the Function's.
    f = first.function
    for name in ("x", "A"):
        i = f.index_in(name)
        assert second.index_in(name) == i
        assert second.input_view(i).shape == first.input_view(i).shape
    for name in ("first", "second"):
        assert second.index_out(name) == f.index_out(name)
        assert second.output_buffer(f.index_out(name)).size == f.nnz_out(name)
    rng = np.random.default_rng(7)
    _assert_probe_outputs(second, rng)
    _assert_probe_outputs(first, rng)
    # The Function of a loaded library is built when asked for, equal to the original.
    assert builder.builds == 1
    x, A = rng.standard_normal(3), rng.standard_normal((2, 3))
    expected = [np.asarray(o).ravel() for o in f(x, A)]
    rebuilt = [np.asarray(o).ravel() for o in second.function(x, A)]
    assert builder.builds == 2
    for a, b in zip(expected, rebuilt, strict=True):
        np.testing.assert_array_equal(a, b)


@needs_compiled_code
def test_definitions_differ_by_parts_and_by_source(tmp_path: Path) -> None:
    base = definition_key(["free_step", 2, 0.1], _MODULES)
    assert base == definition_key(["free_step", 2, 0.1], _MODULES)
    assert base != definition_key(["free_step", 2, math.nextafter(0.1, 1.0)], _MODULES)
    assert base != definition_key(["free_step", 3, 0.1], _MODULES)
    assert base != definition_key(["free_step", 2, 0.1], ("ucontrol.model.compiled_function",))
    with pytest.raises(OSError):
        definition_key([], ("ucontrol.no_such_module",))


@needs_compiled_code
def test_a_foreign_library_under_a_definition_is_built_again(cache: Path) -> None:
    """A file recorded under the definition that is not the Function's: built, not loaded."""
    builder = _Builder("probe_foreign")
    definition = definition_key(["foreign"], _MODULES)
    other = build_library("other", "other", "int other(void) { return 0; }\n")
    os.link(other, library_path(builder.name, definition))
    made = CompiledFunction.cached(builder.name, definition, builder)
    assert builder.builds == 1 and made.compiled
    assert made.library_path != library_path(builder.name, definition)
    _assert_probe_outputs(made, np.random.default_rng(3))


def test_without_compilation_the_function_is_built_and_interpreted(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(NO_COMPILE_ENV, "1")
    builder = _Builder("probe_interpreted")
    definition = definition_key(["interpreted"], _MODULES)
    for builds in (1, 2):
        made = CompiledFunction.cached(builder.name, definition, builder)
        assert not made.compiled and made.library_path is None and builder.builds == builds
        _assert_probe_outputs(made, np.random.default_rng(5))
    assert not any(cache.rglob("*.so"))


LOADED = """
import sys
from ucontrol.model.compiled_function import CompiledFunction

def build():
    raise AssertionError("built")

made = CompiledFunction.cached(sys.argv[1], sys.argv[2], build)
print(made.compiled, "casadi" in sys.modules)
"""


@needs_compiled_code
def test_a_process_loading_a_recorded_library_does_not_import_casadi(cache: Path) -> None:
    builder = _Builder("probe_process")
    definition = definition_key(["process"], _MODULES)
    CompiledFunction.cached(builder.name, definition, builder)
    completed = subprocess.run(
        [sys.executable, "-c", LOADED, builder.name, definition],
        capture_output=True,
        text=True,
        env={**os.environ, CACHE_ENV: str(cache)},
        timeout=120,
    )
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.split() == ["True", "False"]


def _two_link_run(mass_scale: float) -> dict[str, np.ndarray]:
    """The log of 0.5 s of two_link_one_constraint, its controller's masses scaled."""
    import tomllib

    from ucontrol.scene import Scene
    from ucontrol.simulate import simulate

    robots = Path(__file__).resolve().parents[2] / "robots"
    table = tomllib.loads((robots / "two_link_one_constraint.toml").read_text())
    table["controller"].setdefault("model", {})["mass_scale"] = mass_scale
    scene = Scene.from_dict(table, base_dir=robots)
    result = simulate(scene, scene.build_controller(), duration=0.5, progress=False)
    return {name: getattr(result.log, name) for name in result.log.fields}


@needs_compiled_code
def test_a_brogliato_law_loaded_by_its_definition_runs_the_built_laws_loop(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The two-link law built, then loaded for another mass scale: a fresh build's log."""
    from ucontrol.control import brogliato_controller

    built = []
    law_function = brogliato_controller._rigid_law_function

    def counted(*args: object, **kwargs: object) -> ca.Function:
        built.append(1)
        return law_function(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(brogliato_controller, "_rigid_law_function", counted)
    _two_link_run(1.0)
    assert len(built) == 1
    loaded = _two_link_run(1.13)  # the masses are the law's input: the same definition
    assert len(built) == 1
    monkeypatch.setenv(CACHE_ENV, str(cache / "fresh"))
    fresh = _two_link_run(1.13)
    assert len(built) == 2
    assert loaded.keys() == fresh.keys()
    for key in loaded:
        if key != "solver_time":  # a timing
            np.testing.assert_array_equal(loaded[key], fresh[key], err_msg=key)
