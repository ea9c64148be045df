"""Bilateral constraints in Moreau–Jean: a four-bar linkage against its one-coordinate model.

``robots/four_bar.urdf`` is a tree (crank, coupler, rocker; nv = 3) closed by a point closure
between the coupler's and the rocker's ends (3 rows, the out-of-plane one identically zero:
rank 2, a redundant closure). Its free motion under gravity is compared with an independent
reduced model in the crank angle θ alone (closed-form position analysis, Lagrange's equation
integrated by scipy); closure residual, energy, a doubly declared (redundant) closure, a
closed chain hitting a stop, a weld, a joint coupling, Jacobians against finite differences,
and the errors.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import scipy.integrate
from conftest import ROBOTS

from ucontrol.contact.bilateral import BilateralSet, FrameClosure, JointCoupling
from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

A, B, C, D = 0.1, 0.35, 0.3, 0.35  # crank, coupler, rocker, ground lengths [m]
MASS, G = 1.0, 9.81  # [kg] per bar, [m/s²]
CLOSURE = {"type": "point", "frame": "coupler_end", "other_frame": "rocker_end"}


def _angles(theta: float) -> tuple[float, float]:
    """Absolute coupler and rocker angles φ, ψ of the upper assembly at crank angle θ."""
    crank_end = A * np.array([np.cos(theta), np.sin(theta)])
    delta = np.array([D, 0.0]) - crank_end
    length = np.linalg.norm(delta)
    along = (B * B - C * C + length * length) / (2 * length)
    unit = delta / length
    joint = (
        crank_end + along * unit + np.sqrt(B * B - along * along) * np.array([-unit[1], unit[0]])
    )
    phi = np.arctan2(*(joint - crank_end)[::-1])
    psi = np.arctan2(*(joint - np.array([D, 0.0]))[::-1])
    return float(phi), float(psi)


def _rates(theta: float, phi: float, psi: float) -> tuple[float, float]:
    """dφ/dθ, dψ/dθ from the derivative of the loop a e^{iθ} + b e^{iφ} - c e^{iψ} = d."""
    matrix = np.array([[-B * np.sin(phi), C * np.sin(psi)], [B * np.cos(phi), -C * np.cos(psi)]])
    k = np.linalg.solve(matrix, [A * np.sin(theta), -A * np.cos(theta)])
    return float(k[0]), float(k[1])


def _mass_and_potential(theta: float) -> tuple[float, float]:
    """Generalized inertia m(θ) [kg m²] and potential V(θ) [J] of the reduced model."""
    phi, psi = _angles(theta)
    k_phi, k_psi = _rates(theta, phi, psi)
    inertia = [MASS * length**2 / 12 for length in (A, B, C)]
    coupler_centre = A * np.exp(1j * theta) * 1j + 0.5 * B * k_phi * np.exp(1j * phi) * 1j
    mass = (
        MASS * ((A / 2) ** 2 + abs(coupler_centre) ** 2 + (C / 2 * k_psi) ** 2)
        + inertia[0]
        + inertia[1] * k_phi**2
        + inertia[2] * k_psi**2
    )
    heights = 1.5 * A * np.sin(theta) + 0.5 * B * np.sin(phi) + 0.5 * C * np.sin(psi)
    return float(mass), float(MASS * G * heights)


def _reduced_motion(theta0: float, times: np.ndarray) -> np.ndarray:
    """θ(t) of m(θ) θ'' + m'(θ) θ'²/2 + V'(θ) = 0 from rest (DOP853, rtol 1e-12)."""
    step = 1e-5  # [rad], central differences of the closed forms

    def rhs(_: float, y: np.ndarray) -> list[float]:
        theta, rate = y
        mass = _mass_and_potential(theta)[0]
        (m_plus, v_plus), (m_minus, v_minus) = (
            _mass_and_potential(theta + step),
            _mass_and_potential(theta - step),
        )
        dm, dv = (m_plus - m_minus) / (2 * step), (v_plus - v_minus) / (2 * step)
        return [rate, -(0.5 * dm * rate * rate + dv) / mass]

    solution = scipy.integrate.solve_ivp(
        rhs, (0.0, times[-1]), [theta0, 0.0], method="DOP853", t_eval=times, rtol=1e-12, atol=1e-12
    )
    return solution.y[0]


