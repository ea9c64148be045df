"""Reference spreading: impact map, overlap, switch, and the Panda landing against Brogliato."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import load_experiment
from panda_landing import build, dynamics, impact_map, spec

from ucontrol.control.controller import ContactState
from ucontrol.control.reference_spreading import (
    ReferenceSpreadingController,
    SpreadingMode,
    SpreadingSettings,
)
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene

CONTACT = "panda_hand_tcp/table"


def _controller(**changes: Any) -> tuple[Scene, ReferenceSpreadingController]:
    return build({**spec()["controller"], **changes}, ReferenceSpreadingController)


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_post_velocity_is_the_rigid_impact_map(e: float) -> None:
    scene, controller = _controller(restitution=e)
    rng = np.random.default_rng(3)
    q = scene.q0 + 0.1 * rng.standard_normal(scene.robot.nq)
    _, J = dynamics(scene, q)
    v_minus = rng.standard_normal(scene.robot.nv)  # null-space part included
    v_plus = impact_map(scene, q, v_minus, e)
    predicted = controller.post_velocity_map(q, J @ v_minus)
    np.testing.assert_allclose(predicted, J @ v_plus, rtol=0.0, atol=1e-10)
    assert predicted[2] == pytest.approx(-e * (J @ v_minus)[2], abs=1e-10)


def test_references_overlap_around_the_nominal_impact() -> None:
    _, controller = _controller()
    t_i = controller.impact_time(0)
    p, dp = controller.path.derivatives(t_i, 1)
    assert dp[2] == pytest.approx(-0.3, abs=1e-12)  # lands at 0.3 m/s
    # ante: the path up to t_i, extended past it at its velocity there
    x, dx, ddx = controller.ante_reference(t_i + 0.05, 0)
    np.testing.assert_allclose(x, p + 0.05 * dp, atol=1e-15)
    np.testing.assert_allclose(dx, dp, atol=1e-15)
    np.testing.assert_array_equal(ddx, 0.0)
    # post: starts at the impact point with the impact map's velocity, extended before t_i
    controller.post_velocity = np.array([-0.2, -0.08, 0.0])
    x_i, dx_i, _ = controller.post_reference(t_i, 0)
    np.testing.assert_allclose(x_i, p, atol=1e-12)
    np.testing.assert_allclose(dx_i, controller.post_velocity, atol=1e-12)
    x_before, dx_before, _ = controller.post_reference(t_i - 0.05, 0)
    np.testing.assert_allclose(x_before, p - 0.05 * controller.post_velocity, atol=1e-12)
    np.testing.assert_allclose(dx_before, controller.post_velocity, atol=1e-15)
    # velocity: the difference quotient of the position
    h = 1e-6
    for t in (t_i + 0.01, t_i + 0.15):
        slope = controller.post_reference(t + h, 0)[0] - controller.post_reference(t - h, 0)[0]
        np.testing.assert_allclose(slope / (2 * h), controller.post_reference(t, 0)[1], atol=1e-6)
    # after the blend: the contact-phase reference
    t = t_i + controller.settings.blend_time + 0.01
    np.testing.assert_allclose(controller.post_reference(t, 0)[0], controller.desired(t)[0])


def _contacts(gap: float, normal_velocity: float, impulse: float) -> ContactState:
    return ContactState(
        names=[CONTACT],
        gap=np.array([gap]),
        normal_velocity=np.array([normal_velocity]),
        impulse=np.array([impulse]),
        active=np.array([gap <= 0.0]),
        dt=1e-3,
    )


def test_switch_comes_from_the_contact_state_not_the_impulses() -> None:
    scene, controller = _controller()
    t_i = controller.impact_time(0)
    q, v = scene.q0, np.zeros(scene.robot.nv)
    controller(t_i - 2e-3, q, v, _contacts(6e-4, -0.3, 0.0))
    controller(t_i - 1e-3, q, v, _contacts(3e-4, -0.3, 5.0))  # an impulse alone: no impact
    assert controller.mode is SpreadingMode.ANTE
    controller(t_i, q, v, _contacts(0.0, 0.0, 0.0))  # the velocity jumps at the surface
    assert controller.mode is SpreadingMode.INTERIM
    controller(t_i + 2e-3, q, v, _contacts(0.0, 0.0, 0.0))
    assert controller.mode is SpreadingMode.POST
    controller(controller.impact_time(1) - 0.1, q, v, _contacts(0.1, 0.0, 0.0))
    assert controller.mode is SpreadingMode.ANTE  # the next landing


def test_invalid_settings_raise() -> None:
    with pytest.raises(InvalidParameterError, match="restitution"):
        SpreadingSettings(restitution=1.5)
    with pytest.raises(InvalidParameterError, match="blend_time"):
        SpreadingSettings(blend_time=0.0)
    scene, controller = _controller()
    with pytest.raises(InvalidParameterError, match="exactly one phase"):
        ReferenceSpreadingController(
            scene.robot,
            controller.frame,
            controller.path,
            controller.gains,
            contacts=controller.contacts,
            contact_phases=(),
        )


@pytest.mark.slow
def test_reference_spreading_lowers_the_panda_velocity_error_peak() -> None:
    spec()
    compare = load_experiment("impact_control_compare")
    spreading = compare.run("panda", "reference spreading", landings=1)[0]
    brogliato = compare.run("panda", "Brogliato", landings=1)[0]
    # measured 0.258 / 0.0211 = 12.3 (docs/impact_control.md)
    assert brogliato.velocity_error > 8.0 * spreading.velocity_error
    assert spreading.impacts >= 1 and brogliato.impacts >= 1


@pytest.mark.slow
def test_comparison_script_writes_its_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    compare = load_experiment("impact_control_compare")
    compare.main(["--landings", "1", "--tasks", "two_link", "--out", str(tmp_path)])
    table = (tmp_path / "impact_control_compare.md").read_text().splitlines()
    assert len(table) == 2 + len(compare.LAWS)
    rows = {line.split("|")[2].strip(): line.split("|")[3:7] for line in table[2:]}
    assert set(rows) == set(compare.LAWS)
    for figures in rows.values():  # every landing met the ground and was measured
        assert all(np.isfinite(float(x)) for x in figures) and float(figures[3]) >= 1
    assert "Brogliato / reference spreading" in capsys.readouterr().out


@pytest.mark.parametrize("invariant", [False, True])
def test_interim_mode_feeds_back_no_velocity_an_impact_changes(invariant: bool) -> None:
    scene, controller = _controller(impact_invariant=invariant)
    t_i = controller.impact_time(0)
    q = scene.q0
    rng = np.random.default_rng(5)
    v_minus = rng.standard_normal(scene.robot.nv)
    controller(t_i - 1e-3, q, v_minus, _contacts(3e-4, -0.3, 0.0))
    controller(t_i, q, v_minus, _contacts(0.0, 0.0, 0.0))  # the impact: interim mode
    assert controller.mode is SpreadingMode.INTERIM
    before = controller(t_i, q, v_minus, _contacts(0.0, 0.0, 0.0))
    after = controller(t_i, q, impact_map(scene, q, v_minus, 0.0), _contacts(0.0, 0.0, 0.0))
    assert controller.mode is SpreadingMode.INTERIM
    np.testing.assert_allclose(after, before, rtol=0.0, atol=1e-9)
    other = controller(t_i, q, rng.standard_normal(scene.robot.nv), _contacts(0.0, 0.0, 0.0))
    if invariant:  # the invariant part of the velocity is still fed back
        assert np.linalg.norm(other - before) > 1e-3
    else:  # no velocity feedback at all
        np.testing.assert_allclose(other, before, rtol=0.0, atol=1e-9)
