"""The hybrid-zero-dynamics walking law on RABBIT (robots/rabbit.urdf): its parts and its input."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.control.controller import ContactState
from ucontrol.control.hzd_controller import HZDController, HZDSettings, Leg, bezier
from ucontrol.exceptions import (
    FrameNotFoundError,
    InvalidParameterError,
    JointNotFoundError,
    NonFiniteValueError,
    SceneError,
    ShapeError,
    UnknownKeyError,
)
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: A gait-like set of Bézier coefficients (M = 4) [rad]: rows stance hip, stance knee, swing
#: hip, swing knee.
ALPHA = np.array(
    [
        [-0.40, -0.30, -0.10, 0.05, 0.15],
        [0.20, 0.15, 0.10, 0.15, 0.20],
        [0.15, 0.10, -0.30, -0.50, -0.40],
        [0.20, 0.70, 1.00, 0.60, 0.20],
    ]
)
SETTINGS = {"theta_plus": -0.2, "theta_minus": 0.2, "kp": 400.0, "kd": 40.0}
LEFT = 0  # index of foot_left's constraint


def _table(**controller: Any) -> dict[str, Any]:
    table: dict[str, Any] = {
        "type": "hzd",
        "bezier": ALPHA.tolist(),
        "legs": [["hip_left", "knee_left", "foot_left"], ["hip_right", "knee_right", "foot_right"]],
        "stance": "foot_left",
        **SETTINGS,
    }
    table.update(controller)
    contact = {"surface": "ground", "restitution": 0.0, "friction": 0.8}
    return {
        "name": "rabbit_test",
        "robot": {
            "urdf": "rabbit.urdf",
            "passive": ["x", "z", "pitch"],
            "planar_axis": [0.0, 1.0, 0.0],
            "q0": [0.0, 0.79, 0.05, -0.35, 0.2, 0.2, 0.6],
            "gravity": [0.0, 0.0, -9.81],
        },
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
        "contacts": [{"frame": "foot_left", **contact}, {"frame": "foot_right", **contact}],
        "integrator": {"name": "moreau_jean", "dt": 1e-3},
        "controller": table,
    }


def _scene(**controller: Any) -> Scene:
    return Scene.from_dict(_table(**controller), base_dir=ROBOTS)


def _contacts(gap: list[float], normal_velocity: list[float]) -> ContactState:
    """A contact state with NaN impulses: the law must not read them."""
    return ContactState(
        ["foot_left", "foot_right"],
        np.array(gap),
        np.array(normal_velocity),
        np.full(2, np.nan),
        np.zeros(2, dtype=bool),
        1e-3,
    )


def _state(rng: np.random.Generator, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """A random state with the left foot on the ground and at rest."""
    q = np.array([0.1, 0.0, 0.05, -0.35, 0.2, 0.2, 0.6]) + 0.1 * rng.standard_normal(7)
    q[1] -= scene.constraints.gaps(q)[LEFT]
    flow = StanceFlow(scene.constraints)
    v, _ = flow.heel_strike(q, rng.standard_normal(7), LEFT)  # project: the foot at rest
    return q, v


def test_bezier_derivatives_match_finite_differences() -> None:
    step = 1e-5
    for s in (0.0, 0.3, 0.77, 1.0):
        _, first, second = bezier(ALPHA, s)
        up, down = bezier(ALPHA, s + step), bezier(ALPHA, s - step)
        np.testing.assert_allclose(first, (up[0] - down[0]) / (2 * step), atol=1e-8)
        np.testing.assert_allclose(second, (up[1] - down[1]) / (2 * step), atol=1e-7)
    # end points: the first and last coefficients
    np.testing.assert_allclose(bezier(ALPHA, 0.0)[0], ALPHA[:, 0], atol=1e-15)
    np.testing.assert_allclose(bezier(ALPHA, 1.0)[0], ALPHA[:, -1], atol=1e-15)


def test_bezier_against_de_casteljau() -> None:
    """The Bernstein sum against de Casteljau's repeated interpolation."""
    s = 0.37
    points = ALPHA.copy()
    while points.shape[1] > 1:
        points = (1 - s) * points[:, :-1] + s * points[:, 1:]
    np.testing.assert_allclose(bezier(ALPHA, s)[0], points[:, 0], atol=1e-14)