def _q0(theta: float) -> list[float]:
    phi, psi = _angles(theta)
    return [theta, phi - theta, psi]


def _four_bar(theta0: float = 1.0, **changes: Any) -> Scene:
    table: dict[str, Any] = {
        "robot": {"urdf": "four_bar.urdf", "q0": _q0(theta0), "gravity": [0.0, -G, 0.0]},
        "bilateral": [CLOSURE],
        "integrator": {"name": "moreau_jean", "dt": 1e-3},
    }
    table.update(changes)
    return Scene.from_dict(table, base_dir=ROBOTS)


def _residuals(scene: Scene, q: np.ndarray) -> np.ndarray:
    bilateral = scene.constraints.bilateral
    assert bilateral is not None
    return np.array([np.max(np.abs(bilateral.residuals(row))) for row in q])


@pytest.mark.slow
def test_four_bar_follows_its_one_coordinate_model() -> None:
    duration, errors, residuals = 0.5, [], []
    for h in (1e-3, 1e-4):
        scene = _four_bar()
        log = simulate(scene, duration=duration, dt=h, out=None, progress=False).log
        t, q = np.asarray(log.t), np.asarray(log.q)
        every = max(1, round(1e-2 / h))  # compare every 10 ms
        reference = _reduced_motion(1.0, t[::every])
        errors.append(np.max(np.abs(q[::every, 0] - reference)))
        residuals.append(_residuals(scene, q).max())
        energy = np.asarray(log.energy)
        assert np.max(np.abs(energy - energy[0])) < 20.0 * h  # [J], O(h) (3.8 J at rest)
    # Order one: ten times smaller steps, at least five times smaller error [rad].
    assert errors[0] < 0.1 and errors[1] < errors[0] / 5
    # The closure is projected back after every step.
    assert max(residuals) < 1e-11


def test_closure_residual_and_energy_do_not_drift() -> None:
    scene = _four_bar()
    log = simulate(scene, duration=3.0, dt=2e-3, out=None, progress=False).log
    assert _residuals(scene, np.asarray(log.q)).max() < 1e-11
    energy = np.asarray(log.energy)
    half = energy.size // 2
    drift = np.abs(energy - energy[0])
    assert drift[half:].max() < 2.0 * drift[:half].max()  # bounded, not growing


def test_redundant_closure_gives_the_same_motion() -> None:
    single = _four_bar()
    double = _four_bar(bilateral=[CLOSURE, {**CLOSURE, "name": "again"}])
    assert double.constraints.bilateral is not None
    data = pin.Data(double.robot.model)
    pin.computeAllTerms(double.robot.model, data, double.q0, double.v0)
    pin.updateFramePlacements(double.robot.model, data)
    J = double.constraints.bilateral.jacobian(data)
    assert J.shape == (6, 3) and np.linalg.matrix_rank(J) == 2
    runs = [
        np.asarray(simulate(s, duration=0.5, dt=1e-3, out=None, progress=False).log.q)
        for s in (single, double)
    ]
    np.testing.assert_allclose(runs[1], runs[0], rtol=0, atol=1e-9)


