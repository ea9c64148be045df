"""Headless Chromium screenshots of meshcat pages, and where the robot should appear in them."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ucontrol.viz.browser_screenshot import find_chromium
from ucontrol.viz.browser_screenshot import screenshot as write_screenshot
from ucontrol.viz.scene_drawing import CAMERA_FOV, SceneDrawing

#: Size of the screenshots in [px].
WIDTH, HEIGHT = 800, 600


def chromium() -> str:
    """Path of Debian's chromium; skips the test with the reason when it is absent."""
    path = find_chromium()
    if path is None:
        pytest.skip(
            "chromium is not installed (.ci/run installs it: apt-get install -y chromium); "
            "the browser tests need it"
        )
    return path


def screenshot(
    url: str,
    out: Path,
    *,
    virtual_time_ms: int = 1500,
    offline: bool = False,
    min_pixels: int = 0,
) -> np.ndarray:
    """Load ``url`` in headless Chromium and return the screenshot as RGB, shape (H, W, 3).

    Args:
        url: Page address (``http://`` or ``file://``).
        out: PNG file to write.
        virtual_time_ms: Virtual time the page runs before the shot (animations advance).
        offline: Route every network request to a closed port: the page must need none.
        min_pixels: Fewest robot pixels (:func:`orange_mask`) of a shot of a page whose scene
            has arrived; a shot with fewer is taken again (a bounded number of times).
    """
    chromium()
    path = write_screenshot(
        url,
        out,
        width=WIDTH,
        height=HEIGHT,
        virtual_time_ms=virtual_time_ms,
        offline=offline,
        ready=_robot_drawn(min_pixels) if min_pixels else None,
    )
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB")).astype(int)


def _robot_drawn(min_pixels: int) -> Callable[[Path], bool]:
    """Check of a screenshot file: more than ``min_pixels`` robot pixels."""

    def ready(path: Path) -> bool:
        with Image.open(path) as image:
            return int(orange_mask(np.asarray(image.convert("RGB")).astype(int)).sum()) > min_pixels

    return ready


def orange_mask(image: np.ndarray) -> np.ndarray:
    """Pixels of the robot's default colour (orange, shaded), shape (H, W) of bool."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return (r > 120) & (r > g + 40) & (g > b + 20) & (b < 100)


def project(drawing: SceneDrawing, points_world: np.ndarray) -> np.ndarray:
    """Pixel coordinates (x right, y down), shape (N, 2), of world points (N, 3) in the view.

    meshcat's default camera: vertical field of view ``CAMERA_FOV``, at
    ``drawing.camera_position`` looking at meshcat's origin with z up.
    """
    points = (np.asarray(points_world) - drawing.centre) @ drawing.up_rotation.T
    eye = drawing.camera_position
    forward = -eye / np.linalg.norm(eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    relative = points - eye
    depth = relative @ forward
    scale = np.tan(np.radians(CAMERA_FOV / 2.0))
    x = (relative @ right) / (depth * scale * WIDTH / HEIGHT)
    y = (relative @ up) / (depth * scale)
    return np.column_stack([(x + 1.0) * WIDTH / 2.0, (1.0 - y) * HEIGHT / 2.0])


def near_fraction(mask: np.ndarray, pixels: np.ndarray, radius: int = 6) -> float:
    """Fraction of ``pixels`` (N, 2) that have a ``mask`` pixel within ``radius`` px.

    Pixels outside the image count as misses.
    """
    height, width = mask.shape
    hits = 0
    for x, y in np.round(pixels).astype(int):
        if not (0 <= x < width and 0 <= y < height):
            continue
        window = mask[max(y - radius, 0) : y + radius + 1, max(x - radius, 0) : x + radius + 1]
        hits += bool(window.any())
    return hits / len(pixels)
