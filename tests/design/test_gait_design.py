"""The walking-step design of a planar biped (RABBIT), checked with Pinocchio.

The solution against its own constraints recomputed independently, the Bézier fit, the written
scene and the typed errors.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.design.designed_gait import DesignedGait
from ucontrol.design.gait_task import GaitTask
from ucontrol.design.gait_transcription import design_gait
from ucontrol.design.hzd_fit import bernstein, fit_bezier, hzd_scene_text, phase
from ucontrol.exceptions import (
    DesignError,
    InfeasibleDesignError,
    InvalidParameterError,
    NotFoundError,
    UnknownKeyError,
)

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
TASK_FILE = ROBOTS / "rabbit_gait_task.toml"
#: Coarse grid of the tests' solve (the shipped task has 30 intervals).
INTERVALS = 10
#: Tolerance of the program's equality constraints at IPOPT's solution.
_EQUALITY_TOL = 1e-7


@pytest.fixture(scope="module")
def task() -> GaitTask:
    return dataclasses.replace(GaitTask.from_toml(TASK_FILE), intervals=INTERVALS)


@pytest.fixture(scope="module")
def gait(task: GaitTask) -> DesignedGait:
    return design_gait(task)


def _mass_matrix(model: pin.Model, q: np.ndarray) -> np.ndarray:
    M = pin.crba(model, pin.Data(model), q)
    return np.triu(M) + np.triu(M, 1).T


def _xz_jacobian(model: pin.Model, q: np.ndarray, frame: str) -> np.ndarray:
    data = pin.Data(model)
    J = pin.computeFrameJacobian(model, data, q, model.getFrameId(frame), pin.LOCAL_WORLD_ALIGNED)
    return J[[0, 2]]


def _stance_rate(model: pin.Model, frame: str, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Pinned-foot dynamics by Pinocchio's constrained forward dynamics (KKT)."""
    nv = model.nv
    q, v = x[:nv], x[nv:]
    data = pin.Data(model)
    J = _xz_jacobian(model, q, frame)
    pin.forwardKinematics(model, data, q, v, np.zeros(nv))
    drift = pin.getFrameClassicalAcceleration(
        model, data, model.getFrameId(frame), pin.LOCAL_WORLD_ALIGNED
    ).linear[[0, 2]]
    M = _mass_matrix(model, q)
    h = pin.rnea(model, pin.Data(model), q, v, np.zeros(nv))
    u = np.zeros(nv)
    u[3:] = tau
    K = np.block([[M, -J.T], [J, np.zeros((2, 2))]])
    a = np.linalg.solve(K, np.concatenate((u - h, -drift)))[:nv]
    return np.concatenate((v, a))


def test_ipopt_solves_the_step(gait: DesignedGait, task: GaitTask) -> None:
    assert gait.success, gait.status
    assert gait.status == "Solve_Succeeded"
    assert gait.max_violation < _EQUALITY_TOL
    assert gait.stationarity < 1e-6  # KKT: the Lagrangian's gradient, IPOPT's multipliers
    assert gait.step_time == pytest.approx(task.step_length / task.speed, rel=1e-9)
    assert gait.cost > 0.0


def test_the_stance_dynamics_are_pinocchios(gait: DesignedGait, task: GaitTask) -> None:
    """The designed states replayed by RK4 on Pinocchio's constrained dynamics, same grid."""
    model = task.robot.model
    h = gait.step_time / INTERVALS / task.substeps
    for k in range(INTERVALS):
        x = np.concatenate((gait.q[k], gait.v[k]))
        for _ in range(task.substeps):
            k1 = _stance_rate(model, task.stance, x, gait.tau[k])
            k2 = _stance_rate(model, task.stance, x + h / 2 * k1, gait.tau[k])
            k3 = _stance_rate(model, task.stance, x + h / 2 * k2, gait.tau[k])
            k4 = _stance_rate(model, task.stance, x + h * k3, gait.tau[k])
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        expected = np.concatenate((gait.q[k + 1], gait.v[k + 1]))
        assert np.max(np.abs(x - expected)) < 1e-6


