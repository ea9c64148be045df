"""A controller's output that is not a vector of the input's size fails the run cleanly."""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.exceptions import ShapeError, SimulationError
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate


def _ignore(log: object) -> None:
    """An observer that does nothing."""


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
