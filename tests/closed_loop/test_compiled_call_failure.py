"""A casadi call that fails part-way through a run: a typed error, and the log up to then.

The flexible-joint Brogliato law runs through :class:`CompiledFunction` runners, compiled or
(``UCONTROL_NO_COMPILE=1``) in casadi's virtual machine. Its runner is made to fail at its
:data:`_FAILING_CALL`-th call, as a compiled entry returning a non-zero status does: the run
stops with a :class:`SimulationError` caused by the :class:`CompiledCallError`, and the log it
carries is the reference run's, sample for sample, up to the failing step.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import ROBOTS
from ucontrol.cli import main
from ucontrol.exceptions import CompiledCallError, SimulationError
from ucontrol.log import Log
from ucontrol.model.compiled_function import CompiledFunction
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

_SCENE = ROBOTS / "two_link_flexible_one_constraint.toml"
_LAW = "flexible_brogliato_law"
_FAILING_CALL = 40
_DURATION = 0.1  # [s], 100 steps of 1 ms: the law fails within them


def _failing_law(monkeypatch: pytest.MonkeyPatch) -> None:
    """Runners of the law that fail at their _FAILING_CALL-th call; the others untouched."""
    runner = CompiledFunction.runner

    def failing_runner(self: CompiledFunction, inputs: Sequence[int] = ()) -> Callable[..., None]:
        run = runner(self, inputs)
        if self.name != _LAW:
            return run
        calls = [0]

        def run_or_fail(*values: object) -> None:
            calls[0] += 1
            if calls[0] == _FAILING_CALL:
                raise CompiledCallError(self.name, "returned status 1")
            run(*values)

        return run_or_fail

    monkeypatch.setattr(CompiledFunction, "runner", failing_runner)


def _assert_prefix_of(partial: Log, reference: Log) -> None:
    """``partial`` holds ``reference``'s first samples; the failing step's input is not kept."""
    n = len(partial)
    assert 1 < n < len(reference)
    for field in ("t", "q", "v", "gap", "impulse"):
        np.testing.assert_array_equal(getattr(partial, field), getattr(reference, field)[:n])
    np.testing.assert_array_equal(partial.u[: n - 1], reference.u[: n - 1])


def test_a_failing_compiled_call_stops_the_run_and_keeps_its_log(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    scene = Scene.from_toml(_SCENE)
    reference = simulate(scene, duration=_DURATION, progress=False).log
    _failing_law(monkeypatch)
    with pytest.raises(SimulationError, match=f"casadi function '{_LAW}' failed") as raised:
        simulate(scene, duration=_DURATION, progress=False)
    error = raised.value
    assert isinstance(error.__cause__, CompiledCallError)
    assert error.__cause__.function == _LAW and error.__cause__.failure == "returned status 1"
    _assert_prefix_of(error.log, reference)
    assert error.step == len(error.log) - 1 and error.time == reference.t[error.step]


def test_the_command_reports_a_failing_compiled_call_on_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    reference = simulate(Scene.from_toml(_SCENE), duration=_DURATION, progress=False).log
    _failing_law(monkeypatch)
    out = tmp_path / "out"
    assert main(["run", str(_SCENE), "--duration", str(_DURATION), "--out", str(out)]) == 2
    message = capsys.readouterr().err
    assert message.count("\n") == 1 and message.startswith("ucontrol: error: simulation failed")
    assert f"casadi function '{_LAW}' failed: returned status 1" in message
    assert f"saved to {out / 'log.npz'}" in message
    _assert_prefix_of(Log.load(out / "log.npz"), reference)
