"""Metrics of the hopper campaign (experiments/hopper_campaign.toml), read from a run's log.

The ground's height is the foot's height in stance (the campaign moves the ground), the apex
the hip's height above it where the hip's vertical velocity crosses 0 downwards.
"""

from __future__ import annotations

import numpy as np

from ucontrol.analysis.hop_flow import logged_apexes
from ucontrol.simulate import SimulationResult

#: The scene's commanded apex above the ground [m] (robots/hopper.toml).
COMMAND = 0.8
#: Hops the apex error is taken over: the last ones, after the recovery from a push or a step.
LAST_HOPS = 3
#: |pitch| [rad] beyond which the hopper has fallen.
FALLEN_PITCH = 0.6


def _ground(result: SimulationResult) -> float:
    """The foot's median height over the stance samples [m] (NaN without a stance)."""
    q, phase = np.asarray(result.log.q), np.asarray(result.log.phase)
    foot = q[:, 1] - q[:, 4] * np.cos(q[:, 2] + q[:, 3])  # hip height - l cos psi
    stance = phase > 0
    return float(np.median(foot[stance])) if stance.any() else float("nan")


def apexes_above_ground(result: SimulationResult) -> np.ndarray:
    """The hip's apexes above the ground [m], one per hop."""
    q, v = np.asarray(result.log.q), np.asarray(result.log.v)
    return logged_apexes(q[:, 1], v[:, 1])[0] - _ground(result)


def hops(result: SimulationResult) -> int:
    """Number of apexes in the run."""
    return int(apexes_above_ground(result).size)


def apex_error(result: SimulationResult) -> float:
    """Largest |apex - command| / command over the last hops (NaN without a hop)."""
    apexes = apexes_above_ground(result)[-LAST_HOPS:]
    if apexes.size == 0:
        return float("nan")
    return float(np.max(np.abs(apexes - COMMAND)) / COMMAND)


def fell(result: SimulationResult) -> bool:
    """Whether the body pitched beyond :data:`FALLEN_PITCH` or the hip neared the ground.

    Near: within 0.2 m.
    """
    q = np.asarray(result.log.q)
    low = np.min(q[:, 1]) - _ground(result) < 0.2
    return bool(np.max(np.abs(q[:, 2])) > FALLEN_PITCH or low)