def test_outputs_obey_the_linear_law_on_the_pinned_robot() -> None:
    """ÿ = -Kp y - Kd ẏ, ÿ by central differences along the plant's own acceleration.

    The plant's acceleration is that of the robot held at its stance foot under the law's
    torques (StanceFlow's KKT system, normal and tangent rows).
    """
    scene = _scene()
    law = scene.build_controller()
    assert isinstance(law, HZDController)
    flow = StanceFlow(scene.constraints)
    rng = np.random.default_rng(5)
    B = np.zeros((7, 4))
    B[[3, 4, 5, 6], np.arange(4)] = 1.0
    for _ in range(5):
        q, v = _state(rng, scene)
        u = law.torque(q, v, LEFT)
        a, _ = flow.acceleration(q, v, LEFT, B @ u)
        np.testing.assert_allclose(law.solve(q, v, LEFT)[0], a, atol=1e-9)
        y, y_dot = law.outputs(q, v, LEFT)
        eps = 1e-6
        y_dot_up = law.outputs(q + eps * v, v + eps * a, LEFT)[1]
        y_dot_down = law.outputs(q - eps * v, v - eps * a, LEFT)[1]
        y_ddot = (y_dot_up - y_dot_down) / (2 * eps)
        target = -SETTINGS["kp"] * y - SETTINGS["kd"] * y_dot
        np.testing.assert_allclose(y_ddot, target, atol=1e-5 * (1 + np.max(np.abs(target))))


def test_phase_variable_is_the_stance_leg_angle() -> None:
    """θ from the hip and foot positions, θ̇ against finite differences."""
    scene = _scene()
    law = scene.build_controller()
    assert isinstance(law, HZDController)
    q, v = _state(np.random.default_rng(2), scene)
    robot = scene.robot
    hip, foot = robot.frame_position(q, "hip_left"), robot.frame_position(q, "foot_left")
    theta, theta_dot = law.phase_variable(q, 0, v)
    assert theta == pytest.approx(np.arctan2(hip[0] - foot[0], hip[2] - foot[2]), abs=1e-14)
    eps = 1e-7
    rate = (law.phase_variable(q + eps * v, 0)[0] - law.phase_variable(q - eps * v, 0)[0]) / (
        2 * eps
    )
    assert theta_dot == pytest.approx(rate, abs=1e-7)


def test_outputs_relabel_at_the_leg_swap() -> None:
    """The swing foot landing late in the step swaps the legs and q_a's rows."""
    scene = _scene()
    law = scene.build_controller()
    assert isinstance(law, HZDController)
    q = np.array([0.0, 0.0, 0.05, -0.05, 0.2, 0.35, 0.2])
    q[1] -= scene.constraints.gaps(q)[LEFT]
    v = np.zeros(7)
    assert law.settings.phase(law.phase_variable(q, 0)[0]) > 0.5
    assert law.stance == 0
    law(0.0, q, v, _contacts([0.0, 0.01], [0.0, 0.0]))  # swing foot 1 cm up: no swap
    assert law.stance == 0
    law(0.0, q, v, _contacts([0.0, 5e-4], [0.0, 0.3]))  # close but rising: no swap
    assert law.stance == 0
    law(0.0, q, v, _contacts([0.0, 5e-4], [0.0, -0.3]))  # approaching, not yet struck
    assert law.stance == 0
    u = law(0.0, q, v, _contacts([0.0, -2e-4], [0.0, 1e-3]))  # stopped by the impact: swap
    assert law.stance == 1
    assert np.all(np.isfinite(u))  # the NaN impulses were not read
    np.testing.assert_allclose(u, law.torque(q, v, 1), atol=1e-12)
    s_right = law.settings.phase(law.phase_variable(q, 1)[0])
    y_right = law.outputs(q, v, 1)[0] + bezier(ALPHA, s_right)[0]
    np.testing.assert_allclose(y_right, q[[5, 6, 3, 4]], atol=1e-14)


def test_no_swap_early_in_the_step() -> None:
    """A swing foot grazing the ground in the first half of the step keeps the legs."""
    scene = _scene()
    law = scene.build_controller()
    assert isinstance(law, HZDController)
    q = np.array([0.0, 0.0, 0.05, -0.35, 0.2, 0.2, 0.6])
    assert law.settings.phase(law.phase_variable(q, 0)[0]) < 0.5
    law(0.0, q, np.zeros(7), _contacts([0.0, 0.0], [0.0, 0.0]))
    assert law.stance == 0


