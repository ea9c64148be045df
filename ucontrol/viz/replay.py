"""Replay of a saved run in meshcat: an animation in a live viewer or in a standalone HTML page."""

from __future__ import annotations

import html
import json
from pathlib import Path

import meshcat
import numpy as np
from meshcat.animation import Animation
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.viz.meshcat_server import MeshcatServer
from ucontrol.viz.scene_drawing import SceneDrawing

#: Frames per second of simulated time in replays and live views.
FPS = 30.0
#: HTML id of the time label of a replay page.
TIME_LABEL_ID = "ucontrol-time"


def frame_rows(t: NDArray[np.float64], fps: float = FPS) -> NDArray[np.intp]:
    """Rows of a log shown by the frames of an animation at ``fps`` frames per simulated second.

    Frame j shows the first row at or after time ``t[0] + j / fps``; the last row is always
    shown.

    Args:
        t: Sample times in [s], shape (N,), non-decreasing.
        fps: Frames per second of simulated time, > 0.

    Returns:
        Row indices, shape (F,), increasing.
    """
    fps = as_positive("fps", fps)
    times = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * fps + 1e-9)) + 1) / fps  # [s]
    rows = np.minimum(np.searchsorted(t, times - 1e-9), len(t) - 1)
    return np.unique(np.append(rows, len(t) - 1))


def mean_force(log: Log, start: int, stop: int) -> NDArray[np.float64]:
    """Mean normal force of each constraint over the steps of rows ``start`` to ``stop - 1``.

    The impulses of those steps divided by their total length: impulse / dt on one step, the
    mean force over a frame of an animation (an impact then shows as its impulse spread over
    the frame).

    Args:
        log: The run.
        start: First row; the window holds at least this row's step.
        stop: One past the last row.

    Returns:
        Forces in [N] (or [N m] for stops), shape (n,).
    """
    stop = max(stop, start + 1)
    dt = float(log.metadata["dt"])  # [s]
    impulse = log.impulse[start:stop]  # [N s]
    return np.asarray(impulse.sum(axis=0) / (len(impulse) * dt), dtype=float)


def animation(
    drawing: SceneDrawing, viewer: meshcat.Visualizer, log: Log, fps: float = FPS
) -> Animation:
    """The run of ``log`` as a meshcat animation of ``drawing``, played in real time.

    Frame j shows the configuration of row ``frame_rows(log.t, fps)[j]``, the mean contact
    forces since the previous frame and the controller's phase when the log has one.

    Args:
        drawing: The scene drawn in ``viewer``.
        viewer: The meshcat viewer holding the drawing.
        log: The run.
        fps: Frames per second of simulated time.
    """
    rows = frame_rows(log.t, fps)
    phase = log.phase if "phase" in log.fields else None
    result = Animation(default_framerate=fps)
    previous = rows[0]
    for j, row in enumerate(rows):
        force = mean_force(log, previous, row)
        with result.at_frame(viewer, j) as frame:
            drawing.place(
                frame, log.q[row], force, None if phase is None else phase[row], log.t[row]
            )
        previous = row
    return result


def replay(viewer: meshcat.Visualizer, scene: Scene, log: Log, fps: float = FPS) -> SceneDrawing:
    """Draw ``scene`` in ``viewer`` and load the run of ``log`` as an animation (playing).

    The view frames every configuration of the run; meshcat's *Animations* controls pause,
    replay and scrub it.
    """
    drawing = SceneDrawing(scene, viewer, configurations=log.q, phases="phase" in log.fields)
    viewer.set_animation(animation(drawing, viewer, log, fps), play=True, repetitions=1)
    return drawing


def write_html(path: str | Path, scene: Scene, log: Log, fps: float = FPS) -> Path:
    """Write the replay of ``log`` as a standalone HTML page that plays offline.

    The page embeds meshcat's viewer (three.js included) and the animation; it needs neither
    a server nor a network. A meshcat server runs in a subprocess while the page is built.
    The time of the frame shown (the logged time of its row) is written in the bottom left
    corner while the animation plays or is scrubbed.

    Args:
        path: The HTML file to write; its folder is created.
        scene: The scene of the run.
        log: The run.
        fps: Frames per second of simulated time.

    Returns:
        The path written.
    """
    path = Path(path)
    page = _replay_page(scene, log, fps)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page)
    return path


def _replay_page(scene: Scene, log: Log, fps: float) -> str:
    """The standalone HTML page of the replay, with its time label."""
    with MeshcatServer() as server:
        replay(server.viewer, scene, log, fps)
        page = server.static_html()
    head, body_end, tail = page.rpartition("</body>")
    return head + time_overlay(log.t[frame_rows(log.t, fps)], fps) + body_end + tail


class InlinePage:
    """A standalone HTML page shown inline by Jupyter, in an iframe (its ``srcdoc``).

    Args:
        page: The HTML page, e.g. that :func:`write_html` writes.
        height: Height of the frame in [px].
    """

    def __init__(self, page: str, height: int = 420) -> None:
        self.page = page
        self.height = int(as_positive("height", height))

    def _repr_html_(self) -> str:
        source = html.escape(self.page, quote=True)
        return (
            f'<iframe srcdoc="{source}" style="width: 100%; height: {self.height}px; '
            'border: 1px solid #ccc"></iframe>'
        )


def notebook_replay(scene: Scene, log: Log, fps: float = FPS, height: int = 420) -> InlinePage:
    """The replay of ``log`` inline in a Jupyter notebook: the page of :func:`write_html`.

    The page plays offline (no server once built, no network), so an executed notebook, or
    the documentation built from it, keeps the view. A meshcat server runs in a subprocess
    while the page is built.

    Args:
        scene: The scene of the run.
        log: The run.
        fps: Frames per second of simulated time.
        height: Height of the view in [px].

    Returns:
        An object Jupyter displays as the viewer (the last expression of a cell).
    """
    return InlinePage(_replay_page(scene, log, fps), height)


def time_overlay(times: NDArray[np.float64], fps: float) -> str:
    """HTML of a label that shows the time of the animation frame meshcat's viewer shows.

    The viewer's animation clock (``viewer.animator.time``, in seconds of animation, which
    plays at ``fps`` frames per second) gives the frame; the label shows its logged time.

    Args:
        times: Logged time of each frame in [s], shape (F,).
        fps: Frames per second of the animation.

    Returns:
        A ``div`` and the ``script`` that updates it at every repaint.
    """
    values = json.dumps([round(float(t), 9) for t in times])
    return f"""<div id="{TIME_LABEL_ID}" style="position: fixed; left: 12px; bottom: 12px;
 font: 16px monospace; background: rgba(255, 255, 255, 0.85); border: 1px solid #888;
 padding: 2px 6px">t = {times[0]:.3f} s</div>
<script>
(function () {{
  const times = {values};  // [s] logged time of each animation frame
  const label = document.getElementById("{TIME_LABEL_ID}");
  function show() {{
    const frame = Math.round(viewer.animator.time * {fps:g});
    const t = times[Math.min(times.length - 1, Math.max(0, frame))];
    label.textContent = "t = " + t.toFixed(3) + " s";
    requestAnimationFrame(show);
  }}
  show();
}})();
</script>
"""
