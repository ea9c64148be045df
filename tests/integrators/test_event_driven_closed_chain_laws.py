"""Event-driven closed chains with the LZB impact law and with flexible joints.

- The four-bar on a crank stop (``robots/four_bar_stop.toml``) has one degree of freedom held
  by its closure and one unilateral row: the LZB law (energetic restitution) then equals
  Newton's law with the same coefficient, impact after impact.
- A flexible two-link arm whose link coordinates are coupled (a ``coupling`` bilateral row,
  the elbow at -1/2 the shoulder) swings under gravity: the coupling holds to round-off and
  the energy of links, motors and springs, computed independently with Pinocchio, is kept
  to the integrator's tolerance (the bilateral force does no work).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.scene import Scene
from ucontrol.simulate import simulate

STIFFNESS = 200.0  # [N m/rad]
MOTOR_INERTIA = 0.1  # [kg m^2]


@pytest.mark.slow
def test_lzb_on_a_closed_chain_equals_newton() -> None:
    base = Scene.from_toml(ROBOTS / "four_bar_stop.toml")
    logs = {}
    for law in ("newton", "lzb"):
        integrator = dataclasses.replace(base.integrator, impact_law=law)
        logs[law] = simulate(
            dataclasses.replace(base, integrator=integrator), out=None, progress=False
        ).log
    newton, lzb = logs["newton"], logs["lzb"]
    impulse = np.asarray(lzb.impulse)
    assert np.count_nonzero(impulse > 0.0) == 5  # five impacts on the stop in 0.45 s
    # Measured 1.6e-13 rad in q, 8.6e-12 rad/s in v, 1.8e-14 N m s in impulses.
    np.testing.assert_allclose(np.asarray(lzb.q), np.asarray(newton.q), rtol=0, atol=2e-12)
    np.testing.assert_allclose(np.asarray(lzb.v), np.asarray(newton.v), rtol=0, atol=1e-10)
    np.testing.assert_allclose(impulse, np.asarray(newton.impulse), rtol=0, atol=2e-13)


def test_flexible_chain_with_a_coupling_keeps_it_and_its_energy() -> None:
    table = {
        "robot": {
            "urdf": "two_link_flexible.urdf",
            "q0": [0.9, -0.45],
            "gravity": [0.0, -9.81, 0.0],
            "flexible": {
                "joints": ["shoulder", "elbow"],
                "stiffness": STIFFNESS,
                "motor_inertia": MOTOR_INERTIA,
            },
        },
        "bilateral": [
            {"type": "coupling", "joint": "elbow", "other_joint": "shoulder", "ratio": -0.5}
        ],
        "integrator": {"name": "event_driven", "dt": 1e-2},
        "duration": 1.0,
    }
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    log = simulate(scene, out=None, progress=False).log
    q, v = np.asarray(log.q), np.asarray(log.v)
    motor_q, motor_v = np.asarray(log.motor_q), np.asarray(log.motor_v)
    assert np.ptp(q[:, 0]) > 1.0  # it swings [rad]
    assert np.ptp(motor_q - q) > 1e-3  # and the springs work [rad]
    # The coupling: measured 1.1e-16 rad.
    assert np.max(np.abs(q[:, 1] + 0.5 * q[:, 0])) <= 1e-14
    model = scene.robot.model
    data = pin.Data(model)
    energy = []
    for q1, v1, q2, v2 in zip(q, v, motor_q, motor_v, strict=True):
        M = pin.crba(model, data, q1, pin.Convention.WORLD)
        kinetic = 0.5 * v1 @ M @ v1 + 0.5 * MOTOR_INERTIA * (v2 @ v2)  # [J]
        potential = pin.computePotentialEnergy(model, data, q1)  # [J]
        elastic = 0.5 * STIFFNESS * np.sum((q1 - q2) ** 2)  # [J]
        energy.append(kinetic + potential + elastic)
    # Measured 1.7e-12 J of 6.83 J over 1 s (DOP853, rtol 1e-10).
    assert np.max(np.abs(np.array(energy) - energy[0])) <= 2e-11