def test_the_stance_foot_stays_pinned(gait: DesignedGait, task: GaitTask) -> None:
    feet = task.robot.frame_path(gait.q, task.stance)[:, [0, 2]]
    assert np.max(np.abs(feet[0])) < _EQUALITY_TOL
    # RK4 keeps the index-reduced constraint up to its error on the coarse grid
    assert np.max(np.linalg.norm(feet - feet[0], axis=1)) < 1e-4
    for q, v in zip(gait.q, gait.v, strict=True):
        assert np.max(np.abs(_xz_jacobian(task.robot.model, q, task.stance) @ v)) < 1e-3


def test_the_heel_strike_is_the_plastic_impact_map(gait: DesignedGait, task: GaitTask) -> None:
    model = task.robot.model
    q, v_minus = gait.q[-1], gait.v[-1]
    J_new = _xz_jacobian(model, q, task.swing)
    M = _mass_matrix(model, q)
    assert np.max(np.abs(M @ (gait.v_plus - v_minus) - J_new.T @ gait.impulse)) < 1e-7
    assert np.max(np.abs(J_new @ gait.v_plus)) < 1e-7
    # the same post-impact velocity from the impact's closed form
    Minv_Jt = np.linalg.solve(M, J_new.T)
    impulse = -np.linalg.solve(J_new @ Minv_Jt, J_new @ v_minus)
    np.testing.assert_allclose(gait.impulse, impulse, atol=1e-6)
    # the old stance foot lifts off, the impulse is in the friction cone, the foot lands ahead
    J_old = _xz_jacobian(model, q, task.stance)
    assert (J_old @ gait.v_plus)[1] >= -1e-9
    assert gait.impulse[1] > 0.0
    assert abs(gait.impulse[0]) <= task.friction * gait.impulse[1] + 1e-9
    landing = task.robot.frame_position(q, task.swing)
    np.testing.assert_allclose(landing[[0, 2]], [task.step_length, 0.0], atol=1e-7)


def test_the_relabelled_post_impact_state_is_the_start(gait: DesignedGait, task: GaitTask) -> None:
    names = task.robot.joint_names
    q_minus = dict(zip(names, gait.q[-1], strict=True))
    v_plus = dict(zip(names, gait.v_plus, strict=True))
    start_q = dict(zip(names, gait.q[0], strict=True))
    start_v = dict(zip(names, gait.v[0], strict=True))
    swap = {"hip_left": "hip_right", "hip_right": "hip_left"}
    swap |= {"knee_left": "knee_right", "knee_right": "knee_left"}
    for name in names:
        shift = task.step_length if name == "x" else 0.0
        assert q_minus[swap.get(name, name)] - start_q[name] == pytest.approx(shift, abs=1e-8)
        assert v_plus[swap.get(name, name)] == pytest.approx(start_v[name], abs=1e-8)


def test_forces_in_the_friction_cone_and_swing_clear(gait: DesignedGait, task: GaitTask) -> None:
    tangential, normal = gait.force[:, 0], gait.force[:, 1]
    assert np.all(normal > 0.0)
    assert np.all(np.abs(tangential) <= task.friction * normal + 1e-6)
    s = np.linspace(0.0, 1.0, INTERVALS + 1)[1:-1]
    heights = task.robot.frame_path(gait.q, task.swing)[1:-1, 2]
    assert np.all(heights >= task.clearance * 4 * s * (1 - s) - 1e-8)
    residuals = gait.residuals(task.friction)
    assert residuals["friction_margin"] <= 1e-6
    assert residuals["periodic_q"] < 1e-8 and residuals["impact_velocity"] < 1e-7


