"""Figures of saved runs: ``ucontrol plot`` and :func:`ucontrol.viz.run_figures.run_figures`."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest
from PIL import Image

from ucontrol.cli import main
from ucontrol.exceptions import InvalidParameterError
from ucontrol.saved_run import SavedRun
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.viz.run_figures import run_figures

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
PLAIN = ["q.png", "gaps.png", "forces.png", "energy.png"]


@pytest.fixture(scope="module")
def tracking_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """6 s of the one-constraint cycle: free motion, approach, impacts, sliding."""
    out = tmp_path_factory.mktemp("tracking")
    simulate(load_scene(ROBOTS / "two_link_one_constraint.toml"), duration=6.0, out=out)
    return out


def _sizes(paths: list[Path]) -> dict[str, tuple[int, int]]:
    sizes = {}
    for path in paths:
        with Image.open(path) as image:
            assert image.format == "PNG"
            sizes[path.name] = image.size
    return sizes


def test_plain_run_gets_configuration_gaps_forces_and_energy(tmp_path: Path) -> None:
    run = tmp_path / "drop"
    simulate(load_scene(ROBOTS / "two_link_drop.toml"), duration=1.0, out=run)
    assert main(["plot", str(run)]) == 0
    sizes = _sizes(sorted((run / "figures").iterdir()))
    assert sorted(sizes) == sorted(PLAIN)
    # One panel per constraint (2 contacts + 4 stop bounds) in the gap figure.
    assert sizes["gaps.png"][1] > 2 * sizes["energy.png"][1]


@pytest.mark.slow
def test_phase_machine_run_adds_tracking_lyapunov_and_cycle_figures(
    tracking_run: Path, tmp_path: Path
) -> None:
    run = SavedRun.load(tracking_run)
    assert run.scene is not None  # recorded by simulate
    paths = run_figures(run.log, tmp_path, scene=run.scene)
    expected = [*PLAIN, "tracking.png", "cycle_path.png", "cycle_time.png"]
    assert [path.name for path in paths] == expected
    assert all(size[0] > 500 for size in _sizes(paths).values())


@pytest.mark.slow
def test_without_the_scene_the_logged_fields_still_give_the_tracking_figure(
    tracking_run: Path, tmp_path: Path
) -> None:
    log = SavedRun.load(tracking_run).log
    names = [path.name for path in run_figures(log, tmp_path)]
    assert names == [*PLAIN, "tracking.png"]


def test_a_scene_with_another_task_is_refused(tracking_run: Path, tmp_path: Path) -> None:
    log = SavedRun.load(tracking_run).log
    scene = load_scene(ROBOTS / "two_link_one_constraint.toml")
    gap_only = dataclasses.replace(scene, controller={**scene.controller, "tangents": []})
    with pytest.raises(InvalidParameterError, match="the run's 2 task coordinates"):
        run_figures(log, tmp_path, scene=gap_only)  # X = (y) instead of (y, x)


def test_plot_without_matplotlib_names_the_extra(
    tracking_run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in [m for m in sys.modules if m.startswith(("ucontrol.viz", "matplotlib"))]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib fails
    assert main(["plot", str(tracking_run)]) == 2
    assert "pip install 'ucontrol[viz]'" in capsys.readouterr().err  # OptionalDependencyError
