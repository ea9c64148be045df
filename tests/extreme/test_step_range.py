"""Steps (and sampling periods) from 1e-6 s to 1e-2 s through impacts and an accumulation."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import ball_scene

from ucontrol.analysis import BouncingBall
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

STEPS = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2)  # [s]
STIFFNESS = 1e6  # [N/m], compliant
#: The ball 1 mm above the ground thrown down at 1 m/s, e = 0.5: impact after 1 ms,
#: accumulation at 0.21 s.
REFERENCE = BouncingBall(height=1e-3, velocity=-1.0, restitution=0.5)
SPEED = REFERENCE.impact_speed  # [m/s]
#: Compliant's model error: penetration V0 sqrt(m / k) and the contact time it costs.
COMPLIANT_ERROR = 2.0 * SPEED * math.sqrt(1.0 / STIFFNESS)  # [m]


@pytest.mark.parametrize("dt", STEPS)
@pytest.mark.parametrize("name", ["moreau_jean", "event_driven", "compliant"])
def test_every_step_size_is_accurate_and_gains_no_energy(name: str, dt: float) -> None:
    extra = {"stiffness": STIFFNESS} if name == "compliant" else {}
    scene = dataclasses.replace(ball_scene(0.5), q0=np.array([0.101]), v0=np.array([-1.0]))
    scene = dataclasses.replace(
        scene, integrator=dataclasses.replace(scene.integrator, name=name, **extra)
    )
    # A few thousand steps each, 0.3 s at most: every run goes through the first impact.
    duration = min(0.3, (30_000 if name == "moreau_jean" else 2_000) * dt)
    result = simulate(scene, duration=duration, dt=dt, progress=False)
    log = result.log
    assert np.all(np.isfinite(log.q)) and np.all(np.isfinite(log.v))
    error = np.max(np.abs(log.gap[:, 0] - REFERENCE.state(log.t)[0]))
    energy = log.energy
    if name == "moreau_jean":
        assert error <= 2.0 * dt * SPEED, error  # order one
        assert log.gap.min() >= -dt * SPEED
        assert result.summary["energy_increase_at_impacts"] == 0.0
        assert energy.max() <= energy[0] * (1.0 + 1e-12)
    else:
        assert error <= (1e-12 if name == "event_driven" else COMPLIANT_ERROR), error
        assert log.gap.min() >= (-1e-15 if name == "event_driven" else -COMPLIANT_ERROR / 2)
        assert np.max(np.diff(energy)) <= 1e-12 * energy[0]
