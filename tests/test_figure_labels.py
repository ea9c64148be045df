"""Run and study figures: names and units from the URDF, legends and labels placed clear.

Also: clipping stated honestly, impact lines that stand out on every phase band, empty cells
of a success map apart from the colour scale.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb

from ucontrol.analysis.coordinates import coordinate_names, coordinate_units
from ucontrol.analysis.impacts import impact_mask
from ucontrol.convergence import ConvergenceRun, ConvergenceStudy, work_precision_figure
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.viz.figure_notes import clip_note
from ucontrol.viz.phase_colours import PHASE_COLOURS
from ucontrol.viz.run_figures import IMPACT_LINE_COLOUR, run_figure_set

_NUMBER = r"[-+]?\d+(?:\.\d+)?(?:e[-+]\d+)?"


def _moving_joints(urdf: str) -> list[str]:
    """Names of the URDF's joints that move, read from the XML (not through Pinocchio)."""
    return list(_joint_units(ROBOTS / urdf))


def _joint_units(urdf) -> dict[str, str]:
    """Unit of each moving joint of a URDF from its XML type: revolute rad, prismatic m."""
    root = ET.parse(urdf).getroot()
    units = {"revolute": "rad", "continuous": "rad", "prismatic": "m"}
    return {
        joint.attrib["name"]: units[joint.attrib["type"]]
        for joint in root.iter("joint")
        if joint.get("type") != "fixed"
    }


def _legend_labels(ax) -> list[str]:
    legend = ax.get_legend()
    assert legend is not None
    return [text.get_text() for text in legend.get_texts()]


def _relative_luminance(colour) -> float:
    """WCAG 2 relative luminance of an sRGB colour."""
    linear = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in to_rgb(colour)]
    return 0.2126 * linear[0] + 0.7152 * linear[1] + 0.0722 * linear[2]


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
    for ax in figure.axes[:2]:  # revolute joints only: one axis for q, one for v
        assert _legend_labels(ax) == _moving_joints("two_link.urdf")
    assert [ax.get_ylabel() for ax in figure.axes] == ["q [rad]", "v [rad/s]"]


def test_angles_and_lengths_never_share_an_axis() -> None:
    """The Panda's fingers (prismatic, m) get their own axes, apart from the arm's angles."""
    scene = load_scene(ROBOTS / "panda_table.toml")
    units = _joint_units(scene.robot.urdf_path)
    assert set(units.values()) == {"rad", "m"}  # the reference: the URDF's joint types
    log = simulate(scene, duration=0.02).log
    figure = run_figure_set(log, scene=scene)["q"]
    panels = {ax.get_ylabel(): _legend_labels(ax) for ax in figure.axes if ax.get_legend()}
    assert set(panels) == {"q [rad]", "q [m]", "v [rad/s]", "v [m/s]"}
    for label, joints in panels.items():
        unit = label.split("[")[1].removesuffix("]").removesuffix("/s")
        assert {units[joint] for joint in joints} == {unit}, label
    assert sorted(panels["q [rad]"] + panels["q [m]"]) == sorted(units)


def test_constraint_panels_carry_their_units(two_link_scene) -> None:
    """Contacts in [m] and [N]; stops of revolute joints in [rad] and [N m]."""
    units = _joint_units(ROBOTS / "two_link.urdf")
    log = simulate(two_link_scene, duration=0.3, dt=1e-3).log
    figures = run_figure_set(log, scene=two_link_scene)
    expected = {}
    for name in log.constraint_names:
        joint, side = name.split("/")
        stop = side in ("lower", "upper") and joint in units
        expected[name] = ("rad", "N m") if stop and units[joint] == "rad" else ("m", "N")
    assert any(gap == "rad" for gap, _ in expected.values())
    gaps = [ax.get_ylabel() for ax in figures["gaps"].axes]
    assert gaps == [f"{name}\n[{expected[name][0]}]" for name in log.constraint_names]
    for ax in figures["forces"].axes:
        name, unit = ax.get_ylabel().split("\n")
        assert unit == f"[{expected[name][1]}]"
    # Without the scene, a stop's unit is stated as unknown between the two.
    plain = run_figure_set(log)["gaps"]
    assert [ax.get_ylabel().split("\n")[1] for ax in plain.axes] == [
        "[rad or m]" if expected[name][0] == "rad" else "[m]" for name in log.constraint_names
    ]


