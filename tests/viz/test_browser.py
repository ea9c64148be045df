"""The meshcat views in a real browser: headless Chromium draws the robot where it stands.

Each test loads a viewer page (a live meshcat server on localhost, or the exported HTML file)
in Debian's chromium, takes a screenshot and looks for the robot's pixels at the projections
of its links through meshcat's camera. Skipped only when chromium is not installed.
"""

from __future__ import annotations

import dataclasses
import re
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from child_process import Child
from chromium_shot import chromium, near_fraction, orange_mask, project, screenshot

from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate
from ucontrol.viz import browser_screenshot
from ucontrol.viz.meshcat_server import MeshcatServer
from ucontrol.viz.replay import write_html
from ucontrol.viz.scene_drawing import SceneDrawing

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: Fewest robot pixels in a screenshot (the two-link arm covers ~6000 of 480 000).
MIN_PIXELS = 1500
#: Each test is bounded: a few browser launches of at most 60 s each, and a meshcat server;
#: slow (`pytest -m "not slow"` leaves them out).
pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]


def _arm_points(scene: Scene, q: np.ndarray, n: int = 6) -> np.ndarray:
    """Points along both links of the two-link arm at ``q`` in [m], shape (2 n, 3)."""
    robot = scene.robot
    shoulder, elbow, tip = (robot.frame_position(q, f) for f in ("link1", "link2", "end_effector"))
    return np.concatenate([np.linspace(shoulder, elbow, n), np.linspace(elbow, tip, n)])


def _ball_points(scene: Scene, heights: np.ndarray) -> np.ndarray:
    """Centres of the ball at ``heights`` of its joint in [m], shape (N, 3)."""
    return np.array([scene.robot.frame_position(np.array([z]), "ball") for z in heights])


def _centroid(mask: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()])


def test_live_view_draws_the_robot_where_it_stands_and_moves_it(tmp_path: Path) -> None:
    chromium()
    scene = load_scene(ROBOTS / "two_link_drop.toml")
    q1 = np.array([1.6, -1.9])  # elbow up above the shoulder, still in the view
    with MeshcatServer() as server:
        drawing = SceneDrawing(scene, server.viewer)
        # A live page gets its scene through a websocket: a shot taken before it arrived
        # shows no robot and is taken again.
        first = orange_mask(screenshot(server.url, tmp_path / "q0.png", min_pixels=MIN_PIXELS))
        drawing.place(server.viewer, q1, np.zeros(scene.constraints.size))
        second = orange_mask(screenshot(server.url, tmp_path / "q1.png", min_pixels=MIN_PIXELS))
    arm0 = project(drawing, _arm_points(scene, scene.q0))
    arm1 = project(drawing, _arm_points(scene, q1))
    assert first.sum() > MIN_PIXELS and second.sum() > MIN_PIXELS
    assert near_fraction(first, arm0) == 1.0  # every point of both links is drawn
    assert near_fraction(second, arm1) == 1.0
    # The forearm has moved: where it stood at q0 (away from the new arm) is no longer drawn.
    forearm0 = arm0[7:]
    away = forearm0[np.min(np.linalg.norm(forearm0[:, None] - arm1[None], axis=2), axis=1) > 30]
    assert len(away) >= 2 and near_fraction(second, away, radius=2) == 0.0


def test_panda_meshes_are_drawn_at_its_joints(tmp_path: Path) -> None:
    chromium()
    try:
        example_robot_data_dir()
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")
    scene = load_scene(ROBOTS / "panda_table.toml")
    with MeshcatServer() as server:  # a page holding the meshes: no websocket to wait for
        drawing = SceneDrawing(scene, server.viewer)
        page = tmp_path / "panda.html"
        page.write_text(server.static_html())
    image = screenshot(page.as_uri(), tmp_path / "panda.png", offline=True)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    grey = (np.abs(r - b) <= 4) & (np.abs(r - g) <= 4)  # the Panda's white and black meshes
    model, data = scene.robot.model, pin.Data(scene.robot.model)
    pin.forwardKinematics(model, data, scene.q0)
    joints = np.array([data.oMi[j].translation for j in range(1, model.njoints)])
    assert grey.sum() > 10 * MIN_PIXELS
    assert near_fraction(grey, project(drawing, joints), radius=8) == 1.0


