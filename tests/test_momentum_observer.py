"""The generalized-momentum observer: what it estimates from q and the torque sent, nothing else."""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.analysis.cycles import cycle_events
from ucontrol.control.controller import ContactState
from ucontrol.control.joint_pd import JointPD
from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.scene import Scene, builtin_scene
from ucontrol.sensors import MomentumObserver, Sensors, SensorSettings
from ucontrol.simulate import simulate

ROBOTS = builtin_scene().parent
T = 1e-3  # [s] the control period of the scenes below (one step)


def _scene(name: str, drop: tuple[str, ...] = (), **tables: Any) -> Scene:
    table = tomllib.loads((ROBOTS / name).read_text())
    table.pop("reference", None)
    for key in drop:
        table.pop(key)
    table.update(tables)
    return Scene.from_dict(table, base_dir=ROBOTS)


def _residuals(scene: Scene, q: np.ndarray, v: np.ndarray, tau: np.ndarray, gain: float) -> Any:
    """The residual and the jump statistic at each row, from (q, v) rows and the torques told."""
    observer = MomentumObserver(scene.robot.model, gain, T, threshold=1.0)
    r, jump = np.empty_like(v), np.empty(len(v))
    for k in range(len(v)):
        r[k] = observer.update(q[k], v[k], tau[k - 1] if k else np.zeros(v.shape[1]))
        jump[k] = observer.jump
    return r, jump


@pytest.mark.parametrize("gain", [20.0, 200.0])  # [1/s]
def test_step_response_is_first_order_with_bandwidth_the_gain(gain: float) -> None:
    """A constant unknown joint torque on the free swinging arm is recovered as (1 - e^{-K t})."""
    scene = _scene("two_link_drop.toml", drop=("surfaces", "contacts", "stops"))
    tau_ext = np.array([3.0, -1.5])  # [N m] applied by the plant, not told to the observer
    log = simulate(scene, lambda t, q, v, c: tau_ext, duration=0.4).log
    assert np.abs(log.v).max() > 0.5  # the arm moves: C and g are at work
    r, _ = _residuals(scene, log.q, log.v, np.zeros_like(log.u), gain)
    k = np.arange(len(log))[:, None]
    discrete = (1.0 - (1.0 + gain * T) ** -k) * tau_ext  # backward Euler of r' = K (tau - r)
    continuous = (1.0 - np.exp(-gain * log.t))[:, None] * tau_ext
    # Measured: 8e-4 N m from the discrete law (Moreau-Jean against the trapezoid rule); from
    # the continuous law the backward-Euler lag, at most K T / (2 e) |tau_ext| + O((K T)^2).
    assert np.abs(r - discrete).max() < 2e-3
    lag = gain * T / (2.0 * np.e) * np.abs(tau_ext).max()
    assert np.abs(r - continuous).max() < 1.2 * lag + 2e-3
    settled = log.t >= 5.0 / gain - 1e-12
    error = np.abs(r[settled] - tau_ext).max()
    # After 5 / K: (1 + K T)^(-5 / (K T)) of the step remains (e^-5 = 0.7 % as K T -> 0;
    # 1.0 % at K T = 0.2).
    remains = (1.0 + gain * T) ** (-5.0 / (gain * T))
    assert error < remains * np.abs(tau_ext).max() + 2e-3
    assert remains < 0.011


class _Recorder:
    """Wraps a controller and keeps the contact information it is given."""

    def __init__(self, controller: Any) -> None:
        self.controller = controller
        self.seen: list[ContactState] = []

    def __call__(self, t: float, q: np.ndarray, v: np.ndarray, contacts: ContactState) -> Any:
        self.seen.append(contacts)
        return self.controller(t, q, v, contacts)


@pytest.mark.parametrize("control_period", [T, 5 * T])  # [s] one step, or five held
def test_arm_pressed_on_the_ground_at_rest_sees_the_plants_force(control_period: float) -> None:
    """Pressed at rest, the force the controller sees is the plant's contact force."""
    scene = _scene("two_link_one_constraint.toml", sensors={"observer": "momentum"})
    pd = JointPD(scene.robot, q_ref=np.array([0.7, -1.6]), kp=30.0, kd=6.0)  # tip 7 cm below
    recorder = _Recorder(pd)
    log = simulate(scene, recorder, duration=3.0, control_period=control_period).log
    assert np.abs(log.v[-1]).max() < 1e-6  # at rest
    plant = log.impulse[-2, 0] / T  # [N] the contact force of the last step (3.376 N)
    seen = recorder.seen[-1]
    assert plant > 3.0 and seen.dt == pytest.approx(control_period)
    assert abs(seen.force[0] - plant) < 1e-6 * plant  # measured 2e-8 relative
    assert seen.active.tolist() == [True, False, False, False, False]


class _Believing(_Recorder):
    """A recorder whose controller believes the robot is ``robot``."""

    def __init__(self, controller: Any, robot: Any) -> None:
        super().__init__(controller)
        self.robot = robot


