"""Restitution 0 and 1 with every integrator: no rebound, no energy gain, exact energy at e = 1."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import ball_scene

from ucontrol.analysis import BouncingBall
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

#: Integrators and settings of the extreme cases; compliant at 1e6 N/m.
INTEGRATORS = {"moreau_jean": {}, "event_driven": {}, "compliant": {"stiffness": 1e6}}
#: Largest height error against the analytic ball over 3 s, in [m], per integrator.
HEIGHT_TOLERANCE = {"moreau_jean": 0.05, "event_driven": 1e-9, "compliant": 0.05}
#: Largest relative energy drift of the elastic ball: compliant's is set by its rtol = 1e-8.
ENERGY_TOLERANCE = {"moreau_jean": 1e-9, "event_driven": 1e-9, "compliant": 1e-7}


def _with(scene: Scene, name: str) -> Scene:
    settings = dataclasses.replace(scene.integrator, name=name, **INTEGRATORS[name])
    return dataclasses.replace(scene, integrator=settings)


@pytest.mark.parametrize("name", INTEGRATORS)
def test_plastic_ball_stays_down(name: str) -> None:
    result = simulate(_with(ball_scene(0.0), name), duration=1.5, progress=False)
    log = result.log
    reference = BouncingBall(height=1.0, restitution=0.0)
    after = log.t > reference.first_impact_time + 0.01
    assert np.all(np.isfinite(log.q)) and np.all(np.isfinite(log.v))
    # Compliant: its one-sided law rebounds at 2.4e-3 at most (see damping_ratio), < 1e-5 m.
    assert np.max(log.gap[after, 0]) <= (0.0 if name != "compliant" else 1e-5)
    assert np.min(log.gap[:, 0]) >= -5e-3  # h V0 / 2 (Moreau–Jean), m g / k (compliant)
    energy = log.energy
    assert energy[-1] <= 9.81 * (0.1 + 1e-5)  # [J], resting: m g r with r = 0.1 m
    if name == "moreau_jean":
        assert result.summary["energy_increase_at_impacts"] <= 1e-12 * energy[0]
    else:
        assert np.max(np.diff(energy)) <= 1e-9 * energy[0]


@pytest.mark.parametrize("name", INTEGRATORS)
def test_elastic_ball_keeps_its_energy_and_its_heights(name: str) -> None:
    result = simulate(_with(ball_scene(1.0), name), duration=3.0, progress=False)
    log = result.log
    energy = log.energy
    assert np.max(np.abs(energy - energy[0])) <= ENERGY_TOLERANCE[name] * energy[0]
    reference = BouncingBall(height=1.0, restitution=1.0)
    error = np.max(np.abs(log.gap[:, 0] - reference.state(log.t)[0]))
    assert error <= HEIGHT_TOLERANCE[name], error
    assert result.summary["n_impacts"] >= 3
