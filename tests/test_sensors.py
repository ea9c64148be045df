"""Sensors and actuators in the loop: each does to the closed loop what its model says."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ucontrol.control.controller import ContactState
from ucontrol.exceptions import InvalidParameterError, UnknownKeyError
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate

ROBOTS = builtin_scene().parent


def _scene(name: str, **tables: Any) -> Scene:
    table = tomllib.loads((ROBOTS / name).read_text())
    table.pop("reference", None)
    table.update(tables)
    return Scene.from_dict(table, base_dir=ROBOTS)


class _Recorder:
    """A controller that returns fixed torques (or its measured q) and keeps what it saw."""

    def __init__(self, torque: np.ndarray | None = None) -> None:
        self.torque = torque
        self.seen: list[tuple[float, np.ndarray, np.ndarray, ContactState]] = []

    def __call__(self, t: float, q: np.ndarray, v: np.ndarray, contacts: ContactState) -> Any:
        self.seen.append((t, q.copy(), v.copy(), contacts))
        return q[:2].copy() if self.torque is None else self.torque


def test_saturation_caps_the_applied_torque_exactly() -> None:
    scene = _scene("two_link_drop.toml", actuators={"torque_limit": "urdf"})  # effort = 100
    commanded = np.array([500.0, -30.0])
    log = simulate(scene, _Recorder(commanded), duration=0.05).log
    np.testing.assert_array_equal(log.commanded_u, np.tile(commanded, (len(log), 1)))
    np.testing.assert_array_equal(log.u, np.tile([100.0, -30.0], (len(log), 1)))


def test_rate_limit_bounds_the_change_per_period() -> None:
    rate, period = 2000.0, 2e-3  # [N m/s], [s]: 4 N m per period
    scene = _scene("two_link_drop.toml", actuators={"rate_limit": rate})
    recorder = _Recorder(np.array([30.0, -10.0]))
    log = simulate(scene, recorder, duration=0.05, control_period=period).log
    applied = log.u[::2]  # one row per control period
    np.testing.assert_allclose(applied[:7, 0], 4.0 * np.arange(1, 8))  # ramps at r T
    assert applied[7, 0] == 30.0  # up to the command
    np.testing.assert_allclose(applied[:3, 1], [-4.0, -8.0, -10.0])  # then holds the command
    np.testing.assert_array_equal(applied[-1], [30.0, -10.0])


@pytest.mark.parametrize("delay", [1, 3])
def test_delay_shifts_what_the_controller_sees_by_whole_periods(delay: int) -> None:
    hold = 2  # steps per control period
    scene = _scene("two_link_drop.toml", sensors={"delay": delay})
    recorder = _Recorder()  # u = the measured (q1, q2): the torque carries what was seen
    log = simulate(scene, recorder, duration=0.1, control_period=hold * 1e-3).log
    rows = np.arange(0, len(log) - 1, hold)  # rows where the controller ran
    seen_rows = np.maximum(rows - delay * hold, 0)
    np.testing.assert_array_equal(log.u[rows], log.q[seen_rows])
    np.testing.assert_array_equal(log.measured_q[rows], log.q[seen_rows])
    assert np.ptp(log.q[:, 0]) > 1e-3  # the arm moves: a wrong shift would show


def test_quantisation_error_is_bounded_by_half_the_resolution() -> None:
    resolution = 1e-3  # [rad]
    scene = _scene("two_link_drop.toml", sensors={"quantisation": resolution})
    log = simulate(scene, _Recorder(np.zeros(2)), duration=0.3).log
    error = log.measured_q - log.q
    assert np.max(np.abs(error)) <= 0.5 * resolution * (1 + 1e-12)
    steps = log.measured_q / resolution
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert np.max(np.abs(error)) > 0.4 * resolution  # the rounding is really applied


def test_position_noise_is_seeded_and_has_its_standard_deviation() -> None:
    sigma = 1e-3  # [rad]
    scene = _scene("two_link_drop.toml", sensors={"position_noise": sigma, "seed": 7})
    first = simulate(scene, _Recorder(np.zeros(2)), duration=2.0).log
    again = simulate(scene, _Recorder(np.zeros(2)), duration=2.0).log
    np.testing.assert_array_equal(first.measured_q, again.measured_q)
    error = (first.measured_q - first.q)[:-1]  # 2000 samples per joint
    # Standard error of a sample standard deviation: sigma / sqrt(2 N) = 1.6 % here.
    np.testing.assert_allclose(error.std(axis=0), sigma, rtol=0.08)
    assert np.all(np.abs(error.mean(axis=0)) < 4 * sigma / np.sqrt(error.shape[0]))
    other = _scene("two_link_drop.toml", sensors={"position_noise": sigma, "seed": 8})
    assert not np.array_equal(
        simulate(other, _Recorder(np.zeros(2)), duration=0.01).log.measured_q,
        first.measured_q[:11],
    )


def test_force_noise_has_its_standard_deviation_on_the_mean_force() -> None:
    sigma = 2.0  # [N]
    scene = _scene("ball.toml", sensors={"force_noise": sigma, "seed": 1})
    recorder = _Recorder(np.zeros(1))
    simulate(scene, recorder, duration=0.3)  # in flight: the true impulses are zero
    forces = np.array([contacts.force[0] for _, _, _, contacts in recorder.seen])
    np.testing.assert_allclose(forces.std(), sigma, rtol=0.15)


def _velocity_error_after_impact(source: str, observer: str = "oracle") -> tuple[float, float]:
    """|estimate - true| of the ball's velocity 3 and 30 periods after its first impact [m/s]."""
    scene = _scene(
        "ball.toml", sensors={"velocity": source, "velocity_cutoff": 5.0, "observer": observer}
    )  # 5 Hz: time constant 32 ms
    log = simulate(scene, _Recorder(np.zeros(1)), duration=0.6).log
    impact = int(np.argmax(log.impulse[:, 0] > 0))
    assert impact > 0 and log.v[impact + 1, 0] > 3.0  # it rebounds at ~4 m/s
    error = np.abs(log.measured_v[:, 0] - log.v[:, 0])
    return float(error[impact + 3]), float(error[impact + 30])


