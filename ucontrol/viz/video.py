r"""Videos (mp4, gif) and figure-quality stills of a saved run, rendered offline by matplotlib.

The robot is drawn from its URDF's visual geometry in an orthographic view: spheres, boxes,
cylinders and capsules as their exact outlines, meshes as the outline of their vertices, and a
skeleton (joints and the segments to the joints and frames they carry) for bodies without any
visual, as in the meshcat view (:mod:`ucontrol.viz.scene_drawing`). Each plane surface is a thin
grey slab, each contact a marker at its contact point with an arrow along the surface normal of
length proportional to the mean normal force over the frame, and the time and the controller's
phase are written in a corner; a scale bar of round length and an arrow of a round force in
the top right corner give the lengths in [m] and the forces in [N].

Why matplotlib and not the headless-browser screenshots of the meshcat scene: a browser launch
costs seconds and, headless, intermittently never ends its virtual-time budget
(:mod:`ucontrol.viz.browser_screenshot` retries it), so a 10 s video at 30 frames per second
would take many minutes and depend on chromium, swiftshader and a meshcat server; the
matplotlib frame costs tens of milliseconds, is deterministic, needs nothing but matplotlib and
ffmpeg, and the same drawing gives a vector still (PDF, SVG) for a paper. What it gives up is
meshcat's shading: bodies are flat-coloured outlines drawn back to front.

The view looks along the normal of the plane of motion when the motion is planar (the
two-link arm is seen exactly from the front), else obliquely from the front right, above;
"up" is opposite to gravity. The frames are piped to ``ffmpeg`` (H.264 for ``.mp4``, a
palette for ``.gif``): a video of a run of duration :math:`T` at ``fps`` frames per second of
video and ``speed`` simulated seconds per video second has
:math:`\operatorname{round}(T\,\mathrm{fps}/\mathrm{speed})` frames; frame :math:`j` shows
the first sample at or after :math:`t_0 + j\,\mathrm{speed}/\mathrm{fps}`.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrow, Polygon
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

from ucontrol._validation import as_positive
from ucontrol.control.phase import Phase
from ucontrol.exceptions import InvalidParameterError, VideoError
from ucontrol.log import Log
from ucontrol.saved_run import SavedRun
from ucontrol.scene import Scene
from ucontrol.viz.phase_colours import PHASE_COLOURS

#: Video container of each file suffix.
FORMATS = {".mp4": "mp4", ".gif": "gif"}
#: Default frames per second of video.
FPS = 30.0
#: Colour (RGBA in [0, 1]) of robot shapes without a URDF colour, as in the meshcat view.
ROBOT_COLOUR = (0.95, 0.45, 0.05, 1.0)
#: Colour Pinocchio gives to URDF visuals without a material.
_URDF_DEFAULT_COLOUR = (0.9, 0.9, 0.9, 1.0)
#: Colours of the surfaces, contact markers and force arrows (as in the meshcat view).
SURFACE_COLOUR = "#8c8c8c"
CONTACT_COLOUR = "#7b2cbf"
ARROW_COLOUR = "#1f9e3a"
#: Length of the arrow of a force equal to the robot's weight, as a fraction of the view radius.
WEIGHT_ARROW = 0.5
#: Longest force arrow, as a fraction of the view radius.
MAX_ARROW = 1.0
#: Points on the circle of a cylinder or capsule outline.
_CIRCLE_POINTS = 48
#: Configurations used to frame the view.
_FRAMING_SAMPLES = 200

Matrix = NDArray[np.float64]
Vector = NDArray[np.float64]
#: A body, segment or surface to draw: (depth toward the camera [m], image outline (K, 2) [m],
#: colour, kind: "body", "segment" or "surface").
_Shape = tuple[float, Matrix, tuple[float, ...] | str, str]


@dataclass(frozen=True)
class View:
    """An orthographic view of a scene.

    Attributes:
        right: Unit vector of the image's x-axis in the world, shape (3,).
        up: Unit vector of the image's y-axis in the world, shape (3,).
        toward_camera: Unit vector from the scene to the camera, shape (3,).
        centre: World point at the centre of the image in [m], shape (3,).
        radius: Half the side of the square the image shows, in [m].
    """

    right: Vector
    up: Vector
    toward_camera: Vector
    centre: Vector
    radius: float

    def project(self, points: Matrix) -> Matrix:
        """Image coordinates in [m] of world points, shape (K, 2) from (K, 3)."""
        centred = np.atleast_2d(points) - self.centre
        return np.column_stack([centred @ self.right, centred @ self.up])

    def depth(self, points: Matrix) -> float:
        """Mean distance of ``points`` toward the camera in [m] (larger: nearer)."""
        return float(np.mean((np.atleast_2d(points) - self.centre) @ self.toward_camera))


class SceneRenderer:
    """The scene of a run drawn by matplotlib at any sample of its log.

    Args:
        scene: The scene of the run.
        log: The run.
        width: Image width in [px] (rounded up to an even number, as H.264 needs).
        height: Image height in [px] (rounded up to an even number).
        dpi: Dots per inch of the figure: sets the size of lines and text in [px].
        force_scale: Arrow length per unit of normal contact force in [m/N]; default: the
            robot's weight is half the view radius (:data:`WEIGHT_ARROW`).

    Raises:
        InvalidParameterError: ``log`` is not a run of ``scene`` (configuration size), or a
            size is not positive.
    """

    def __init__(
        self,
        scene: Scene,
        log: Log,
        *,
        width: int = 960,
        height: int = 720,
        dpi: float = 120.0,
        force_scale: float | None = None,
    ) -> None:
        robot = scene.robot
        if log.q.shape[1] != robot.nq:
            raise InvalidParameterError(
                "log", f"nq = {log.q.shape[1]}", f"a run of scene {scene.name!r} (nq = {robot.nq})"
            )
        self.width = 2 * int(np.ceil(as_positive("width", width) / 2))
        self.height = 2 * int(np.ceil(as_positive("height", height) / 2))
        self.dpi = as_positive("dpi", dpi)
        self.scene, self.log = scene, log
        self._model = robot.model
        self._data = pin.Data(robot.model)
        self._geometry = _visual_geometry(scene)
        self._geometry_data = pin.GeometryData(self._geometry)
        self._outlines = [_body_outline(obj.geometry) for obj in self._geometry.geometryObjects]
        self._skeleton_joints = _undrawn_joints(self._model, self._geometry)
        self._contacts = [
            (robot.frame_id(c.frame), c.surface.normal, c.radius) for c in scene.contacts
        ]
        self.view = _view(scene, self._points(log.q, bodies=False), self._points(log.q))
        mass = sum(inertia.mass for inertia in self._model.inertias)  # [kg]
        weight = mass * (float(np.linalg.norm(robot.gravity)) or 9.81)  # [N]
        if force_scale is None:
            force_scale = WEIGHT_ARROW * self.view.radius / weight if weight > 0.0 else 1.0
        self.force_scale = as_positive("force_scale", force_scale)  # [m/N]
        self._dt = float(log.metadata["dt"])  # [s]

    def figure(self) -> Figure:
        """A new figure of the renderer's size with the empty view (no robot drawn yet)."""
        figure = Figure(figsize=(self.width / self.dpi, self.height / self.dpi), dpi=self.dpi)
        ax = figure.add_axes((0.0, 0.0, 1.0, 1.0))
        aspect = self.width / self.height
        r = self.view.radius
        ax.set_xlim(-r * max(aspect, 1.0), r * max(aspect, 1.0))
        ax.set_ylim(-r / min(aspect, 1.0), r / min(aspect, 1.0))
        ax.set_aspect("equal")
        ax.set_axis_off()
        return figure

    def draw(
        self, figure: Figure, row: int, *, previous: int | None = None, alpha: float = 1.0
    ) -> None:
        """Draw the scene at log row ``row`` into ``figure`` (made by :meth:`figure`).

        Args:
            figure: The figure; its axes are cleared unless ``alpha`` < 1 (a strobe overlay).
            row: Row of the log shown.
            previous: Row of the previous frame: the force arrows show the mean normal force
                over the steps from it to ``row`` (an impact shows as its impulse spread over
                the frame); default the step of ``row`` alone.
            alpha: Opacity of the robot (strobe images draw earlier rows faded).
        """
        ax = figure.axes[0]
        if alpha >= 1.0:
            for artist in [*ax.patches, *ax.lines, *ax.texts, *ax.collections]:
                artist.remove()
        q = self.log.q[row]
        shapes = self._shapes(q)
        if alpha >= 1.0:
            shapes += self._surface_shapes()
        layer = 2.0 if alpha >= 1.0 else 1.0  # a strobe's faded bodies behind the robot
        for _, xy, colour, kind in sorted(shapes, key=lambda shape: shape[0]):
            if kind == "surface":
                ax.add_patch(
                    Polygon(xy, facecolor=colour, edgecolor="0.35", lw=1.0, alpha=0.6, zorder=0)
                )
            elif kind == "segment":
                ax.plot(xy[:, 0], xy[:, 1], color=colour, lw=4.0, alpha=alpha, zorder=layer)
            else:
                ax.add_patch(
                    Polygon(
                        xy, facecolor=colour, edgecolor="0.2", lw=0.6, alpha=alpha, zorder=layer
                    )
                )
        if alpha >= 1.0:
            self._draw_contacts(ax, q, row, previous)
            self._draw_label(ax, row)
            self._draw_scales(ax)

    def _points(self, configurations: Matrix, *, bodies: bool = True) -> Matrix:
        """World positions of joints, frames and contact points (and bodies' outlines)."""
        model, data = self._model, self._data
        step = max(1, len(configurations) // _FRAMING_SAMPLES)
        points: list[Matrix] = []
        for q in configurations[::step]:
            pin.framesForwardKinematics(model, data, q)
            points.append(np.array([data.oMi[j].translation for j in range(1, model.njoints)]))
            points.append(np.array([data.oMf[f].translation for f in range(1, model.nframes)]))
            points.extend(
                (data.oMf[frame].translation - radius * normal).reshape(1, 3)
                for frame, normal, radius in self._contacts
            )
            if not bodies:
                continue
            pin.updateGeometryPlacements(model, data, self._geometry, self._geometry_data)
            for k, outline in enumerate(self._outlines):
                if outline is not None:
                    pose = self._geometry_data.oMg[k]
                    points.append(outline @ pose.rotation.T + pose.translation)
        return np.vstack([block.reshape(-1, 3) for block in points])

    def _shapes(self, q: Vector) -> list[_Shape]:
        """(depth, image outline, colour, kind) of every body at ``q``."""
        model, data, view = self._model, self._data, self.view
        pin.framesForwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, self._geometry, self._geometry_data)
        shapes: list[_Shape] = []
        for k, (obj, outline) in enumerate(
            zip(self._geometry.geometryObjects, self._outlines, strict=True)
        ):
            if outline is None:
                continue
            pose = self._geometry_data.oMg[k]
            if isinstance(obj.geometry, coal.Sphere):  # its outline is a circle in any view
                world = pose.translation + obj.geometry.radius * _circle(view.right, view.up)
            else:
                world = outline @ pose.rotation.T + pose.translation
            colour = tuple(float(c) for c in obj.meshColor)
            if np.allclose(colour, _URDF_DEFAULT_COLOUR):
                colour = ROBOT_COLOUR
            shapes.append((view.depth(world), _hull(view.project(world)), colour, "body"))
        for joint, ends in self._skeleton_joints:
            origin = data.oMi[joint]
            start = origin.translation
            for end in ends:
                world = np.array([start, origin.act(end)])
                shapes.append((view.depth(world), view.project(world), ROBOT_COLOUR, "segment"))
            ring = start + 0.03 * view.radius * _circle(view.right, view.up)
            shapes.append((view.depth(start), view.project(ring), ROBOT_COLOUR, "body"))
        return shapes

    def _surface_shapes(self) -> list[_Shape]:
        """One thin slab per plane surface, its top face the plane, around the view."""
        planes = {c.surface.name: c.surface for c in self.scene.contacts}
        view = self.view
        shapes: list[_Shape] = []
        side, thickness = 2.4 * view.radius, 0.04 * view.radius  # [m]
        for plane in planes.values():
            normal = plane.normal
            foot = view.centre - normal * (normal @ (view.centre - plane.point))
            a = np.cross(normal, view.toward_camera)
            if np.linalg.norm(a) < 1e-9:
                a = np.cross(normal, view.up)
            a /= np.linalg.norm(a)
            b = np.cross(normal, a)
            corners = [
                foot + 0.5 * side * (sa * a + sb * b) - depth * normal
                for sa in (-1, 1)
                for sb in (-1, 1)
                for depth in (0.0, thickness)
            ]
            world = np.array(corners)
            # Behind everything: the surface is drawn first.
            shapes.append((-np.inf, _hull(view.project(world)), SURFACE_COLOUR, "surface"))
        return shapes

    def _draw_contacts(self, ax: object, q: Vector, row: int, previous: int | None) -> None:
        """Contact markers and arrows of the mean normal force since ``previous``."""
        data, view = self._data, self.view
        start = row if previous is None else min(previous, row)
        stop = max(row, start + 1)
        impulse = self.log.impulse[start:stop]  # [N s]
        names = self.log.constraint_names
        forces = impulse.sum(axis=0) / (len(impulse) * self._dt)  # [N]
        for i, (frame, normal, radius) in enumerate(self._contacts):
            point = data.oMf[frame].translation - radius * normal
            (xy,) = view.project(point)
            ax.plot(xy[0], xy[1], "o", color=CONTACT_COLOUR, ms=5, zorder=5)  # type: ignore[attr-defined]
            name = self.scene.contacts[i].name
            force = float(forces[names.index(name)]) if name in names else 0.0
            length = min(force * self.force_scale, MAX_ARROW * view.radius)  # [m]
            if length <= 1e-3 * view.radius:
                continue
            (tip,) = view.project(point + length * normal)
            ax.add_patch(  # type: ignore[attr-defined]
                FancyArrow(
                    xy[0],
                    xy[1],
                    tip[0] - xy[0],
                    tip[1] - xy[1],
                    width=0.012 * view.radius,
                    head_width=0.05 * view.radius,
                    head_length=0.05 * view.radius,
                    length_includes_head=True,
                    color=ARROW_COLOUR,
                    zorder=6,
                )
            )

    def scales(self) -> tuple[float, float]:
        """The length of the scale bar in [m] and the force of the scale arrow in [N].

        Each a round number (1, 2 or 5 times a power of ten): the bar at most a quarter of
        the view's width, the arrow at most a third of the view radius long.
        """
        return _round_down(0.5 * self.view.radius), _round_down(
            self.view.radius / (3.0 * self.force_scale)
        )

    def _draw_scales(self, ax: object) -> None:
        """A length scale bar and a force scale arrow in the top right corner."""
        length, force = self.scales()
        x_low, x_high = ax.get_xlim()  # type: ignore[attr-defined]
        y_low, y_high = ax.get_ylim()  # type: ignore[attr-defined]
        pad = 0.04 * (x_high - x_low)  # [m]
        right, bottom = x_high - pad, y_high - 2.0 * pad  # of the bar
        ax.plot(  # type: ignore[attr-defined]
            [right - length, right], [bottom, bottom], color="k", lw=3.0, solid_capstyle="butt"
        )
        ax.text(  # type: ignore[attr-defined]
            right - 0.5 * length,
            bottom + 0.01 * (y_high - y_low),
            f"{length:g} m",
            ha="center",
            va="bottom",
            fontsize=9,
        )
        arrow = force * self.force_scale  # [m]
        base = bottom - 0.1 * (y_high - y_low)  # of the arrow
        ax.add_patch(  # type: ignore[attr-defined]
            FancyArrow(
                right - arrow,
                base,
                arrow,
                0.0,
                width=0.012 * self.view.radius,
                head_width=0.05 * self.view.radius,
                head_length=min(0.05 * self.view.radius, arrow),
                length_includes_head=True,
                color=ARROW_COLOUR,
            )
        )
        ax.text(  # type: ignore[attr-defined]
            right - 0.5 * arrow,
            base + 0.03 * self.view.radius,
            f"{force:g} N",
            ha="center",
            va="bottom",
            fontsize=9,
            color=ARROW_COLOUR,
        )

    def _draw_label(self, ax: object, row: int) -> None:
        """Time and, for a phase-machine run, the phase, in the top left corner."""
        text = f"t = {self.log.t[row]:.3f} s"
        colour = "white"
        if "phase" in self.log.fields:
            phase = Phase(int(self.log.phase[row]))
            text += f"   {phase.name.lower()}"
            colour = PHASE_COLOURS[phase]
        ax.text(  # type: ignore[attr-defined]
            0.02,
            0.97,
            text,
            transform=ax.transAxes,  # type: ignore[attr-defined]
            va="top",
            fontsize=11,
            family="monospace",
            bbox={"facecolor": colour, "edgecolor": "0.5", "pad": 3.0},
        )