def test_torque_limit_clips() -> None:
    scene = _scene(torque_limit=5.0)
    law = scene.build_controller()
    assert isinstance(law, HZDController)
    q, v = _state(np.random.default_rng(3), scene)
    free = _scene().build_controller()
    assert isinstance(free, HZDController)
    u_free = free.torque(q, v, LEFT)
    assert np.max(np.abs(u_free)) > 5.0
    np.testing.assert_allclose(law.torque(q, v, LEFT), np.clip(u_free, -5.0, 5.0))


@pytest.mark.parametrize(
    ("key", "value", "error"),
    [
        ("bezier", [[0.0, 1.0, 2.0]] * 3, ShapeError),
        ("bezier", [[0.0, 1.0]] * 4, ShapeError),
        ("bezier", [[0.0, 1.0, float("nan")]] * 4, NonFiniteValueError),
        ("bezier", [["a", "b", "c"]] * 4, InvalidParameterError),
        ("theta_minus", -0.3, InvalidParameterError),
        ("theta_plus", "x", InvalidParameterError),
        ("kp", 0.0, InvalidParameterError),
        ("kd", -1.0, InvalidParameterError),
        ("contact_gap", -1e-3, InvalidParameterError),
        ("torque_limit", 0.0, InvalidParameterError),
    ],
)
def test_bad_settings_are_refused(key: str, value: Any, error: type[Exception]) -> None:
    settings = {"bezier": ALPHA, **SETTINGS, key: value}
    with pytest.raises(error, match=key):
        HZDSettings(**settings)


@pytest.mark.parametrize(
    ("key", "value", "error", "match"),
    [
        ("legs", [["hip_left", "knee_left", "foot_left"]], InvalidParameterError, "legs"),
        ("legs", [["hip_left", "knee_left"], ["a", "b"]], InvalidParameterError, "legs"),
        (
            "legs",
            [["hip_left", "knee_left", "foot_left"], ["hip_right", "knee_right", "tibia_right"]],
            InvalidParameterError,
            "tibia_right",
        ),
        (
            "legs",
            [["hip_left", "knee_left", "foot_left"], ["hip_right", "ankle", "foot_right"]],
            JointNotFoundError,
            "ankle",
        ),
        (
            "legs",
            [["hip_left", "knee_left", "foot_left"], ["hip_right", "pitch", "foot_right"]],
            InvalidParameterError,
            "pitch",
        ),
        ("stance", "foot_middle", InvalidParameterError, "foot_middle"),
        ("gains", 1.0, UnknownKeyError, "gains"),
    ],
)
def test_bad_tables_are_refused(key: str, value: Any, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        _scene(**{key: value}).build_controller()


def test_missing_key_is_refused() -> None:
    table = _table()
    del table["controller"]["kp"]
    with pytest.raises(SceneError, match="kp"):
        Scene.from_dict(table, base_dir=ROBOTS).build_controller()


def test_other_actuated_joints_are_refused() -> None:
    table = _table()
    table["robot"]["passive"] = ["x", "z"]
    with pytest.raises(InvalidParameterError, match="hips and two knees"):
        Scene.from_dict(table, base_dir=ROBOTS).build_controller()


def test_bad_legs_are_refused() -> None:
    scene = _scene()
    settings = HZDSettings(bezier=ALPHA, **SETTINGS)
    left = Leg("hip_left", "knee_left", "foot_left", 0)
    with pytest.raises(InvalidParameterError, match="legs"):
        HZDController(scene.robot, legs=[left], stance="foot_left", settings=settings)
    ghost = Leg("hip_right", "knee_right", "toe", 1)
    with pytest.raises(FrameNotFoundError, match="toe"):
        HZDController(scene.robot, legs=[left, ghost], stance="foot_left", settings=settings)


def test_unknown_contact_is_refused() -> None:
    law = _scene().build_controller()
    assert isinstance(law, HZDController)
    with pytest.raises(InvalidParameterError, match="contact"):
        law.torque(np.zeros(7), np.zeros(7), 5)
