"""Replay of a saved run in meshcat: an animation in a live viewer or in a standalone HTML page."""

from __future__ import annotations

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

    Args:
        path: The HTML file to write; its folder is created.
        scene: The scene of the run.
        log: The run.
        fps: Frames per second of simulated time.

    Returns:
        The path written.
    """
    path = Path(path)
    with MeshcatServer() as server:
        replay(server.viewer, scene, log, fps)
        html = server.static_html()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html)
    return path
