"""Moving surfaces and environment shapes as drawn in meshcat (recorded, no server)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from conftest import ROBOTS
from meshcat.animation import Animation

sys.path.append(str(Path(__file__).resolve().parents[1] / "viz"))
from recording_window import recording_viewer

from ucontrol.scene import load_scene
from ucontrol.viz.scene_drawing import SceneDrawing


def _track(animation: Animation, path: str, name: str) -> list[list[float]]:
    for clip_path, clip in animation.clips.items():
        if clip_path.lower() == path:
            return list(clip.tracks[name].values)
    raise KeyError(path)


def test_moving_table_is_drawn_where_it_is() -> None:
    scene = load_scene(ROBOTS / "ball_vibrating_table.toml")
    viewer, _ = recording_viewer()
    drawing = SceneDrawing(scene, viewer)
    animation = Animation()
    times = [0.0, 0.03, 0.07]
    for frame, t in enumerate(times):
        drawing.place(animation.at_frame(viewer, frame), scene.q0, np.zeros(1), None, t)
    positions = np.array(_track(animation, "/meshcat/ucontrol/surfaces/table", "position"))
    motion = scene.contacts[0].surface.motion
    assert motion is not None
    expected = np.array([motion(t)[0] for t in times])  # [m]
    # In the drawing's root node (the scene's world), the table moved by its displacement.
    np.testing.assert_allclose(positions - positions[0], expected - expected[0], rtol=0, atol=1e-12)


def test_environment_shapes_are_drawn() -> None:
    scene = load_scene(ROBOTS / "box_drop_collision.toml")
    viewer, window = recording_viewer()
    SceneDrawing(scene, viewer)
    assert "/meshcat/ucontrol/shapes/ground" in window.objects()
