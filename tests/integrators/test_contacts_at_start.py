r"""Contacts closed at the start of a run (MoreauJean's first-step rule).

A block put flat on a 30° incline by trigonometry, its pitch one ulp above 30°, has corner gaps
of :math:`-6.9\cdot10^{-18}` and :math:`2.1\cdot10^{-17}` m (at 30° to the last bit both round
to 0). Without the rule the corner with the positive gap is out of the first step, the block
falls on one corner and tilts by :math:`5.7\cdot10^{-5}` rad (measured with the rule switched
off below); with it both corners are held from the first step, the pitch stays at its start to
round-off (measured 1.1e-16 rad from 30°), and the normal impulses of the first step carry the
weight's normal component, :math:`m g \cos 30^\circ h`, as the analytic sliding solution says
(measured error 1.0e-14 N s: closing the start's gaps within the step). The rule must not touch
a real approach: a ball 0.1 nm above the ground falling at 1 m/s still bounces with Newton's
law.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ucontrol.integrators import step_stages
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
SLOPE = math.radians(30.0)
#: Half-height of the block of robots/planar_block.urdf, in [m]; its mass in [kg].
HALF_HEIGHT, MASS, G = 0.05, 1.0, 9.81


def _block_on_incline() -> Scene:
    """robots/block_incline.toml with the block on the incline to round-off (gaps ~ ±1e-17 m)."""
    import tomllib

    table: dict[str, Any] = tomllib.loads((ROBOTS / "block_incline.toml").read_text())
    centre = HALF_HEIGHT * np.array([math.sin(SLOPE), math.cos(SLOPE)])
    table["robot"]["q0"] = [float(centre[0]), float(centre[1]), math.nextafter(SLOPE, math.inf)]
    table["duration"] = 0.2
    return Scene.from_dict(table, base_dir=ROBOTS, default_name="block_on_incline")


def test_the_gaps_of_the_block_round_to_both_signs() -> None:
    """The set-up is the one the rule is for: one corner's gap is positive, by round-off only."""
    scene = _block_on_incline()
    state = scene.build_integrator().evaluate(scene.q0, scene.v0, 0.0)
    assert np.abs(state.gap).max() < 1e-16
    assert state.gap.max() > 0.0


def test_a_block_put_on_an_incline_slides_without_tilting() -> None:
    result = simulate(_block_on_incline(), out=None, progress=False)
    log = result.log
    assert np.abs(log.q[:, 2] - SLOPE).max() <= 1e-14  # measured 1.1e-16, the start's ulp
    assert log.active[0].all()  # both corners in the first step
    h = float(log.t[1] - log.t[0])
    normal_impulse = log.impulse[0].sum()
    # Closing the start's gaps (up to 2.1e-17 m) within the step adds about m g_0 / h = 2e-14 N s.
    assert normal_impulse == pytest.approx(MASS * G * math.cos(SLOPE) * h, abs=5e-14)


def test_without_the_rule_the_block_tilts(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same run with the rule switched off: the defect the rule removes is real."""
    monkeypatch.setattr(step_stages, "START_GAP_TOLERANCE", -1.0)
    log = simulate(_block_on_incline(), out=None, progress=False).log
    assert np.abs(log.q[:, 2] - SLOPE).max() > 1e-5  # measured 5.7e-5 rad
    assert not log.active[0].all()


@pytest.mark.parametrize("restitution", [0.0, 0.5, 1.0])
def test_a_real_approach_at_the_start_still_bounces(restitution: float) -> None:
    """A ball 0.1 nm above the ground falling at 1 m/s: Newton's law on the first step."""
    table = {
        "name": "ball",
        "duration": 0.002,
        "robot": {"urdf": "ball.urdf", "q0": [0.1 + 1e-10], "v0": [-1.0], "gravity": [0, 0, 0]},
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
        "contacts": [
            {"frame": "ball", "surface": "ground", "radius": 0.1, "restitution": restitution}
        ],
        "integrator": {"name": "moreau_jean", "dt": 1e-3},
    }
    scene = Scene.from_dict(table, base_dir=ROBOTS, default_name="ball")
    log = simulate(scene, out=None, progress=False).log
    assert log.v[1, 0] == pytest.approx(restitution * 1.0, abs=1e-14)