def test_bezier_fit_keeps_the_impact_relations(gait: DesignedGait, task: GaitTask) -> None:
    fit = fit_bezier(gait, task.degree)
    assert fit.alpha.shape == (4, task.degree + 1)
    # positions: the end relabelled (stance and swing swapped) is the start
    np.testing.assert_allclose(fit.alpha[:, 0], fit.alpha[[2, 3, 0, 1], -1], atol=1e-12)
    theta, rate = phase(gait, gait.q, gait.v)
    assert np.all(rate > 0.0)
    assert fit.theta_plus == pytest.approx(theta[0], abs=1e-7)
    assert fit.theta_minus == pytest.approx(theta[-1], abs=1e-12)
    # slopes at the start: d q_a / d theta of the post-impact (relabelled) state
    a = gait.actuated_indices
    slope = fit.degree * (fit.alpha[:, 1] - fit.alpha[:, 0]) / (fit.theta_minus - fit.theta_plus)
    np.testing.assert_allclose(slope, gait.v[0, a] / rate[0], atol=1e-6)
    # the fit follows the designed step (the design penalised the misfit)
    assert fit.max_error < 1e-2
    np.testing.assert_allclose(bernstein(5, np.array([0.3])).sum(), 1.0)


def test_scene_text_has_the_hzd_interface(gait: DesignedGait, task: GaitTask) -> None:
    fit = fit_bezier(gait, task.degree)
    scene = tomllib.loads(
        hzd_scene_text(gait, fit, urdf="rabbit.urdf", friction=task.friction, kp=400, kd=40)
    )
    controller = scene["controller"]
    assert controller["type"] == "hzd" and controller["stance"] == "foot_left"
    assert np.asarray(controller["bezier"]).shape == (4, task.degree + 1)
    assert controller["legs"] == [list(leg) for leg in task.legs]
    assert controller["theta_plus"] < 0.0 < controller["theta_minus"]
    q0 = np.asarray(scene["robot"]["q0"])
    np.testing.assert_allclose(q0, gait.q[0], atol=1e-4)  # raised by the RK4 drift at most
    heights = [task.robot.frame_position(q0, foot)[2] for foot in ("foot_left", "foot_right")]
    assert min(heights) >= 0.0 and max(heights) < 1e-4
    assert all(c["restitution"] == 0.0 for c in scene["contacts"])
    assert scene["integrator"]["name"] == "moreau_jean"


@pytest.mark.parametrize(
    ("change", "error", "name"),
    [
        ({"step_length": -0.1}, InvalidParameterError, "step_length"),
        ({"stance": "hand"}, NotFoundError, "hand"),
        ({"limits": {"torque": 0.0}}, InvalidParameterError, "torque_limit"),
        ({"limits": {"elbow": 1.0}}, UnknownKeyError, "elbow"),
        ({"limits": {"hip": [1.0, -1.0]}}, InvalidParameterError, "hip"),
        ({"scene_friction": 0.0}, InvalidParameterError, "scene_friction"),
        ({"fit": {"degree": 8}}, InvalidParameterError, "degree"),
        ({"step_time_min": 0.9, "step_time_max": 0.5}, InvalidParameterError, "step_time_max"),
        ({"legs": [["hip_left", "knee_left", "foot_left"]]}, InvalidParameterError, "legs"),
        ({"passive": ["x", "z"]}, InvalidParameterError, "passive"),
    ],
)
def test_bad_task_raises_a_typed_error(change: dict, error: type, name: str) -> None:
    data = tomllib.loads(TASK_FILE.read_text())
    for key, value in change.items():
        if isinstance(value, dict):
            data[key] = {**data.get(key, {}), **value}
        else:
            data[key] = value
    with pytest.raises(error, match=name):
        GaitTask.from_dict(data, base=ROBOTS)


def test_fit_needs_degree_four(gait: DesignedGait) -> None:
    with pytest.raises(DesignError, match="degree"):
        fit_bezier(gait, 3)


def test_unreachable_step_is_infeasible(task: GaitTask) -> None:
    """A 2 m step of a robot with 0.8 m legs cannot be walked: a typed error, no hang."""
    impossible = dataclasses.replace(task, step_length=2.0, intervals=4, max_iter=30)
    with pytest.raises(InfeasibleDesignError, match="IPOPT") as caught:
        design_gait(impossible)
    assert caught.value.best is not None and not caught.value.best.success