def test_the_observer_runs_on_the_model_the_controller_believes() -> None:
    """At rest the force seen solves J^T lambda = g_believed(q) - tau, not the plant's."""
    scene = _scene("two_link_one_constraint.toml", sensors={"observer": "momentum"})
    believed = scene.robot.with_scaled_inertia(1.2)
    pd = JointPD(scene.robot, q_ref=np.array([0.7, -1.6]), kp=30.0, kd=6.0)
    recorder = _Believing(pd, believed)
    log = simulate(scene, recorder, duration=3.0).log
    q, tau = log.q[-2], log.u[-3]  # the last call's sample, and the torque held before it
    model = believed.model
    data = model.createData()
    frame = model.getFrameId("end_effector")
    J_n = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[1]  # (nv,)
    g = pin.computeGeneralizedGravity(model, data, q)
    expected = J_n @ (g - tau) / (J_n @ J_n)  # [N] least squares of one column
    seen = recorder.seen[-1].force[0]
    plant = log.impulse[-2, 0] / T
    assert abs(seen - expected) < 1e-6 * abs(expected)
    assert abs(seen - plant) > 0.05 * plant  # the believed masses show


def test_each_impact_is_seen_in_the_sample_after_it_without_the_impulses() -> None:
    """On the first landing of two_link_one_constraint, the jump of r flags each impact."""
    scene = _scene("two_link_one_constraint.toml")
    log = simulate(scene, duration=5.6).log  # the first landing and its accumulation
    model = scene.robot.model
    difference = np.array(
        [pin.difference(model, a, b) / T for a, b in zip(log.q[:-1], log.q[1:], strict=True)]
    )
    v_from_q = np.vstack([log.v[:1], difference])  # what the robot measures: q only
    threshold = 1.0  # [N m]
    impacts = np.flatnonzero(log.impulse[:, 0] > 0.0)  # row k: the step from t_k to t_k+1
    # The velocity from q spreads a jump over two samples (theta = 1/2): the smallest impulse
    # seen is then 0.11 N s, against 0.040 N s with the velocity itself (measured).
    for v, smallest, count in ((log.v, 0.035, 6), (v_from_q, 0.1, 4)):
        large = impacts[log.impulse[impacts, 0] > smallest]  # [N s] the first ones, 1.41 down
        assert large.size == count
        _, jump = _residuals(scene, log.q, v, log.u, gain=50.0)
        detected = np.flatnonzero(jump > threshold)
        for k in large:  # seen at t_k+1 (or t_k+2 with the velocity from q)
            assert k + 1 in detected or k + 2 in detected
        # Every detection follows an impact by at most two samples: no false alarm.
        assert all(np.any((d - impacts >= 1) & (d - impacts <= 2)) for d in detected)
    # The persistent force alone stays well under the threshold (K T lambda |J| ~ 0.2 N m).
    r, jump = _residuals(scene, log.q, log.v, log.u, gain=50.0)
    assert jump[log.t > 5.55].max() < 0.25 * threshold
    # The plain jump ||r_k - r_k-1|| holds r's decay: above the threshold for 14 periods after
    # the first impact, which would read as an impact each period.
    plain = np.linalg.norm(np.diff(r, axis=0), axis=1)
    first = impacts[0] + 1  # the row where r jumps
    assert np.all(plain[first : first + 14] > threshold)


def test_brogliato_cycle_closes_with_the_momentum_observer() -> None:
    """The tracking law runs its first cycle on the observer's forces, within 1 % of the plant's."""
    runs = {
        name: simulate(_scene("two_link_one_constraint.toml", sensors=sensors), duration=11.0)
        for name, sensors in (("oracle", {}), ("momentum", {"observer": "momentum"}))
    }
    log = runs["momentum"].log
    cycle = cycle_events(log)[0]
    assert cycle.complete  # landed, settled, constrained phase, took off
    # The first impact is seen at the period where the oracle sees it (t = 4.664 s).
    assert cycle.first_impact == cycle_events(runs["oracle"].log)[0].first_impact
    tracking = runs["momentum"].summary["tracking"]["cycles"][0]
    oracle = runs["oracle"].summary["tracking"]["cycles"][0]
    # Measured: constrained error 0.84 mm (oracle 0.57 mm), free 69.7 um (the oracle's).
    assert tracking["constrained_error_max"] < 2e-3
    assert tracking["free_error_max"] < 1.2 * oracle["free_error_max"]
    # In the loop too, each impulse above 0.1 N s is flagged in the next sample, and no flag
    # comes without an impulse in the two samples before it.
    impacts = np.flatnonzero(log.impulse.sum(axis=1) > 0.0)
    detected = np.flatnonzero(log.impact_detected)
    assert set(np.flatnonzero(log.impulse[:, 0] > 0.1) + 1) <= set(detected)
    assert all(np.any((d - impacts >= 1) & (d - impacts <= 2)) for d in detected)
    np.testing.assert_array_equal(log.momentum_residual[0], 0.0)
    plateau = (log.t > 6.0) & (log.t < 9.5)
    rows = np.flatnonzero(plateau)
    seen = log.contact_force[rows, 0]  # what the law read at t_k: the period before it
    plant = log.impulse[rows - 1, 0] / T
    assert np.abs(seen - plant).max() < 0.01 * plant.max()  # measured 0.2 %


