"""Moreau–Jean on the bouncing ball against its analytic solution (m = 1 kg, g = 9.81, 1 m)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ball_scene

from ucontrol.analysis import BouncingBall, impact_mask
from ucontrol.simulate import simulate

RADIUS = 0.1  # [m], the ball's centre starts at 1.1 m
MASS, GRAVITY = 1.0, 9.81


def _run(restitution: float, dt: float, duration: float = 3.0):
    return simulate(ball_scene(restitution), duration=duration, dt=dt, progress=False).log


def _height_error(log, reference: BouncingBall) -> float:
    height, _ = reference.state(log.t)
    return float(np.max(np.abs(log.q[:, 0] - RADIUS - height)))


def _impact_time_errors(restitution: float, dt: float) -> np.ndarray:
    """|t_num - t_exact| of the impacts whose preceding flight lasts at least 20 steps."""
    log = _run(restitution, dt)
    reference = BouncingBall(height=1.0, restitution=restitution, gravity=GRAVITY)
    expected = reference.impact_times(3.0)
    resolved = expected[np.diff(expected, prepend=0.0) > 20 * dt]
    found = log.t[np.flatnonzero(impact_mask(log)[:, 0])]
    assert found.size >= resolved.size >= 3
    return np.abs(found[: resolved.size] - resolved)


@pytest.mark.parametrize("restitution", [0.9, 0.5])
def test_impact_times_within_order_h(restitution: float) -> None:
    coarse = _impact_time_errors(restitution, 1e-3)
    fine = _impact_time_errors(restitution, 1e-4)
    # Each impact is located within two steps of its predecessor's error: O(h) per impact.
    for dt, errors in ((1e-3, coarse), (1e-4, fine)):
        assert np.all(errors <= 2.0 * dt * np.arange(1, errors.size + 1)), errors
    # And the error is first order: ten times smaller steps, >= 5 times smaller errors.
    n = min(coarse.size, fine.size)
    assert np.max(coarse[:n]) / np.max(fine[:n]) >= 5.0


@pytest.mark.parametrize("restitution", [0.9, 0.5])
def test_height_error_shrinks_eightfold_per_decade_of_h(restitution: float) -> None:
    reference = BouncingBall(height=1.0, restitution=restitution, gravity=GRAVITY)
    coarse = _height_error(_run(restitution, 1e-3), reference)
    fine = _height_error(_run(restitution, 1e-4), reference)
    assert coarse / fine >= 8.0, (coarse, fine)


@pytest.mark.parametrize("restitution", [0.0, 0.5, 0.9, 1.0])
def test_newton_law_exact_at_every_impact(restitution: float) -> None:
    log = _run(restitution, 1e-3)
    u = log.normal_velocity[:, 0]
    steps = np.flatnonzero(log.impulse[:-1, 0] > 0.0)
    closing = steps[u[steps] < 0.0]
    assert closing.size > 0
    assert np.max(np.abs(u[closing + 1] + restitution * u[closing])) <= 1e-12
    # An active constraint that is not closing (resting or separating) gets e = 0: u⁺ = 0.
    others = np.setdiff1d(steps, closing)
    assert np.max(np.abs(u[others + 1]), initial=0.0) <= 1e-12


@pytest.mark.parametrize("dt", [1e-3, 1e-4])
def test_inelastic_ball_rests_after_accumulation_with_weight_impulse(dt: float) -> None:
    reference = BouncingBall(height=1.0, restitution=0.5, gravity=GRAVITY)
    log = _run(0.5, dt, duration=2.0)
    resting = (log.t > reference.accumulation_time + 0.05)[:-1]
    assert resting.sum() > 100
    np.testing.assert_allclose(log.impulse[:-1][resting, 0], MASS * GRAVITY * dt, rtol=1e-12)
    np.testing.assert_allclose(log.v[1:][resting, 0], 0.0, atol=1e-12)
    assert np.ptp(log.q[1:][resting, 0]) <= 1e-12  # at rest, not creeping


@pytest.mark.parametrize("restitution", [0.0, 0.5, 0.9])
def test_energy_never_rises_across_an_impact(restitution: float) -> None:
    log = _run(restitution, 1e-3)
    steps = np.flatnonzero(impact_mask(log)[:-1, 0])
    assert steps.size >= 1
    jumps = log.energy[steps + 1] - log.energy[steps]
    assert np.max(jumps) <= 1e-12 * log.energy[0]


def test_elastic_ball_keeps_its_energy_over_fifty_impacts() -> None:
    reference = BouncingBall(height=1.0, restitution=1.0, gravity=GRAVITY)
    duration = reference.impact_times(60.0)[50] + 0.1
    result = simulate(ball_scene(1.0), duration=duration, dt=1e-3, progress=False)
    assert result.summary["n_impacts"] >= 50
    drift = np.max(np.abs(result.log.energy - result.log.energy[0])) / result.log.energy[0]
    assert drift <= 1e-10, drift


def test_every_contact_solution_satisfies_complementarity() -> None:
    for restitution in (0.0, 0.5, 1.0):
        log = _run(restitution, 1e-3)
        assert np.max(log.complementarity_residual) < 1e-8
