"""Mesh environment shapes drawn from their files, moving shapes drawn where they are.

No browser: the meshcat commands a drawing sends are recorded (``tests/viz/recording_window``)
and checked against the scene: the mesh's geometry is the file's content, placed with the
shape's placement and scale; a moving shape's animation track is its displacement x(t).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
from conftest import ROBOTS
from meshcat.animation import Animation

sys.path.append(str(Path(__file__).resolve().parents[1] / "viz"))
from recording_window import recording_viewer

from ucontrol.contact.surface_motion import Sinusoid
from ucontrol.scene import load_scene
from ucontrol.viz.scene_drawing import ROOT, SceneDrawing


def _transforms(window, path: str) -> list[np.ndarray]:
    """Every transform set on ``path``, as (4, 4) matrices."""
    return [
        np.array(c["matrix"], dtype=float).reshape(4, 4).T  # column-major in meshcat
        for c in window.commands
        if c["type"] == "set_transform" and c["path"] == path
    ]


def _track(animation: Animation, path: str, name: str) -> np.ndarray:
    for clip_path, clip in animation.clips.items():
        if clip_path.lower() == path.lower():
            return np.array(clip.tracks[name].values, dtype=float)
    raise KeyError(path)


def _wedge_scene(scale: list[float], rpy: list[float], file: str = "meshes/wedge.obj"):
    scene = load_scene(ROBOTS / "ball_mesh_wedge.toml")
    pairs = []
    for pair in scene.collision_pairs:
        other = pair.other
        if not isinstance(other, str) and other.type == "mesh":
            other = dataclasses.replace(
                other,
                mesh=ROBOTS / file,
                scale=np.array(scale),
                rpy=np.array(rpy),
                position=np.array([0.1, -0.2, 0.05]),
            )
        pairs.append(dataclasses.replace(pair, other=other))
    return dataclasses.replace(scene, collision_pairs=tuple(pairs))


def test_mesh_shape_is_drawn_from_its_file_with_placement_and_scale() -> None:
    scale, rpy = [1.5, 0.5, 2.0], [0.1, -0.2, 0.3]
    scene = _wedge_scene(scale, rpy)
    viewer, window = recording_viewer()
    SceneDrawing(scene, viewer)
    path = f"/meshcat/{ROOT}/shapes/wedge"
    drawn = window.objects()[path]
    geometry = drawn["geometries"][0]
    assert geometry["format"] == "obj"
    assert geometry["data"] == (ROBOTS / "meshes" / "wedge.obj").read_text()
    pose = _transforms(window, path)[-1]
    rotation = pin.rpy.rpyToMatrix(*rpy)
    # The node's transform: rotation times the scale of each column, the shape's position.
    np.testing.assert_allclose(pose[:3, :3], rotation * np.array(scale), rtol=0, atol=1e-15)
    np.testing.assert_allclose(pose[:3, 3], [0.1, -0.2, 0.05], rtol=0, atol=1e-15)


def test_other_mesh_formats_are_drawn_as_their_scaled_hull(tmp_path: Path) -> None:
    # A unit cube written as PLY (coal reads it, meshcat has no PLY loader).
    corners = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    faces = [
        (0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)
    ]  # fmt: skip
    lines = ["ply", "format ascii 1.0", "element vertex 8", "property float x"]
    lines += ["property float y", "property float z", "element face 6"]
    lines += ["property list uchar int vertex_indices", "end_header"]
    lines += [" ".join(str(c) for c in corner) for corner in corners]
    lines += ["4 " + " ".join(str(i) for i in face) for face in faces]
    (tmp_path / "cube.ply").write_text("\n".join(lines) + "\n", encoding="utf-8")
    scene = _wedge_scene([2.0, 1.0, 0.5], [0.0, 0.0, 0.0], file=str(tmp_path / "cube.ply"))
    viewer, window = recording_viewer()
    SceneDrawing(scene, viewer)
    path = f"/meshcat/{ROOT}/shapes/wedge"
    geometry = window.objects()[path]["geometries"][0]
    packed = geometry["data"]["attributes"]["position"]["array"]  # a msgpack Float32Array
    vertices = np.frombuffer(packed.data, dtype=np.float32).reshape(-1, 3).astype(float)
    # The hull's vertices are the scaled cube's corners; the node is not scaled again.
    expected = np.array(corners, dtype=float) * [2.0, 1.0, 0.5]
    assert sorted(map(tuple, vertices.round(6))) == sorted(map(tuple, expected))  # float32
    pose = _transforms(window, path)[-1]
    np.testing.assert_allclose(pose[:3, :3], np.eye(3), rtol=0, atol=1e-15)


def test_moving_shapes_are_drawn_where_they_are() -> None:
    scene = load_scene(ROBOTS / "ball_vibrating_box.toml")
    motion = Sinusoid(amplitude=np.array([0.02, -0.01, 0.03]), frequency=9.0, phase=0.4)
    scale = [0.5, 2.0, 1.0]
    wedge = _wedge_scene(scale, [0.2, 0.0, 0.1])
    pairs = [
        dataclasses.replace(pair, other=dataclasses.replace(pair.other, motion=motion))
        for pair in wedge.collision_pairs
        if not isinstance(pair.other, str) and pair.other.type == "mesh"
    ]
    for case, shape_name in (
        (scene, "table"),
        (dataclasses.replace(wedge, collision_pairs=tuple(pairs)), "wedge"),
    ):
        viewer, _ = recording_viewer()
        drawing = SceneDrawing(case, viewer)
        animation = Animation()
        times = [0.0, 0.03, 0.07]
        for frame, t in enumerate(times):
            drawing.place(animation.at_frame(viewer, frame), case.q0, np.zeros(0), None, t)
        path = f"/meshcat/{ROOT}/shapes/{shape_name}"
        positions = _track(animation, path, "position").reshape(-1, 3)
        shape = next(p.other for p in case.collision_pairs if not isinstance(p.other, str))
        assert shape.motion is not None
        expected = np.array([shape.motion(t)[0] for t in times]) + shape.position  # [m]
        np.testing.assert_allclose(positions, expected, rtol=0, atol=1e-15)
        if shape_name == "wedge":
            scales = _track(animation, path, "scale").reshape(-1, 3)
            np.testing.assert_allclose(scales, np.tile(scale, (3, 1)), rtol=0, atol=0)
