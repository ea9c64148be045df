"""Impact-invariant projection of the task-space laws: what an impact cannot change."""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.control.controller import ContactState
from ucontrol.control.impedance_controller import ImpedanceController
from ucontrol.exceptions import InvalidParameterError, URDFError
from ucontrol.model import example_robot_data_dir
from ucontrol.scene import Scene

SPREADING_KEYS = ("restitution", "blend_time", "interim_time", "impact_speed", "contact_gap")


def _impedance(**changes: Any) -> tuple[Scene, ImpedanceController]:
    """The impedance law on the task of robots/panda_landing_rs.toml."""
    try:
        example_robot_data_dir()
    except URDFError:
        pytest.skip("example-robot-data is not installed (extra `robots`)")
    spec = tomllib.loads((ROBOTS / "panda_landing_rs.toml").read_text())
    table = {k: v for k, v in spec["controller"].items() if k not in SPREADING_KEYS}
    spec["controller"] = {**table, "type": "impedance", "joint_damping": 2.0, **changes}
    scene = Scene.from_dict(spec, base_dir=ROBOTS, default_name="panda_landing")
    controller = scene.build_controller()
    assert isinstance(controller, ImpedanceController)
    return scene, controller


def _impact(scene: Scene, q: np.ndarray, v: np.ndarray, e: float) -> np.ndarray:
    """v+ of a rigid impact of the TCP on the table (KKT system of Newton's law)."""
    model = scene.robot.model
    data = model.createData()
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    pin.computeJointJacobians(model, data, q)
    frame = model.getFrameId("panda_hand_tcp")
    pin.updateFramePlacement(model, data, frame)
    J_c = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[2:3]
    K = np.block([[M, -J_c.T], [J_c, np.zeros((1, 1))]])
    return np.linalg.solve(K, np.concatenate([M @ v, -e * (J_c @ v)]))[: scene.robot.nv]


@pytest.mark.parametrize("e", [0.0, 0.7])
def test_projected_error_is_unchanged_by_an_impact(e: float) -> None:
    scene, controller = _impedance(impact_invariant=True)
    rng = np.random.default_rng(7)
    q = scene.q0 + 0.1 * rng.standard_normal(scene.robot.nq)
    v_minus = rng.standard_normal(scene.robot.nv)
    v_plus = _impact(scene, q, v_minus, e)
    P, P_x = controller.invariant_projectors(q)
    assert np.linalg.norm(v_plus - v_minus) > 0.1  # the impact changes the velocity
    np.testing.assert_allclose(P @ v_plus, P @ v_minus, rtol=0.0, atol=1e-10)
    _, J = _jacobian(scene, q)
    dx_d = np.array([0.1, -0.2, -0.3])
    error_minus, error_plus = J @ v_minus - dx_d, J @ v_plus - dx_d  # [m/s]
    assert np.linalg.norm(error_plus - error_minus) > 0.1
    np.testing.assert_allclose(P_x @ error_plus, P_x @ error_minus, rtol=0.0, atol=1e-10)
    np.testing.assert_allclose(J @ P, P_x @ J, rtol=0.0, atol=1e-10)  # J P = P_x J


def _jacobian(scene: Scene, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    model = scene.robot.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    frame = model.getFrameId("panda_hand_tcp")
    pin.updateFramePlacement(model, data, frame)
    return data.oMf[frame].translation, pin.getFrameJacobian(
        model, data, frame, pin.LOCAL_WORLD_ALIGNED
    )[:3]


def test_torque_jump_at_impact_is_smaller_with_the_projection() -> None:
    jumps = {}
    for invariant in (False, True):
        scene, controller = _impedance(impact_invariant=invariant)
        q = scene.q0
        v_minus = np.linalg.pinv(_jacobian(scene, q)[1]) @ np.array([0.05, 0.0, -0.3])
        v_plus = _impact(scene, q, v_minus, 0.0)
        t = controller.contact_phases[0].start  # the nominal impact: in the window
        contacts = ContactState(
            names=[controller.contacts[0].name],
            gap=np.zeros(1),
            normal_velocity=np.zeros(1),
            impulse=np.zeros(1),
            active=np.ones(1, dtype=bool),
            dt=1e-3,
        )
        before = controller(t, q, v_minus, contacts)
        after = controller(t, q, v_plus, contacts)
        jumps[invariant] = float(np.linalg.norm(after - before))  # [N m]
    assert jumps[False] > 1.0
    assert jumps[True] < 1e-9 * jumps[False] + 1e-10


def test_invalid_options_raise() -> None:
    with pytest.raises(InvalidParameterError, match="impact_invariant"):
        _impedance(impact_invariant="yes")
    scene, controller = _impedance()
    with pytest.raises(InvalidParameterError, match="impact_invariant"):
        ImpedanceController(
            scene.robot, controller.frame, controller.path, controller.gains, impact_invariant=True
        )
    with pytest.raises(InvalidParameterError, match="invariant_window"):
        _impedance(impact_invariant=True, invariant_window=0.0)
