"""The convergence study: numerical reference, report files, command line and its errors."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene

from ucontrol.analysis.convergence import run_convergence, write_report
from ucontrol.cli import main
from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.scene import Scene, load_scene


def test_without_analytic_reference_the_tightest_event_driven_run_is_the_reference(
    two_link_scene: Scene,
) -> None:
    assert two_link_scene.reference is None
    study = run_convergence(
        two_link_scene,
        duration=0.6,
        integrators=["moreau_jean", "event_driven"],
        dts=(1e-2, 1e-3),
        tolerances=(1e-6,),
        sample_dt=1e-2,
    )
    assert "event_driven (RK45) at rtol = 1e-12" in study.reference
    coarse, fine = (run.error for run in study.of("moreau_jean"))
    assert fine < coarse / 5.0
    assert study.of("event_driven")[0].error <= 1e-9
    assert study.of("event_driven")[0].n_events > 0


def test_report_files(tmp_path: Path) -> None:
    study = run_convergence(
        ball_scene(0.9),
        duration=1.0,
        dts=(1e-2, 1e-3),
        tolerances=(1e-6,),
        stiffnesses=(1e5,),
        sample_dt=1e-2,
    )
    paths = write_report(study, tmp_path / "report")
    with paths["csv"].open() as handle:
        rows = list(csv.DictReader(handle))
    assert [row["integrator"] for row in rows] == [
        "moreau_jean",
        "moreau_jean",
        "event_driven",
        "compliant",
    ]
    assert float(rows[1]["error"]) == pytest.approx(study.runs[1].error, rel=1e-6)
    markdown = paths["markdown"].read_text()
    assert "observed order" in markdown and "moreau_jean at equal error" in markdown
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(study.orders()) == {"moreau_jean"}  # one run each for the others


def test_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = main(
        [
            "convergence",
            str(ROBOTS / "ball.toml"),
            "--out",
            str(tmp_path),
            "--duration",
            "0.6",
            "--integrators",
            "moreau_jean",
            "event_driven",
            "--dts",
            "1e-2",
            "1e-3",
            "--tolerances",
            "1e-8",
            "--sample-dt",
            "1e-2",
        ]
    )
    assert status == 0
    output = capsys.readouterr().out
    assert "BouncingBall" in output and "| moreau_jean | dt |" in output
    for name in ("convergence.csv", "convergence.md", "work_precision.png"):
        assert (tmp_path / name).is_file()


def test_bad_studies_are_typed_errors(two_link_scene: Scene) -> None:
    scene = ball_scene(0.9)
    with pytest.raises(NotFoundError, match="integrator 'rk4'"):
        run_convergence(scene, integrators=["rk4"])
    with pytest.raises(InvalidParameterError, match="`dts`"):
        run_convergence(scene, integrators=["moreau_jean"], dts=())
    with pytest.raises(InvalidParameterError, match="`tolerances`"):
        run_convergence(scene, integrators=["event_driven"], tolerances=(0.0,))
    with pytest.raises(InvalidParameterError, match="divides"):
        run_convergence(two_link_scene, duration=0.1, integrators=["moreau_jean"], dts=(1e-2, 3e-3))
    flipped = ball_scene(0.9)  # a fresh robot model: gravity pointing up
    flipped.robot.model.gravity.linear = np.array([0.0, 0.0, 9.81])
    with pytest.raises(InvalidParameterError, match="gravity pressing"):
        run_convergence(flipped, integrators=["moreau_jean"], dts=(1e-2,))


def test_closed_loop_runs_share_the_control_period() -> None:
    scene = load_scene(ROBOTS / "two_link_one_constraint.toml")  # Brogliato's tracking law
    study = run_convergence(
        scene,
        duration=0.3,
        integrators=["moreau_jean", "event_driven"],
        dts=(1e-3, 2e-4),
        tolerances=(1e-8,),
        control_period=1e-3,
    )
    coarse, fine = (run.error for run in study.of("moreau_jean"))
    assert fine < coarse / 3.0  # the same controlled system at every step: order one
    assert study.of("event_driven")[0].error <= 1e-9
    with pytest.raises(InvalidParameterError, match="divides the control period"):
        run_convergence(
            scene, duration=0.1, integrators=["moreau_jean"], dts=(3e-3,), control_period=1e-3
        )


def test_a_scene_method_of_another_integrator_is_left_to_it() -> None:
    scene = ball_scene(0.9)
    settings = dataclasses.replace(scene.integrator, name="compliant", method="LSODA")
    study = run_convergence(
        dataclasses.replace(scene, integrator=settings),
        duration=0.5,
        dts=(1e-2,),
        tolerances=(1e-6,),
        stiffnesses=(1e5,),
        sample_dt=1e-2,
    )
    assert [run.integrator for run in study.runs] == ["moreau_jean", "event_driven", "compliant"]
    assert study.of("event_driven")[0].error <= 1e-12
