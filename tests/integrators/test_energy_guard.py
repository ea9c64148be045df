"""The energy guard of a Moreau–Jean step: written once, run by every path, off under "siconos".

A contact with e = 1 and θ = 1 under gravity: the impulse that reverses the approach speed
also works against the step's gravity over the displacement it causes, and adds
G = ½ P h g > 0 (docs/moreau_jean.md). The project's law redoes such a step plastic; Siconos'
convention (``newton_law = "siconos"``) has no guard and keeps the gain.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from conftest import needs_compiled_code

from ucontrol.integrators import step_stages
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import SimulationResult, simulate

ROBOTS = builtin_scene().parent


def _ball(newton_law: str) -> Scene:
    """A ball dropped from 0.2 m onto the ground, e = 1, θ = 1: one active row per impact."""
    table = {
        "name": "ball",
        "duration": 0.5,
        "robot": {"urdf": "ball.urdf", "q0": [0.3], "v0": [0.0], "gravity": [0, 0, -9.81]},
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
        "contacts": [{"frame": "ball", "surface": "ground", "radius": 0.1, "restitution": 1.0}],
        "integrator": {"name": "moreau_jean", "dt": 1e-3, "theta": 1.0, "newton_law": newton_law},
    }
    return Scene.from_dict(table, base_dir=ROBOTS, default_name="ball")


def _four_bar(newton_law: str) -> Scene:
    """The four-bar (bilateral closure rows) falling onto its crank stop, e = 1, θ = 1."""
    table = tomllib.loads((ROBOTS / "four_bar_stop.toml").read_text())
    table["integrator"] = {
        "name": "moreau_jean",
        "dt": 1e-3,
        "theta": 1.0,
        "newton_law": newton_law,
    }
    table["stops"][0]["restitution"] = 1.0
    return Scene.from_dict(table, base_dir=ROBOTS)


def _largest_impact_gain(result: SimulationResult) -> float:
    """The largest energy change over a step with an impulse, in [J]."""
    log = result.log
    impacts = log.impulse[:-1].sum(axis=1) > 0.0
    assert impacts.any()
    return float(np.diff(log.energy)[impacts].max())


def _run(scene: Scene, compiled: bool) -> SimulationResult:
    """``scene`` run with the fast paths (where they exist) or with the reference alone."""
    with pytest.MonkeyPatch.context() as patch:
        if not compiled:
            patch.setenv("UCONTROL_NO_COMPILE", "1")
        return simulate(scene, progress=False)


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("build", [_ball, _four_bar])
def test_the_guard_makes_gaining_steps_plastic(build, compiled: bool) -> None:  # type: ignore[no-untyped-def]
    result = _run(build("closing"), compiled)
    assert result.summary["n_plastic_steps"] >= 1
    assert _largest_impact_gain(result) <= 1e-12  # measured 0 J


@pytest.mark.parametrize("build", [_ball, _four_bar])
def test_the_siconos_law_runs_no_guard(build) -> None:  # type: ignore[no-untyped-def]
    """With and without bilateral rows: no plastic step, and the gain is kept."""
    result = _run(build("siconos"), True)
    assert result.summary["n_plastic_steps"] == 0
    # Measured: 0.019 J (ball), 0.0097 J (four-bar).
    assert _largest_impact_gain(result) > 1e-3


@pytest.mark.parametrize("compiled", [pytest.param(True, marks=needs_compiled_code), False])
def test_without_the_guard_the_one_row_step_gains_energy(
    compiled: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The guard switched off where it is defined: both paths of a one-row step lose it."""
    monkeypatch.setattr(step_stages, "ENERGY_GAIN_TOLERANCE", math.inf)
    scene = _ball("closing")
    if compiled:
        assert "single row" in scene.build_integrator().fast_paths
    result = _run(scene, compiled)
    assert result.summary["n_plastic_steps"] == 0
    assert _largest_impact_gain(result) > 1e-3  # the defect the guard removes (0.019 J)