def test_closed_chain_hitting_a_stop_keeps_newton_and_the_closure() -> None:
    e = 0.6
    stop = {"joint": "crank_joint", "lower": 0.2, "restitution": e}
    scene = _four_bar(1.0, stops=[stop])
    log = simulate(scene, duration=0.5, dt=1e-3, out=None, progress=False).log
    impulse = np.asarray(log.impulse)[:, 0]
    u = np.asarray(log.normal_velocity)[:, 0]
    # First steps of contact (not those held by persistence, which carry the weight).
    impacts = np.flatnonzero((impulse[1:] > 0.0) & (impulse[:-1] == 0.0)) + 1
    assert impacts.size >= 1 and u[impacts[0]] < -0.1
    for k in impacts:  # Newton's law on the unilateral row while the closure holds
        assert abs(u[k + 1] + e * u[k]) <= 1e-9 * abs(u[k])
    assert _residuals(scene, np.asarray(log.q)).max() < 1e-6


def test_weld_to_the_world_holds_a_free_body() -> None:
    table = {
        "robot": {
            "urdf": "box_collision.urdf",
            "floating_base": True,
            "q0": [0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 1.0],
        },
        "bilateral": [{"type": "weld", "frame": "box", "other_frame": "universe"}],
    }
    with pytest.raises(InvalidParameterError, match="box=universe"):
        Scene.from_dict(table, base_dir=ROBOTS)  # the box is not at the world's origin
    table["robot"]["q0"] = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    log = simulate(scene, duration=0.1, dt=1e-3, out=None, progress=False).log
    assert np.max(np.abs(np.asarray(log.v))) < 1e-12
    assert np.max(np.abs(np.asarray(log.q)[:, :6])) < 1e-12


def test_jacobians_match_finite_differences(rng: np.random.Generator) -> None:
    robot = RobotModel.from_urdf(ROBOTS / "four_bar.urdf")
    closures = [
        FrameClosure(frame="coupler_end", other_frame="rocker_end"),
        FrameClosure(frame="coupler_end", other_frame="rocker_end", kind="weld"),
        JointCoupling(joint="rocker_joint", other_joint="crank_joint", ratio=-0.5, offset=0.1),
    ]
    bilateral = BilateralSet(robot, closures)
    assert bilateral.size == 10
    step = 1e-7
    for _ in range(3):
        q = rng.uniform(-1.0, 1.0, 3)
        data = pin.Data(robot.model)
        pin.computeAllTerms(robot.model, data, q, np.zeros(3))
        pin.updateFramePlacements(robot.model, data)
        J = bilateral.jacobian(data)
        direction = rng.standard_normal(3)
        plus = bilateral.residuals(pin.integrate(robot.model, q, step * direction))
        minus = bilateral.residuals(pin.integrate(robot.model, q, -step * direction))
        derivative = (plus - minus) / (2 * step)
        # The point and coupling rows everywhere; the weld's where it holds (h = 0) only.
        np.testing.assert_allclose(J[[0, 1, 2, 9]] @ direction, derivative[[0, 1, 2, 9]], atol=1e-6)
    # A weld of a frame to itself moved along a motion: h = 0 there, its rows exact.
    weld = BilateralSet(
        robot, [FrameClosure(frame="coupler", other_frame="coupler_end", kind="weld")]
    )
    q = rng.uniform(-1.0, 1.0, 3)
    data = pin.Data(robot.model)
    pin.computeAllTerms(robot.model, data, q, np.zeros(3))
    pin.updateFramePlacements(robot.model, data)
    np.testing.assert_allclose(weld.jacobian(data), 0.0, atol=1e-12)  # rigidly attached


def test_bad_bilateral_inputs_raise_typed_errors() -> None:
    with pytest.raises(InvalidParameterError, match="q0"):
        _four_bar(robot={"urdf": "four_bar.urdf", "q0": [1.0, 0.0, 0.0]})
    with pytest.raises(NotFoundError, match="hinge"):
        _four_bar(bilateral=[{"type": "hinge"}])
    with pytest.raises(InvalidParameterError, match="kind"):
        FrameClosure(frame="a", other_frame="b", kind="line")
    scene = _four_bar(integrator={"name": "compliant", "dt": 1e-3})
    with pytest.raises(InvalidParameterError, match="bilateral"):
        scene.build_integrator()