def _round_down(value: float) -> float:
    """The largest of 1, 2 or 5 times a power of ten that is at most ``value`` (> 0)."""
    power = 10.0 ** np.floor(np.log10(value))
    return float(max(m * power for m in (1.0, 2.0, 5.0) if m * power <= value * (1 + 1e-12)))


def frame_rows(t: NDArray[np.float64], fps: float, speed: float = 1.0) -> NDArray[np.intp]:
    r"""Rows of a log shown by the frames of a video, one per :math:`\mathrm{speed}/\mathrm{fps}`.

    Args:
        t: Sample times in [s], shape (N,), non-decreasing.
        fps: Frames per second of video, > 0.
        speed: Simulated seconds per second of video, > 0.

    Returns:
        Row indices, shape (F,) with F = max(1, round((t[-1] - t[0]) fps / speed)); frame j
        shows the first row at or after t[0] + j speed / fps.
    """
    fps, speed = as_positive("fps", fps), as_positive("speed", speed)
    count = max(1, round((t[-1] - t[0]) * fps / speed))
    times = t[0] + np.arange(count) * speed / fps  # [s]
    return np.minimum(np.searchsorted(t, times - 1e-9), len(t) - 1)


def write_video(
    run_dir: str | Path,
    path: str | Path,
    *,
    fps: float = FPS,
    speed: float = 1.0,
    scene: str | Path | None = None,
    width: int = 960,
    height: int = 720,
    progress: bool | None = None,
) -> Path:
    """Write the run saved in ``run_dir`` as a video file (``.mp4`` or ``.gif``).

    Args:
        run_dir: The run directory (``ucontrol run ... --out DIR``).
        path: The video file to write; its suffix chooses the format; its folder is created.
        fps: Frames per second of video.
        speed: Simulated seconds per second of video (2: twice as fast as real time).
        scene: Scene file of the run, instead of the one its log names.
        width: Width in [px] (rounded up to even).
        height: Height in [px] (rounded up to even).
        progress: Show a progress bar (tqdm); default when standard error is a terminal.

    Returns:
        The path written. It has round(duration fps / speed) frames.

    Raises:
        InvalidParameterError: The suffix is neither ``.mp4`` nor ``.gif``, or a number is
            not positive.
        RunNotFoundError: ``run_dir`` holds no run.
        SceneError: The scene of the run is unknown.
        VideoError: ffmpeg is not installed, or failed.
    """
    path = Path(path)
    container = FORMATS.get(path.suffix.lower())
    if container is None:
        raise InvalidParameterError("path", str(path), f"a file ending in {' or '.join(FORMATS)}")
    fps, speed = as_positive("fps", fps), as_positive("speed", speed)
    executable = shutil.which("ffmpeg")
    if executable is None:
        raise VideoError("ffmpeg is not installed (Debian: apt-get install -y ffmpeg)")
    run = SavedRun.load(run_dir, scene)
    renderer = SceneRenderer(run.require_scene(), run.log, width=width, height=height)
    rows = frame_rows(run.log.t, fps, speed)
    path.parent.mkdir(parents=True, exist_ok=True)
    command = [
        executable,
        "-y",
        "-loglevel",
        "error",
        "-f",
        "rawvideo",
        "-pix_fmt",
        "rgba",
        "-s",
        f"{renderer.width}x{renderer.height}",
        "-r",
        f"{fps:g}",
        "-i",
        "-",
        *_encoder_flags(container, fps),
        str(path),
    ]
    figure = renderer.figure()
    canvas = FigureCanvasAgg(figure)
    show = sys.stderr.isatty() if progress is None else progress
    bar = _progress_bar(len(rows), path.name) if show else None
    with subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE) as encoder:
        stdin = encoder.stdin
        if stdin is None:  # cannot happen with stdin=PIPE; keeps the type checker informed
            raise VideoError("ffmpeg has no standard input")
        try:
            previous: int | None = None
            for row in rows:
                renderer.draw(figure, int(row), previous=previous)
                canvas.draw()
                stdin.write(bytes(canvas.buffer_rgba()))
                previous = int(row)
                if bar is not None:
                    bar(1)
            stdin.close()
        except BrokenPipeError:
            pass  # ffmpeg stopped: its status and messages say why
        finally:
            if bar is not None:
                bar(0, close=True)
        errors = encoder.stderr.read().decode(errors="replace") if encoder.stderr else ""
        status = encoder.wait()
    if status != 0:
        raise VideoError(f"ffmpeg failed (exit status {status}) writing {path}: {errors[-800:]}")
    return path


