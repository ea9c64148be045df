"""Scene `[integrator]` and `[reference]` tables for the event-driven and compliant integrators."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from conftest import ROBOTS

from ucontrol.cli import main
from ucontrol.convergence import run_convergence
from ucontrol.exceptions import InvalidParameterError, NotFoundError, SceneError, UnknownKeyError
from ucontrol.integrators import Compliant, EventDriven, MoreauJean
from ucontrol.scene import IntegratorSettings, Scene, load_scene

BALL_TOML = (ROBOTS / "ball.toml").read_text()
INTEGRATOR_TABLE = '[integrator]\nname = "moreau_jean"\ndt = 1e-3\ntheta = 0.5\n'


def _scene(tmp_path: Path, integrator: str = INTEGRATOR_TABLE, reference: str = "") -> Scene:
    text = BALL_TOML.replace(INTEGRATOR_TABLE, integrator)
    text = text[: text.index("[reference]")] + reference if reference else text
    (tmp_path / "ball.urdf").write_text((ROBOTS / "ball.urdf").read_text())
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return load_scene(path)


def test_each_integrator_is_built_with_its_settings(tmp_path: Path) -> None:
    event_driven = _scene(
        tmp_path,
        '[integrator]\nname = "event_driven"\ndt = 1e-2\n'
        'rtol = 1e-7\natol = 1e-9\nmethod = "RK45"\nzeno_velocity = 1e-4\n',
    )
    integrator = event_driven.build_integrator()
    assert isinstance(integrator, EventDriven)
    assert (integrator.dt, integrator.rtol, integrator.atol) == (1e-2, 1e-7, 1e-9)
    assert (integrator.method, integrator.zeno_velocity) == ("RK45", 1e-4)
    compliant = _scene(
        tmp_path,
        '[integrator]\nname = "compliant"\nstiffness = 1e7\n'
        'contact_model = "hunt_crossley"\nmethod = "LSODA"\n',
    )
    integrator = compliant.build_integrator(dt=5e-3)
    assert isinstance(integrator, Compliant)
    assert (integrator.dt, integrator.stiffness) == (5e-3, 1e7)
    assert (integrator.contact_model, integrator.method) == ("hunt_crossley", "LSODA")
    assert (integrator.rtol, integrator.atol) == (1e-8, 1e-10)  # the integrator's defaults
    assert isinstance(_scene(tmp_path).build_integrator(), MoreauJean)


def test_settings_of_other_integrators_are_checked_and_ignored() -> None:
    settings = IntegratorSettings(name="moreau_jean", stiffness=1e5, method="Radau")
    scene = dataclasses.replace(load_scene(ROBOTS / "ball.toml"), integrator=settings)
    assert isinstance(scene.build_integrator(), MoreauJean)
    with pytest.raises(InvalidParameterError, match="`stiffness`"):
        IntegratorSettings(name="moreau_jean", stiffness=-1.0)


def test_bad_integrator_settings(tmp_path: Path) -> None:
    with pytest.raises(UnknownKeyError, match=r"'stifness'.*\[integrator\]"):
        _scene(tmp_path, '[integrator]\nname = "compliant"\nstifness = 1e6\n')
    with pytest.raises(InvalidParameterError, match=r"`method` must be one of \['DOP853'"):
        _scene(tmp_path, '[integrator]\nname = "event_driven"\nmethod = "Radau"\n')
    with pytest.raises(InvalidParameterError, match="`method`"):
        IntegratorSettings(method="Euler")
    with pytest.raises(InvalidParameterError, match="`contact_model`"):
        _scene(tmp_path, '[integrator]\nname = "compliant"\ncontact_model = "hertz"\n')
    for key in ("rtol", "atol", "zeno_velocity", "stiffness"):
        with pytest.raises(InvalidParameterError, match=f"`{key}` must be > 0"):
            IntegratorSettings(**{key: 0.0})


def test_reference_table(tmp_path: Path) -> None:
    scene = _scene(tmp_path, reference='[reference]\ntype = "bouncing_ball"\n')
    assert scene.reference == {"type": "bouncing_ball", "contact": "ball/ground"}
    assert load_scene(ROBOTS / "table_drop.toml").reference["contact"] == "foot_fl/ground"
    with pytest.raises(NotFoundError, match=r"reference type 'pendulum'.*bouncing_ball"):
        _scene(tmp_path, reference='[reference]\ntype = "pendulum"\n')
    with pytest.raises(UnknownKeyError, match=r"'height'.*\[reference\]"):
        _scene(tmp_path, reference='[reference]\ntype = "bouncing_ball"\nheight = 1.0\n')
    with pytest.raises(NotFoundError, match=r"contact 'wall'.*ball/ground"):
        _scene(tmp_path, reference='[reference]\ntype = "bouncing_ball"\ncontact = "wall"\n')
    with pytest.raises(SceneError, match="needs the key 'type'"):
        _scene(tmp_path, reference='[reference]\ncontact = "ball/ground"\n')
    with pytest.raises(SceneError, match="must be a table"):  # ball.urdf is in tmp_path
        Scene.from_dict(
            {"robot": {"urdf": "ball.urdf", "q0": [1.1]}, "reference": 3}, base_dir=tmp_path
        )
    with pytest.raises(SceneError, match="needs a \\[\\[contacts\\]\\]"):
        Scene.from_dict(
            {"robot": {"urdf": "ball.urdf", "q0": [1.1]}, "reference": {"type": "bouncing_ball"}},
            base_dir=tmp_path,
        )


def test_reference_contact_removed_after_loading_is_named_when_used() -> None:
    scene = load_scene(ROBOTS / "ball.toml")
    twin = dataclasses.replace(scene.contacts[0], name="ball/ground/twin")
    renamed = dataclasses.replace(scene, contacts=(twin,))  # the scene stays valid
    with pytest.raises(NotFoundError, match=r"contact 'ball/ground'.*ball/ground/twin"):
        run_convergence(renamed, integrators=["moreau_jean"], dts=(1e-2,))


def test_run_command_with_each_integrator(tmp_path: Path) -> None:
    for name in ("event_driven", "compliant"):
        out = tmp_path / name
        status = main(
            [
                "run",
                str(ROBOTS / "ball.toml"),
                "--out",
                str(out),
                "--duration",
                "0.6",
                "--dt",
                "1e-2",
                "--integrator",
                name,
                "--no-progress",
            ]
        )
        assert status == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["integrator"] == name and summary["n_events"] >= 1
