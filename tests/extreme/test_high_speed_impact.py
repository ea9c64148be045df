"""An impact at 100 m/s: exact Newton's law, bounded penetration, no energy gain."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import ball_scene

from ucontrol.analysis import BouncingBall
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

SPEED = 100.0  # [m/s]
#: The ball 0.1 m above the ground thrown down at 100 m/s, e = 0.9.
REFERENCE = BouncingBall(height=0.1, velocity=-SPEED, restitution=0.9)


def _scene(name: str, **settings: object) -> Scene:
    scene = dataclasses.replace(ball_scene(0.9), q0=np.array([0.2]), v0=np.array([-SPEED]))
    integrator = dataclasses.replace(scene.integrator, name=name, **settings)
    return dataclasses.replace(scene, integrator=integrator)


def test_event_driven_rebounds_exactly() -> None:
    log = simulate(_scene("event_driven"), duration=0.5, progress=False).log
    height, velocity = REFERENCE.state(log.t)
    assert np.max(np.abs(log.gap[:, 0] - height)) <= 1e-10  # heights up to 410 m
    assert np.max(np.abs(log.v[:, 0] - velocity)) <= 1e-10
    assert log.gap.min() >= 0.0


def test_moreau_jean_keeps_newton_law_and_bounds_the_penetration() -> None:
    result = simulate(_scene("moreau_jean"), duration=0.5, progress=False)
    log = result.log
    u = log.normal_velocity[:, 0]
    step = np.flatnonzero(log.impulse[:-1, 0] > 0.0)
    assert step.size == 1
    assert u[step + 1] == pytest.approx(-0.9 * u[step], rel=1e-12)
    assert log.gap.min() >= -1e-3 * SPEED  # one step at the impact speed
    assert result.summary["energy_increase_at_impacts"] == 0.0


@pytest.mark.parametrize("stiffness", [1e6, 1e9, 1e12])
def test_compliant_rebounds_with_the_restitution_at_any_stiffness(stiffness: float) -> None:
    log = simulate(_scene("compliant", stiffness=stiffness), duration=0.05, progress=False).log
    rebound = log.v[-1, 0] + 9.81 * (log.t[-1] - REFERENCE.first_impact_time)  # [m/s]
    assert rebound == pytest.approx(0.9 * REFERENCE.impact_speed, rel=2e-3)
    depth = REFERENCE.impact_speed * np.sqrt(1.0 / stiffness)  # [m], undamped bound
    assert log.gap.min() >= -depth
    assert np.max(np.diff(log.energy)) <= 1e-12 * log.energy[0]
