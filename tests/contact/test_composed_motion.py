"""Surface motions from a scene: sums of motions and Python functions named ``module:name``.

The composed motion is checked against its terms evaluated apart (and their closed forms), and
the ball of ``robots/ball.urdf`` on a plate moved by the sum against the same ball on a plate
moved by a hand-written Python function of the same x(t).
"""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.contact.surface_motion import (
    MotionSum,
    Polynomial,
    Sinusoid,
    UserMotion,
    check_motion,
)
from ucontrol.exceptions import (
    InvalidParameterError,
    NotFoundError,
    SceneError,
    UserFunctionError,
)
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

SPEED, AMPLITUDE, OMEGA, PHASE = 0.2, 0.01, 30.0, 0.4  # [m/s], [m], [rad/s], [rad]
RAMP = {"type": "ramp", "velocity": [0.0, 0.0, SPEED]}
SINUSOID = {
    "type": "sinusoid",
    "amplitude": [0.0, 0.0, AMPLITUDE],
    "frequency": OMEGA,
    "phase": PHASE,
}
#: x(t) = ramp + sinusoid written out by hand, in a module the scene names.
MODULE = """
import numpy as np

def shaker(t):
    angle = {omega} * t + {phase}
    x = {speed} * t + {amplitude} * np.sin(angle)
    v = {speed} + {amplitude} * {omega} * np.cos(angle)
    a = -{amplitude} * {omega} ** 2 * np.sin(angle)
    return np.array([0.0, 0.0, x]), np.array([0.0, 0.0, v]), np.array([0.0, 0.0, a])

def flat(t):
    return np.zeros(2), np.zeros(3), np.zeros(3)

def wrong_velocity(t):
    return np.array([0.0, 0.0, t]), np.zeros(3), np.zeros(3)

not_callable = 3.0
"""


@pytest.fixture
def module_dir(tmp_path: Path) -> Path:
    """A folder beside the scene holding ``ucontrol_test_shaker.py``; unloaded afterwards."""
    source = MODULE.format(speed=SPEED, amplitude=AMPLITUDE, omega=OMEGA, phase=PHASE)
    (tmp_path / "ucontrol_test_shaker.py").write_text(textwrap.dedent(source))
    yield tmp_path
    sys.modules.pop("ucontrol_test_shaker", None)
    if str(tmp_path) in sys.path:
        sys.path.remove(str(tmp_path))


def _ball(motion: Any, base_dir: Path) -> Scene:
    table = {
        "robot": {"urdf": str(ROBOTS / "ball.urdf"), "q0": [0.3], "gravity": [0.0, 0.0, -9.81]},
        "surfaces": {"plate": {"type": "plane", "normal": [0.0, 0.0, 1.0], "motion": motion}},
        "contacts": [{"frame": "ball", "surface": "plate", "radius": 0.1, "restitution": 0.6}],
        "integrator": {"name": "moreau_jean", "dt": 1e-3},
    }
    return Scene.from_dict(table, base_dir=base_dir)


def test_a_composed_motion_is_the_sum_of_its_terms(tmp_path: Path) -> None:
    motion = _ball([RAMP, SINUSOID], tmp_path).contacts[0].surface.motion
    assert isinstance(motion, MotionSum)
    ramp = Polynomial(coefficients=[[0.0, 0.0, 0.0], [0.0, 0.0, SPEED]])
    sinusoid = Sinusoid(amplitude=[0.0, 0.0, AMPLITUDE], frequency=OMEGA, phase=PHASE)
    for t in np.linspace(0.0, 1.0, 11):
        x, v, a = motion(float(t))
        for total, first, second in zip((x, v, a), ramp(t), sinusoid(t), strict=True):
            np.testing.assert_allclose(total, first + second, rtol=0.0, atol=1e-15)
        angle = OMEGA * t + PHASE  # the closed form of the sum, along z
        assert abs(x[2] - (SPEED * t + AMPLITUDE * np.sin(angle))) <= 1e-15
        assert abs(v[2] - (SPEED + AMPLITUDE * OMEGA * np.cos(angle))) <= 1e-14
        assert abs(a[2] + AMPLITUDE * OMEGA**2 * np.sin(angle)) <= 1e-13
    check_motion(motion, np.linspace(0.0, 1.0, 5))


def test_a_ball_on_the_composed_motion_moves_as_on_the_python_one(module_dir: Path) -> None:
    composed = _ball([RAMP, SINUSOID], module_dir)
    python = _ball({"type": "python", "function": "ucontrol_test_shaker:shaker"}, module_dir)
    assert isinstance(python.contacts[0].surface.motion, UserMotion)
    logs = [
        simulate(scene, duration=0.6, out=None, progress=False).log for scene in (composed, python)
    ]
    impulse = np.asarray(logs[0].impulse)[:, 0]
    assert np.count_nonzero(impulse > 0.0) >= 2  # it lands and bounces on the moving plate
    for name in ("q", "v", "gap", "impulse"):
        np.testing.assert_allclose(
            np.asarray(getattr(logs[0], name)), np.asarray(getattr(logs[1], name)), atol=1e-12
        )


def test_a_composed_motion_nests_and_moves_shapes(tmp_path: Path) -> None:
    table = {
        "robot": {"urdf": str(ROBOTS / "ball.urdf"), "q0": [0.3]},
        "shapes": {"rock": {"type": "sphere", "radius": 0.1, "motion": [RAMP, [SINUSOID]]}},
    }
    scene = Scene.from_dict(table, base_dir=tmp_path)
    assert scene.name  # the scene builds with the nested sum
    motion = _ball([RAMP, [SINUSOID]], tmp_path).contacts[0].surface.motion
    reference = _ball([RAMP, SINUSOID], tmp_path).contacts[0].surface.motion
    for got, expected in zip(motion(0.37), reference(0.37), strict=True):
        np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize(
    ("function", "reason"),
    [
        ("ucontrol_test_missing_module:shaker", "cannot import module"),
        ("ucontrol_test_shaker:missing", "no callable 'missing'"),
        ("ucontrol_test_shaker:not_callable", "no callable 'not_callable'"),
        ("ucontrol_test_shaker", "expected 'module:name'"),
        (3, "expected 'module:name'"),
    ],
)
def test_a_python_motion_that_does_not_import_is_an_error(
    module_dir: Path, function: Any, reason: str
) -> None:
    with pytest.raises(UserFunctionError, match=reason) as raised:
        _ball({"type": "python", "function": function}, module_dir)
    assert raised.value.spec == str(function)


def test_bad_motion_specs_are_errors(module_dir: Path) -> None:
    with pytest.raises(InvalidParameterError, match="displacement at t = 0"):
        _ball({"type": "python", "function": "ucontrol_test_shaker:flat"}, module_dir)
    with pytest.raises(InvalidParameterError, match="velocity at t = 0"):
        _ball({"type": "python", "function": "ucontrol_test_shaker:wrong_velocity"}, module_dir)
    with pytest.raises(SceneError, match="non-empty array"):
        _ball([], module_dir)
    with pytest.raises(NotFoundError, match="motion type"):
        _ball([RAMP, {"type": "spiral"}], module_dir)
    with pytest.raises(SceneError, match="must be a table"):
        _ball([RAMP, 3.0], module_dir)
    with pytest.raises(InvalidParameterError, match="velocity"):
        _ball({"type": "ramp", "velocity": [1.0, 2.0]}, module_dir)
    with pytest.raises(InvalidParameterError, match="at least one motion"):
        MotionSum(())
