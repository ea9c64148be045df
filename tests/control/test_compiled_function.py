"""Casadi laws compiled to C: same outputs as casadi's virtual machine and as the numpy law."""

from __future__ import annotations

import ctypes
import gc
import math
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import needs_compiled_code

from ucontrol.control.controller import ContactState
from ucontrol.exceptions import CompiledCallError
from ucontrol.model import compiled_function, native_call
from ucontrol.model.compile_cache import CACHE_ENV, build_library, cache_dir
from ucontrol.model.compiled_function import (
    NO_COMPILE_ENV,
    CompiledFunction,
    compilation_disabled,
)
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: Compiled C against casadi's virtual machine / the numpy law: the same expressions.
_TOLERANCE = 1e-12


def _function() -> ca.Function:
    x = ca.SX.sym("x", 3)
    A = ca.SX.sym("A", 2, 3)  # a matrix input, column-major
    return ca.Function("probe", [x, A], [ca.vertcat(ca.sin(x[0]) * x[1], A @ x), x[2] ** 2])


def _reference(x: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.concatenate([[math.sin(x[0]) * x[1]], A @ x]), np.array([x[2] ** 2])


def test_runner_writes_the_outputs_of_the_inputs_in_place(tmp_path, monkeypatch):
    """``runner()`` on inputs written through ``input_view``: the values of ``__call__``."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    rng = np.random.default_rng(1)
    for function in (CompiledFunction(_function()), CompiledFunction(_function(), compile=False)):
        run, outputs = function.runner(), (function.output_buffer(0), function.output_buffer(1))
        for _ in range(10):
            x, A = rng.standard_normal(3), rng.standard_normal((2, 3))
            function.input_view(0)[...], function.input_view(1)[...] = x, A
            assert run() is None
            for out, ref in zip(outputs, _reference(x, A), strict=True):
                np.testing.assert_allclose(out, ref, rtol=0.0, atol=_TOLERANCE)


def test_native_runner_equals_the_ctypes_call_and_keeps_its_buffers(tmp_path, monkeypatch):
    """The builtin runner of native_call: the ctypes call's outputs, alive after its owner."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    if native_call._extension() is None:
        pytest.skip("installed without its C extension: compiled calls go through ctypes")
    rng = np.random.default_rng(2)
    function = CompiledFunction(_function())
    run = function.runner()
    assert type(run).__name__ == "builtin_function_or_method"  # not the ctypes lambda
    ctypes_call = function._call
    view, outputs = function.input_view, (function.output_buffer(0), function.output_buffer(1))
    del function  # the runner keeps the buffers it points to alive
    gc.collect()
    for _ in range(10):
        x, A = rng.standard_normal(3), rng.standard_normal((2, 3))
        view(0)[...], view(1)[...] = x, A
        run()
        native = [out.copy() for out in outputs]
        assert ctypes_call() == 0
        for out, value, ref in zip(outputs, native, _reference(x, A), strict=True):
            np.testing.assert_array_equal(value, out)  # the same compiled code
            np.testing.assert_allclose(value, ref, rtol=0.0, atol=_TOLERANCE)


def test_native_runner_raises_on_a_nonzero_status(tmp_path, monkeypatch):
    """A compiled entry returning a status other than 0 raises a CompiledCallError naming it."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    if native_call._extension() is None:
        pytest.skip("installed without its C extension: compiled calls go through ctypes")
    source = (
        "int failing(const double **a, double **r, long long *iw, double *w, int m) {return 3;}"
    )
    library = ctypes.CDLL(str(build_library("failing", source, source)))
    entry = ctypes.cast(library.failing, ctypes.c_void_p).value
    pointers, work = (ctypes.c_void_p * 1)(), np.zeros(1)
    address = ctypes.addressof(pointers)
    run = native_call.native_runner(
        entry, address, address, work.ctypes.data, work.ctypes.data, library, "failing"
    )
    assert run is not None
    with pytest.raises(CompiledCallError, match="'failing' failed: returned status 3") as raised:
        run()
    assert raised.value.function == "failing" and raised.value.failure == "returned status 3"


def test_a_failing_call_in_casadis_virtual_machine_is_a_compiled_call_error():
    """A casadi error (a root finder without a root) becomes a one-line CompiledCallError."""
    x, p = ca.SX.sym("x"), ca.SX.sym("p")
    residual = ca.Function("residual", [x, p], [x**2 + 1.0 + p])  # a root only for p <= -1
    roots = ca.rootfinder("no_root", "newton", residual, {"error_on_fail": True})
    function = CompiledFunction(roots, compile=False)
    (root,) = function(np.array([0.5]), np.array([-2.0]))
    np.testing.assert_allclose(root, [1.0], rtol=0.0, atol=_TOLERANCE)  # x**2 = 1
    run = function.runner()
    function.input_view(1)[...] = 0.0
    for call in (run, lambda: function(None, None)):
        with pytest.raises(CompiledCallError, match=r"'no_root' failed: .*rootfinder") as raised:
            call()
        assert raised.value.function == "no_root" and "\n" not in str(raised.value)


@pytest.mark.parametrize("compile", [True, False])
def test_bound_output_is_written_in_place(compile, tmp_path, monkeypatch):
    """bind_output: the call writes into the given array (compiled or not); bad arrays refused."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    function = CompiledFunction(_function(), compile=compile)
    target = np.zeros((3, 1), order="F")
    function.bind_output(0, target)
    x, A = np.array([0.3, -1.2, 2.0]), np.arange(6.0).reshape(2, 3)
    function(x, A)
    np.testing.assert_allclose(target.ravel(), _reference(x, A)[0], rtol=0.0, atol=_TOLERANCE)
    assert np.shares_memory(function.output_buffer(0), target)
    with pytest.raises(ValueError, match="output 1 of probe"):
        function.bind_output(1, np.zeros(2))  # output 1 has one value
    with pytest.raises(ValueError, match="output 0 of probe"):
        function.bind_output(0, np.zeros((3, 2))[:, 0])  # not its own memory once raveled


def test_runner_through_ctypes_without_the_extension(tmp_path, monkeypatch):
    """Without the extension (no Python headers), runner() calls through ctypes: same values."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    monkeypatch.setattr(compiled_function, "native_runner", lambda *args: None)
    function = CompiledFunction(_function())
    run = function.runner()
    assert function.compiled and type(run).__name__ == "function"
    x, A = np.array([0.3, -1.2, 2.0]), np.arange(6.0).reshape(2, 3)
    function.input_view(0)[...], function.input_view(1)[...] = x, A
    run()
    for out, ref in zip(function(None, None), _reference(x, A), strict=True):
        np.testing.assert_allclose(out, ref, rtol=0.0, atol=_TOLERANCE)


def _scaled() -> ca.Function:
    x, s = ca.SX.sym("x", 3), ca.SX.sym("s")
    return ca.Function("scaled", [x, s], [s * x])


@pytest.mark.parametrize("path", ["native", "ctypes", "virtual machine"])
def test_runner_copies_its_arguments_into_their_inputs(path, tmp_path, monkeypatch):
    """runner(inputs): its arguments written first, as ``input_view(i)[...] = value`` does.

    Contiguous and strided float64 arrays (copied by the extension), a float for an input of
    one value, and values numpy converts (integers, a list), against the analytic outputs.
    """
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    if path == "native" and native_call._extension() is None:
        pytest.skip("installed without its C extension: compiled calls go through ctypes")
    if path == "ctypes":
        monkeypatch.setattr(compiled_function, "native_runner", lambda *args: None)
    function = CompiledFunction(_scaled(), compile=path != "virtual machine")
    run, out = function.runner((0, 1)), function.output_buffer(0)
    native = type(run).__name__ == "builtin_function_or_method"
    assert native == (path == "native")
    rng = np.random.default_rng(3)
    values = [
        rng.standard_normal(3),
        rng.standard_normal(9)[::3],
        np.array([1, -2, 4]),
        [0.5, 2, -1],
    ]
    for x in values:
        for s in (1.5, np.float64(-0.25), np.array([2.0])):
            assert run(x, s) is None
            expected = float(np.asarray(s).item()) * np.asarray(x, dtype=float)
            np.testing.assert_allclose(out, expected, rtol=0.0, atol=_TOLERANCE)
    with pytest.raises(ValueError):  # numpy's, as input_view(0)[...] = a 4-vector raises
        run(np.zeros(4), 1.0)
    with pytest.raises((TypeError, ValueError), match=r"argument"):  # (C's or zip's)
        run(np.zeros(3))


def test_compiled_function_matches_analytic_values(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    rng = np.random.default_rng(0)
    compiled, fallback = CompiledFunction(_function()), CompiledFunction(_function(), compile=False)
    assert compiled.compiled and not fallback.compiled
    assert compiled.library_path is not None and compiled.library_path.parent == cache_dir()
    for _ in range(20):
        x, A = rng.standard_normal(3), rng.standard_normal((2, 3))
        expected = _reference(x, A)
        for function in (compiled, fallback):
            for out, ref in zip(function(x, A), expected, strict=True):
                np.testing.assert_allclose(out, ref, rtol=0.0, atol=_TOLERANCE)


def test_cache_is_built_once_by_concurrent_builders(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    with ThreadPoolExecutor(max_workers=3) as pool:
        functions = list(pool.map(lambda _: CompiledFunction(_function()), range(3)))
    assert all(f.compiled for f in functions)
    assert len({f.library_path for f in functions}) == 1
    assert len(list(cache_dir().glob("probe_*.so"))) == 1  # no partial or duplicate library
    # Reused, not rebuilt: a build renames a new file into place (a new inode); a lookup only
    # records its use (the modification time).
    inode = functions[0].library_path.stat().st_ino
    assert CompiledFunction(_function()).library_path.stat().st_ino == inode


def test_fallback_without_compiler_or_when_disabled(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    missing = CompiledFunction(_function())
    monkeypatch.delenv("CC")
    monkeypatch.setenv(NO_COMPILE_ENV, "1")
    assert compilation_disabled()
    disabled = CompiledFunction(_function())
    assert not missing.compiled and not disabled.compiled
    x, A = np.array([0.3, -1.2, 2.0]), np.arange(6.0).reshape(2, 3)
    for function in (missing, disabled):
        for out, ref in zip(function(x, A), _reference(x, A), strict=True):
            np.testing.assert_allclose(out, ref, rtol=0.0, atol=_TOLERANCE)


def _inputs(scene: Scene, rng: np.random.Generator, steps: int):
    """Random states around q0 and contact readings, at increasing times."""
    names = scene.build_integrator().constraints.names
    q0, v0 = scene.initial_state()
    n = len(names)
    for k in range(steps):
        q = q0 + 0.05 * rng.standard_normal(q0.size)
        v = v0 + 0.3 * rng.standard_normal(v0.size)
        impulse = np.where(rng.random(n) < 0.5, rng.uniform(0.0, 0.02, n), 0.0)
        contacts = ContactState(
            names, rng.uniform(0.0, 0.1, n), rng.standard_normal(n), impulse, impulse > 0, 1e-3
        )
        yield 0.7 * k, q, v, contacts  # 0.7 s apart: the phases of the cycle are visited


@pytest.mark.parametrize(
    "name", ["two_link_flexible_one_constraint", "two_link_flexible_two_constraints"]
)
def test_flexible_law_compiled_equals_fallback(name, monkeypatch):
    # the session's cache: the scenes' laws, compiled once for every test that runs them
    scene = Scene.from_toml(ROBOTS / f"{name}.toml")
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    compiled = scene.build_controller()
    monkeypatch.setenv(NO_COMPILE_ENV, "1")
    fallback = scene.build_controller()
    assert compiled._law.compiled and not fallback._law.compiled
    rng = np.random.default_rng(1)
    for t, q, v, contacts in _inputs(scene, rng, 40):
        u_compiled, u_fallback = compiled(t, q, v, contacts), fallback(t, q, v, contacts)
        np.testing.assert_allclose(u_compiled, u_fallback, rtol=0.0, atol=_TOLERANCE)
        assert compiled.V == pytest.approx(fallback.V, rel=0.0, abs=_TOLERANCE)
        assert compiled.phase == fallback.phase


@needs_compiled_code
@pytest.mark.parametrize(
    "name", ["two_link_one_constraint", "two_link_two_constraints", "panda_table"]
)
def test_rigid_law_compiled_equals_its_reference(name, monkeypatch):
    """The compiled rigid law against its reference: the same Function in casadi's VM."""
    # the session's cache: the scenes' laws, compiled once for every test that runs them
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    scene = Scene.from_toml(ROBOTS / f"{name}.toml")
    compiled = scene.build_controller()
    monkeypatch.setenv(NO_COMPILE_ENV, "1")
    reference = scene.build_controller()
    assert compiled._rigid_law.compiled and not reference._rigid_law.compiled
    rng = np.random.default_rng(2)
    for t, q, v, contacts in _inputs(scene, rng, 40):
        u_compiled, u_reference = compiled(t, q, v, contacts), reference(t, q, v, contacts)
        scale = max(1.0, float(np.max(np.abs(u_reference))))
        np.testing.assert_allclose(u_compiled, u_reference, rtol=0.0, atol=_TOLERANCE * scale)
        assert compiled.V1 == pytest.approx(reference.V1, rel=1e-12, abs=1e-12)
        assert compiled.V == pytest.approx(reference.V, rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(compiled.X, reference.X, rtol=0.0, atol=1e-14)
        assert compiled.phase == reference.phase


def test_symbolic_kinematics_of_the_law_equal_pinocchios():
    """C, the frame position, its Jacobian and dJ of a small robot's law against Pinocchio."""
    import pinocchio as pin

    from ucontrol.control.brogliato_controller import _symbolic_kinematics
    from ucontrol.model.symbolic_model import inertia_parameters

    scene = Scene.from_toml(ROBOTS / "two_link_one_constraint.toml")
    controller = scene.build_controller()
    robot, frame = controller.robot, controller.task.frame
    kinematics = _symbolic_kinematics(robot, frame)
    assert kinematics is not None
    # The inertias an input: those of a heavier model, in the same Function.
    robot = robot.with_scaled_inertia(1.3)
    inertia = inertia_parameters(robot.model)
    model, data, frame_id = robot.model, pin.Data(robot.model), robot.frame_id(frame)
    lwa = pin.LOCAL_WORLD_ALIGNED
    generator = np.random.default_rng(4)
    for _ in range(20):
        q, v = generator.uniform(-3.0, 3.0, robot.nq), generator.standard_normal(robot.nv)
        C, p, J, dJ = (np.array(x) for x in kinematics(q, v, inertia))
        np.testing.assert_allclose(C, pin.computeCoriolisMatrix(model, data, q, v), atol=1e-14)
        pin.updateFramePlacement(model, data, frame_id)
        np.testing.assert_allclose(p.ravel(), data.oMf[frame_id].translation, atol=1e-14)
        J_pin = pin.getFrameJacobian(model, data, frame_id, lwa)[:3]
        dJ_pin = pin.getFrameJacobianTimeVariation(model, data, frame_id, lwa)[:3]
        np.testing.assert_allclose(J, J_pin, atol=1e-14)
        np.testing.assert_allclose(dJ, dJ_pin, atol=1e-13)
    panda = Scene.from_toml(ROBOTS / "panda_table.toml").build_controller()
    assert _symbolic_kinematics(panda.robot, panda.task.frame) is None  # nv = 7: Pinocchio's


@pytest.mark.parametrize("no_compile", ["0", "1"])
def test_only_a_small_robots_law_takes_the_symbolic_kinematics(no_compile, monkeypatch):
    """On both paths: the law's inputs are the symbolic kinematics' q, or Pinocchio's terms."""
    monkeypatch.setenv(NO_COMPILE_ENV, no_compile)
    two_link = Scene.from_toml(ROBOTS / "two_link_one_constraint.toml").build_controller()
    panda = Scene.from_toml(ROBOTS / "panda_table.toml").build_controller()
    assert two_link._configuration_input is not None and panda._configuration_input is None
    assert "q" in two_link._law_index and "C" not in two_link._law_index
    assert "C" in panda._law_index and "q" not in panda._law_index


def test_gains_and_stiffness_are_parameters_of_one_library(monkeypatch):
    """Sweeping gains (rigid) or gains and stiffness (flexible) reuses the compiled law."""
    from dataclasses import replace

    from ucontrol.control import BrogliatoController, FlexibleBrogliatoController

    # the session's cache: the two-link laws, compiled once for every test that runs them
    monkeypatch.delenv(NO_COMPILE_ENV, raising=False)
    rigid = Scene.from_toml(ROBOTS / "two_link_one_constraint.toml").build_controller()
    gains = replace(rigid.gains, gamma1=3.0 * rigid.gains.gamma1, gamma2=0.5)
    swept = BrogliatoController(rigid.robot, rigid.task, rigid.cycle, gains)
    # One library: the same file, found again by its definition (a second name of the file).
    assert swept._rigid_law.library_path.samefile(rigid._rigid_law.library_path)
    monkeypatch.setenv(NO_COMPILE_ENV, "1")
    reference = BrogliatoController(rigid.robot, rigid.task, rigid.cycle, gains)
    scene = Scene.from_toml(ROBOTS / "two_link_one_constraint.toml")
    for t, q, v, contacts in _inputs(scene, np.random.default_rng(4), 10):
        np.testing.assert_allclose(
            swept(t, q, v, contacts), reference(t, q, v, contacts), rtol=0.0, atol=1e-11
        )
    monkeypatch.delenv(NO_COMPILE_ENV)
    flexible = Scene.from_toml(ROBOTS / "two_link_flexible_one_constraint.toml").build_controller()
    joints = flexible.flexible
    stiffer = replace(joints, stiffness=10.0 * joints.stiffness)
    other = FlexibleBrogliatoController(
        flexible.robot, stiffer, flexible.task, flexible.cycle, gains
    )
    assert other._law.library_path.samefile(flexible._law.library_path)
