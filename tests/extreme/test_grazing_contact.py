"""Grazing contacts: touching a ceiling at the apex, and sliding on the ground."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene

from ucontrol.contact import Plane, PointContact
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

GRAVITY = 9.81  # [m/s²]
INTEGRATORS = {"moreau_jean": {}, "event_driven": {}, "compliant": {"stiffness": 1e6}}


def _with(scene: Scene, name: str) -> Scene:
    settings = dataclasses.replace(scene.integrator, name=name, **INTEGRATORS[name])
    return dataclasses.replace(scene, integrator=settings)


@pytest.mark.parametrize("name", INTEGRATORS)
def test_ball_thrown_up_to_touch_a_ceiling_flies_on(name: str) -> None:
    # Centre from 0.1 m up to exactly 1.1 m, where the 0.1 m ball touches the ceiling at 1.2 m.
    ceiling = Plane(
        point=np.array([0.0, 0.0, 1.2]), normal=np.array([0.0, 0.0, -1.0]), name="ceiling"
    )
    speed = math.sqrt(2.0 * GRAVITY * 1.0)  # [m/s]
    scene = dataclasses.replace(
        ball_scene(0.9),
        contacts=(PointContact(frame="ball", surface=ceiling, radius=0.1, restitution=0.9),),
        q0=np.array([0.1]),
        v0=np.array([speed]),
        reference=None,
    )
    log = simulate(_with(scene, name), duration=0.9, progress=False).log
    flight = 0.1 + speed * log.t - 0.5 * GRAVITY * log.t**2
    assert np.max(np.abs(log.q[:, 0] - flight)) <= 1e-9
    assert np.max(log.impulse) <= 1e-9
    assert log.gap.min() >= -1e-9
    assert np.max(np.abs(log.energy - log.energy[0])) <= 1e-12 * log.energy[0]


@pytest.mark.parametrize("name", INTEGRATORS)
def test_free_ball_slides_on_the_ground(name: str) -> None:
    # Resting contact with a tangential velocity: frictionless, it slides on for ever.
    scene = dataclasses.replace(
        load_scene(ROBOTS / "free_ball.toml"),
        q0=np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]),
        v0=np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
    )
    log = simulate(_with(scene, name), duration=1.0, progress=False).log
    np.testing.assert_allclose(log.q[:, 0], log.t, atol=1e-9)
    sink = 0.0 if name != "compliant" else GRAVITY / 1e6  # [m], m g / k
    settled = log.t > 0.6  # compliant settles on its spring first (ζ = 0.034, ω = 1000 /s)
    np.testing.assert_allclose(log.gap[settled, 0], -sink, atol=1e-12 if not sink else 1e-8)
    np.testing.assert_allclose(log.impulse[:-1][settled[:-1], 0], GRAVITY * 1e-3, rtol=1e-6)
