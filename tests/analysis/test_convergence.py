"""The convergence study: numerical reference, report files, command line and its errors."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene

from ucontrol.cli import main
from ucontrol.convergence import run_convergence, write_report
from ucontrol.exceptions import InvalidParameterError, NotFoundError, UnknownKeyError
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


def test_a_settings_variant_is_a_curve_of_its_own(tmp_path: Path) -> None:
    # Moreau–Jean with midpoint = true beside the default one, on the flexible-joint arm.
    study = run_convergence(
        load_scene(ROBOTS / "two_link_flexible_drop.toml"),
        duration=0.1,  # before the first impact
        integrators=["moreau_jean"],
        dts=(2e-4, 1e-4),
        sample_dt=1e-3,
        variants={"moreau_jean midpoint": {"name": "moreau_jean", "midpoint": True}},
    )
    assert study.curves() == ["moreau_jean", "moreau_jean midpoint"]
    default, midpoint = study.of("moreau_jean"), study.of("moreau_jean midpoint")
    assert [run.variant for run in default + midpoint] == ["", "", *["moreau_jean midpoint"] * 2]
    assert all(run.integrator == "moreau_jean" for run in midpoint)
    orders = study.orders()
    assert orders["moreau_jean"] == pytest.approx(1.0, abs=0.15)  # measured 0.97
    assert orders["moreau_jean midpoint"] == pytest.approx(2.0, abs=0.1)  # measured 2.00
    paths = write_report(study, tmp_path)
    with paths["csv"].open() as handle:
        rows = list(csv.DictReader(handle))
    assert [row["variant"] for row in rows] == ["", "", *["moreau_jean midpoint"] * 2]
    assert "| moreau_jean midpoint | dt |" in paths["markdown"].read_text()


def test_bad_variants_are_typed_errors() -> None:
    scene = ball_scene(0.9)

    def study(variants):
        return run_convergence(scene, integrators=["moreau_jean"], dts=(1e-2,), variants=variants)

    with pytest.raises(UnknownKeyError, match="midpiont"):
        study({"mid": {"name": "moreau_jean", "midpiont": True}})
    with pytest.raises(InvalidParameterError, match="name"):
        study({"mid": {"midpoint": True}})
    with pytest.raises(NotFoundError, match="integrator 'rk4'"):
        study({"mid": {"name": "rk4"}})
    with pytest.raises(InvalidParameterError, match="variant label"):
        study({"moreau_jean": {"name": "moreau_jean", "theta": 1.0}})
    with pytest.raises(InvalidParameterError, match="the sweep sets"):
        study({"coarse": {"name": "moreau_jean", "dt": 1e-2}})
    with pytest.raises(InvalidParameterError, match="theta"):
        study({"implicit": {"name": "moreau_jean", "theta": 2.0}})
