"""ucontrol.testing: each assertion passes on a real run and fails on a doctored log.

The failures must name the cycle, the time and the value that failed.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from ucontrol.control.phase import Event, Phase
from ucontrol.log import Log
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate
from ucontrol.testing import (
    CampaignCase,
    RunAssertionError,
    assert_cycles_complete,
    assert_force_tracks,
    assert_lyapunov_decreases,
    assert_no_energy_gain,
    assert_penetration_below,
    campaign_cases,
)


@pytest.fixture(scope="module")
def arm():
    """Two cycles of Brogliato's rigid one-constraint case (21 s)."""
    scene = Scene.from_toml(builtin_scene("two_link_one_constraint.toml"))
    return simulate(scene, duration=21.0, progress=False)


@pytest.fixture(scope="module")
def ball():
    """The bouncing ball (e = 0.9) for 1.5 s: three impacts."""
    return simulate(Scene.from_toml(builtin_scene("ball.toml")), duration=1.5, progress=False)


def _copy(log: Log, tmp_path) -> Log:
    return Log.load(log.save(tmp_path / "copy.npz"))


def _tau0_rows(log: Log) -> np.ndarray:
    return np.flatnonzero(log.events[:, 0] & Event.TAU0)


def test_real_runs_pass(arm, ball):
    assert_cycles_complete(arm, min_cycles=2)
    assert_force_tracks(arm, within=0.05)
    assert_no_energy_gain(arm)
    assert_lyapunov_decreases(arm)
    assert_penetration_below(arm, 1e-4)
    assert_no_energy_gain(ball.log)
    # Moreau-Jean (theta = 1/2) lets the ball sink about theta h v_impact in its impact step
    v_impact = np.sqrt(2.0 * 9.81 * 1.0)  # [m/s], dropped from a 1 m gap
    assert_penetration_below(ball.log, 1.1 * 0.5 * 1e-3 * v_impact)
    with pytest.raises(RunAssertionError):
        assert_penetration_below(ball.log, 0.9 * 0.5 * 1e-3 * v_impact)


def test_penetration_names_constraint_time_and_depth(arm, tmp_path):
    log = _copy(arm.log, tmp_path)
    k = int(_tau0_rows(log)[1]) + 1500  # inside cycle 1
    log._arrays["gap"][k, 0] = -0.002
    with pytest.raises(RunAssertionError) as caught:
        assert_penetration_below(log, 1e-3)
    error = caught.value
    assert error.time == log.t[k] and error.value == pytest.approx(0.002)
    assert error.cycle == 1
    assert "'end_effector/ground'" in str(error) and f"{log.t[k]:.6g} s" in str(error)


def test_incomplete_cycle_names_cycle_contact_and_event(arm, tmp_path):
    log = _copy(arm.log, tmp_path)
    rows = _tau0_rows(log)
    cycle1 = slice(rows[1], len(log))
    log._extras["events"][cycle1, 0] &= ~np.int64(Event.TAKEOFF)
    with pytest.raises(RunAssertionError) as caught:
        assert_cycles_complete(log)
    error = caught.value
    assert error.cycle == 1 and error.time == pytest.approx(log.t[rows[1]])
    assert "t_d (takeoff)" in str(error) and "'end_effector/ground'" in str(error)
    with pytest.raises(RunAssertionError, match="2 cycle"):
        assert_cycles_complete(arm, min_cycles=3)


def test_force_error_names_cycle_time_and_relative_error(arm, tmp_path):
    log = _copy(arm.log, tmp_path)
    rows = _tau0_rows(log)
    held = np.flatnonzero(log.contact_phase[:, 0] == Phase.CONSTRAINED)
    held = held[held >= rows[1]]  # the constrained phase of cycle 1
    log._extras["contact_force"][held, 0] *= 1.2
    with pytest.raises(RunAssertionError) as caught:
        assert_force_tracks(log, within=0.05)
    error = caught.value
    # the real run tracks to ~1e-5, so the doctored error is 1.2 (1 + e) - 1 ~ 0.2
    assert error.cycle == 1 and error.value == pytest.approx(0.2, abs=1e-3)
    assert log.t[held[0]] < error.time < log.t[held[-1]]
    assert_force_tracks(log, within=0.25)


def test_energy_gain_names_the_impact_and_the_gain(ball, tmp_path):
    log = _copy(ball.log, tmp_path)
    impacts = np.flatnonzero(log.impulse[:-1, 0] > 0.0)
    k = int(impacts[1])
    original = log.energy[k + 1] - log.energy[k]  # [J]; the ball is not actuated
    log._arrays["energy"][k + 1] += 5.0
    with pytest.raises(RunAssertionError) as caught:
        assert_no_energy_gain(log)
    error = caught.value
    assert error.time == log.t[k] and error.value == pytest.approx(5.0 + original)
    assert "'ball/ground'" in str(error)


def test_a_nan_in_the_log_fails_instead_of_passing(ball, tmp_path):
    log = _copy(ball.log, tmp_path)
    k = int(np.flatnonzero(log.impulse[:-1, 0] > 0.0)[0])  # the first impact step
    log._arrays["gap"][k + 1, 0] = np.nan
    with pytest.raises(RunAssertionError, match="penetrates nan") as caught:
        assert_penetration_below(log, 1.0)
    assert caught.value.time == log.t[k + 1]
    log._arrays["energy"][k + 1] = np.nan
    with pytest.raises(RunAssertionError, match="adds nan J") as caught:
        assert_no_energy_gain(log, tolerance=1.0)
    assert caught.value.time == log.t[k]


def test_lyapunov_rise_names_both_cycles(arm, tmp_path):
    log = _copy(arm.log, tmp_path)
    rows = _tau0_rows(log)
    V0 = float(log.V[rows[0]])
    log._extras["V"][rows[1]] = 10.0 * V0
    with pytest.raises(RunAssertionError) as caught:
        assert_lyapunov_decreases(log)
    error = caught.value
    assert error.cycle == 1 and error.time == pytest.approx(log.t[rows[1]])
    assert error.value == pytest.approx(10.0 * V0)
    assert "cycle 0" in str(error)
    # V rises slightly inside Omega phases in discrete time: caught when asked for 0
    with pytest.raises(RunAssertionError, match="within an Omega phase"):
        assert_lyapunov_decreases(arm, omega_rise=0.0)


def test_phase_assertions_need_a_phase_machine_log(ball):
    with pytest.raises(RunAssertionError, match="phase-machine"):
        assert_cycles_complete(ball)


def test_campaign_cases_are_pytest_params_with_the_runs(tmp_path):
    path = tmp_path / "cases.toml"
    path.write_text(
        textwrap.dedent(
            """
            [campaign]
            scene = "ball.toml"
            duration = 0.1
            [grid]
            "contacts.0.restitution" = [0.25, 0.75]
            """
        )
    )
    params = campaign_cases(path)
    assert [p.id for p in params] == ["run-00000", "run-00001"]
    cases = [p.values[0] for p in params]
    assert all(isinstance(case, CampaignCase) for case in cases)
    assert [case.scene().contacts[0].restitution for case in cases] == [0.25, 0.75]
    assert cases[0].scene().duration == 0.1
