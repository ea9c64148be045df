"""A 1 g bead struck by a 1000 kg block (mass ratio 1e6): Newton's law across the ratio."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import ROBOTS
from scipy.optimize import brentq

from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

GRAVITY = 9.81  # [m/s²]
BLOCK, BEAD = 1000.0, 1e-3  # masses [kg]
E_GROUND, E_BEAD = 0.8, 0.9  # restitutions of robots/mass_ratio.toml
BLOCK_HEIGHT = 0.2  # [m], the bead's joint sits on the block's top face
WINDOW = 0.2  # [s] of ballistic motion after the block strikes the bead


def _scene(name: str) -> Scene:
    scene = load_scene(ROBOTS / "mass_ratio.toml")
    return dataclasses.replace(scene, integrator=dataclasses.replace(scene.integrator, name=name))


def _after_the_strike() -> tuple[float, tuple[float, float, float, float]]:
    """Time [s] the rebounding block strikes the falling bead, and (z_b, u_b, z_d, u_d) after.

    z_b: block bottom height, z_d = z_b + 0.2 + q_bead: bead height [m]; u: velocities [m/s].
    """
    t_ground = math.sqrt(2.0 * 0.5 / GRAVITY)
    rebound = E_GROUND * GRAVITY * t_ground

    def block(t: float) -> float:
        return rebound * (t - t_ground) - 0.5 * GRAVITY * (t - t_ground) ** 2

    def bead(t: float) -> float:
        return 1.0 - 0.5 * GRAVITY * t**2

    t = brentq(
        lambda t: bead(t) - block(t) - BLOCK_HEIGHT, t_ground + 1e-9, t_ground + 1.0, xtol=1e-15
    )
    u_block, u_bead = rebound - GRAVITY * (t - t_ground), -GRAVITY * t
    relative = -E_BEAD * (u_bead - u_block)  # Newton's law on the bead-block stop
    u_block_after = (BLOCK * u_block + BEAD * u_bead - BEAD * relative) / (BLOCK + BEAD)
    return t, (block(t), u_block_after, bead(t), u_block_after + relative)


def _errors(log) -> tuple[float, float]:
    t_strike, (z_block, u_block, z_bead, u_bead) = _after_the_strike()
    window = (log.t > t_strike) & (log.t < t_strike + WINDOW)
    s = log.t[window] - t_strike
    block = z_block + u_block * s - 0.5 * GRAVITY * s**2
    bead = z_bead + u_bead * s - 0.5 * GRAVITY * s**2
    height = log.q[window, 0] + BLOCK_HEIGHT + log.q[window, 1]
    return float(np.max(np.abs(log.q[window, 0] - block))), float(np.max(np.abs(height - bead)))


def test_event_driven_is_exact_across_the_mass_ratio() -> None:
    result = simulate(_scene("event_driven"), progress=False)
    block_error, bead_error = _errors(result.log)
    assert max(block_error, bead_error) <= 1e-9
    assert result.log.gap.min() >= 0.0
    assert result.summary["n_events"] >= 3


def test_moreau_jean_converges_across_the_mass_ratio() -> None:
    errors = [
        max(_errors(simulate(_scene("moreau_jean"), dt=dt, progress=False).log))
        for dt in (1e-3, 1e-4)
    ]
    assert errors[0] <= 2e-2 and errors[1] < errors[0] / 5.0


@pytest.mark.parametrize("name", ["moreau_jean", "event_driven", "compliant"])
def test_no_energy_gain_across_the_mass_ratio(name: str) -> None:
    result = simulate(_scene(name), progress=False)
    log = result.log
    assert np.all(np.isfinite(log.q)) and np.all(np.isfinite(log.v))
    energy = log.energy
    if name == "moreau_jean":
        assert result.summary["energy_increase_at_impacts"] <= 1e-12 * energy[0]
        assert log.gap.min() >= -2.5e-3  # O(h u): 1 ms at 3 m/s (block), 7 m/s (bead)
    else:
        assert np.max(np.diff(energy)) <= 1e-12 * energy[0]
        # Compliant at 1e6 N/m under a ton: penetration V sqrt(M / k) = 0.1 m.
        assert log.gap.min() >= (0.0 if name == "event_driven" else -0.11)
