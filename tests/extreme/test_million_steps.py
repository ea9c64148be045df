"""One million Moreau–Jean steps of the elastic ball: no drift through the floor, no energy gain."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ball_scene

STEPS = 1_000_000
DT = 1e-3  # [s]: 1000 s, 1107 flights of 0.9 s
BLOCK = 100_000  # steps per block of the drift check


@pytest.mark.slow
def test_a_million_steps_of_the_elastic_ball() -> None:
    scene = ball_scene(1.0)
    integrator = scene.build_integrator(dt=DT)
    q, v = scene.q0, scene.v0
    tau = np.zeros(1)
    lowest = np.full(STEPS // BLOCK, np.inf)  # lowest gap of each block [m]
    highest_energy = -np.inf  # [J]
    highest_gap = np.full(STEPS // BLOCK, -np.inf)  # apex of each block [m]
    impacts = 0
    for k in range(STEPS):  # a lean loop: the integrator protocol without logging
        state = integrator.evaluate(q, v)
        energy = state.kinetic_energy + state.potential_energy
        highest_energy = max(highest_energy, energy)
        block = k // BLOCK
        lowest[block] = min(lowest[block], state.gap[0])
        highest_gap[block] = max(highest_gap[block], state.gap[0])
        outcome = integrator.step(state, tau)
        impacts += outcome.impulse[0] > 0.0
        q, v = outcome.q, outcome.v
    energy0 = 9.81 * 1.1  # [J], m g y0 at rest
    assert np.isfinite(q).all() and np.isfinite(v).all()
    assert impacts >= 1100
    assert highest_energy <= energy0 * (1.0 + 1e-9)
    assert abs(energy - energy0) <= 1e-9 * energy0
    # An impact step penetrates by less than h V0 / 2, in the last block as in the first.
    bound = 0.5 * DT * math.sqrt(2.0 * 9.81 * 1.0)
    assert lowest.min() >= -bound
    # And the ball still rises to 1 m (sampled every h: within g h² / 8 of the apex).
    np.testing.assert_allclose(highest_gap, 1.0, atol=9.81 * DT**2 / 8.0 + 1e-9)
