r"""The position update of free-flyer and planar joints in Moreau–Jean (``_advance``).

A ball rolling without slipping on the ground turns about its contact point. Pinocchio's
integration of a free-flyer (the exponential of SE(3)) moves the body along the screw of its
twist, so within a step the centre turns about the contact point and sinks by
:math:`r(\omega h)^2/2`; a held contact never pushes it back (measured: 4.1 mm after 0.8 s of
rolling at 1 m/s, h = 1 ms, θ = 1). Moreau–Jean moves the origin of these joints along a
straight line instead (:math:`\mathbb{R}^3 \times SO(3)`, :math:`\mathbb{R}^2 \times SO(2)` for
a planar joint), so at θ = 1, where the displacement uses the velocity the contact problem
constrained, the centre stays at its height to round-off (measured error 0).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ucontrol.integrators import moreau_jean
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
RADIUS, SPEED = 0.1, 1.0  # [m], [m/s]

_DISK_URDF = """<?xml version="1.0"?>
<robot name="disk">
  <link name="base"/>
  <joint name="planar" type="planar">
    <parent link="base"/>
    <child link="disk"/>
  </joint>
  <link name="disk">
    <inertial>
      <mass value="1.0"/>
      <inertia ixx="0.0025" iyy="0.0025" izz="0.005" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
</robot>
"""


def _rolling_ball() -> Scene:
    """The free-flying ball of robots/free_ball.toml rolling on the ground at SPEED, μ = 0.5."""
    table: dict[str, Any] = {
        "name": "rolling_ball",
        "duration": 0.8,
        "robot": {
            "urdf": "free_ball.urdf",
            "floating_base": True,
            "q0": [0.0, 0.0, RADIUS, 0.0, 0.0, 0.0, 1.0],
            "v0": [SPEED, 0.0, 0.0, 0.0, SPEED / RADIUS, 0.0],  # no slip: v = ω r
            "gravity": [0.0, 0.0, -9.81],
        },
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
        "contacts": [
            {
                "frame": "ball",
                "surface": "ground",
                "radius": RADIUS,
                "restitution": 0.0,
                "friction": 0.5,
            }
        ],
        "integrator": {"name": "moreau_jean", "dt": 1e-3, "theta": 1.0},
    }
    return Scene.from_dict(table, base_dir=ROBOTS, default_name="rolling_ball")


def _rolling_disk(folder: Path) -> Scene:
    """A disk on a planar joint (x-y plane, gravity along -y) rolling on the line y = 0."""
    (folder / "disk.urdf").write_text(_DISK_URDF)
    table: dict[str, Any] = {
        "name": "rolling_disk",
        "duration": 0.8,
        "robot": {
            "urdf": "disk.urdf",
            "q0": [0.0, RADIUS, 1.0, 0.0],  # (x, y, cos, sin)
            "v0": [SPEED, 0.0, -SPEED / RADIUS],  # rolling towards +x turns clockwise
            "gravity": [0.0, -9.81, 0.0],
            "planar_axis": [0.0, 0.0, 1.0],
        },
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]}},
        "contacts": [
            {
                "frame": "disk",
                "surface": "ground",
                "radius": RADIUS,
                "restitution": 0.0,
                "friction": 0.5,
            }
        ],
        "integrator": {"name": "moreau_jean", "dt": 1e-3, "theta": 1.0},
    }
    return Scene.from_dict(table, base_dir=folder, default_name="rolling_disk")


def _exponential_update(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pinocchio's integration on every joint (the update this module's rule replaces)."""
    original = moreau_jean.MoreauJean.__init__

    def init(self: moreau_jean.MoreauJean, *args: Any, **kwargs: Any) -> None:
        original(self, *args, **kwargs)
        self._free_flyers, self._planar_joints = [], []

    monkeypatch.setattr(moreau_jean.MoreauJean, "__init__", init)


def test_a_rolling_ball_keeps_its_height() -> None:
    log = simulate(_rolling_ball(), out=None, progress=False).log
    height_error = np.abs(log.q[:, 2] - RADIUS)
    assert height_error[:3].max() <= 1e-6  # the first steps settle the contact (1.9e-7 m)
    assert height_error[3:].max() <= 1e-12  # measured 0
    assert log.q[-1, 0] > 0.79  # it rolled (0.81 m: the step's speed gain, docs/moreau_jean.md)


def test_a_rolling_disk_on_a_planar_joint_keeps_its_height(tmp_path: Path) -> None:
    log = simulate(_rolling_disk(tmp_path), out=None, progress=False).log
    height_error = np.abs(log.q[:, 1] - RADIUS)
    assert height_error[:3].max() <= 1e-6  # the first steps settle the contact
    assert height_error[3:].max() <= 1e-12  # measured 0
    np.testing.assert_allclose(np.hypot(log.q[:, 2], log.q[:, 3]), 1.0, atol=1e-12)
    assert log.q[-1, 0] > 0.79


def test_the_exponential_update_sinks_the_rolling_ball(monkeypatch: pytest.MonkeyPatch) -> None:
    """The defect the rule removes: the SE(3) exponential sinks the ball by millimetres."""
    _exponential_update(monkeypatch)
    log = simulate(_rolling_ball(), out=None, progress=False).log
    assert RADIUS - log.q[:, 2].min() > 1e-3  # measured 4.1e-3 m
