"""Compliant contact: restitution of the force laws, rest, energy, settings and limits."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import ball_scene

from ucontrol.exceptions import IntegrationError, InvalidParameterError
from ucontrol.integrators import Compliant
from ucontrol.integrators.contact_laws import (
    MAX_DAMPING_RATIO,
    damping_ratio,
    one_sided_restitution,
)
from ucontrol.integrators.methods import CONTACT_MODELS
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

MASS, GRAVITY, RADIUS = 1.0, 9.81, 0.1  # the ball of robots/ball.toml: [kg], [m/s²], [m]
IMPACT_SPEED = math.sqrt(2.0 * GRAVITY)  # [m/s], dropped from 1 m


def _compliant(scene: Scene, **settings: object) -> Scene:
    integrator = dataclasses.replace(scene.integrator, name="compliant", **settings)
    return dataclasses.replace(scene, integrator=integrator)


def _rebound(restitution: float, **settings: object) -> tuple[float, int]:
    """Rebound speed / impact speed of the dropped ball, from one 0.6 s step; and its events."""
    scene = ball_scene(restitution)
    integrator = Compliant(scene.robot, scene.constraints, dt=0.6, **settings)
    outcome = integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(1))
    height = outcome.q[0] - RADIUS
    return math.sqrt(outcome.v[0] ** 2 + 2.0 * GRAVITY * height) / IMPACT_SPEED, outcome.events


@pytest.mark.parametrize("restitution", [0.0, 1e-3, 0.1, 0.5, 0.7, 0.9, 0.99, 1.0])
def test_damping_ratio_gives_the_restitution_of_the_one_sided_law(restitution: float) -> None:
    zeta = damping_ratio(restitution)
    expected = max(restitution, one_sided_restitution(MAX_DAMPING_RATIO))
    assert one_sided_restitution(zeta) == pytest.approx(expected, rel=1e-10, abs=1e-15)


def test_one_sided_restitution_matches_the_oscillator_released_at_zero_force() -> None:
    # ζ = -ln e / sqrt(π² + ln² e) is the two-sided value: one-sided, e = 0.9 rebounds at 0.902.
    log_e = math.log(0.9)
    assert one_sided_restitution(-log_e / math.hypot(math.pi, log_e)) == pytest.approx(
        0.902026, abs=1e-6
    )
    assert one_sided_restitution(1.0) == pytest.approx(math.exp(-2.0))
    assert one_sided_restitution(3.0) < one_sided_restitution(1.0) < one_sided_restitution(0.3)


@pytest.mark.parametrize("restitution", [0.9, 0.5])
def test_linear_law_rebounds_with_the_restitution(restitution: float) -> None:
    ratio, events = _rebound(restitution, stiffness=1e8)
    assert events == 2  # contact begins, contact ends
    assert ratio == pytest.approx(restitution, abs=1e-3)  # gravity acts during the 0.3 ms


@pytest.mark.parametrize("restitution", [0.9, 0.5])
def test_hunt_crossley_law_dissipates_less_than_newton(restitution: float) -> None:
    # Its damping 3(1 - e)/2 is the small-dissipation approximation: e_eff > e, worse for low e.
    ratio, _ = _rebound(restitution, stiffness=1e10, contact_model="hunt_crossley")
    assert restitution < ratio < 1.0
    assert ratio - restitution < (0.02 if restitution == 0.9 else 0.2)


@pytest.mark.slow
def test_resting_ball_sinks_by_its_weight_over_the_stiffness() -> None:
    stiffness = 1e6  # [N/m]
    log = simulate(
        _compliant(ball_scene(0.0), stiffness=stiffness), duration=2.0, progress=False
    ).log
    resting = log.t > 1.5
    np.testing.assert_allclose(log.gap[resting, 0], -MASS * GRAVITY / stiffness, rtol=1e-6)
    np.testing.assert_allclose(log.impulse[:-1][resting[:-1], 0], MASS * GRAVITY * 1e-3, rtol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("model", CONTACT_MODELS)
def test_energy_with_the_elastic_part_never_rises(model: str) -> None:
    scene = _compliant(ball_scene(0.9), stiffness=1e6, contact_model=model, rtol=1e-10, atol=1e-12)
    result = simulate(scene, duration=1.5, progress=False)
    energy = result.log.energy
    assert result.summary["n_events"] >= 4
    assert np.max(np.diff(energy)) <= 1e-9 * energy[0]
    assert energy[-1] < 0.9 * energy[0]


def test_elastic_linear_contact_keeps_the_energy() -> None:
    result = simulate(
        _compliant(ball_scene(1.0), stiffness=1e6, rtol=1e-10, atol=1e-12),
        duration=1.5,
        progress=False,
    )
    energy = result.log.energy
    assert np.max(np.abs(energy - energy[0])) <= 1e-9 * energy[0]


def test_chattering_contacts_stop_with_a_typed_error() -> None:
    scene = ball_scene(0.9)
    integrator = Compliant(scene.robot, scene.constraints, dt=0.6, stiffness=1e6, max_events=1)
    with pytest.raises(IntegrationError, match=r"contact events.*ball/ground") as info:
        integrator.step(integrator.evaluate(scene.q0, scene.v0), np.zeros(1))
    assert info.value.integrator == "compliant"


def test_bad_settings_are_typed_errors() -> None:
    scene = ball_scene(0.9)
    robot, constraints = scene.robot, scene.constraints
    with pytest.raises(InvalidParameterError, match="`method`"):
        Compliant(robot, constraints, dt=1e-3, method="DOP853")
    with pytest.raises(InvalidParameterError, match="`contact_model`"):
        Compliant(robot, constraints, dt=1e-3, contact_model="hertz")
    with pytest.raises(InvalidParameterError, match="`stiffness`"):
        Compliant(robot, constraints, dt=1e-3, stiffness=0.0)
