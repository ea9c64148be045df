"""A capsule-link arm brushing a box obstacle, against the same arm with a hand-declared point.

robots/capsule_arm_box.toml (a collision pair link2 ↔ box shape: coal's capsule–box witness
row) and robots/capsule_arm_points.toml (frame "tip" with the capsule's radius against the
plane of the box's top face) are the same mechanics while the far cap slides on that face.
"""

from __future__ import annotations

import coal
import numpy as np
from conftest import ROBOTS

from ucontrol.scene import Scene
from ucontrol.simulate import simulate

_MU = 0.3  # Coulomb coefficient of both scenes
_LENGTH = 0.5  # link lengths [m]


def _log(name: str):
    return simulate(Scene.from_toml(ROBOTS / f"{name}.toml"), out=None, progress=False).log


def test_capsule_links_are_capsules() -> None:
    scene = Scene.from_toml(ROBOTS / "capsule_arm_box.toml")
    geometry = scene.constraints.collision
    assert geometry is not None
    shapes = [item.geometry for item in geometry.geometry_model.geometryObjects]
    assert all(isinstance(shape, coal.Capsule) for shape in shapes)
    assert [(s.radius, s.halfLength) for s in shapes] == [(0.03, 0.25)] * 2


def test_capsule_arm_slides_on_the_box_like_the_hand_declared_point() -> None:
    shapes, points = _log("capsule_arm_box"), _log("capsule_arm_points")
    # Measured: 5.6e-16 (q), 4.4e-15 (v), 8.5e-15 (impulses) over the 0.8 s run.
    for key in ("q", "v", "gap", "impulse", "friction_impulse"):
        np.testing.assert_allclose(
            np.asarray(getattr(shapes, key)), np.asarray(getattr(points, key)), rtol=0, atol=1e-12
        )
    # It brushes the box: contact from the landing on, the cap sliding along the top face
    # with the friction impulse on the cone's boundary (|P_t| = mu P_n).
    normal = np.asarray(shapes.impulse)[:, 0]
    tangential = np.linalg.norm(np.asarray(shapes.friction_impulse)[:, 0], axis=1)
    contact = np.flatnonzero(normal > 0.0)
    assert contact.size > 500
    q = np.asarray(shapes.q)
    tip_x = _LENGTH * (np.cos(q[:, 0]) + np.cos(q[:, 0] + q[:, 1]))  # [m]
    sliding = contact[np.abs(np.diff(tip_x)[contact[contact < len(tip_x) - 1]]) > 1e-5]
    path = np.abs(np.diff(tip_x)[contact[contact < len(tip_x) - 1]]).sum()  # [m]
    assert path > 0.05  # measured 0.071 m: 4 cm forward, then 3 cm back
    assert sliding.size > 0.9 * contact.size
    # Coulomb's cone is met to the friction solver's tolerance while sliding.
    np.testing.assert_allclose(tangential[sliding], _MU * normal[sliding], rtol=1e-6)
