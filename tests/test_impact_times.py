"""Impact times in the log: each integrator's against the bouncing ball's closed form."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import ROBOTS, ball_scene

from ucontrol.analysis import impact_mask
from ucontrol.exceptions import LogFileError, NotFoundError
from ucontrol.integrators.contact_laws import damping_ratio
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.scene.push import Push
from ucontrol.simulate import simulate

GRAVITY, HEIGHT, MASS = 9.81, 1.0, 1.0  # the ball of robots/ball.toml: [m/s²], [m], [kg]
RESTITUTION = 0.9
CONTACT = "ball/ground"


def _closed_form_impact_times(count: int) -> np.ndarray:
    r"""t_n = t_0 + 2 e V_0 (1 - e^n) / (g (1 - e)), the sum of the flights' 2 e^n V_0 / g [s]."""
    speed = math.sqrt(2.0 * GRAVITY * HEIGHT)  # [m/s], dropped at rest
    n = np.arange(count)
    e = RESTITUTION
    return speed / GRAVITY + 2.0 * e * speed * (1.0 - e**n) / (GRAVITY * (1.0 - e))


def _log(integrator: str, duration: float, **settings: object) -> Log:
    scene = ball_scene(RESTITUTION)
    settings_ = dataclasses.replace(scene.integrator, name=integrator, **settings)
    scene = dataclasses.replace(scene, integrator=settings_)
    return simulate(scene, duration=duration, progress=False).log


def test_event_driven_impact_times_are_the_analytic_ones() -> None:
    log = _log("event_driven", 3.0)
    impacts = log.impacts
    assert impacts.t.size == 4  # t_3 = 2.64 s, t_4 = 3.30 s
    assert list(impacts.constraint) == [CONTACT] * 4
    error = np.max(np.abs(impacts.t - _closed_form_impact_times(4)))
    assert error <= 1e-9, error  # measured 1.3e-15 s
    np.testing.assert_array_equal(log.impact_times_of(CONTACT), impacts.t)


@pytest.mark.parametrize("dt", [1e-3, 1e-4])
def test_moreau_jean_impact_times_are_the_start_of_the_impact_steps(dt: float) -> None:
    log = _log("moreau_jean", 3.0, dt=dt)
    impacts = log.impacts
    # The impact table names the steps whose rows hold the impact impulses.
    np.testing.assert_array_equal(impacts.t, log.t[np.flatnonzero(impact_mask(log)[:, 0])])
    expected = _closed_form_impact_times(impacts.t.size)
    assert impacts.t.size == 4
    # The first impact within one step h; each later one a step further at most (each flight
    # adds its O(h) time-stepping error: measured 0.48, 1.7, 2.3, 2.9 ms at h = 1 ms).
    errors = np.abs(impacts.t - expected)
    assert np.all(errors <= dt * np.arange(1, 5)), errors / dt


def test_compliant_onsets_tend_to_the_rigid_impact_times_as_stiffness_grows() -> None:
    """Compliant onsets: the first exact, the next late by less than a contact's duration.

    The first onset ends a free flight; each contact then delays the next onset by less than
    its half period π/ω_d, ω_d = ω sqrt(1 - ζ²), ω = sqrt(k/m): the compliance's error, which
    shrinks as k^(-1/2).
    """
    lags = []
    zeta = damping_ratio(RESTITUTION)
    for stiffness in (1e6, 1e8):
        onsets = _log("compliant", 1.3, stiffness=stiffness).impacts.t
        assert onsets.size == 2  # t_1 = 1.264 s
        lag = onsets - _closed_form_impact_times(2)
        assert abs(lag[0]) <= 1e-9, lag[0]  # measured 1.9e-15 s
        half_period = math.pi / (math.sqrt(stiffness / MASS) * math.sqrt(1.0 - zeta**2))
        assert 0.0 < lag[1] <= half_period, (lag[1], half_period)
        lags.append(lag[1])
    assert lags[0] / lags[1] == pytest.approx(10.0, rel=0.05)  # measured 10.01


