"""The recursive Newton–Euler dynamics of the design against Pinocchio's rnea and crba."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.design.recursive_dynamics import RecursiveDynamics
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


@pytest.mark.parametrize("scene", ["panda_table.toml", "two_link_one_constraint.toml"])
def test_mass_matrix_and_nonlinear_effects_match_pinocchio(scene: str) -> None:
    robot = Scene.from_toml(ROBOTS / scene).robot
    dynamics = RecursiveDynamics(robot)
    model, data = robot.model, pin.Data(robot.model)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        v = rng.uniform(-2.0, 2.0, robot.nv)
        h = np.asarray(dynamics.nonlinear_effects(q, v)).ravel()
        g = np.asarray(dynamics.gravity(q)).ravel()
        M = np.asarray(dynamics.mass_matrix(q))
        M_pin = pin.crba(model, data, q, pin.Convention.WORLD)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        # measured 1e-15 relative (rounding)
        np.testing.assert_allclose(h, pin.nonLinearEffects(model, data, q, v), atol=1e-12)
        np.testing.assert_allclose(g, pin.computeGeneralizedGravity(model, data, q), atol=1e-12)
        np.testing.assert_allclose(M, M_pin, atol=1e-12)
