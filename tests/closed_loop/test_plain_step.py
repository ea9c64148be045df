"""The plain loop's fused step (``_ClosedLoop.plain_step``) against the staged loop.

A run whose controller acts on the plant's own rigid state at every step, without sensors,
actuators or observer, takes ``plain_step``; an observer that does nothing sends the same run
through :meth:`sample`, :meth:`control` and :meth:`advance`. Both must write the same log,
bit for bit, and fail the same way.
"""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.exceptions import ShapeError, SimulationError
from ucontrol.scene import load_scene
from ucontrol.simulate import _ClosedLoop, simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out


def _ignore(log: object) -> None:
    """An observer: makes the loop staged."""


@pytest.mark.parametrize(
    ("name", "duration"),
    [("two_link_one_constraint", 6.0), ("panda_table", 2.0), ("ball", 1.0)],
)
def test_plain_step_writes_the_log_of_the_staged_loop(name: str, duration: float) -> None:
    scene = load_scene(name)
    integrator = scene.build_integrator()
    assert _ClosedLoop(scene, integrator, scene.build_controller(), 2, 1, None).plain
    assert not _ClosedLoop(scene, integrator, scene.build_controller(), 2, 1, _ignore).plain
    plain = simulate(scene, duration=duration, progress=False)
    staged = simulate(scene, duration=duration, progress=False, observer=_ignore)
    assert len(plain.log) == len(staged.log) == round(duration / integrator.dt) + 1
    assert plain.log.fields == staged.log.fields
    for field in plain.log.fields:
        np.testing.assert_array_equal(getattr(plain.log, field), getattr(staged.log, field))
    assert plain.summary["n_impacts"] == staged.summary["n_impacts"]


@pytest.mark.parametrize("observer", [None, _ignore])
def test_a_wrong_output_fails_alike_on_both_paths(observer) -> None:
    scene = load_scene("two_link_one_constraint")
    calls = []

    def controller(t, q, v, contacts):
        calls.append(t)
        return np.zeros(3) if len(calls) > 5 else [0.0, 0.0]  # a list is converted

    with pytest.raises(SimulationError) as failure:
        simulate(scene, controller=controller, duration=0.1, progress=False, observer=observer)
    assert isinstance(failure.value.__cause__, ShapeError)
    assert len(failure.value.log) == 6  # the failed step's state is kept, its row closed
    np.testing.assert_array_equal(failure.value.log.u, np.zeros((6, 2)))
