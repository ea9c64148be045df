"""Energy balance: energy minus actuator work only falls, and only at impacts."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ucontrol.analysis import actuator_work, impact_mask
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: Energy error of one Moreau-Jean step (θ = 1/2, h = 1 ms) of the controlled arm, in [J].
STEP_TOLERANCE = 1e-6


def test_energy_minus_actuator_work_changes_only_at_impacts() -> None:
    scene = load_scene(ROBOTS / "two_link_one_constraint.toml")
    log = simulate(scene, duration=6.0).log  # landing at 4.7 s, then sliding without friction
    work = actuator_work(log)
    assert work[0] == 0.0 and np.ptp(work) > 0.1  # [J] the controller works
    change = np.diff(log.energy - work)  # [J] over each step
    impacts = impact_mask(log)[:-1].any(axis=1)
    assert impacts.sum() >= 5
    assert np.abs(change[~impacts]).max() < STEP_TOLERANCE  # free and sliding: conserved
    assert change.max() < STEP_TOLERANCE  # never created
    assert change[impacts].sum() < -1e-2  # the impacts dissipate (e = 0.7)


def test_actuator_work_is_zero_without_torque() -> None:
    log = simulate(load_scene(ROBOTS / "ball.toml"), duration=0.1).log
    np.testing.assert_array_equal(actuator_work(log), np.zeros(len(log)))
