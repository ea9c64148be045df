"""Rigid limit of the flexible closed loop: the same law on the flexible arm and on its limit.

The rigid limit of the flexible arm is the rigid arm whose joints carry the motors' inertia
(``FlexibleJoints.rigid_limit``); the passivity-based law runs on it reading each motor at its
link (``experiments/stiffness_sweep.py``, ``on_rigid_plant``). Both runs track the same link
reference; they differ by the spring deflection δ = q1 - q2 of the flexible run, about
(transmitted torque) / K. The end-effector map of the two-link arm moves the tip by at most
(l1 + l2) ‖δq‖₁ = 1 m/rad × ‖δq‖₁, so in free motion the two end-effector paths stay within
(l1 + l2) max ‖δ‖₁ (measured ratio 0.71 at K = 1e6), which shrinks as 1/K.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_experiment

from ucontrol.control import Phase

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

LINKS = 1.0  # l1 + l2 [m]
DT = 1e-3  # [s]


@pytest.fixture(scope="module")
def distances() -> dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per K: distance [m] of the tip paths, the deflection ‖q1 - q2‖₁ [rad], the phases."""
    sweep = load_experiment("stiffness_sweep")
    result = {}
    for stiffness in (1e5, 1e6):
        flexible, rigid, scene = sweep.closed_loop_runs(stiffness, DT, 10.5)  # one cycle
        distance = np.linalg.norm(
            scene.robot.frame_path(flexible.q, sweep.TIP)
            - scene.robot.frame_path(rigid.q, sweep.TIP),
            axis=1,
        )
        deflection = np.abs(flexible.q - flexible.motor_q).sum(axis=1)
        result[stiffness] = (distance, deflection, flexible.phase)
    return result


def test_free_motion_within_the_deflection_bound_and_shrinking_as_one_over_k(distances) -> None:
    free = {}
    for stiffness, (distance, deflection, phase) in distances.items():
        before_landing = slice(0, int(np.argmax(phase != Phase.FREE)))
        free[stiffness] = distance[before_landing].max()
        assert free[stiffness] <= LINKS * deflection[before_landing].max()
    assert free[1e6] < 1e-5  # [m], measured 8.9e-6
    assert 8.0 < free[1e5] / free[1e6] < 12.0  # 1/K: measured 10.0


def test_both_slide_along_the_same_ground_path(distances) -> None:
    # In the middle of the constrained phase ([6, 9] s of the cycle) both hold the ground and
    # track the same x_d(t): the distance is the sum of their tracking errors (each < 5e-4 m).
    distance, _, phase = distances[1e6]
    middle = slice(int(6.0 / DT), int(9.0 / DT))
    assert np.all(phase[middle] == Phase.CONSTRAINED)
    assert distance[middle].max() < 1e-3  # [m], measured 2.4e-4
