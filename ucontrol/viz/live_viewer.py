"""Live meshcat view of a running simulation, passed to :func:`ucontrol.simulate` as observer."""

from __future__ import annotations

import time
from collections.abc import Callable

import meshcat
import numpy as np

from ucontrol._validation import as_positive
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.viz.replay import FPS, mean_force
from ucontrol.viz.scene_drawing import SceneDrawing


class LiveViewer:
    """Draw a run while it is computed: ``simulate(scene, observer=LiveViewer(scene, viewer))``.

    Called with the log after every step, it draws a frame every ``1 / fps`` of simulated
    time: the configuration, the mean contact forces since the previous frame and the phase of
    the controller (when the log has a ``phase`` field). With ``speed`` it waits so that
    simulated time runs at most ``speed`` times faster than wall time.

    Args:
        scene: The scene being run.
        viewer: The meshcat viewer (e.g. :attr:`MeshcatServer.viewer`); the scene is drawn
            at its initial configuration at once.
        fps: Frames per second of simulated time, > 0.
        speed: Simulated seconds per wall-clock second, > 0 (1: real time), or None to draw
            as fast as the simulation runs.
        phases: Draw the label of the controller's phase.
        force_scale: Arrow length per unit of contact force in [m/N]; default see
            :class:`SceneDrawing`.
        clock: Wall clock in [s] that paces the frames (tests inject a simulated one).
        sleep: Waits the given time in [s] of ``clock``.
    """

    def __init__(
        self,
        scene: Scene,
        viewer: meshcat.Visualizer,
        *,
        fps: float = FPS,
        speed: float | None = 1.0,
        phases: bool = False,
        force_scale: float | None = None,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.drawing = SceneDrawing(scene, viewer, phases=phases, force_scale=force_scale)
        self._viewer = viewer
        self._fps = as_positive("fps", fps)  # [1/s] of simulated time
        self._speed = None if speed is None else as_positive("speed", speed)
        self._next = 0.0
        self._last_row = 0
        self._start: float | None = None
        self._clock = clock
        self._sleep = sleep
        self.frames = 0

    def __call__(self, log: Log) -> None:
        """Draw the last row of ``log`` if a frame is due."""
        row = len(log) - 1
        t = float(log.t[row])
        if self._start is None:
            self._start = self._clock() - (0.0 if self._speed is None else t / self._speed)
        if t + 1e-9 < self._next:
            return
        self._next = (np.floor(t * self._fps + 1e-9) + 1.0) / self._fps  # [s], next frame
        if self._speed is not None:
            self._sleep(max(0.0, t / self._speed - (self._clock() - self._start)))
        self.show(log, row)

    def show(self, log: Log, row: int = -1) -> None:
        """Draw row ``row`` of ``log`` now (e.g. the last one, when the run has ended)."""
        row = row % len(log)
        force = mean_force(log, min(self._last_row, row), row)
        phase = int(log.phase[row]) if "phase" in log.fields else None
        self.drawing.place(self._viewer, np.asarray(log.q[row]), force, phase, float(log.t[row]))
        self._last_row = row
        self.frames += 1