def test_impact_table_survives_save_and_load(tmp_path: Path) -> None:
    log = _log("event_driven", 1.5)
    path = log.save(tmp_path / "log.npz")
    loaded = Log.load(path)
    np.testing.assert_array_equal(loaded.impacts.t, log.impacts.t)
    np.testing.assert_array_equal(loaded.impacts.constraint, log.impacts.constraint)
    assert loaded.impacts.t.size == 2
    assert "impact_t" not in loaded.fields  # a table of its own, not per-sample arrays
    with np.load(path) as archive:
        np.testing.assert_array_equal(archive["impact_constraint"], [0, 0])


def test_log_written_without_an_impact_table_loads_with_none(tmp_path: Path) -> None:
    log = _log("event_driven", 0.1)
    path = log.save(tmp_path / "log.npz")
    with np.load(path) as archive:
        content = {key: archive[key] for key in archive.files}
    del content["impact_t"], content["impact_constraint"]
    np.savez(path, **content)
    loaded = Log.load(path)
    assert loaded.impacts.t.shape == (0,) and loaded.impacts.constraint.shape == (0,)


def test_broken_impact_table_is_a_log_file_error(tmp_path: Path) -> None:
    log = _log("event_driven", 0.1)
    path = log.save(tmp_path / "log.npz")
    with np.load(path) as archive:
        content = {key: archive[key] for key in archive.files}
    content["impact_t"], content["impact_constraint"] = np.array([0.5]), np.array([3])
    np.savez(path, **content)
    with pytest.raises(LogFileError, match=r"impact table .* \[3\] for 1 constraints"):
        Log.load(path)


def test_impact_times_of_an_unknown_constraint_names_the_known_ones() -> None:
    log = Log(1, nq=1, nv=1, nu=1, constraint_names=[CONTACT])
    with pytest.raises(NotFoundError, match=CONTACT):
        log.impact_times_of("ball/wall")


@pytest.mark.slow
def test_moreau_jean_impacts_are_the_landings_after_flights_not_the_held_contact() -> None:
    # The Panda's tool bounces on the table (e = 0.5) from t = 2 s and is then pressed on it.
    # Before the release band and the shared rule the summary counted 35 "impacts" in these
    # 3 s (every pressed step that closed faster than 1e-6 m/s) and the steps 4.
    result = simulate(Scene.from_toml(ROBOTS / "panda_table_impedance.toml"), duration=3.0)
    log = result.log
    contact = log.constraint_names.index("panda_hand_tcp/table")
    pressed = log.impulse[:-1, contact] > 0.0
    landings = np.flatnonzero(pressed & ~np.concatenate(([False], pressed[:-1])))
    # Each pressed run starts after a flight (the tool above the table in the step before).
    assert np.all(log.gap[landings - 1, contact] > 0.0)
    np.testing.assert_array_equal(log.impacts.t, log.t[landings])
    assert landings.size == 4 and pressed[landings[-1] :].all()  # held from the last on
    assert result.summary["n_impacts"] == log.impacts.t.size
    np.testing.assert_array_equal(np.flatnonzero(impact_mask(log)[:, contact]), landings)


def test_a_held_contact_pushed_into_the_ground_has_an_impact() -> None:
    # A plastic ball lands at t_0 = sqrt(2 h / g) = 0.4515 s and rests, held step after step;
    # pushed down at 0.5 m/s it has an impact although held (faster than 0.1 m/s), pushed at
    # 0.05 m/s its contact only closes again (below that speed, as a held contact's drift).
    pushes = (Push(time=1.0, velocity=np.array([-0.5])), Push(time=1.5, velocity=np.array([-0.05])))
    result = simulate(ball_scene(0.0, pushes=pushes), duration=2.0, progress=False)
    log = result.log
    np.testing.assert_allclose(log.impacts.t, [math.sqrt(2.0 / GRAVITY), 1.0], atol=1e-3)
    assert result.summary["n_impacts"] == 2
    np.testing.assert_array_equal(log.t[np.flatnonzero(impact_mask(log)[:, 0])], log.impacts.t)
    assert np.all(log.impulse[460:-1, 0] > 0.0)  # held from the landing on