def test_the_controllers_contacts_carry_none_of_the_plants_impulses() -> None:
    """With the momentum observer, any plant impulses give the same measurement."""
    scene = _scene("two_link_one_constraint.toml", sensors={"observer": "momentum"})
    assert scene.sensors is not None
    constraints = scene.constraints
    seen = []
    for fill in (0.0, 1e3, np.nan):
        sensors = Sensors(scene.sensors, scene.robot, constraints, None, T)
        q, v = np.array([0.7, -1.6]), np.zeros(2)
        n = constraints.size
        for k in range(3):
            contacts = ContactState(
                constraints.names, np.zeros(n), np.zeros(n), np.full(n, fill), np.ones(n, bool), T
            )
            out = sensors.measure(q, v, contacts, 0.001 * k, np.array([1.0, 2.0]))
        seen.append(out[2])
    for other in seen[1:]:
        np.testing.assert_array_equal(other.impulse, seen[0].impulse)
        np.testing.assert_array_equal(other.active, seen[0].active)
    assert seen[0].impulse[0] > 0.0  # the contact is pressed: the torque told is not g(q)


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ({"observer": "kalman"}, r"`observer`.*'kalman'"),
        ({"observer_gain": 0.0}, r"`observer_gain`"),
        ({"impact_threshold": -1.0}, r"`impact_threshold`"),
        ({"contact_gap": -1e-3}, r"`contact_gap`"),
        ({"force_threshold": "low"}, r"`force_threshold`"),
        ({"observer": "momentum", "force_noise": 1.0}, r"`force_noise`"),
    ],
)
def test_bad_observer_settings(table: dict[str, Any], match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        SensorSettings(**table)


def test_flexible_arm_pressed_at_rest_sees_the_plants_force() -> None:
    """With flexible joints the links' torque is the springs': the force is still the plant's."""
    scene = _scene("two_link_flexible_one_constraint.toml", sensors={"observer": "momentum"})
    assert scene.flexible is not None
    pd = JointPD(scene.robot, q_ref=np.array([0.7, -1.6]), kp=30.0, kd=6.0, flexible=scene.flexible)
    recorder = _Recorder(pd)
    log = simulate(scene, recorder, duration=3.0).log
    assert np.abs(log.v[-1]).max() < 1e-6 and np.abs(log.motor_v[-1]).max() < 1e-6  # at rest
    plant = log.impulse[-2, 0] / T  # [N] (3.225 N)
    seen = recorder.seen[-1].force[0]
    assert plant > 3.0
    assert abs(seen - plant) < 1e-6 * plant  # measured 2e-13 relative


def test_momentum_observer_bad_arguments() -> None:
    model = _scene("two_link_drop.toml").robot.model
    with pytest.raises(InvalidParameterError, match=r"`gain`"):
        MomentumObserver(model, -1.0, T, 1.0)
    with pytest.raises(InvalidParameterError, match=r"`period`"):
        MomentumObserver(model, 50.0, 0.0, 1.0)
    observer = MomentumObserver(model, 50.0, T, 1.0)
    with pytest.raises(ShapeError, match=r"`tau`"):
        observer.update(np.zeros(2), np.zeros(2), np.zeros(3))
    scene = _scene("two_link_one_constraint.toml", sensors={"observer": "momentum"})
    assert scene.sensors is not None
    sensors = Sensors(scene.sensors, scene.robot, scene.constraints, None, T)
    n = scene.constraints.size
    contacts = ContactState(scene.constraints.names, *np.zeros((3, n)), np.zeros(n, bool), T)
    with pytest.raises(InvalidParameterError, match=r"`tau`"):
        sensors.measure(np.array([0.9, -1.6]), np.zeros(2), contacts, 0.0)
    free = _scene("free_ball.toml").robot  # nv = 6: not the arm
    with pytest.raises(InvalidParameterError, match=r"`believed robot`"):
        Sensors(scene.sensors, scene.robot, scene.constraints, None, T, believed=free)


def test_contact_forces_solve_the_residual_by_least_squares() -> None:
    """Two closed constraints on the arm: r = J^T lambda gives back lambda; none gives none."""
    model = _scene("two_link_drop.toml").robot.model
    observer = MomentumObserver(model, 50.0, T, 1.0)
    J = np.array([[0.4, -0.7], [1.0, 0.3]])  # (m, nv): two independent normal rows
    forces = np.array([2.0, 5.0])  # [N]
    observer.residual = J.T @ forces
    np.testing.assert_allclose(observer.contact_forces(J), forces, rtol=1e-12)
    assert observer.contact_forces(np.zeros((0, 2))).shape == (0,)
