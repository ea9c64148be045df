"""Event-driven integration of bilateral constraints: the four-bar linkage of four_bar.urdf.

The closure (a point closure, 3 rows of rank 2) is held at acceleration level and projected
at every event and step end. Checked against independent references: the one-coordinate
model of ``test_bilateral.py`` (closed-form position analysis, Lagrange's equation), energy
conservation, the closure residual and its velocity rows, and Newton's law at a crank stop
through the kinetic energy of the one-degree-of-freedom chain (T⁺ = e² T⁻ at the stop's
configuration, whose potential energy is computed at the closed-form assembly).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS
from test_bilateral import CLOSURE, _four_bar, _q0, _reduced_motion, _residuals

from ucontrol.contact.bilateral import BilateralSet, FrameClosure, JointCoupling
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

EVENT_DRIVEN = {"name": "event_driven", "dt": 1e-2}


def _run(scene: Scene, duration: float) -> Any:
    return simulate(scene, duration=duration, out=None, progress=False).log


def _velocity_residuals(scene: Scene, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Largest |J_b v| at each sample, in [m/s]."""
    bilateral = scene.constraints.bilateral
    assert bilateral is not None
    model = scene.robot.model
    data = pin.Data(model)
    rows = []
    for q_k, v_k in zip(q, v, strict=True):
        pin.computeAllTerms(model, data, q_k, v_k)
        pin.updateFramePlacements(model, data)
        rows.append(np.max(np.abs(bilateral.jacobian(data) @ v_k)))
    return np.array(rows)


@pytest.mark.slow
def test_four_bar_holds_its_closure_and_energy_for_5_s() -> None:
    scene = _four_bar(integrator=EVENT_DRIVEN)
    log = _run(scene, 5.0)
    q, v, energy = np.asarray(log.q), np.asarray(log.v), np.asarray(log.energy)
    # Measured 1.0e-15 m and 1.3e-15 m/s (projection at every step end), far within the
    # 1e-10 m asked.
    assert _residuals(scene, q).max() <= 1e-14
    assert _velocity_residuals(scene, q, v).max() <= 1e-14
    # rtol = 1e-10: measured 1.8e-10 J of 3.76 J over 5 s.
    assert np.max(np.abs(energy - energy[0])) <= 1e-9


def test_four_bar_follows_its_one_coordinate_model() -> None:
    log = _run(_four_bar(integrator=EVENT_DRIVEN), 1.0)
    t, q = np.asarray(log.t), np.asarray(log.q)
    reference = _reduced_motion(1.0, t[::10])
    # Measured 3.1e-8 rad over 1 s: the reference's finite-difference forces (step 1e-5 rad)
    # and both integrators' tolerances.
    assert np.max(np.abs(q[::10, 0] - reference)) <= 3e-7


def test_redundant_closure_gives_the_same_motion() -> None:
    single = _run(_four_bar(integrator=EVENT_DRIVEN), 0.5)
    scene = _four_bar(bilateral=[CLOSURE, {**CLOSURE, "name": "again"}], integrator=EVENT_DRIVEN)
    double = _run(scene, 0.5)  # 6 rows of rank 2
    # Measured 9.8e-15 rad: the pseudo-inverse keeps the same constrained dynamics.
    np.testing.assert_allclose(np.asarray(double.q), np.asarray(single.q), rtol=0, atol=1e-13)
    assert _residuals(scene, np.asarray(double.q)).max() <= 1e-14


def test_closed_chain_hitting_a_stop_keeps_newton_and_the_closure() -> None:
    e, stop = 0.6, 0.2  # restitution, crank angle of the stop [rad]
    scene = Scene.from_toml(ROBOTS / "four_bar_stop.toml")
    assert scene.stops[0].lower == stop and scene.stops[0].restitution == e
    assert scene.integrator.name == "event_driven" and scene.duration == 0.45
    log = _run(scene, 0.45)
    q, v, energy = np.asarray(log.q), np.asarray(log.v), np.asarray(log.energy)
    impulse, gap = np.asarray(log.impulse)[:, 0], np.asarray(log.gap)[:, 0]
    model = scene.robot.model
    data = pin.Data(model)
    pin.computeAllTerms(model, data, np.array(_q0(stop)), np.zeros(3))
    at_stop = data.potential_energy  # [J], the assembly at the stop
    impacts = np.flatnonzero(impulse > 0.0)
    impacts = impacts[impacts + 1 < energy.size]
    assert impacts.size == 5  # at 0.144, 0.278, 0.360, 0.410 and 0.440 s
    for k in impacts:
        before, after = energy[k] - at_stop, energy[k + 1] - at_stop  # kinetic at impact [J]
        # One degree of freedom: Newton's law u⁺ = -e u⁻ at the stop row is T⁺ = e² T⁻.
        # Measured at most 8.3e-16 J (kinetic energies at impact 0.011 to 0.65 J).
        assert abs(after - e * e * before) <= 1e-14
        assert v[k, 0] < 0.0 < v[k + 1, 0] and gap[k + 1] > 0.0
    # Measured 7.8e-16 m and 7.7e-16 m/s.
    assert _residuals(scene, q).max() <= 1e-14
    assert _velocity_residuals(scene, q, v).max() <= 1e-14


def test_drift_of_the_rows_matches_finite_differences(rng: np.random.Generator) -> None:
    robot = RobotModel.from_urdf(ROBOTS / "four_bar.urdf")
    closures = [
        FrameClosure(frame="coupler_end", other_frame="rocker_end"),
        FrameClosure(frame="coupler_end", other_frame="rocker_end", kind="weld"),
        FrameClosure(frame="coupler_end", other_frame="crank", kind="weld"),
        JointCoupling(joint="rocker_joint", other_joint="crank_joint", ratio=-0.5),
    ]
    bilateral = BilateralSet(robot, closures)
    model, data = robot.model, pin.Data(robot.model)
    step = 1e-6  # [s]
    for _ in range(3):
        q, v = rng.uniform(-1.0, 1.0, 3), rng.standard_normal(3)

        def rows_times_v(q_: np.ndarray, v: np.ndarray = v) -> np.ndarray:
            pin.computeAllTerms(model, data, q_, v)
            pin.updateFramePlacements(model, data)
            return bilateral.jacobian(data) @ v

        # d/dt (J(q(t)) v) at fixed v, q(t) = q ⊕ t v: J̇ v, by central differences.
        derivative = (
            rows_times_v(pin.integrate(model, q, step * v))
            - rows_times_v(pin.integrate(model, q, -step * v))
        ) / (2 * step)
        pin.forwardKinematics(model, data, q, v, np.zeros(3))
        pin.updateFramePlacements(model, data)
        # Measured 1.2e-10 (rows of size up to 1.1 m/s²).
        np.testing.assert_allclose(bilateral.drift(data), derivative, rtol=0, atol=1e-9)


def test_compliant_still_refuses_bilateral_constraints() -> None:
    scene = _four_bar(integrator={"name": "compliant", "dt": 1e-3})
    with pytest.raises(InvalidParameterError, match="bilateral"):
        scene.build_integrator()