@pytest.mark.parametrize("clock", ["virtual time", "real time"])
def test_html_export_plays_offline(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, clock: str
) -> None:
    chromium()
    if clock == "real time":  # the launch that follows a hung virtual-time budget
        monkeypatch.setattr(browser_screenshot, "ATTEMPTS", 1)
    ball = load_scene(ROBOTS / "ball.toml")
    scene = dataclasses.replace(
        ball, contacts=(dataclasses.replace(ball.contacts[0], restitution=0.0),)
    )
    result = simulate(scene, duration=1.0)  # falls for 0.45 s, then rests on the ground
    page = write_html(tmp_path / "ball.html", scene, result.log)
    assert b"http" not in re.sub(rb"<script>.*?</script>", b"", page.read_bytes(), flags=re.S)
    shots = {}
    # Virtual time in [ms]: early, and after the end of the 1 s run. A real-time launch plays
    # the animation as fast as the machine draws it: the ball is somewhere on its way down.
    for ms in (100, 3000) if clock == "virtual time" else (3000,):
        image = screenshot(
            page.as_uri(), tmp_path / f"ball_{ms}.png", virtual_time_ms=ms, offline=True
        )
        mask = orange_mask(image)
        assert mask.sum() > MIN_PIXELS / 3
        shots[ms] = _centroid(mask)
    with MeshcatServer() as server:  # the same framing as the export: the run's configurations
        drawing = SceneDrawing(scene, server.viewer, configurations=result.log.q)
    top, rest = project(drawing, _ball_points(scene, np.array([1.1, 0.1])))  # [px]
    fall = rest[1] - top[1]  # [px] down the screen
    assert fall > 100
    # Played to the end, the ball rests on the ground, far from where the page first drew it
    # (q0, 1.1 m up); early on, it is somewhere on its vertical way down (virtual time is no
    # exact clock of the animation: its start may lag or lead by a few hundred ms).
    early = shots[100] if clock == "virtual time" else shots[3000]
    assert abs(early[0] - top[0]) < 0.1 * fall
    assert top[1] - 0.2 * fall < early[1] < rest[1] + 0.2 * fall
    if clock == "virtual time":
        assert np.linalg.norm(shots[3000] - rest) < 0.2 * fall


def test_ucontrol_view_replays_a_saved_run(tmp_path: Path) -> None:
    chromium()
    scene = load_scene(ROBOTS / "ball.toml")
    result = simulate(scene, duration=1.0, out=tmp_path / "run")
    child = Child([sys.executable, "-m", "ucontrol.cli", "view", str(tmp_path / "run")])
    try:
        url = child.url("replay of")
        mask = orange_mask(
            screenshot(
                url, tmp_path / "replay.png", virtual_time_ms=300, min_pixels=MIN_PIXELS // 3
            )
        )
        status = child.interrupt()
    finally:
        child.stop()
    assert status == 0, "".join(child.stderr)
    with MeshcatServer() as server:
        drawing = SceneDrawing(scene, server.viewer, configurations=result.log.q)
    path = project(drawing, _ball_points(scene, np.linspace(0.1, 1.1, 30)))  # the ball's line
    assert mask.sum() > MIN_PIXELS / 3
    assert abs(_centroid(mask)[0] - path[:, 0].mean()) < 10  # on the vertical of its fall
    assert path[:, 1].min() - 40 < _centroid(mask)[1] < path[:, 1].max() + 40


def test_ucontrol_run_view_draws_live_and_still_writes_the_log(tmp_path: Path) -> None:
    chromium()
    out = tmp_path / "run"
    command = [
        sys.executable,
        "-m",
        "ucontrol.cli",
        "run",
        str(ROBOTS / "two_link_drop.toml"),
        "--duration",
        "1.0",
        "--out",
        str(out),
        "--view",
    ]
    child = Child(command)
    try:
        url = child.url("open")  # the run starts once the browser has the page
        mask = orange_mask(screenshot(url, tmp_path / "live.png", min_pixels=MIN_PIXELS))
        child.wait_for("Ctrl-C")
        status = child.interrupt()
    finally:
        child.stop()
    assert status == 0, "".join(child.stderr)
    assert "1000 steps" in child.output and (out / "log.npz").is_file()
    assert mask.sum() > MIN_PIXELS
