"""A scene's ``[[pushes]]``: velocity changes of the robot at given times."""

from __future__ import annotations

import tomllib
import warnings

import numpy as np
import pytest

from ucontrol.campaign.overrides import apply_overrides
from ucontrol.exceptions import (
    EnergyGainWarning,
    InvalidParameterError,
    SceneError,
    ShapeError,
    UnknownKeyError,
)
from ucontrol.scene import Scene
from ucontrol.scene.builtin_scenes import builtin_scene
from ucontrol.simulate import simulate


def _scene(name: str, **overrides: object) -> Scene:
    path = builtin_scene(name)
    table = apply_overrides(tomllib.loads(path.read_text()), overrides)
    return Scene.from_dict(table, base_dir=path.parent)


def test_the_push_is_added_at_its_sample() -> None:
    """Against the same run without the push: equal before, v + dv at the first sample >= t."""
    pushed = _scene("hopper_push", duration=2.1)
    plain = _scene("hopper_push", duration=2.1, **{"pushes.0.velocity.0": 0.0})
    with warnings.catch_warnings():
        warnings.simplefilter("error", EnergyGainWarning)  # the push is left out of the audit
        a = simulate(pushed, progress=False).log
    b = simulate(plain, progress=False).log
    k = 2000  # t = 2.0 s at dt = 1 ms
    assert np.array_equal(np.asarray(a.v)[:k], np.asarray(b.v)[:k])
    jump = np.asarray(a.v)[k] - np.asarray(b.v)[k]
    assert np.max(np.abs(jump - [1.0, 0.0, 0.0, 0.0, 0.0])) < 1e-12
    assert float(np.asarray(a.v)[k - 1, 0]) == pytest.approx(0.0, abs=1e-12)


def test_a_push_between_samples_waits_for_the_next() -> None:
    scene = _scene("hopper_push", duration=2.1, **{"pushes.0.time": 1.9995})
    v = np.asarray(simulate(scene, progress=False).log.v)
    assert v[1999, 0] == pytest.approx(0.0, abs=1e-12)
    assert v[2000, 0] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(
    ("push", "error", "match"),
    [
        ({"time": 1.0, "velocity": [0.0] * 5, "force": 1.0}, UnknownKeyError, "force"),
        ({"velocity": [0.0] * 5}, SceneError, "time"),
        ({"time": -1.0, "velocity": [0.0] * 5}, InvalidParameterError, "time"),
        ({"time": 1.0, "velocity": [0.0] * 3}, ShapeError, "velocity"),
    ],
)
def test_bad_pushes_are_refused(push: dict[str, object], error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        _scene("hopper", pushes=[push])