def write_still(
    run_dir: str | Path,
    path: str | Path,
    *,
    time: float | None = None,
    strobe: Sequence[float] = (),
    scene: str | Path | None = None,
    width: float = 6.0,
    height: float = 4.5,
    dpi: float = 300.0,
) -> Path:
    """Write one figure-quality image of a run: PNG at ``dpi``, or vector PDF or SVG.

    Args:
        run_dir: The run directory.
        path: The image file (``.png``, ``.pdf``, ``.svg``); its folder is created.
        time: Time shown in [s] (the first sample at or after it); default the last sample.
        strobe: Earlier times in [s] drawn faded behind it (a chronophotograph of the motion).
        scene: Scene file of the run, instead of the one its log names.
        width: Width in [in].
        height: Height in [in].
        dpi: Resolution of a PNG in dots per inch.

    Returns:
        The path written.

    Raises:
        InvalidParameterError: A time outside the run, or a size that is not positive.
        RunNotFoundError: ``run_dir`` holds no run.
        SceneError: The scene of the run is unknown.
    """
    run = SavedRun.load(run_dir, scene)
    t = run.log.t
    dpi = as_positive("dpi", dpi)
    renderer = SceneRenderer(
        run.require_scene(),
        run.log,
        width=round(as_positive("width", width) * dpi),
        height=round(as_positive("height", height) * dpi),
        dpi=dpi,
    )

    def row_at(name: str, value: float) -> int:
        if not t[0] - 1e-12 <= value <= t[-1] + 1e-12:
            raise InvalidParameterError(name, value, f"a time in [{t[0]:g}, {t[-1]:g}] s")
        return min(int(np.searchsorted(t, value - 1e-9)), len(t) - 1)

    row = len(t) - 1 if time is None else row_at("time", time)
    figure = renderer.figure()
    renderer.draw(figure, row)
    earlier = sorted(row_at("strobe", value) for value in strobe)
    for k, ghost in enumerate(earlier):
        renderer.draw(figure, ghost, alpha=0.15 + 0.45 * (k + 1) / (len(earlier) + 1))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi)
    return path