@pytest.mark.parametrize("observer", ["oracle", "momentum"])  # impacts: plant's, or flagged
def test_observer_survives_the_impact_where_the_filter_lags(observer: str) -> None:
    lag_3, lag_30 = _velocity_error_after_impact("difference")
    observer_3, observer_30 = _velocity_error_after_impact("observer", observer)
    jump = 4.43 + 3.99  # [m/s], the ball's velocity jump at its first impact
    alpha = 2 * np.pi * 5.0 * 1e-3 / (1 + 2 * np.pi * 5.0 * 1e-3)  # filter gain per period
    # The filter forgets the jump as (1 - alpha)^n: after 30 periods 39 % of it remains.
    assert lag_3 > 0.9 * jump * (1 - alpha) ** 3
    assert lag_30 > 0.9 * jump * (1 - alpha) ** 30
    # Re-initialised, the observer keeps only the filter's own lag behind the constant
    # acceleration g, which builds up as (g / omega_c)(1 - (1 - alpha)^n) after the reset.
    steady_lag = 9.81 / (2 * np.pi * 5.0)  # [m/s]
    assert observer_3 < steady_lag * (1 - (1 - alpha) ** 4) + 1e-3
    assert observer_30 < steady_lag * (1 - (1 - alpha) ** 31) + 1e-3


def test_true_velocity_by_default_and_exact_without_noise() -> None:
    scene = _scene("two_link_drop.toml", sensors={"delay": 0})
    log = simulate(scene, _Recorder(np.zeros(2)), duration=0.05).log
    # The last row has no controller call: it holds the last measurement, like u.
    np.testing.assert_array_equal(log.measured_q[:-1], log.q[:-1])
    np.testing.assert_array_equal(log.measured_v[:-1], log.v[:-1])


@pytest.mark.parametrize(
    ("table", "error", "match"),
    [
        ({"sensors": {"noise": 1.0}}, UnknownKeyError, r"'noise' in \[sensors\]"),
        ({"sensors": {"position_noise": -1.0}}, InvalidParameterError, r"position_noise"),
        ({"sensors": {"velocity": "kalman"}}, InvalidParameterError, r"'kalman'"),
        ({"sensors": {"delay": 1.5}}, InvalidParameterError, r"`delay`"),
        ({"sensors": {"velocity_cutoff": 0.0}}, InvalidParameterError, r"velocity_cutoff"),
        ({"sensors": {"position_noise": "high"}}, InvalidParameterError, r"'high'"),
        ({"actuators": {"torque_limit": [-1.0, 2.0]}}, InvalidParameterError, r"torque_limit"),
        ({"actuators": {"slew": 1.0}}, UnknownKeyError, r"'slew' in \[actuators\]"),
    ],
)
def test_bad_sensor_and_actuator_tables(table: dict[str, Any], error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        _scene("two_link_drop.toml", **table)


def test_nothing_of_sensors_is_imported_without_the_tables() -> None:
    code = (
        "import sys\n"
        "from ucontrol.scene import load_scene\n"
        "from ucontrol.simulate import simulate\n"
        "simulate(load_scene(), duration=0.01)\n"
        "print([m for m in sys.modules if m.startswith('ucontrol.sensors')])\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert result.stdout.strip() == "[]"


def test_log_fields_stay_absent_without_the_tables(tmp_path: Path) -> None:
    log = simulate(_scene("two_link_drop.toml"), duration=0.01).log
    assert not {"measured_q", "measured_v", "commanded_u"} & set(log.fields)


def test_sensors_on_a_moving_surface_see_the_gap_at_their_time() -> None:
    """The measured gaps of a vibrating table are those of the measurement's time."""
    scene = _scene("ball_vibrating_table.toml", sensors={"delay": 0})
    recorder = _Recorder(np.zeros(scene.robot.nu))
    log = simulate(scene, recorder, duration=0.2).log
    seen = np.array([contacts.gap[0] for _, _, _, contacts in recorder.seen])
    np.testing.assert_allclose(seen, log.gap[: len(seen), 0], atol=1e-12)
