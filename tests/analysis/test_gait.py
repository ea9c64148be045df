"""Period-one gaits by Newton on the stride map: the rimless wheel against its closed forms."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS
from test_rimless_wheel import (
    ETA,
    MULTIPLIER_TOLERANCE,
    OMEGA_STAR,
    PERIOD_TOLERANCE,
    STEADY_TOLERANCE,
    _post_strike_velocity,
    _step_period,
)

from ucontrol.analysis.gait import find_gait
from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.exceptions import SolverError, StrideError
from ucontrol.scene import Scene


def _wheel() -> tuple[StanceFlow, np.ndarray]:
    scene = Scene.from_toml(ROBOTS / "rimless_wheel.toml")
    return StanceFlow(scene.constraints), scene.q0


def _speed_chart(q0: np.ndarray) -> tuple[Any, Any]:
    """The post-strike speed as the section's coordinate (the strike configuration is fixed)."""

    def to_state(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return q0, _post_strike_velocity(float(z[0]))

    def from_state(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return v[2:3]

    return to_state, from_state


def test_newton_finds_the_rimless_wheel_gait_of_the_closed_forms() -> None:
    flow, q0 = _wheel()
    gait = find_gait(flow, *_speed_chart(q0), np.array([1.0]))
    assert abs(gait.z[0] - OMEGA_STAR) <= STEADY_TOLERANCE * OMEGA_STAR
    assert abs(gait.period - _step_period(OMEGA_STAR)) <= PERIOD_TOLERANCE
    assert gait.multipliers.shape == (1,)
    assert abs(gait.multipliers[0] - ETA**2) <= MULTIPLIER_TOLERANCE
    assert gait.stable and gait.iterations <= 10


@pytest.mark.slow
def test_the_post_strike_velocity_as_chart_gives_the_same_gait_and_multiplier() -> None:
    # Section coordinates: the whole velocity v (3,) at the strike configuration (fixed by the
    # geometry; the stride's image is read after the translation and the spoke relabelling,
    # which leave v unchanged). The strike removes the 2 velocity directions that move the
    # new foot: multipliers 0, dropped.
    flow, q0 = _wheel()
    gait = find_gait(
        flow,
        lambda z: (q0, z),
        lambda q, v: v,
        _post_strike_velocity(1.0),
        drop_trivial=2,
    )
    np.testing.assert_allclose(gait.v, _post_strike_velocity(OMEGA_STAR), rtol=1e-9)
    assert abs(np.sort(np.abs(np.linalg.eigvals(gait.jacobian)))[0]) <= 1e-6
    assert gait.multipliers.shape == (1,)
    assert abs(gait.multipliers[0] - ETA**2) <= MULTIPLIER_TOLERANCE


def test_a_section_never_crossed_and_a_search_that_does_not_converge_are_errors() -> None:
    flow, q0 = _wheel()
    short = StanceFlow(flow.constraints, max_duration=0.05)
    with pytest.raises(StrideError, match="no foot struck"):
        find_gait(short, *_speed_chart(q0), np.array([1.0]))
    with pytest.raises(SolverError, match="no convergence in 1 iterations"):
        find_gait(flow, *_speed_chart(q0), np.array([1.0]), max_iter=1)
