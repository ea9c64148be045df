"""Run figures: joint names from the URDF, legends beside the curves, clipping stated honestly."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene
from matplotlib.backends.backend_agg import FigureCanvasAgg

from ucontrol.analysis.impacts import impact_mask
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.viz.figure_notes import clip_note
from ucontrol.viz.run_figures import coordinate_names, run_figure_set

_NUMBER = r"[-+]?\d+(?:\.\d+)?(?:e[-+]\d+)?"


def _moving_joints(urdf: str) -> list[str]:
    """Names of the URDF's joints that move, read from the XML (not through Pinocchio)."""
    root = ET.parse(ROBOTS / urdf).getroot()
    return [joint.attrib["name"] for joint in root.iter("joint") if joint.get("type") != "fixed"]


@pytest.fixture(scope="module")
def resting_ball():
    """A ball with e = 0.5 that bounces, then rests on the ground: impacts and a carried force."""
    scene = ball_scene(0.5)
    return simulate(scene, duration=3.0, dt=1e-3).log


def test_joint_names_come_from_the_urdf(two_link_scene) -> None:
    model = two_link_scene.robot.model
    q_names, v_names = coordinate_names(model, model.nq, model.nv)
    assert q_names == v_names == _moving_joints("two_link.urdf")
    log = simulate(two_link_scene, duration=0.05, dt=1e-3).log
    figure = run_figure_set(log, scene=two_link_scene)["q"]
    for ax in figure.axes[:2]:
        legend = ax.get_legend()
        assert legend is not None
        labels = [text.get_text() for text in legend.get_texts()]
        assert labels == _moving_joints("two_link.urdf")


def test_free_flyer_coordinates_are_named_per_axis() -> None:
    scene = load_scene(ROBOTS / "free_ball.toml")
    model = scene.robot.model
    q_names, v_names = coordinate_names(model, model.nq, model.nv)
    (joint,) = _moving_joints("free_ball.urdf") or ["root_joint"]
    assert len(q_names) == 7 and len(v_names) == 6
    assert q_names[:3] == [f"{joint}.{axis}" for axis in "xyz"]
    assert q_names[6] == f"{joint}.qw"  # Pinocchio's quaternion is (x, y, z, w)
    assert v_names[3:] == [f"{joint}.w{axis}" for axis in "xyz"]


def test_without_a_scene_the_coordinates_are_numbered() -> None:
    assert coordinate_names(None, 3, 2) == (["q[0]", "q[1]", "q[2]"], ["v[0]", "v[1]"])


def test_legends_lie_beside_the_axes(resting_ball) -> None:
    figures = run_figure_set(resting_ball)
    for name, figure in figures.items():
        canvas = FigureCanvasAgg(figure)
        canvas.draw()
        renderer = canvas.get_renderer()
        for ax in figure.axes:
            legend = ax.get_legend()
            if legend is None:
                continue
            box = legend.get_window_extent(renderer)
            axes_box = ax.get_window_extent(renderer)
            assert box.x0 >= axes_box.x1, (name, box, axes_box)  # right of the plotting area
            assert box.x1 <= figure.bbox.x1 + 1.0, name  # and inside the figure


def test_clipped_impacts_are_stated_with_their_range(resting_ball) -> None:
    log = resting_ball
    dt = float(log.metadata["dt"])
    force = log.impulse[:-1, 0] / dt  # [N]
    impacts = impact_mask(log)[:-1, 0]
    weight = 1.0 * 9.81  # [N] the 1 kg ball at rest
    assert np.median(force[(force > 0) & ~impacts]) == pytest.approx(weight, rel=1e-6)
    (ax,) = run_figure_set(log)["forces"].axes
    _, high = ax.get_ylim()
    assert high < force.max()  # the impact peaks do not set the scale ...
    assert high >= weight  # ... the force carried at rest does
    notes = [text.get_text() for text in ax.texts if "clipped" in text.get_text()]
    assert len(notes) == 1
    above = force[force > high]
    match = re.match(
        rf"(\d+) samples? above the axis clipped: ({_NUMBER}) to ({_NUMBER}) N", notes[0]
    )
    assert match is not None, notes[0]
    count, first, last = match.groups()
    assert int(count) == above.size
    assert float(first) == pytest.approx(above.min(), rel=5e-3)
    assert float(last) == pytest.approx(above.max(), rel=5e-3)


def test_clip_note_of_values_within_the_axis_is_none() -> None:
    rng = np.random.default_rng(5)
    values = rng.uniform(-1.0, 1.0, 100)
    assert clip_note(values, -1.0, 1.0, "N") is None
    note = clip_note(np.append(values, [-3.0, 2.5]), -1.0, 1.0, "N")
    assert note == "1 sample above the axis clipped: 2.5 N; 1 sample below the axis clipped: -3 N"
