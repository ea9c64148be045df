"""The compass walker with small foot masses tends to the simplest walker as beta -> 0."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS
from scipy.integrate import solve_ivp

from ucontrol.analysis.gait import Gait, find_gait
from ucontrol.analysis.simplest_walker import SimplestWalker
from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.exceptions import ShapeError
from ucontrol.scene import Scene

#: The scene's gravity [m/s²]; time unit of the simplest walker sqrt(l/g), l = 1 m.
RATE_SCALE = math.sqrt(9.81)
#: Richardson extrapolation of the gaits at beta = 1e-3 and 1e-4 against the beta -> 0 walker
#: (measured: 1.4e-8 on the section's coordinates, 1.8e-8 on the period, 1.8e-5 on the
#: multipliers, which move faster with beta: 1.4e-2 at 1e-3, 1.4e-3 at 1e-4); the gaits
#: themselves differ from the limit by O(beta) (1.5e-4 at 1e-3).
LIMIT_TOLERANCE = 1e-7
MULTIPLIER_TOLERANCE = 5e-5
DOWNHILL = np.array([1.0, 0.0, 0.0])


def _scene(tmp_path: Path, beta: float) -> Scene:
    """The shipped compass walker with feet of mass beta (the hip's is 1 kg)."""
    urdf = (ROBOTS / "compass_walker.urdf").read_text()
    urdf_path = tmp_path / f"compass_{beta:g}.urdf"
    urdf_path.write_text(urdf.replace('<mass value="0.01"/>', f'<mass value="{beta!r}"/>'))
    toml = (ROBOTS / "compass_walker.toml").read_text()
    toml_path = tmp_path / f"compass_{beta:g}.toml"
    toml_path.write_text(toml.replace('"compass_walker.urdf"', f'"{urdf_path.name}"'))
    return Scene.from_toml(toml_path)


def _chart(flow: StanceFlow) -> tuple[Any, Any]:
    """The chart z = (θ, θ̇, φ̇) after a strike, in the simplest walker's units.

    q = (x, z, hip_a, hip_b): the stance leg's rotation is -θ, the swing leg's -(θ - φ), with
    φ = 2θ after a strike; leg a is the stance leg of ``to_state``.
    """

    def to_state(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta, dtheta, dphi = z
        q = np.array([-math.sin(theta), math.cos(theta), -theta, theta])
        hip = -dtheta * np.array([math.cos(theta), math.sin(theta)])
        return q, RATE_SCALE * np.array([*hip, -dtheta, dphi - dtheta])

    def from_state(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        stance = flow.stance_of(q, v)
        swing = 1 - stance
        rate_stance, rate_swing = v[2 + stance], v[2 + swing]
        return np.array(
            [-q[2 + stance], -rate_stance / RATE_SCALE, (rate_swing - rate_stance) / RATE_SCALE]
        )

    return to_state, from_state


@pytest.fixture(scope="module")
def gaits(tmp_path_factory: pytest.TempPathFactory) -> dict[float, Gait]:
    tmp_path = tmp_path_factory.mktemp("compass")
    z0 = np.array([0.2003109, -0.1998325, -0.0158230])
    found = {}
    for beta in (1e-3, 1e-4):
        flow = StanceFlow(_scene(tmp_path, beta).constraints, ahead=DOWNHILL)
        found[beta] = find_gait(flow, *_chart(flow), z0, step=1e-6)
    return found


def test_the_gaits_tend_to_the_simplest_walker_as_the_foot_mass_vanishes(
    gaits: dict[float, Gait],
) -> None:
    walker = SimplestWalker(slope=0.009)
    limit = find_gait(walker, walker.to_state, walker.from_state, np.array([0.2, -0.2]))
    theta, dtheta = limit.z
    z_limit = np.array([theta, dtheta, (1.0 - math.cos(2.0 * theta)) * dtheta])
    small, smaller = gaits[1e-3], gaits[1e-4]
    # O(beta): a tenth of the foot mass, a tenth of the distance to the limit.
    ratio = np.linalg.norm(small.z - z_limit) / np.linalg.norm(smaller.z - z_limit)
    assert 9.5 < ratio < 10.5
    # Richardson in beta (ratio 10) removes the O(beta) term.
    extrapolated = (10.0 * smaller.z - small.z) / 9.0
    assert np.max(np.abs(extrapolated - z_limit)) <= LIMIT_TOLERANCE
    period = (10.0 * smaller.period - small.period) / 9.0 * RATE_SCALE
    assert abs(period - limit.period) <= LIMIT_TOLERANCE
    # Multipliers: the complex pair of the limit, and a third one that vanishes with beta
    # (with massless feet the strike fixes φ̇⁺ from θ̇⁺).
    pair = [np.sort_complex(gait.multipliers[:2]) for gait in (small, smaller)]
    extrapolated_pair = (10.0 * pair[1] - pair[0]) / 9.0
    reference = np.sort_complex(np.linalg.eigvals(walker.stride_jacobian(limit.z)))
    assert np.max(np.abs(extrapolated_pair - reference)) <= MULTIPLIER_TOLERANCE
    assert abs(smaller.multipliers[2]) < 1e-6 and smaller.stable


def test_the_scuff_is_ignored_and_the_swing_foot_strikes_ahead(
    tmp_path: Path, gaits: dict[float, Gait]
) -> None:
    scene = _scene(tmp_path, 1e-4)
    flow = StanceFlow(scene.constraints, ahead=DOWNHILL)
    q, v = _chart(flow)[0](gaits[1e-4].z)
    stride = flow.stride(q, v)
    # The struck foot (b) is ahead of the old stance foot (a, at x = 0), a step length away.
    assert stride.stance == 1
    assert stride.q[0] - math.sin(stride.q[3]) == pytest.approx(2.0 * math.sin(gaits[1e-4].z[0]))
    # The swing foot went below the slope on the way (the scuff that is ignored): its gap at
    # the gait's scuff time is negative.
    state = np.concatenate((q, v))
    scuff_time = 1.854 / RATE_SCALE  # [s] deepest point of the beta -> 0 walker's scuff

    solution = solve_ivp(
        lambda _, y: np.concatenate((y[4:], flow.acceleration(y[:4], y[4:], 0)[0])),
        (0.0, scuff_time),
        state,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
    )
    assert -1e-4 < scene.constraints.gaps(solution.y[:4, -1])[1] < -1e-5


def test_a_direction_of_travel_of_the_wrong_shape_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ShapeError, match="ahead"):
        StanceFlow(_scene(tmp_path, 1e-2).constraints, ahead=np.array([1.0, 0.0]))