def test_free_flyer_coordinates_are_named_per_axis() -> None:
    scene = load_scene(ROBOTS / "free_ball.toml")
    model = scene.robot.model
    q_names, v_names = coordinate_names(model, model.nq, model.nv)
    q_units, v_units = coordinate_units(model, model.nq, model.nv)
    assert q_units == ["m"] * 3 + ["1"] * 4  # position, then the unit quaternion
    assert v_units == ["m/s"] * 3 + ["rad/s"] * 3
    (joint,) = _moving_joints("free_ball.urdf") or ["root_joint"]
    assert len(q_names) == 7 and len(v_names) == 6
    assert q_names[:3] == [f"{joint}.{axis}" for axis in "xyz"]
    assert q_names[6] == f"{joint}.qw"  # Pinocchio's quaternion is (x, y, z, w)
    assert v_names[3:] == [f"{joint}.w{axis}" for axis in "xyz"]


def test_without_a_scene_the_coordinates_are_numbered() -> None:
    assert coordinate_names(None, 3, 2) == (["q[0]", "q[1]", "q[2]"], ["v[0]", "v[1]"])
    assert coordinate_units(None, 2, 1) == (["?", "?"], ["?"])


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


def test_impacts_alone_scale_the_axis_by_their_mean_and_clip_the_peaks() -> None:
    """The e = 0.9 ball only takes impacts: its 20 ms mean sets the scale, not the kN peaks."""
    log = simulate(ball_scene(0.9), duration=3.0, dt=1e-3).log
    dt = float(log.metadata["dt"])
    force = log.impulse[:-1, 0] / dt  # [N]
    impacts = impact_mask(log)[:-1, 0]
    assert np.all(force[~impacts] == 0.0) and impacts.sum() >= 3
    (ax,) = run_figure_set(log)["forces"].axes
    _, high = ax.get_ylim()
    mean = ax.get_lines()[1].get_ydata()  # the moving mean, drawn second
    assert np.max(mean) <= high < 0.2 * np.min(force[impacts])  # the mean in view, peaks not
    (note,) = [text.get_text() for text in ax.texts if "clipped" in text.get_text()]
    assert note.startswith(f"{impacts.sum()} samples above the axis clipped")


def test_impact_lines_stand_out_on_every_phase_band() -> None:
    """WCAG contrast of the dashed impact lines against each band colour at least 4.5:1."""
    scene = load_scene(ROBOTS / "panda_table.toml")
    log = simulate(scene, duration=2.0).log
    assert impact_mask(log).any()
    (ax,) = run_figure_set(log, scene=scene)["energy"].axes
    assert "impact" in _legend_labels(ax)
    line = _relative_luminance(IMPACT_LINE_COLOUR)
    for colour in PHASE_COLOURS.values():
        band = _relative_luminance(colour)
        assert (max(band, line) + 0.05) / (min(band, line) + 0.05) >= 4.5, colour
    drawn = [l for l in ax.get_lines() if l.get_linestyle() == "--"]
    assert drawn and all(l.get_color() == IMPACT_LINE_COLOUR for l in drawn)


