"""Videos and stills of a saved run: frame count, playability, and what the frames show.

The written files are read back by ffprobe / ffmpeg (the decoder), not by the code that wrote
them. The ball's image is checked against the URDF: its diameter in pixels sets the scale,
and its centre then moves between frames by the logged height changes at that scale.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS
from scipy import ndimage

from ucontrol.exceptions import InvalidParameterError, VideoError
from ucontrol.log import Log
from ucontrol.saved_run import SavedRun
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.viz import video
from ucontrol.viz.video import frame_rows, write_still, write_video

pytestmark = pytest.mark.skipif(shutil.which("ffprobe") is None, reason="ffmpeg not installed")

DURATION = 1.0  # [s] simulated


@pytest.fixture(scope="module")
def ball_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A ball dropped from 1 m, saved: it falls for 0.45 s, bounces, and rises."""
    out = tmp_path_factory.mktemp("ball")
    simulate(load_scene(ROBOTS / "ball.toml"), duration=DURATION, dt=1e-3, out=out)
    return out


def _probe(path: Path) -> dict[str, str]:
    completed = subprocess.run(
        [
            "ffprobe",
            "-v",
            "error",
            "-count_frames",
            "-select_streams",
            "v:0",
            "-show_entries",
            "stream=nb_read_frames,width,height,codec_name",
            "-of",
            "json",
            str(path),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(completed.stdout)["streams"][0]


def _frames(path: Path, width: int, height: int) -> np.ndarray:
    """Every decoded frame as RGB, shape (F, height, width, 3)."""
    raw = subprocess.run(
        ["ffmpeg", "-v", "error", "-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        capture_output=True,
        check=True,
    ).stdout
    return np.frombuffer(raw, dtype=np.uint8).reshape(-1, height, width, 3)


@pytest.mark.parametrize(("suffix", "fps", "speed"), [(".mp4", 12.0, 1.0), (".gif", 10.0, 0.5)])
def test_frame_count_is_duration_times_fps(ball_run, tmp_path, suffix, fps, speed) -> None:
    path = write_video(
        ball_run, tmp_path / f"ball{suffix}", fps=fps, speed=speed, width=321, height=240
    )
    stream = _probe(path)
    assert int(stream["nb_read_frames"]) == round(DURATION * fps / speed)
    assert (int(stream["width"]), int(stream["height"])) == (322, 240)  # even for H.264
    assert stream["codec_name"] == ("h264" if suffix == ".mp4" else "gif")


def test_frames_show_the_logged_heights(ball_run, tmp_path) -> None:
    width, height, fps = 320, 480, 10.0
    path = write_video(ball_run, tmp_path / "ball.mp4", fps=fps, width=width, height=height)
    frames = _frames(path, width, height).astype(float)
    orange = np.array([0.95, 0.45, 0.05]) * 255  # the ball's colour (it has no material)
    sphere = ET.parse(ROBOTS / "ball.urdf").getroot().find(".//sphere")
    assert sphere is not None
    radius = float(sphere.attrib["radius"])  # [m] from the URDF, not from the renderer
    log = Log.load(ball_run / "log.npz")
    rows = frame_rows(log.t, fps)
    # Frames without a force arrow: no impulse since the previous frame (read from the log).
    quiet = [
        j for j in range(len(rows)) if not log.impulse[rows[j - 1] if j else 0 : rows[j] + 1].any()
    ]
    assert len(quiet) >= 0.8 * len(rows)
    tops, widths = [], []
    for frame in frames[quiet]:
        # The ball: the dark (luminance) region around its orange pixels; luminance, not
        # colour, because H.264 halves the colour resolution. Its top and its width: the
        # contact marker widens neither.
        luminance = frame @ np.array([0.299, 0.587, 0.114])
        labels, _ = ndimage.label(luminance < 175.0)
        seeds = np.argwhere(np.linalg.norm(frame - orange, axis=2) < 60.0)
        assert len(seeds) > 50
        y, x = np.median(seeds, axis=0).astype(int)
        ys, xs = np.nonzero(labels == labels[y, x])
        tops.append(ys.min())  # [px] from the top of the image
        widths.append(xs.max() - xs.min() + 1)  # [px]
    assert np.ptp(widths) <= 2  # the same diameter in every frame
    heights = log.q[rows[quiet], 0]  # [m] of the ball's centre
    assert np.ptp(heights) > 0.5  # it fell
    # The image height is affine in the logged height (residual within a pixel or so) ...
    slope, intercept = np.polyfit(heights, tops, 1)  # [px/m], [px]
    residual = np.array(tops) - (slope * heights + intercept)  # [px]
    assert np.max(np.abs(residual)) <= 1.5
    # ... at the scale of the ball's own diameter in the image (to a pixel of that diameter).
    scale = float(np.median(widths)) / (2.0 * radius)  # [px/m]
    assert abs(-slope - scale) <= 1.5 / (2.0 * radius)


def test_still_image_formats(ball_run, tmp_path) -> None:
    png = write_still(ball_run, tmp_path / "still.png", time=0.3, width=4.0, height=3.0, dpi=50)
    stream = _probe(png)
    assert (int(stream["width"]), int(stream["height"])) == (200, 150)
    pdf = write_still(ball_run, tmp_path / "still.pdf", strobe=(0.1, 0.2, 0.3))
    assert pdf.read_bytes().startswith(b"%PDF")


def test_errors_name_the_argument(ball_run, tmp_path, monkeypatch) -> None:
    with pytest.raises(InvalidParameterError, match="path"):
        write_video(ball_run, tmp_path / "ball.avi")
    with pytest.raises(InvalidParameterError, match="fps"):
        write_video(ball_run, tmp_path / "ball.mp4", fps=0.0)
    with pytest.raises(InvalidParameterError, match="time"):
        write_still(ball_run, tmp_path / "still.png", time=DURATION + 1.0)
    monkeypatch.setattr(video.shutil, "which", lambda name: None)
    with pytest.raises(VideoError, match="ffmpeg is not installed"):
        write_video(ball_run, tmp_path / "ball.mp4")


def test_frame_rows_sample_the_run_at_the_frame_times() -> None:
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(1e-3, 3e-3, 500))  # [s] irregular samples
    rows = frame_rows(t, fps=25.0, speed=0.5)
    assert len(rows) == round((t[-1] - t[0]) * 25.0 / 0.5)
    times = t[0] + np.arange(len(rows)) * 0.5 / 25.0
    assert np.all(t[rows] >= times - 1e-9)  # the first sample at or after each frame time
    assert np.all(t[np.maximum(rows - 1, 0)][1:] < times[1:])


def test_cli_view_writes_the_video(ball_run, tmp_path, capsys) -> None:
    """`ucontrol view DIR --video FILE --fps F` (active once the command has the flag)."""
    from ucontrol.cli import main

    with pytest.raises(SystemExit):
        main(["view", "--help"])
    if "--video" not in capsys.readouterr().out:
        pytest.skip("`ucontrol view` has no --video flag yet")
    path = tmp_path / "cli.mp4"
    assert main(["view", str(ball_run), "--video", str(path), "--fps", "8"]) == 0
    assert int(_probe(path)["nb_read_frames"]) == round(DURATION * 8)


def test_scale_bar_and_force_arrow_state_their_lengths(ball_run) -> None:
    """The scale bar and arrow are as long as the metres and newtons they state.

    The ball's URDF diameter sets the image's metre; the force scale draws the ball's weight
    (URDF mass) at WEIGHT_ARROW view radii.
    """
    from matplotlib.patches import FancyArrow, Polygon

    root = ET.parse(ROBOTS / "ball.urdf").getroot()
    radius = float(root.find(".//sphere").attrib["radius"])  # type: ignore[union-attr]
    mass = float(root.find(".//mass").attrib["value"])  # type: ignore[union-attr]
    run = SavedRun.load(ball_run)
    renderer = video.SceneRenderer(run.require_scene(), run.log)
    figure = renderer.figure()
    renderer.draw(figure, 0)
    (ax,) = figure.axes
    (ball,) = [
        p
        for p in ax.patches
        if isinstance(p, Polygon)
        and not isinstance(p, FancyArrow)
        and np.ptp(p.get_xy()[:, 1]) > 0.5 * radius
    ]
    diameter = np.ptp(ball.get_xy()[:, 0])  # [m] in image coordinates
    assert diameter == pytest.approx(2.0 * radius, rel=1e-2)
    texts = {t.get_text() for t in ax.texts}
    length, force = renderer.scales()
    assert f"{length:g} m" in texts and f"{force:g} N" in texts
    (bar,) = [line for line in ax.get_lines() if len(line.get_xdata()) == 2]
    assert np.ptp(bar.get_xdata()) == pytest.approx(length, rel=1e-12)
    (arrow,) = [p for p in ax.patches if isinstance(p, FancyArrow)]  # no contact force at t = 0
    assert np.ptp(arrow.get_xy()[:, 0]) == pytest.approx(force * renderer.force_scale, rel=1e-9)
    weight_arrow = mass * 9.81 * renderer.force_scale  # [m]
    assert weight_arrow == pytest.approx(video.WEIGHT_ARROW * renderer.view.radius, rel=1e-9)
    for value in (length, force):  # round numbers: 1, 2 or 5 times a power of ten
        mantissa = value / 10.0 ** np.floor(np.log10(value))
        assert min(abs(mantissa - m) for m in (1.0, 2.0, 5.0)) < 1e-9
