"""What a scene drawing sends to meshcat: framing, shapes, arrows and labels."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from meshcat.animation import Animation
from recording_window import recording_viewer

from ucontrol.control.phase import Phase
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import load_scene
from ucontrol.viz.scene_drawing import CAMERA_FOV, MAX_ARROW, WEIGHT_ARROW, SceneDrawing

ROBOTS = Path(__file__).resolve().parents[2] / "robots"

#: A two-link arm without any visual geometry, its tip touching nothing yet.
BARE_URDF = """<?xml version="1.0"?>
<robot name="bare">
  <link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0"
    izz="1"/></inertial></link>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <link name="b"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0"
    izz="1"/></inertial></link>
  <joint name="tip_joint" type="fixed"><parent link="b"/><child link="tip"/>
    <origin xyz="0.3 0 0"/></joint>
  <link name="tip"/>
</robot>
"""
BARE_SCENE = """
[robot]
urdf = "bare.urdf"
q0 = [-0.3, 0.5]
[[contacts]]
frame = "tip"
surface = {point = [0.0, 0.0, -1.0], normal = [0.0, 0.0, 1.0]}
radius = 0.05
"""


def _frame_points(model: pin.Model, q: np.ndarray) -> np.ndarray:
    data = pin.Data(model)
    pin.framesForwardKinematics(model, data, q)
    return np.array([data.oMf[f].translation for f in range(1, model.nframes)])


def _track(animation: Animation, path: str, name: str) -> list[list[float]]:
    """The values of the track ``name`` of the clip of node ``path`` (meshcat path)."""
    for clip_path, clip in animation.clips.items():
        if clip_path.lower() == path:
            return list(clip.tracks[name].values)
    raise KeyError(path)


def test_view_frames_every_configuration_and_turns_up_to_meshcat_z() -> None:
    scene = load_scene(ROBOTS / "two_link_drop.toml")
    rng = np.random.default_rng(7)
    configurations = np.column_stack([rng.uniform(0, np.pi, 50), rng.uniform(-np.pi, 0, 50)])
    viewer, window = recording_viewer()
    drawing = SceneDrawing(scene, viewer, configurations=configurations)
    np.testing.assert_allclose(drawing.up_rotation @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-12)
    for q in configurations:
        distance = np.linalg.norm(_frame_points(scene.robot.model, q) - drawing.centre, axis=1)
        assert distance.max() <= drawing.radius
    half_fov = np.radians(CAMERA_FOV / 2.0)
    assert np.linalg.norm(drawing.camera_position) * np.sin(half_fov) >= drawing.radius
    # The arm moves in the world's xy-plane: the camera looks along the plane's normal.
    normal = drawing.up_rotation @ [0.0, 0.0, 1.0]
    direction = drawing.camera_position / np.linalg.norm(drawing.camera_position)
    assert abs(direction @ normal) > 0.95
    assert window.properties("/Grid") == {"visible": False}  # the surfaces are drawn instead
    position = window.properties("/Cameras/default/rotated/<object>")["position"]
    x, y, z = drawing.camera_position
    np.testing.assert_allclose(position, [x, z, -y])  # three.js is y-up


def test_bodies_without_visual_geometry_get_simple_shapes(tmp_path: Path) -> None:
    (tmp_path / "bare.urdf").write_text(BARE_URDF)
    (tmp_path / "bare.toml").write_text(BARE_SCENE)
    scene = load_scene(tmp_path / "bare.toml")
    viewer, window = recording_viewer()
    SceneDrawing(scene, viewer)
    objects = window.objects()
    prefix = "/meshcat/ucontrol/robot/visuals/"

    def geometry(name: str) -> dict[str, float]:
        return objects[prefix + name]["geometries"][0]

    assert geometry("skeleton_1")["type"] == "SphereGeometry"  # a ball at each joint
    assert geometry("skeleton_2")["type"] == "SphereGeometry"
    assert geometry("skeleton_1_0")["height"] == pytest.approx(0.4)  # j1 -> j2
    assert geometry("skeleton_2_0")["height"] == pytest.approx(0.3)  # j2 -> tip frame
    assert geometry("contact_0")["radius"] == pytest.approx(0.05)  # the contact sphere
    assert "/meshcat/ucontrol/surfaces/plane" in objects


def test_arrow_length_is_proportional_to_the_contact_force() -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    viewer, _ = recording_viewer()
    drawing = SceneDrawing(scene, viewer)
    weight = 1.0 * 9.81  # [N], the 1 kg ball
    assert drawing.force_scale * weight == pytest.approx(WEIGHT_ARROW * drawing.radius)
    animation = Animation()
    cap = MAX_ARROW * drawing.radius / drawing.force_scale  # [N]
    forces = [0.0, weight, 1.5 * weight, 10.0 * cap]
    for frame, force in enumerate(forces):
        drawing.place(animation.at_frame(viewer, frame), scene.q0, np.array([force]))
    shaft = _track(animation, "/meshcat/ucontrol/contacts/0/arrow", "scale")
    head = _track(animation, "/meshcat/ucontrol/contacts/0/head", "scale")
    lengths = [scale[1] for scale in shaft]
    assert lengths[0] < 1e-5 and head[0][1] < 1e-5  # no force, no arrow
    assert lengths[1] == pytest.approx(drawing.force_scale * weight)
    assert lengths[2] == pytest.approx(1.5 * lengths[1])
    assert lengths[3] == pytest.approx(MAX_ARROW * drawing.radius)  # impacts: capped
    tips = _track(animation, "/meshcat/ucontrol/contacts/0/head", "position")
    bottom = scene.q0[0] - 0.1  # [m] the contact point, on the ball's surface
    np.testing.assert_allclose([tip[2] - bottom for tip in tips[1:3]], lengths[1:3])


def test_only_the_current_phase_label_is_shown() -> None:
    scene = load_scene(ROBOTS / "two_link_one_constraint.toml")
    viewer, _ = recording_viewer()
    drawing = SceneDrawing(scene, viewer, phases=True)
    animation = Animation()
    for frame, phase in enumerate(Phase):
        drawing.place(animation.at_frame(viewer, frame), scene.q0, np.zeros(1), phase)
    for phase in Phase:
        scales = _track(animation, f"/meshcat/ucontrol/phase/{phase.name.lower()}", "scale")
        shown = [frame for frame, scale in enumerate(scales) if scale[0] == 1.0]
        assert shown == [int(phase)]


def test_bad_arguments_raise_typed_errors() -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    viewer, _ = recording_viewer()
    with pytest.raises(InvalidParameterError, match="configurations"):
        SceneDrawing(scene, viewer, configurations=np.zeros((3, 2)))
    with pytest.raises(InvalidParameterError, match="force_scale"):
        SceneDrawing(scene, viewer, force_scale=-1.0)
