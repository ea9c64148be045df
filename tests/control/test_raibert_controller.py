"""Raibert's hopping laws on the shipped hopper (robots/hopper.toml), Moreau-Jean closed loop."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from ucontrol.analysis.hop_flow import logged_apexes
from ucontrol.campaign.overrides import apply_overrides
from ucontrol.control.raibert_controller import RaibertController, RaibertSettings
from ucontrol.exceptions import InvalidParameterError, NotFoundError, UnknownKeyError
from ucontrol.scene import Scene, load_scene
from ucontrol.scene.builtin_scenes import builtin_scene
from ucontrol.simulate import simulate

#: The issue's acceptance: every apex within 1 % of the command.
APEX_TOLERANCE = 0.01


def _scene(**overrides: object) -> Scene:
    path = builtin_scene("hopper")
    table = apply_overrides(tomllib.loads(path.read_text()), overrides)
    return Scene.from_dict(table, base_dir=path.parent)


def _apexes(q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return logged_apexes(q[:, 1], v[:, 1])


def test_fifty_hops_at_the_commanded_apex() -> None:
    scene = load_scene("hopper")
    log = simulate(scene, duration=35.0, progress=False).log
    apexes, _ = _apexes(np.asarray(log.q), np.asarray(log.v))
    assert apexes.size >= 50
    assert np.max(np.abs(apexes[:50] - 0.8)) / 0.8 < APEX_TOLERANCE
    phases = set(np.unique(np.asarray(log.phase)).tolist())
    assert phases == {0, 1, 2, 3}  # flight, compression, thrust, extended


def test_foot_placement_drives_the_forward_speed() -> None:
    """From rest to 0.5 m/s: the speed at the apexes settles within 10 %.

    Raibert's law keeps an offset where T_s differs from the stance's duration.
    """
    log = simulate(_scene(**{"controller.speed": 0.5}), duration=8.0, progress=False).log
    q, v = np.asarray(log.q), np.asarray(log.v)
    apexes, k = _apexes(q, v)
    assert np.all(np.abs(v[k[-4:], 0] - 0.5) < 0.05)
    assert np.max(np.abs(apexes - 0.8)) / 0.8 < APEX_TOLERANCE


def test_thrust_fills_the_energy_deficit() -> None:
    """The thrust times the leg's remaining stroke is the energy still missing.

    At the bottom of a vertical stance, against the target's closed form.
    """
    scene = load_scene("hopper")
    law = scene.build_controller()
    assert isinstance(law, RaibertController)
    m, m_f, g, k = law.mass, law.foot_mass, 9.81, 3000.0
    l, l0, apex = 0.35, 0.5, 0.8
    q, v = np.array([0.0, l, 0.0, 0.0, l]), np.array([0.0, 0.0, 0.0, 0.0, 1e-9])
    target = m * g * l0 + m * g * (apex - l0) * ((m + m_f) / m) ** 2
    energy = m * g * l + 0.5 * k * (l0 - l) ** 2
    assert law.thrust(q, v) == pytest.approx((target - energy) / (l0 - l), rel=1e-12)
    assert law.stance_phase(q, v) == 2


def test_bad_settings_are_refused() -> None:
    with pytest.raises(InvalidParameterError, match="apex"):
        RaibertSettings(apex=0.4, leg_length=0.5)
    with pytest.raises(InvalidParameterError, match="leg_stiffness"):
        RaibertSettings(apex=0.8, leg_stiffness=-1.0)


def test_bad_tables_are_refused() -> None:
    with pytest.raises(UnknownKeyError, match="thrust_gain"):
        _scene(**{"controller.thrust_gain": 1.0}).build_controller()
    with pytest.raises(NotFoundError, match="toe"):
        _scene(**{"controller.contact": "toe"}).build_controller()
    with pytest.raises(InvalidParameterError, match="joints"):
        _scene(**{"controller.joints": ["x", "z"]}).build_controller()


def test_a_passive_hip_is_refused() -> None:
    with pytest.raises(InvalidParameterError, match="hip"):
        _scene(**{"robot.passive": ["x", "z", "pitch", "hip"]}).build_controller()


def test_a_joint_of_several_coordinates_is_refused() -> None:
    ball = load_scene("free_ball").robot
    with pytest.raises(InvalidParameterError, match="root_joint"):
        RaibertController(
            ball, contact=0, settings=RaibertSettings(apex=0.8), joints=("root_joint",) * 5
        )
