"""Replays and live views: which rows are drawn, with which forces, and at what pace."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
from recording_window import recording_viewer

from ucontrol.exceptions import ViewerError
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.viz.live_viewer import LiveViewer
from ucontrol.viz.meshcat_server import MeshcatServer
from ucontrol.viz.replay import animation, frame_rows, mean_force, write_html
from ucontrol.viz.scene_drawing import SceneDrawing

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
BALL_NODE = "/meshcat/ucontrol/robot/visuals/ball_0"


def _ball_transforms(window: object) -> list[float]:
    """Heights of the ball's visual in the set_transform commands sent, in [m]."""
    return [
        c["matrix"][14]  # column-major 4 x 4: translation z
        for c in window.commands  # type: ignore[attr-defined]
        if c["type"] == "set_transform" and c["path"] == BALL_NODE
    ]


def test_frames_are_one_per_period_of_simulated_time_and_end_on_the_last_row() -> None:
    t = np.arange(1001) * 1e-3  # [s]
    rows = frame_rows(t, fps=30.0)
    np.testing.assert_allclose(t[rows], np.arange(31) / 30.0, atol=1e-3)  # 30/30 s: the end
    assert rows[-1] == 1000 and np.all(np.diff(rows) > 0)
    assert frame_rows(t[:990], fps=30.0)[-1] == 989  # the last row, off the frame times


def test_mean_force_of_a_resting_ball_is_its_weight() -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    resting = dataclasses.replace(scene, q0=np.array([0.1]))  # on the ground
    log = simulate(resting, duration=0.2).log
    for start, stop in ((0, 1), (10, 43), (100, 199)):
        assert mean_force(log, start, stop)[0] == pytest.approx(9.81, rel=1e-9)


def test_animation_shows_the_logged_configurations_at_the_frame_rows() -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    log = simulate(scene, duration=1.0).log
    viewer, _ = recording_viewer()
    drawing = SceneDrawing(scene, viewer, configurations=log.q)
    clip = animation(drawing, viewer, log, fps=20.0).clips
    rows = frame_rows(log.t, 20.0)
    heights = [
        value[2]
        for value in next(c for p, c in clip.items() if p.lower() == BALL_NODE)
        .tracks["position"]
        .values
    ]
    np.testing.assert_allclose(heights, log.q[rows, 0], atol=1e-12)
    assert len(heights) == 21


class _SimulatedClock:
    """A wall clock that only advances when slept on, or by ``work`` [s] at each reading."""

    def __init__(self, work: float = 0.0) -> None:
        self.now = 100.0  # [s], an arbitrary origin
        self.work = work
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        self.now += self.work  # the simulation's own cost between two readings
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds >= 0.0
        self.sleeps.append(seconds)
        self.now += seconds


def test_live_viewer_draws_one_frame_per_period() -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    viewer, window = recording_viewer()
    live = LiveViewer(scene, viewer, fps=30.0, speed=None)
    log = simulate(scene, duration=0.5, observer=live).log
    assert live.frames == 16  # t = 0, 1/30, ..., 15/30 s
    drawn = _ball_transforms(window)[-16:]  # after the drawing's own placements at q0
    np.testing.assert_allclose(drawn, log.q[frame_rows(log.t, 30.0)[:16], 0], atol=1e-12)


@pytest.mark.parametrize("work", [0.0, 1e-3, 0.1])  # [s] of computation per clock reading
def test_live_viewer_paces_frames_to_speed_times_the_wall_clock(work: float) -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    viewer, _ = recording_viewer()
    clock = _SimulatedClock(work)
    drawn_at: list[tuple[float, float]] = []  # (simulated time [s], wall time [s]) per frame

    class _Paced(LiveViewer):
        def show(self, log: object, row: int = -1) -> None:
            drawn_at.append((float(log.t[row]), clock.now))  # type: ignore[attr-defined]
            super().show(log, row)  # type: ignore[arg-type]

    speed = 2.0
    paced = _Paced(scene, viewer, fps=30.0, speed=speed, clock=clock, sleep=clock.sleep)
    simulate(scene, duration=0.4, observer=paced)
    t, wall = np.array(drawn_at).T
    assert len(t) == 13  # frames at 0, 1/30, ..., 12/30 s
    # Each frame is drawn once the wall clock has run t / speed since the first one, up to
    # one reading of the clock (``work``; round-off 1e-12 s).
    late = (wall - wall[0]) - (t - t[0]) / speed  # [s]
    assert np.all(late >= -work - 1e-12)
    if work == 0.0:  # a free simulation: the pacing alone sets the wall time, exactly
        np.testing.assert_allclose(late, 0.0, atol=1e-12)
        assert wall[-1] - wall[0] == pytest.approx(0.4 / speed, abs=1e-12)
    elif work >= 1 / 30 / speed:  # slower than the pace: it never waits, it only falls behind
        assert sum(clock.sleeps) == 0.0 and np.all(np.diff(late) > 0.0)


def test_html_export_embeds_the_viewer_and_the_animation(tmp_path: Path) -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    log = simulate(scene, duration=0.3).log
    page = write_html(tmp_path / "sub" / "ball.html", scene, log)
    html = page.read_text()
    assert "MeshCat.Viewer" in html and "three" in html.lower()  # the viewer, in the page
    assert html.count("data:application/octet-binary;base64,") > 10  # the scene's commands


def test_a_server_that_cannot_start_raises_a_viewer_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(sys, "executable", "/bin/false")
    with pytest.raises(ViewerError, match="meshcat server stopped"):
        MeshcatServer()


def test_html_export_shows_the_logged_time_of_each_frame(tmp_path: Path) -> None:
    import json
    import re

    from ucontrol.viz.replay import TIME_LABEL_ID

    scene = load_scene(ROBOTS / "ball.toml")
    log = simulate(scene, duration=0.5, dt=1.5e-3).log  # frame times off the step grid
    html = write_html(tmp_path / "ball.html", scene, log, fps=20.0).read_text()
    assert html.count(f'id="{TIME_LABEL_ID}"') == 1
    assert html.index(TIME_LABEL_ID) > html.index("new MeshCat.Viewer")  # after the viewer
    match = re.search(r"const times = (\[.*?\]);", html)
    assert match is not None
    times = json.loads(match.group(1))
    np.testing.assert_allclose(times, log.t[frame_rows(log.t, 20.0)], atol=1e-9)
    assert "viewer.animator.time * 20" in html  # the frame of meshcat's animation clock


def test_notebook_replay_is_the_html_page_in_an_iframe(tmp_path: Path) -> None:
    import html

    from ucontrol.exceptions import InvalidParameterError
    from ucontrol.viz.replay import InlinePage, notebook_replay

    scene = load_scene(ROBOTS / "ball.toml")
    log = simulate(scene, duration=0.2).log
    inline = notebook_replay(scene, log, height=300)._repr_html_()
    assert inline.startswith('<iframe srcdoc="') and "height: 300px" in inline
    source = html.unescape(inline.split('srcdoc="')[1].split('" style=')[0])
    page = write_html(tmp_path / "ball.html", scene, log).read_text()
    assert source.count("new MeshCat.Viewer") == page.count("new MeshCat.Viewer") == 1
    assert len(source) == pytest.approx(len(page), rel=1e-3)  # the same page (uuids differ)
    with pytest.raises(InvalidParameterError, match="height"):
        InlinePage(page, height=0)
