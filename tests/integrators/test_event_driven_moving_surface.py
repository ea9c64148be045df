"""Event-driven integration against moving planes, against closed forms.

Events on the moving gap, Newton's law on the relative velocity, and the surface's
acceleration in the contact's. The 1 kg ball of ``robots/ball.urdf`` (vertical prismatic joint,
radius 0.1 m) flies ballistically between impacts, so the impact instant and the velocities on
either side of it are reconstructed from the logged samples in closed form (the root of the
ballistic gap); the period-1 orbit of the vibrating table is
:func:`ucontrol.analysis.poincare.vibrating_table_period_one`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
import scipy.optimize
from conftest import ROBOTS

from ucontrol.analysis.poincare import vibrating_table_period_one
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

G, RADIUS = 9.81, 0.1  # [m/s²], [m]


def _ball(motion: dict[str, Any], q0: float, v0: float = 0.0, e: float = 0.0) -> Scene:
    table = {
        "robot": {"urdf": "ball.urdf", "q0": [q0], "v0": [v0], "gravity": [0.0, 0.0, -G]},
        "surfaces": {"plate": {"type": "plane", "normal": [0.0, 0.0, 1.0], "motion": motion}},
        "contacts": [{"frame": "ball", "surface": "plate", "radius": RADIUS, "restitution": e}],
        "integrator": {"name": "event_driven", "dt": 1e-3},
    }
    return Scene.from_dict(table, base_dir=ROBOTS)


def _run(scene: Scene, duration: float, dt: float) -> Any:
    return simulate(scene, duration=duration, dt=dt, out=None, progress=False).log


def _impacts(log: Any, surface: Any, e: float) -> list[tuple[float, float, float]]:
    """(time [s], post-impact velocity [m/s], Newton residual) of each impact of the log.

    The ball flies between samples: the impact time is the root of the ballistic gap from the
    sample before it, the velocities before and after follow from the samples on either side.
    The Newton residual is :math:`|u^+ + e u^-| / |u^-|` with relative velocities.
    """
    t, z = np.asarray(log.t), np.asarray(log.q)[:, 0]
    v, impulse = np.asarray(log.v)[:, 0], np.asarray(log.impulse)[:, 0]
    found = []
    for k in np.flatnonzero(impulse > 0.0):
        if k + 1 >= t.size:
            break

        def gap(time: float, k: int = k) -> float:
            tau = time - t[k]
            return z[k] + v[k] * tau - 0.5 * G * tau * tau - RADIUS - surface(time)[0][2]

        t_i = scipy.optimize.brentq(gap, t[k], t[k + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
        plate = surface(t_i)[1][2]  # [m/s]
        before = v[k] - G * (t_i - t[k]) - plate
        after = v[k + 1] + G * (t[k + 1] - t_i)
        found.append((t_i, after, abs(after - plate + e * before) / abs(before)))
    return found


@pytest.mark.parametrize("offset", [0.0, 1.0])
def test_ball_on_a_vibrating_table_reaches_the_period_one_orbit(offset: float) -> None:
    """Started on the orbit (offset 0) or 2 mm and 0.1 m/s off it (offset 1)."""
    base = Scene.from_toml(ROBOTS / "ball_vibrating_table.toml")
    contact = base.contacts[0]
    motion, e = contact.surface.motion, contact.restitution
    assert motion is not None
    phase_star, leave = vibrating_table_period_one(
        amplitude=motion.amplitude[2], frequency=motion.frequency, restitution=e, gravity=G
    )
    period = 2 * np.pi / motion.frequency  # [s]
    dt = 0.0071  # [s], sampling only: no sample within 1e-4 s of an impact nT (n < 71)
    scene = dataclasses.replace(
        base,
        integrator=dataclasses.replace(base.integrator, name="event_driven", dt=dt),
        q0=base.q0 + offset * 2e-3,
        v0=base.v0 - offset * 0.1,
    )
    duration = 2.0 if offset == 0.0 else 7.0  # [s]: the transient shrinks as 0.5^n
    impacts = _impacts(_run(scene, duration, dt), motion, e)
    assert len(impacts) == round(duration / period)
    # Measured on the orbit 1.1e-14 rad and 4.4e-15 m/s; over the last five of 35 impacts
    # from off the orbit 2.7e-10 rad and 5.0e-11 m/s (the transient): 1e-8 is asked.
    tolerance = 2e-13 if offset == 0.0 else 3e-9
    for n, (t_i, after, newton) in enumerate(impacts):
        # Newton's law on the relative velocity: measured at most 5.0e-15 (relative).
        assert newton <= 5e-14
        if offset == 0.0 or n >= len(impacts) - 5:  # steady: the last five impacts
            phase = (motion.frequency * t_i + motion.phase) % (2 * np.pi)
            assert abs(phase - phase_star) <= tolerance
            assert abs(after - leave) <= tolerance


@pytest.mark.parametrize("acceleration", [0.0, 2.0, -3.0])
def test_ball_resting_on_a_moving_plate_carries_m_g_plus_a(acceleration: float) -> None:
    speed, h = 0.5, 1e-2  # [m/s], [s]
    motion = {
        "type": "polynomial",
        "coefficients": [[0.0, 0.0, 0.0], [0.0, 0.0, speed], [0.0, 0.0, 0.5 * acceleration]],
    }
    log = _run(_ball(motion, q0=RADIUS, v0=speed), duration=0.3, dt=h)
    impulse = np.asarray(log.impulse)[:-1, 0]  # [N s]; the last row has no step
    # ∫λ dt over a step: m (g + a) h. Measured 4.4e-16 (relative), 1.4e-16 m, 2.2e-16 m/s.
    np.testing.assert_allclose(impulse / h, 1.0 * (G + acceleration), rtol=5e-15)
    np.testing.assert_allclose(np.asarray(log.gap)[:, 0], 0.0, atol=2e-15)
    t = np.asarray(log.t)
    np.testing.assert_allclose(np.asarray(log.v)[:, 0], speed + acceleration * t, atol=3e-15)


def test_impact_on_a_rising_plate_follows_the_closed_form() -> None:
    speed, height, e = 0.5, 0.2, 0.8  # [m/s], [m] gap at t = 0, restitution
    motion = {"type": "polynomial", "coefficients": [[0.0, 0.0, 0.0], [0.0, 0.0, speed]]}
    # Closed form: height - g t²/2 = speed t; rebound speed + e (g t* + speed) [m/s].
    t_star = (-speed + np.sqrt(speed**2 + 2 * G * height)) / G
    rebound = speed + e * (G * t_star + speed)
    log = _run(_ball(motion, q0=RADIUS + height, e=e), duration=0.3, dt=0.013)
    (t_i, after, newton), *_ = _impacts(log, _ball(motion, q0=1.0).contacts[0].surface.motion, e)
    # Measured 2.8e-17 s, 0 m/s and 1.1e-16 (relative).
    assert abs(t_i - t_star) <= 1e-15
    assert abs(after - rebound) <= 1e-15
    assert newton <= 1e-15