def _encoder_flags(container: str, fps: float) -> list[str]:
    """The ffmpeg output flags of a container: H.264 (playable everywhere) or a paletted gif."""
    if container == "mp4":
        return [
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "-preset",
            "veryfast",
            "-crf",
            "20",
            "-movflags",
            "+faststart",
            "-r",
            f"{fps:g}",
        ]
    palette = "split[a][b];[a]palettegen=stats_mode=diff[p];[b][p]paletteuse=dither=bayer"
    return ["-vf", palette, "-r", f"{fps:g}", "-f", "gif"]


def _progress_bar(total: int, name: str) -> Callable[..., None]:
    """A tqdm bar of ``total`` frames as a function: ``bar(n)`` advances, ``close=True`` ends."""
    from tqdm import tqdm

    bar = tqdm(total=total, desc=name, unit="frame", file=sys.stderr)

    def advance(n: int, *, close: bool = False) -> None:
        if n:
            bar.update(n)
        if close:
            bar.close()

    return advance


def _view(scene: Scene, kinematic: Matrix, points: Matrix) -> View:
    """The orthographic view that frames ``points`` (K, 3), up opposite to gravity.

    Args:
        scene: The scene (gravity, planar axis, contact radii).
        kinematic: Joint, frame and contact points (K, 3): the plane or line of the motion.
        points: Every point to show (K', 3), bodies' outlines included.
    """
    gravity = scene.robot.gravity
    norm = float(np.linalg.norm(gravity))
    up = -gravity / norm if norm > 0.0 else np.array([0.0, 0.0, 1.0])
    low, high = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (low + high)
    half = 0.5 * float(np.linalg.norm(high - low))
    margin = max(0.1 * half, max((c.radius for c in scene.contacts), default=0.0), 0.05)
    # Horizontal "front" and "side" of the world, as seen by the meshcat view.
    side = np.cross(up, [0.0, 1.0, 0.0]) if abs(up[1]) < 0.9 else np.cross(up, [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    front = np.cross(side, up)  # toward the viewer of a default scene
    normal, line = _plane_of_motion(scene, kinematic)
    if normal is not None and abs(normal @ up) < 0.9:  # planar: seen square on
        toward = normal if normal @ (-front + 0.5 * side) >= 0.0 else -normal
    elif line is not None:  # along a line: seen from the front, level
        toward = -front if abs(front @ line) < 0.9 else side
    else:  # in space: from the front right, above
        toward = -1.2 * front + 0.8 * side + 0.7 * up
    toward = toward / np.linalg.norm(toward)
    right = np.cross(up, toward)
    if np.linalg.norm(right) < 1e-9:  # looking along up: any right will do
        right = side
    right /= np.linalg.norm(right)
    image_up = np.cross(toward, right)
    view = View(right, image_up, toward, centre, 1.0)
    image = view.project(points)
    extent = float(np.max(np.abs(image))) if image.size else 1.0  # [m]
    return View(right, image_up, toward, centre, max(extent, half) + margin)


def _plane_of_motion(scene: Scene, points: Matrix) -> tuple[Vector | None, Vector | None]:
    """The normal of the plane the scene moves in, and the direction of its line if collinear.

    The plane is the scene's ``planar_axis`` when it declares one, else that of the points
    (K, 3) when they lie in one; either may be None.
    """
    centred = points - points.mean(axis=0)
    _, spread, axes = np.linalg.svd(centred, full_matrices=False)
    spread = np.concatenate([spread, np.zeros(3 - spread.size)])
    line = axes[0] if spread[0] > 0.0 and spread[1] < 1e-6 * spread[0] else None
    if scene.planar_axis is not None:
        return np.asarray(scene.planar_axis, dtype=float), line
    if axes.shape[0] == 3 and spread[0] > 0.0 and spread[2] < 1e-6 * spread[0] and line is None:
        return axes[2], None
    return None, line


def _visual_geometry(scene: Scene) -> pin.GeometryModel:
    """The URDF's visual geometry (empty for a model built otherwise)."""
    robot = scene.robot
    if robot.urdf_path is None:
        return pin.GeometryModel()
    package_dirs = [str(path) for path in robot.urdf_path.parents]  # package:// lookups
    return pin.buildGeomFromUrdf(
        robot.model, str(robot.urdf_path), pin.GeometryType.VISUAL, package_dirs=package_dirs
    )


def _undrawn_joints(
    model: pin.Model, geometry: pin.GeometryModel
) -> list[tuple[int, list[pin.SE3 | Vector]]]:
    """Joints whose body has no visual, each with the points (in its frame) it carries."""
    drawn = {obj.parentJoint for obj in geometry.geometryObjects}
    skeleton = []
    for joint in range(1, model.njoints):
        if joint in drawn:
            continue
        ends = [model.jointPlacements[child].translation for child in model.children[joint]]
        ends += [
            frame.placement.translation
            for frame in model.frames
            if frame.parentJoint == joint and frame.type != pin.FrameType.JOINT
        ]
        distinct = {tuple(np.round(end, 9)) for end in ends if np.linalg.norm(end) > 1e-6}
        skeleton.append((joint, [np.array(end) for end in sorted(distinct)]))
    return skeleton


def _body_outline(shape: object) -> Matrix | None:
    """Points in the shape's frame whose projected convex hull is the shape's outline.

    Exact for boxes; spheres, cylinders and capsules by their circles of
    :data:`_CIRCLE_POINTS` points (the sphere by three great circles); meshes by their
    vertices (the corners of their convex hull). None for shapes it cannot draw.
    """
    circle = _circle(np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    if isinstance(shape, coal.Sphere):
        r = shape.radius
        return r * np.vstack([circle, circle[:, [0, 2, 1]], circle[:, [2, 0, 1]]])
    if isinstance(shape, coal.Box):
        half = shape.halfSide
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    if isinstance(shape, coal.Cylinder | coal.Capsule):
        r, h = shape.radius, shape.halfLength
        rings = [shape.radius * circle + [0.0, 0.0, z] for z in (-h, h)]
        if isinstance(shape, coal.Capsule):
            rings += [r * circle[:, [0, 2, 1]] + [0, 0, z] for z in (-h, h)]
            rings += [r * circle[:, [2, 0, 1]] + [0, 0, z] for z in (-h, h)]
        return np.vstack(rings)
    vertices = getattr(shape, "vertices", None)
    if callable(vertices):
        points = np.asarray(vertices(), dtype=float).reshape(-1, 3)
        if len(points) >= 4:
            try:
                return points[ConvexHull(points).vertices]
            except QhullError:
                return points
    return None


def _circle(a: Vector, b: Vector) -> Matrix:
    """Unit circle in the plane of orthonormal ``a``, ``b``, shape (_CIRCLE_POINTS, 3)."""
    angles = np.linspace(0.0, 2.0 * np.pi, _CIRCLE_POINTS, endpoint=False)
    return np.outer(np.cos(angles), a) + np.outer(np.sin(angles), b)


def _hull(points: Matrix) -> Matrix:
    """The convex hull of image points (K, 2), in order; the points themselves if degenerate."""
    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points
