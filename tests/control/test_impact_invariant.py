"""Impact-invariant projection of the task-space laws: what an impact cannot change."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from panda_landing import SPREADING_KEYS, build, dynamics, impact_map, spec

from ucontrol.control.controller import ContactState
from ucontrol.control.impedance_controller import ImpedanceController
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene


def _impedance(**changes: Any) -> tuple[Scene, ImpedanceController]:
    """The impedance law on the task of robots/panda_landing_rs.toml."""
    table = {k: v for k, v in spec()["controller"].items() if k not in SPREADING_KEYS}
    changes = {"type": "impedance", "joint_damping": 2.0, **changes}
    return build({**table, **changes}, ImpedanceController)


@pytest.mark.parametrize("e", [0.0, 0.7])
def test_projected_error_is_unchanged_by_an_impact(e: float) -> None:
    scene, controller = _impedance(impact_invariant=True)
    rng = np.random.default_rng(7)
    q = scene.q0 + 0.1 * rng.standard_normal(scene.robot.nq)
    v_minus = rng.standard_normal(scene.robot.nv)
    v_plus = impact_map(scene, q, v_minus, e)
    P, P_x = controller.invariant_projectors(q)
    assert np.linalg.norm(v_plus - v_minus) > 0.1  # the impact changes the velocity
    np.testing.assert_allclose(P @ v_plus, P @ v_minus, rtol=0.0, atol=1e-10)
    _, J = dynamics(scene, q)
    dx_d = np.array([0.1, -0.2, -0.3])
    error_minus, error_plus = J @ v_minus - dx_d, J @ v_plus - dx_d  # [m/s]
    assert np.linalg.norm(error_plus - error_minus) > 0.1
    np.testing.assert_allclose(P_x @ error_plus, P_x @ error_minus, rtol=0.0, atol=1e-10)
    np.testing.assert_allclose(J @ P, P_x @ J, rtol=0.0, atol=1e-10)  # J P = P_x J


def test_torque_jump_at_impact_is_smaller_with_the_projection() -> None:
    jumps = {}
    for invariant in (False, True):
        scene, controller = _impedance(impact_invariant=invariant)
        q = scene.q0
        v_minus = np.linalg.pinv(dynamics(scene, q)[1]) @ np.array([0.05, 0.0, -0.3])
        v_plus = impact_map(scene, q, v_minus, 0.0)
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
