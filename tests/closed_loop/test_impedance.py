r"""The impedance controller: its law against an independent assembly, its rest in contact.

References: at a static equilibrium pressing the ground with gravity compensation, the contact
force is :math:`f_d + n^T K_p n\, d` (d: depth of the desired point below the surface; 0 when
it is projected on the surface), the tangential position the desired one; the torque at a
random state against the gravity of the recursive Newton–Euler algorithm, a finite-difference
Jacobian through ``pin.integrate`` and the null-space projector :math:`I - J^T (J J^T)^{-1} J`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOTS, load_experiment

from ucontrol.control.controller import ContactState
from ucontrol.control.desired_cycle import ContactPhase
from ucontrol.control.impedance_controller import ImpedanceController, ImpedanceGains
from ucontrol.control.segment_path import SegmentPath
from ucontrol.exceptions import (
    InvalidParameterError,
    NonFiniteValueError,
    NotFoundError,
    PathOutOfReachError,
    PathThroughSurfaceError,
    ShapeError,
    UnknownKeyError,
)
from ucontrol.scene import Scene
from ucontrol.scene.impedance_table import impedance_from_table
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

#: Finite-difference step of the Jacobian, in [rad].
H = 1e-7


@dataclass(frozen=True)
class FixedPoint:
    """A constant desired point (a nominal path of any period)."""

    point: np.ndarray
    period: float = 100.0

    def __call__(self, t: float) -> tuple[np.ndarray, ...]:
        return self.derivatives(t, 2)

    def derivatives(self, t: float, order: int) -> tuple[np.ndarray, ...]:
        return (np.asarray(self.point, dtype=float), *(np.zeros(3) for _ in range(order)))


def _scene(name: str) -> tuple[Scene, dict]:
    """A scene of robots/ with a zero controller, and its original controller table."""
    table = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
    controller = table.pop("controller")
    table["controller"] = {"type": "zero"}
    return Scene.from_dict(table, base_dir=ROBOTS), controller


@pytest.mark.parametrize(("project", "depth"), [(True, 0.01), (False, 0.01), (False, 0.003)])
def test_rest_on_the_ground_presses_with_the_spring_and_the_desired_force(project, depth) -> None:
    scene, _ = _scene("two_link_one_constraint")
    contact = scene.contacts[0]  # ground y >= 0, normal +y
    stiffness = np.array([250.0, 400.0, 100.0])  # [N/m]
    force = 5.0  # [N]
    target = np.array([0.65, -depth, 0.0])
    controller = ImpedanceController(
        scene.robot,
        "end_effector",
        FixedPoint(target),
        ImpedanceGains(stiffness=stiffness, damping=60.0),
        contacts=[contact],
        contact_phases=[ContactPhase(contact=contact.name, start=0.0, end=100.0, force=force)],
        project=project,
    )
    result = simulate(scene, controller, duration=4.0, dt=1e-3, progress=False)
    log = result.log
    rest = log.t >= 3.5
    expected = force + (0.0 if project else stiffness[1] * depth)  # [N]
    measured = log.contact_force[rest, 0]
    # Moreau–Jean holds the contact at the velocity level: the tip rests a drift of ~1e-7 m
    # inside the ground, which adds K_yy * (-gap) to the spring; with it, the balance is exact.
    gap = log.gap[rest, 0]
    assert np.abs(gap).max() <= 1e-6
    np.testing.assert_allclose(measured, expected + stiffness[1] * gap, rtol=1e-9)
    assert np.abs(measured - expected).max() <= 1e-4 * expected
    np.testing.assert_allclose(log.task_position[rest, 0], target[0], atol=1e-8)
    np.testing.assert_allclose(log.task_position[rest, 1], 0.0, atol=1e-5)  # on the ground
    np.testing.assert_allclose(log.lambda_d[rest, 0], force)


def test_free_rest_reaches_the_desired_point() -> None:
    scene, _ = _scene("two_link_one_constraint")
    target = np.array([0.6, 0.15, 0.0])
    controller = ImpedanceController(
        scene.robot,
        "end_effector",
        FixedPoint(target),
        ImpedanceGains(stiffness=300.0, damping=60.0),
    )
    log = simulate(scene, controller, duration=4.0, dt=1e-3, progress=False).log
    np.testing.assert_allclose(log.task_position[-1], target, atol=1e-7)
    assert log.impulse[:, 0].max() == 0.0  # never touched the ground


def _finite_difference_jacobian(model, q: np.ndarray, frame: int) -> np.ndarray:
    data = pin.Data(model)

    def position(q_: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(model, data, q_)
        return data.oMf[frame].translation.copy()

    columns = []
    for i in range(model.nv):
        step = np.zeros(model.nv)
        step[i] = H
        plus = position(pin.integrate(model, q, step))
        minus = position(pin.integrate(model, q, -step))
        columns.append((plus - minus) / (2 * H))
    return np.array(columns).T


def test_panda_torque_matches_an_independent_assembly() -> None:
    rng = np.random.default_rng(7)
    scene, _ = _scene("panda_table")
    contact = scene.contacts[0]  # table z >= 0.2, normal +z
    model = scene.robot.model
    frame = model.getFrameId("panda_hand_tcp")
    stiffness = np.array([[800.0, 100.0, 0.0], [100.0, 600.0, 50.0], [0.0, 50.0, 900.0]])
    damping = np.diag([40.0, 30.0, 50.0])
    gains = ImpedanceGains(
        stiffness=stiffness,
        damping=damping,
        joint_damping=0.3,
        posture_stiffness=20.0,
        posture_damping=4.0,
    )
    path = SegmentPath(start=[0.4, 0.0, 0.15], end=[0.6, 0.1, 0.25], period=4.0)
    # Below the table on [0, ~1) and (~3, 4): the phase [2.5, 5] covers both, modulo 4 s.
    phase = ContactPhase(contact=contact.name, start=2.5, end=5.0, force=10.0)
    posture = scene.q0 + rng.normal(0.0, 0.1, model.nq)
    controller = ImpedanceController(
        scene.robot,
        "panda_hand_tcp",
        path,
        gains,
        contacts=[contact],
        contact_phases=[phase],
        posture=posture,
    )
    state = ContactState(
        names=[contact.name],
        gap=np.zeros(1),
        normal_velocity=np.zeros(1),
        impulse=np.zeros(1),
        active=np.zeros(1, dtype=bool),
        dt=1e-3,
    )
    n = np.array([0.0, 0.0, 1.0])
    # (t, in the phase, f_d): away from the smooth rise (0.1 s) and fall (0.5 s) of f_d.
    for t, in_phase, f_d in ((0.3, True, 10.0), (1.5, False, 0.0), (2.7, True, 10.0)):
        q = scene.q0 + rng.normal(0.0, 0.2, model.nq)
        v = rng.normal(0.0, 0.5, model.nv)
        tau = controller(t, q, v, state)
        J = _finite_difference_jacobian(model, q, frame)
        data = pin.Data(model)
        pin.framesForwardKinematics(model, data, q)
        x = data.oMf[frame].translation
        g = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
        p, dp = path.derivatives(t, 1)
        if in_phase and p[2] < 0.2:  # projected on the table
            p, dp = p.copy(), dp.copy()
            p[2], dp[2] = 0.2, 0.0
        task_force = stiffness @ (p - x) + damping @ (dp - J @ v) - n * f_d
        N = np.eye(model.nv) - J.T @ np.linalg.solve(J @ J.T, J)
        expected = (
            g
            + J.T @ task_force
            - 0.3 * v
            + N @ (20.0 * pin.difference(model, q, posture) - 4.0 * v)
        )
        np.testing.assert_allclose(tau, expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())
        # The posture torque does no work along the task: J M^-1 is not involved, but N J^T = 0.
        np.testing.assert_allclose(N @ J.T, 0.0, atol=1e-6)


def test_table_builder_refuses_a_flexible_scene() -> None:
    scene, _ = _scene("two_link_flexible_one_constraint")
    _, table = _scene("two_link_one_constraint")
    impedance = {
        "type": "impedance",
        "frame": "end_effector",
        "stiffness": 400.0,
        "damping": 40.0,
        "path": table["path"],
        "contact_phases": table["contact_phases"],
    }
    with pytest.raises(InvalidParameterError) as raised:
        impedance_from_table(scene, impedance)
    assert "flexible" in str(raised.value)


def _table(**changes: object) -> tuple[Scene, dict]:
    scene, table = _scene("two_link_one_constraint")
    impedance = {
        "type": "impedance",
        "frame": "end_effector",
        "stiffness": 400.0,
        "damping": 40.0,
        "path": table["path"],
        "contact_phases": table["contact_phases"],
    }
    impedance.update(changes)
    return scene, {key: value for key, value in impedance.items() if value is not None}


@pytest.mark.parametrize(
    ("changes", "error", "name"),
    [
        (
            {"stiffness": [[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]},
            InvalidParameterError,
            "stiffness",
        ),
        ({"stiffness": [100.0, -1.0, 100.0]}, InvalidParameterError, "stiffness"),
        ({"stiffness": 0.0}, InvalidParameterError, "stiffness"),
        ({"stiffness": [1.0, 2.0]}, ShapeError, "stiffness"),
        ({"damping": [1.0, math.nan, 1.0]}, NonFiniteValueError, "damping"),
        ({"damping": True}, InvalidParameterError, "damping"),
        ({"joint_damping": -1.0}, InvalidParameterError, "joint_damping"),
        ({"force_rise_time": 0.0}, InvalidParameterError, "force_rise_time"),
        ({"force_fall_time": 5.0}, InvalidParameterError, "force_rise_time + force_fall_time"),
        ({"project": "yes"}, InvalidParameterError, "[controller] project"),
    ],
)
def test_invalid_gains_and_settings_raise_typed_errors(changes, error, name) -> None:
    scene, table = _table(**changes)
    with pytest.raises(error) as raised:
        impedance_from_table(scene, table)
    assert raised.value.name == name


def test_table_errors_name_what_is_wrong() -> None:
    scene, table = _table(gain=1.0)
    with pytest.raises(UnknownKeyError, match="gain"):
        impedance_from_table(scene, table)
    scene, table = _table(contacts=["hand/ground"])
    with pytest.raises(NotFoundError, match="hand/ground"):
        impedance_from_table(scene, table)
    scene, table = _table(contact_phases=[])  # the circle dips below the ground: no phase
    with pytest.raises(PathThroughSurfaceError) as raised:
        impedance_from_table(scene, table)
    assert raised.value.gap == pytest.approx(-0.1, abs=1e-4)  # the circle's lowest point
    scene, table = _table(
        path={"type": "circle", "centre": [0.65, 0, 0], "radius": 0.5, "period": 10.0}
    )
    with pytest.raises(PathOutOfReachError):
        impedance_from_table(scene, table)
    scene, table = _table()
    controller = impedance_from_table(scene, table)
    state = ContactState(["other"], np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1, bool), 1e-3)
    with pytest.raises(NotFoundError, match="end_effector/ground"):
        controller(0.0, scene.q0, scene.v0, state)


def test_comparison_experiment_measures_both_controllers() -> None:
    experiment = load_experiment("impedance_vs_brogliato")
    runs = experiment.main(["--cycles", "1", "--no-figures"])
    assert [(r.task, r.controller) for r in runs] == [
        ("two-link, 1 constraint", "brogliato"),
        ("two-link, 1 constraint", "impedance"),
        ("Panda, table", "brogliato"),
        ("Panda, table", "impedance"),
    ]
    for r in runs:
        (landing,) = r.landings
        assert landing.impacts >= 1 and landing.transition > 0.0
        # The first impulse obeys Newton's law with the plant's restitution:
        # P = (1 + e) m_eff |u_n^-|, m_eff = 1 / (J_n M^-1 J_n^T) at the impact.
        i = r.log.constraint_names.index(r.phase.contact)
        row = int(np.flatnonzero(r.log.impulse[:, i] > 0.0)[0])
        contact = r.scene.contacts[0]
        model = r.scene.robot.model
        data = pin.Data(model)
        q = r.log.q[row, : model.nq]
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        frame = model.getFrameId(contact.frame)
        J_n = (
            contact.surface.normal
            @ pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
        )
        m_eff = 1.0 / float(J_n @ np.linalg.solve(M, J_n))  # [kg]
        expected = (1.0 + contact.restitution) * m_eff * -r.log.normal_velocity[row, i]
        assert landing.first_impulse == pytest.approx(expected, rel=0.05)
        # In the plateau the mean contact force is the desired one within 2 %.
        assert landing.force_error_mean < 0.02
