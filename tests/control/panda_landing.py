"""The Panda landing task of robots/panda_landing_rs.toml and its rigid impact map (tests)."""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.exceptions import URDFError
from ucontrol.model import example_robot_data_dir
from ucontrol.scene import Scene

FRAME = "panda_hand_tcp"
#: Keys of the reference-spreading table that the impedance law does not take.
SPREADING_KEYS = ("restitution", "blend_time", "interim_time", "impact_speed", "contact_gap")


def spec() -> dict[str, Any]:
    """The scene's table (skips the test without example-robot-data)."""
    try:
        example_robot_data_dir()
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")
    return tomllib.loads((ROBOTS / "panda_landing_rs.toml").read_text())


def scene_with(controller: dict[str, Any]) -> Scene:
    """The scene with another ``[controller]`` table."""
    table = spec()
    table["controller"] = controller
    return Scene.from_dict(table, base_dir=ROBOTS, default_name="panda_landing")


def build(controller: dict[str, Any], kind: type) -> tuple[Scene, Any]:
    """The scene with another ``[controller]`` table and its controller, of class ``kind``."""
    scene = scene_with(controller)
    built = scene.build_controller()
    assert isinstance(built, kind)
    return scene, built


def dynamics(scene: Scene, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M (nv, nv) and the TCP's translational Jacobian (3, nv, world axes) at q."""
    model = scene.robot.model
    data = model.createData()
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    pin.computeJointJacobians(model, data, q)
    frame = model.getFrameId(FRAME)
    pin.updateFramePlacement(model, data, frame)
    return M, pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:3]


def impact_map(scene: Scene, q: np.ndarray, v: np.ndarray, e: float) -> np.ndarray:
    """v+ of a rigid impact of the TCP on the table z >= 0.2: the KKT system of Newton's law.

    [[M, -J_c^T], [J_c, 0]] [v+; P] = [M v-; -e J_c v-], J_c the Jacobian's z row.
    """
    M, J = dynamics(scene, q)
    J_c = J[2:3]
    K = np.block([[M, -J_c.T], [J_c, np.zeros((1, 1))]])
    return np.linalg.solve(K, np.concatenate([M @ v, -e * (J_c @ v)]))[: scene.robot.nv]
