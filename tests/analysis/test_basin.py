"""Basins of attraction of gaits, probed by iterating stride maps.

References: the rimless wheel's closed-form threshold (the post-strike speed that carries the
hub over the top of its stance spoke, docs/legged.md), the simplest walker's gait of Garcia et
al. (1998) and its multipliers (inside the unit circle: a neighbourhood is in the basin), and
the same probe run serially and as tasks of a Dask cluster.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROBOTS

from ucontrol.analysis.basin import OUTCOMES, probe_basin, stride_outcome
from ucontrol.analysis.simplest_walker import SimplestWalker
from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene

# The wheel of robots/rimless_wheel.toml (docs/legged.md).
ALPHA, SLOPE, RHO, LENGTH, GRAVITY = math.pi / 8, 0.1, 0.5, 1.0, 9.81
ETA = (math.cos(2 * ALPHA) + RHO**2) / (1 + RHO**2)
BETA = 4 * GRAVITY * math.sin(ALPHA) * math.sin(SLOPE) / (LENGTH * (1 + RHO**2))
OMEGA_STAR = math.sqrt(ETA**2 * BETA / (1 - ETA**2))  # [rad/s]
#: Post-strike speed below which the hub does not pass over its stance spoke [rad/s].
OMEGA_OVER = math.sqrt(2 * GRAVITY * (1 - math.cos(ALPHA - SLOPE)) / (LENGTH * (1 + RHO**2)))
#: The simplest walker's stable gait at γ = 0.009 (Garcia et al. 1998).
WALKER_GAIT = np.array([0.2003109005, -0.1998325])


class _WheelChart:
    """z = ω⁺: the rotation about spoke 0's foot in the scene's strike configuration."""

    def __init__(self, q0: np.ndarray) -> None:
        self.q0 = q0

    def to_state(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        omega = float(z[0])
        return self.q0, omega * np.array([math.cos(ALPHA), math.sin(ALPHA), 1.0])

    @staticmethod
    def from_state(_q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.array([v[2]])


@pytest.mark.slow
def test_rimless_wheel_basin_starts_at_the_closed_form_threshold() -> None:
    scene = Scene.from_toml(ROBOTS / "rimless_wheel.toml")
    chart = _WheelChart(scene.q0)
    starts = np.array([[0.70], [0.78], [0.81], [0.825], [0.86], [1.0], [1.6]])
    table = probe_basin(
        StanceFlow(scene.constraints),
        chart.to_state,
        chart.from_state,
        np.array([OMEGA_STAR]),
        starts,
        max_strides=20,
        tol=1e-3,
        progress=False,
    )
    # OMEGA_OVER = 0.8171 rad/s: above it the wheel vaults and the map (ω⁺)² ->
    # η²((ω⁺)² + β) contracts to the gait by η² = 0.586 a stride; below, it rocks back.
    in_basin = table["outcome"] == "gait"
    np.testing.assert_array_equal(in_basin, starts[:, 0] > OMEGA_OVER)
    # Strides to reach the gait within 1e-3 relative, from the affine map in (ω⁺)².
    for omega, strides in zip(starts[in_basin, 0], table["strides"][in_basin], strict=True):
        square, expected = omega**2, 0
        while abs(math.sqrt(square) - OMEGA_STAR) > 1e-3 * max(1.0, OMEGA_STAR):
            square, expected = ETA**2 * (square + BETA), expected + 1
        assert strides == expected


def test_simplest_walker_outcomes() -> None:
    walker = SimplestWalker(slope=0.009)
    chart = (walker, walker.to_state, walker.from_state, WALKER_GAIT)
    at_gait = stride_outcome(*chart, WALKER_GAIT, tol=1e-8)
    assert (at_gait.outcome, at_gait.strides) == ("gait", 0)
    # Multipliers of modulus 0.59: a start 1e-3 away comes within 1e-6 in about 14 strides.
    near = stride_outcome(*chart, WALKER_GAIT + np.array([1e-3, 0.0]), tol=1e-6, max_strides=40)
    assert near.outcome == "gait" and 5 <= near.strides <= 25
    assert near.distance <= 1e-6 * max(1.0, float(np.linalg.norm(WALKER_GAIT)))
    slow = stride_outcome(*chart, np.array([0.2, -0.05]))  # too slow to pass the normal
    assert (slow.outcome, slow.strides) == ("fall", 1)
    assert "hip reached the slope" in slow.reason  # it falls back
    short = stride_outcome(*chart, WALKER_GAIT + np.array([1e-3, 0.0]), tol=1e-9, max_strides=2)
    assert (short.outcome, short.strides) == ("unsettled", 2)


def test_bad_arguments_are_typed_errors() -> None:
    walker = SimplestWalker(slope=0.009)
    chart = (walker, walker.to_state, walker.from_state, WALKER_GAIT)
    with pytest.raises(InvalidParameterError, match="max_strides"):
        stride_outcome(*chart, WALKER_GAIT, max_strides=0)
    with pytest.raises(InvalidParameterError, match="tol"):
        stride_outcome(*chart, WALKER_GAIT, tol=-1.0)
    with pytest.raises(InvalidParameterError, match="z0"):
        stride_outcome(*chart, np.zeros(3))


@pytest.mark.slow
def test_dask_probe_equals_the_serial_one() -> None:
    from distributed import Client, LocalCluster

    walker = SimplestWalker(slope=0.009)
    theta, rate = np.meshgrid([0.17, 0.2, 0.23], [-0.25, -0.2, -0.1])
    starts = np.column_stack((theta.ravel(), rate.ravel()))
    args = (walker, SimplestWalker.to_state, SimplestWalker.from_state, WALKER_GAIT, starts)
    serial = probe_basin(*args, max_strides=30, tol=1e-6, progress=False)
    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster,
        Client(cluster) as client,
    ):
        spread = probe_basin(*args, max_strides=30, tol=1e-6, client=client, progress=False)
    assert list(serial["outcome"].cat.categories) == list(OUTCOMES)
    assert serial.drop(columns="reason").equals(spread.drop(columns="reason"))
    assert (serial["reason"] == spread["reason"]).all()
    assert (serial["outcome"] == "gait").any() and (serial["outcome"] != "gait").any()