def test_empty_cells_of_the_success_map_are_hatched_grey_with_a_legend_entry(rng) -> None:
    import pandas as pd
    from matplotlib.colors import to_rgba

    from ucontrol.campaign.figures import EMPTY_CELL, success_map_figure

    a, b = rng.choice([0.1, 0.2, 0.3], 60), rng.choice([1.0, 2.0, 3.0, 4.0], 60)
    keep = ~((a == 0.2) & (b == 3.0)) & ~((a == 0.3) & (b == 1.0))  # two cells left empty
    frame = pd.DataFrame(
        {"a": a[keep], "b": b[keep], "success": rng.uniform(size=keep.sum()) < 0.5}
    )
    figure = success_map_figure(frame, "a", "b", "test")
    ax = figure.axes[0]
    hatched = sorted(
        (round(p.get_x() + 0.5), round(p.get_y() + 0.5)) for p in ax.patches if p.get_hatch()
    )
    assert hatched == [(1, 2), (2, 0)]  # (column of a, row of b) of the empty cells
    (image,) = ax.get_images()
    cells = np.ma.masked_invalid(image.get_array())
    assert sorted(zip(*np.nonzero(cells.mask), strict=True)) == [(0, 2), (2, 1)]  # (row, col)
    # Grey is no colour of the rate's scale: far from every colour the map gives a rate.
    grey = np.array(to_rgba(EMPTY_CELL["facecolor"])[:3])
    scale = image.get_cmap()(np.linspace(0.0, 1.0, 256))[:, :3]
    assert np.min(np.linalg.norm(scale - grey, axis=1)) > 0.15
    (legend,) = figure.legends
    assert [text.get_text() for text in legend.get_texts()] == ["no runs in the cell"]


def _published_study(case: str) -> ConvergenceStudy:
    """A convergence study read back from the CSV table docs/figures/<case>.csv."""
    import csv

    path = ROBOTS.parent / "docs" / "figures" / f"{case}.csv"
    with path.open() as table:
        runs = tuple(
            ConvergenceRun(
                integrator=row["integrator"],
                parameter=row["parameter"],
                value=float(row["value"]),
                dt=float(row["dt_s"]),
                error=float(row["error"]),
                wall_time_s=float(row["wall_time_s"]),
                steps=int(row["steps"]),
                n_events=int(row["n_events"]),
                variant=row.get("variant") or "",
            )
            for row in csv.DictReader(table)
        )
    return ConvergenceStudy(
        scene=case, duration=3.0, reference="published", error_unit="rad", runs=runs
    )


@pytest.mark.parametrize("case", ["two_link_drop", "ball_e09", "two_link_flexible_drop"])
def test_work_precision_labels_never_overlap(case: str) -> None:
    figure = work_precision_figure(_published_study(case))
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    (ax,) = figure.axes
    assert ax.get_ylabel() == "error [rad]"
    boxes = [text.get_window_extent(renderer) for text in ax.texts]
    assert len(boxes) >= 0.5 * len(_published_study(case).runs)  # most points labelled
    axes_box = ax.get_window_extent(renderer)
    for i, box in enumerate(boxes):
        assert axes_box.x0 <= box.x0 and box.x1 <= axes_box.x1
        assert axes_box.y0 <= box.y0 and box.y1 <= axes_box.y1
        assert not any(box.overlaps(other) for other in boxes[:i]), ax.texts[i].get_text()
    (legend,) = figure.legends
    assert legend.get_window_extent(renderer).y1 <= axes_box.y0  # below the axes
    # Each label in its curve's colour, at one of its curve's points.
    lines = {line.get_color(): line for line in ax.get_lines()}
    for text in ax.texts:
        line = lines[text.get_color()]
        assert tuple(text.xy) in set(zip(line.get_xdata(), line.get_ydata(), strict=True))


def test_a_configuration_error_over_lengths_and_angles_says_both(two_link_scene) -> None:
    from ucontrol.convergence import run_convergence

    scene = load_scene(ROBOTS / "rocking_block.toml")  # x, z prismatic; pitch revolute
    study = run_convergence(
        scene, duration=0.02, integrators=["moreau_jean"], dts=[1e-3], sample_dt=1e-3
    )
    assert study.error_unit == "m or rad"
    assert "[m or rad]" in study.reference
    arm = run_convergence(
        two_link_scene, duration=0.02, integrators=["moreau_jean"], dts=[1e-3], sample_dt=1e-3
    )
    assert arm.error_unit == "rad"
