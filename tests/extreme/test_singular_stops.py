"""The arm stretched against its elbow stop (a singular configuration) falls onto the ground."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ucontrol.scene import Scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

INTEGRATORS = {"moreau_jean": {}, "event_driven": {}, "compliant": {"stiffness": 1e6}}


@pytest.mark.parametrize("name", INTEGRATORS)
def test_stretched_arm_held_by_its_stops(two_link_scene: Scene, name: str) -> None:
    # Gravity presses the elbow on its stop θ2 = -1e-4 (arm stretched: the end-effector
    # Jacobian is singular); the arm falls until the ground and the shoulder stop θ1 = π close
    # together: three constraints on two joints.
    scene = dataclasses.replace(
        two_link_scene,
        q0=np.array([math.pi - 0.3, -1e-4]),
        integrator=dataclasses.replace(two_link_scene.integrator, name=name, **INTEGRATORS[name]),
    )
    result = simulate(scene, duration=1.5, progress=False)
    log = result.log
    assert np.all(np.isfinite(log.q)) and np.all(np.isfinite(log.v))
    elbow_upper, shoulder_upper = (
        log.constraint_names.index(n) for n in ("elbow/upper", "shoulder/upper")
    )
    tolerance = {"moreau_jean": 1e-3, "event_driven": 1e-12, "compliant": 1e-3}[name]
    assert log.gap[:, [elbow_upper, shoulder_upper]].min() >= -tolerance  # the stops hold
    assert log.gap[:, 0].min() >= -tolerance  # and the ground
    energy = log.energy
    if name == "moreau_jean":
        assert result.summary["energy_increase_at_impacts"] <= 1e-9 * energy[0]
        assert energy.max() <= energy[0]
    else:
        assert np.max(np.diff(energy)) <= 1e-12 * energy[0]
    assert energy[-1] < 1e-3 * energy[0]  # e = 0 stops: it comes to rest
