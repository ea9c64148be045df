"""Task paths (segment, polyline, spline): derivatives vs finite differences, C⁴ joins, errors.

References: high-order central differences of each derivative, the waypoints the paths must
pass through, forward kinematics of the inverse-kinematics solutions of the reach check.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.contact.point_contact import PointContact
from ucontrol.control.circle_path import CirclePath
from ucontrol.control.desired_cycle import ContactPhase, DesiredCycle
from ucontrol.control.path_reach import check_reach
from ucontrol.control.path_table import path_from_table
from ucontrol.control.polyline_path import PolylinePath
from ucontrol.control.segment_path import SegmentPath
from ucontrol.control.spline_path import SplinePath
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.exceptions import (
    InvalidParameterError,
    NonFiniteValueError,
    PathOutOfReachError,
    PathThroughSurfaceError,
    SceneError,
    ShapeError,
    UnknownKeyError,
)
from ucontrol.scene import Scene

#: Step of the central differences, in [s].
H = 1e-4
#: Agreement of a derivative with the difference of the one below, relative to its scale.
RTOL = 1e-6
#: Continuity check: the two sides of a join are evaluated this far apart, in [s].
DELTA = 1e-9


def _paths(rng: np.random.Generator) -> dict[str, object]:
    waypoints = rng.uniform(-0.5, 0.5, size=(5, 3))
    return {
        "segment": SegmentPath(start=[0.6, 0.1, 0.0], end=[0.8, -0.05, 0.1], period=4.0),
        "segment_rest": SegmentPath(
            start=[0.6, 0.1, 0.0], end=[0.8, -0.05, 0.1], period=4.0, rest_time=0.5
        ),
        "polyline": PolylinePath(waypoints=waypoints, period=6.0, rest_time=0.3),
        "polyline_times": PolylinePath(
            waypoints=waypoints, period=6.0, times=[0.5, 1.0, 2.5, 3.0, 5.0], rest_time=0.1
        ),
        "spline": SplinePath(waypoints=waypoints, period=5.0),
        "spline_times": SplinePath(waypoints=waypoints, period=5.0, times=[1, 1.5, 2.0, 3.9, 4.2]),
        "spline_two": SplinePath(waypoints=waypoints[:2], period=2.0),
    }


def _joins(path: object) -> list[float]:
    if isinstance(path, SegmentPath):
        rest = path.rest_time
        return [0.0, rest, 0.5 * path.period, 0.5 * path.period + rest]
    times = list(path.times)  # type: ignore[attr-defined]
    rest = getattr(path, "rest_time", 0.0)
    return times + [t + rest for t in times] + [times[0] + path.period]  # type: ignore[attr-defined]


def _difference(path: object, t: float, k: int) -> np.ndarray:
    """Sixth-order central difference of derivative k at t."""
    f = lambda s: path.derivatives(s, k)[k]  # type: ignore[attr-defined]  # noqa: E731
    return (
        45.0 * (f(t + H) - f(t - H))
        - 9.0 * (f(t + 2 * H) - f(t - 2 * H))
        + (f(t + 3 * H) - f(t - 3 * H))
    ) / (60.0 * H)


@pytest.mark.parametrize("name", list(_paths(np.random.default_rng(0))))
def test_derivatives_match_central_differences(name: str) -> None:
    rng = np.random.default_rng(1)
    path = _paths(np.random.default_rng(0))[name]
    joins = np.array(_joins(path))
    times = rng.uniform(-path.period, 2.0 * path.period, 40)
    for t in times:
        if np.min(np.abs(t - joins[:, None] + path.period * np.arange(-2, 3))) < 4 * H:
            continue  # derivative 5 jumps at a join: the difference of order 4 is O(H) there
        values = path.derivatives(float(t), 4)
        assert len(values) == 5 and all(v.shape == (3,) for v in values)
        for k in range(4):
            scale = max(1.0, float(np.abs(values[k + 1]).max()))
            error = np.abs(values[k + 1] - _difference(path, float(t), k)).max()
            assert error <= RTOL * scale, (name, t, k + 1, error)
        p, _, ddp = path(float(t))
        np.testing.assert_array_equal(p, values[0])
        np.testing.assert_array_equal(ddp, values[2])


@pytest.mark.parametrize("name", list(_paths(np.random.default_rng(0))))
def test_c4_at_every_join_and_across_the_period(name: str) -> None:
    path = _paths(np.random.default_rng(0))[name]
    for join in _joins(path):
        for shift in (0.0, path.period, -path.period):
            before = path.derivatives(join + shift - DELTA, 5)
            after = path.derivatives(join + shift + DELTA, 5)
            for k in range(5):
                # A continuous derivative moves by at most |derivative k + 1| * 2 DELTA.
                bound = 2 * DELTA * max(np.abs(before[k + 1]).max(), np.abs(after[k + 1]).max())
                assert np.abs(after[k] - before[k]).max() <= bound + 1e-9, (name, join, k)
    for t in np.linspace(0.0, path.period, 7):
        for a, b in zip(path.derivatives(t, 4), path.derivatives(t + path.period, 4), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-9)


def test_spline_fifth_derivative_jumps_so_degree_five_is_needed() -> None:
    path = _paths(np.random.default_rng(0))["spline"]
    t = float(path.times[2])
    jump = path.derivatives(t + DELTA, 5)[5] - path.derivatives(t - DELTA, 5)[5]
    assert np.abs(jump).max() > 1.0  # piecewise quintic: C⁴ and no more


def test_spline_interpolates_its_waypoints() -> None:
    rng = np.random.default_rng(2)
    waypoints = rng.uniform(-1.0, 1.0, size=(6, 3))
    times = np.sort(rng.uniform(0.0, 3.0, 6))
    path = SplinePath(waypoints=waypoints, period=3.5, times=times)
    for t, w in zip(times, waypoints, strict=True):
        np.testing.assert_allclose(path(t)[0], w, atol=1e-12)
        np.testing.assert_allclose(path(t + 3.5)[0], w, atol=1e-12)
    default = SplinePath(waypoints=waypoints, period=3.5)
    chords = np.linalg.norm(np.roll(waypoints, -1, axis=0) - waypoints, axis=1)
    np.testing.assert_allclose(np.diff(np.append(default.times, 3.5)), 3.5 * chords / chords.sum())


def test_polyline_rests_on_waypoints_and_runs_straight_legs() -> None:
    rng = np.random.default_rng(3)
    waypoints = rng.uniform(-1.0, 1.0, size=(4, 3))
    path = PolylinePath(waypoints=waypoints, period=8.0, rest_time=0.4)
    for i, t in enumerate(path.times):
        for s in (t, t + 0.2, t + 0.4):
            values = path.derivatives(s, 4)
            np.testing.assert_allclose(values[0], waypoints[i], atol=1e-14)
            for k in range(1, 5):
                np.testing.assert_allclose(values[k], 0.0, atol=1e-9)
        # Mid-leg: on the straight line between waypoint i and i + 1, half-way by symmetry.
        end = path.times[i + 1] if i + 1 < 4 else 8.0
        middle = path(0.5 * (t + 0.4 + end))[0]
        np.testing.assert_allclose(middle, 0.5 * (waypoints[i] + waypoints[(i + 1) % 4]))


def test_segment_is_back_and_forth_symmetric() -> None:
    path = SegmentPath(start=[0.0, 0.0, 0.0], end=[0.3, 0.4, 0.0], period=2.0)
    np.testing.assert_allclose(path(0.0)[0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(path(1.0)[0], [0.3, 0.4, 0.0])
    for t in np.random.default_rng(4).uniform(0.0, 1.0, 10):
        np.testing.assert_allclose(path(2.0 - t)[0], path(t)[0], atol=1e-12)
    # Largest speed of the nonic step: 315/128 * length / (P/2).
    speed = max(np.linalg.norm(path(t)[1]) for t in np.linspace(0, 1, 2001))
    assert speed == pytest.approx(315 / 128 * 0.5 / 1.0, rel=1e-6)


@pytest.mark.parametrize(
    ("build", "error", "name"),
    [
        (lambda: SplinePath(waypoints=[[0, 0, 0]], period=1.0), InvalidParameterError, "waypoints"),
        (
            lambda: PolylinePath(waypoints=[[0, 0, 0]], period=1.0),
            InvalidParameterError,
            "waypoints",
        ),
        (lambda: SplinePath(waypoints=[[0, 0], [1, 0]], period=1.0), ShapeError, "waypoints"),
        (
            lambda: SplinePath(waypoints=[[0, 0, 0], [1, math.nan, 0]], period=1.0),
            NonFiniteValueError,
            "waypoints",
        ),
        (
            lambda: SplinePath(waypoints=[[0, 0, 0], [1, 0, 0]], period=1.0, times=[0.5, 0.5]),
            InvalidParameterError,
            "times",
        ),
        (
            lambda: SplinePath(waypoints=[[0, 0, 0], [1, 0, 0]], period=1.0, times=[0.0, 1.0]),
            InvalidParameterError,
            "times",
        ),
        (
            lambda: SplinePath(waypoints=[[0, 0, 0], [0, 0, 0], [1, 0, 0]], period=1.0),
            InvalidParameterError,
            "waypoints",
        ),
        (
            lambda: PolylinePath(
                waypoints=[[0, 0, 0], [1, 0, 0], [1, 0, 0]], period=1.0, times=[0, 0.3, 0.6]
            ),
            InvalidParameterError,
            "waypoints",
        ),
        (
            lambda: PolylinePath(waypoints=[[0, 0, 0], [1, 0, 0]], period=1.0, rest_time=0.5),
            InvalidParameterError,
            "rest_time",
        ),
        (
            lambda: PolylinePath(
                waypoints=[[0, 0, 0], [1, 0, 0]], period=1.0, times=[0, 0.1], rest_time=0.2
            ),
            InvalidParameterError,
            "rest_time",
        ),
        (
            lambda: SegmentPath(start=[1, 0, 0], end=[1, 0, 0], period=1.0),
            InvalidParameterError,
            "end",
        ),
        (
            lambda: SegmentPath(start=[0, 0, 0], end=[1, 0, 0], period=-1.0),
            InvalidParameterError,
            "period",
        ),
        (
            lambda: SegmentPath(start=[0, 0, 0], end=[1, 0, 0], period=1.0, rest_time=0.5),
            InvalidParameterError,
            "rest_time",
        ),
    ],
)
def test_invalid_paths_raise_typed_errors(build, error, name) -> None:
    with pytest.raises(error) as raised:
        build()
    assert raised.value.name == name


def test_spline_with_times_may_revisit_a_waypoint() -> None:
    path = SplinePath(waypoints=[[0, 0, 0], [0, 0, 0], [1, 0, 0]], period=3.0, times=[0, 1, 2])
    np.testing.assert_allclose(path(1.0)[0], [0, 0, 0], atol=1e-12)


def test_path_table_builds_every_type_and_rejects_bad_tables() -> None:
    tables = {
        "circle": {"type": "circle", "centre": [0.6, 0, 0], "radius": 0.1, "period": 10.0},
        "segment": {"type": "segment", "start": [0, 0, 0], "end": [1, 0, 0], "period": 2.0},
        "polyline": {
            "type": "polyline",
            "waypoints": [[0, 0, 0], [1, 0, 0], [1, 1, 0]],
            "period": 3.0,
            "rest_time": 0.1,
        },
        "spline": {"type": "spline", "waypoints": [[0, 0, 0], [1, 0, 0], [1, 1, 0]], "period": 3.0},
    }
    classes = {"circle": CirclePath, "segment": SegmentPath, "polyline": PolylinePath}
    classes["spline"] = SplinePath
    for kind, table in tables.items():
        path = path_from_table(table)
        assert isinstance(path, classes[kind])
        if kind != "circle":
            rebuilt = path_from_table(path.describe())  # type: ignore[attr-defined]
            t = 0.37
            np.testing.assert_allclose(rebuilt(t)[0], path(t)[0])
    with pytest.raises(InvalidParameterError, match="type"):
        path_from_table({"type": "helix", "period": 1.0})
    with pytest.raises(UnknownKeyError, match="radius"):
        path_from_table({**tables["segment"], "radius": 1.0})
    with pytest.raises(SceneError, match="period"):
        path_from_table({"type": "spline", "waypoints": [[0, 0, 0], [1, 0, 0]]})
    with pytest.raises(InvalidParameterError) as raised:
        path_from_table({**tables["spline"], "times": [0, 2, 1]})
    assert raised.value.name == "times"


def _two_link_scene() -> Scene:
    table = tomllib.loads((ROBOTS / "two_link_one_constraint.toml").read_text())
    table["controller"] = {"type": "zero"}
    return Scene.from_dict(table, base_dir=ROBOTS)


def test_reach_check_solutions_reproduce_the_path() -> None:
    scene = _two_link_scene()
    path = SplinePath(waypoints=[[0.7, 0.1, 0], [0.55, 0.05, 0], [0.6, -0.05, 0]], period=4.0)
    solutions = check_reach(path, scene.robot, "end_effector", scene.q0, samples=50)
    model = scene.robot.model
    data = pin.Data(model)
    frame = model.getFrameId("end_effector")
    for q, t in zip(solutions, np.linspace(0, 4.0, 50, endpoint=False), strict=True):
        pin.framesForwardKinematics(model, data, q)
        assert np.linalg.norm(data.oMf[frame].translation - path(t)[0]) <= 1e-6


def test_a_path_out_of_reach_raises() -> None:
    scene = _two_link_scene()  # links 0.5 m + 0.5 m: nothing beyond 1 m from the shoulder
    path = SplinePath(waypoints=[[0.7, 0.1, 0], [1.2, 0.2, 0], [0.6, 0.3, 0]], period=4.0)
    with pytest.raises(PathOutOfReachError) as raised:
        check_reach(path, scene.robot, "end_effector", scene.q0, samples=50)
    error = raised.value
    assert error.frame == "end_effector" and error.residual > 0.01
    assert np.linalg.norm(error.point) > 1.0
    np.testing.assert_allclose(error.point, path(error.time)[0])
    with pytest.raises(InvalidParameterError):
        check_reach(path, scene.robot, "end_effector", scene.q0, samples=0)


@pytest.mark.parametrize(
    "path",
    [
        SplinePath(waypoints=[[0.7, 0.05, 0], [0.6, -0.05, 0], [0.5, 0.05, 0]], period=10.0),
        PolylinePath(waypoints=[[0.7, 0.05, 0], [0.6, -0.05, 0], [0.5, 0.05, 0]], period=10.0),
        SegmentPath(start=[0.7, 0.05, 0], end=[0.6, -0.05, 0], period=10.0),
    ],
)
def test_desired_cycle_rejects_a_path_through_the_ground(path) -> None:
    scene = _two_link_scene()
    contact = scene.contacts[0]
    task = TaskCoordinates(scene.robot, "end_effector", [contact], [[1.0, 0.0, 0.0]])
    below = np.array(
        [t for t in np.linspace(0, 10.0, 4000, endpoint=False) if path(t)[0][1] < -1e-6]
    )
    far = ContactPhase(contact=contact.name, start=0.9, end=1.0, force=1.0)
    cycle = DesiredCycle(path=path, contact_phases=(far,), approach_time=0.8, takeoff_time=0.1)
    with pytest.raises(PathThroughSurfaceError) as raised:
        cycle.check(task)
    assert below.min() - 1e-2 <= raised.value.time <= below.max() + 1e-2
    assert raised.value.gap == pytest.approx(min(path(t)[0][1] for t in below), abs=1e-4)
    # A contact phase covering the dip makes the same path valid.
    phase = ContactPhase(
        contact=contact.name, start=below.min() - 0.01, end=below.max() + 0.01, force=1.0
    )
    cycle = DesiredCycle(path=path, contact_phases=(phase,), approach_time=0.8, takeoff_time=0.1)
    cycle.check(task)
    assert isinstance(contact, PointContact)


def test_brogliato_controller_tracks_a_spline_cycle() -> None:
    from ucontrol.control.brogliato_controller import BrogliatoController, BrogliatoGains
    from ucontrol.simulate import simulate

    scene = _two_link_scene()
    contact = scene.contacts[0]
    # Twelve points of the scene's circle (centre (0.65, 0), radius 0.1, period 10 s).
    angles = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    waypoints = np.stack([0.65 + 0.1 * np.cos(angles), 0.1 * np.sin(angles), 0 * angles], axis=1)
    path = SplinePath(waypoints=waypoints, period=10.0, times=10.0 * angles / (2 * np.pi))
    circle = CirclePath(centre=[0.65, 0, 0], radius=0.1, period=10.0)
    worst = max(np.linalg.norm(path(t)[0] - circle(t)[0]) for t in np.linspace(0, 10, 500))
    assert worst < 1e-4  # a quintic spline through 12 points of a circle
    task = TaskCoordinates(scene.robot, "end_effector", [contact], [[1.0, 0.0, 0.0]])
    phase = ContactPhase(contact=contact.name, start=5.0, end=10.0, force=5.0)
    cycle = DesiredCycle(path=path, contact_phases=(phase,), depth_min=0.01)
    controller = BrogliatoController(
        scene.robot, task, cycle, BrogliatoGains(gamma1=8.0, gamma2=7.0), posture=scene.q0
    )
    result = simulate(scene, controller, duration=10.5, dt=1e-3, progress=False)
    stability = result.summary["weak_stability"]
    assert stability["n_complete_cycles"] == 1
    assert result.summary["tracking"]["force_error_mid_max"] < 1e-3
