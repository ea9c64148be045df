r"""Moreau–Jean with Coulomb friction and bilateral constraints (the mixed Coulomb problem).

- ``robots/block_incline_welded.toml``: the block of ``block_incline.toml`` cut in two free
  planar halves welded together (6 weld rows of rank 3) slides or sticks exactly as the whole
  block, with the acceleration :math:`g(\sin\alpha - \mu\cos\alpha)` when it slides.
- ``robots/slider_crank.toml``: a closed chain whose slider slides on the floor with friction.
  The loss of :math:`T + V` (computed here with Pinocchio) equals the work of the friction
  impulses over the foot's displacement to order one in h; the closure residual stays at the
  frictionless level; Coulomb's law holds at every step on velocities read from the state.
- Coulomb friction in a joint of the four-bar (``robots/four_bar.toml``): the energy lost
  equals the joint friction's work.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS

from ucontrol.exceptions import InvalidParameterError
from ucontrol.integrators import MoreauJean
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate
from ucontrol.solvers import PinocchioContactSolver

G = 9.81  # [m/s²]
ALPHA = math.radians(30.0)  # incline of block_incline.toml


def _with_friction(scene: Scene, mu: float) -> Scene:
    contacts = [dataclasses.replace(contact, friction=mu) for contact in scene.contacts]
    return dataclasses.replace(scene, contacts=contacts)


def _run(scene: Scene, duration: float, dt: float | None = None) -> Any:
    return simulate(scene, duration=duration, dt=dt, out=None, progress=False).log


@pytest.mark.parametrize("mu", [0.3, 0.7], ids=["slip", "stick"])
def test_welded_halves_move_as_the_whole_block(mu: float) -> None:
    whole = _run(_with_friction(load_scene(ROBOTS / "block_incline.toml"), mu), 0.5)
    halves = _run(_with_friction(load_scene(ROBOTS / "block_incline_welded.toml"), mu), 0.5)
    q, v = np.asarray(halves.q), np.asarray(halves.v)
    # Both halves follow the whole block: measured 9.4e-16 m (slip), 0 (stick).
    for half in (slice(0, 3), slice(3, 6)):
        np.testing.assert_allclose(q[:, half], whole.q, rtol=0, atol=1e-14)
        np.testing.assert_allclose(v[:, half], whole.v, rtol=0, atol=1e-13)
    # Same normal impulses (measured 7e-16 N s) and the same total friction impulse: sticking
    # corners share it in a way that is not unique.
    np.testing.assert_allclose(halves.impulse, whole.impulse, rtol=0, atol=1e-14)
    np.testing.assert_allclose(
        np.asarray(halves.friction_impulse).sum(axis=1),
        np.asarray(whole.friction_impulse).sum(axis=1),
        rtol=0,
        atol=1e-14,
    )
    assert set(np.asarray(halves.solver_status)[:-1].tolist()) == {1}  # every step solved
    assert np.max(halves.complementarity_residual) <= 3e-15  # measured 2.5e-16 [m/s]
    downhill = np.array([math.cos(ALPHA), -math.sin(ALPHA)])
    speed = v[:, :2] @ downhill  # [m/s]
    if math.tan(ALPHA) < mu:
        assert np.max(np.abs(v)) <= 2e-15  # measured 1.5e-16 [m/s]
    else:
        acceleration = np.diff(speed) / 1e-3  # [m/s²]
        expected = G * (math.sin(ALPHA) - mu * math.cos(ALPHA))
        assert np.max(np.abs(acceleration - expected)) <= 3e-12  # measured 3.1e-13 [m/s²]


def _energy(model: pin.Model, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """T + V at each sample [J], from Pinocchio."""
    data = pin.Data(model)
    energy = []
    for q_k, v_k in zip(q, v, strict=True):
        energy.append(pin.computeKineticEnergy(model, data, q_k, v_k))
        energy[-1] += pin.computePotentialEnergy(model, data, q_k)
    return np.array(energy)


def _closure(scene: Scene, q: np.ndarray) -> float:
    bilateral = scene.constraints.bilateral
    assert bilateral is not None
    return max(float(np.max(np.abs(bilateral.residuals(row)))) for row in q)


@pytest.mark.slow
def test_slider_crank_friction_work_equals_the_energy_loss() -> None:
    scene = load_scene(ROBOTS / "slider_crank.toml")
    model = scene.robot.model
    mu = scene.contacts[0].friction
    foot = model.getFrameId("slider_foot")
    data = pin.Data(model)
    imbalance = []
    for h in (1e-3, 1e-4):
        log = _run(scene, 0.4, h)
        q, v = np.asarray(log.q), np.asarray(log.v)
        feet = []
        for q_k in q:
            pin.framesForwardKinematics(model, data, q_k)
            feet.append(data.oMf[foot].translation.copy())
        friction = np.asarray(log.friction_impulse)[:-1, 0]  # step k -> k+1 [N s]
        work = np.sum(friction * np.diff(np.array(feet), axis=0)) / h  # [J]
        energy = _energy(model, q, v)
        imbalance.append(abs(energy[-1] - energy[0] - work))
        assert work < -1.0  # friction does work (measured -1.34 J)
        # The foot stays on the floor (the projection keeps held contacts): measured 0 m.
        assert np.min(log.gap) >= -1e-16
        P_n = np.asarray(log.impulse)[:-1, 0]
        assert P_n.min() > 0.0  # in contact throughout
        # Coulomb's law on the post-step velocities of the slider (x along the floor, y normal).
        u_t, u_n, P_t = v[1:, 2], v[1:, 3], friction[:, 0]
        assert np.max(np.abs(u_n)) <= 5e-17  # measured 5.2e-18 [m/s]
        sliding = np.abs(u_t) > 1e-12
        assert (u_t < -1e-12).any() and (u_t > 1e-12).any()  # slides back, then forth
        np.testing.assert_allclose(np.abs(P_t[sliding]), mu * P_n[sliding], rtol=1e-12)
        assert np.all(P_t[sliding] * u_t[sliding] < 0.0)
        assert np.all(np.abs(P_t[~sliding]) <= mu * P_n[~sliding] * (1.0 + 1e-12))
        assert np.max(log.complementarity_residual) <= 1e-15  # measured 7.9e-17 [m/s]
        # The closure at the frictionless level: measured 8.3e-13 m against 1.0e-12 m at
        # h = 1e-3, 3.6e-14 m against 2.2e-16 m at 1e-4 (both within the projection's 1e-12).
        frictionless = _run(_with_friction(scene, 0.0), 0.05, h)
        assert _closure(scene, q) <= max(2.0 * _closure(scene, frictionless.q), 2e-12)
    # Order one: measured 1.7e-2 J and 1.7e-3 J (of 1.34 J of friction work).
    assert imbalance[0] < 0.05 and imbalance[1] < imbalance[0] / 5


@pytest.mark.slow
def test_four_bar_joint_coulomb_friction_work_equals_the_energy_loss() -> None:
    coulomb = 0.3  # [N m] in the crank joint
    imbalance = []
    for h in (1e-3, 1e-4):
        base = load_scene(ROBOTS / "four_bar.toml")
        table: dict[str, Any] = {
            "robot": {"urdf": "four_bar.urdf", "q0": base.q0.tolist(), "gravity": [0, -G, 0]},
            "bilateral": [{"type": "point", "frame": "coupler_end", "other_frame": "rocker_end"}],
            "joint_friction": {"coulomb": {"crank_joint": coulomb}},
            "integrator": {"name": "moreau_jean", "dt": h},
        }
        scene = Scene.from_dict(table, base_dir=ROBOTS)
        log = _run(scene, 0.5, h)
        q, v = np.asarray(log.q), np.asarray(log.v)
        energy = _energy(scene.robot.model, q, v)
        # The crank's friction torque -F_c sgn(v⁺) over each step's rotation [J].
        work = -coulomb * np.sum(np.abs(np.diff(q[:, 0])))
        imbalance.append(abs(energy[-1] - energy[0] - work))
        assert work < -1.0  # measured -1.28 J (of 3.76 J)
        assert _closure(scene, q) <= 2e-12  # measured 9.7e-13 m
    # Order one: measured 8.0e-3 J and 8.2e-4 J.
    assert imbalance[0] < 0.05 and imbalance[1] < imbalance[0] / 5


def test_friction_solver_without_bilateral_rows_is_refused() -> None:
    scene = load_scene(ROBOTS / "slider_crank.toml")
    with pytest.raises(InvalidParameterError, match="friction_solver"):
        MoreauJean(
            scene.robot,
            scene.constraints,
            dt=1e-3,
            friction_solver=PinocchioContactSolver(),
        )


def test_frictionless_closed_chain_keeps_its_held_contact_on_the_floor() -> None:
    """Without friction the mixed step's projection also keeps the held contacts' gaps.

    Projecting onto the closure alone pushed the slider 1.5 mm into the floor in 0.7 s; with
    the held contacts' normal rows in the Gauss–Newton steps the gap stays at round-off
    (measured -1.9e-16 m).
    """
    scene = _with_friction(load_scene(ROBOTS / "slider_crank.toml"), 0.0)
    log = _run(scene, 0.7)
    assert log.impulse.max() > 0.0  # the slider is held on the floor
    assert log.gap.min() >= -1e-14
    assert _closure(scene, log.q) <= 1e-10
