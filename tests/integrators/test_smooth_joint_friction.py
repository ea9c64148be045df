"""Viscous joint friction in the event-driven and compliant integrators.

A free slider and a free pendulum about a vertical axis (no gravity torque) with viscous
friction D decay as v(t) = v0 exp(-D t / I), q(t) = q0 + v0 I / D (1 - exp(-D t / I)): both
integrators follow the closed form to their tolerance, and Moreau–Jean's run converges to it.
Coulomb joint friction is refused by both, naming the integrator.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_joint_friction import INERTIA, _one_joint, _rod_scene

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import InvalidParameterError
from ucontrol.integrators.compliant import Compliant
from ucontrol.integrators.event_driven import EventDriven
from ucontrol.integrators.moreau_jean import MoreauJean
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel

D = 0.8  # [N s/m] or [N m s/rad]
V0 = 1.5  # [m/s] or [rad/s]
DURATION = 1.0  # [s]


def _closed_form(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    decay = np.exp(-D * t / INERTIA)
    return V0 * INERTIA / D * (1.0 - decay), V0 * decay


def _run(integrator, steps: int) -> tuple[np.ndarray, np.ndarray]:
    q, v = np.zeros(1), np.array([V0])
    qs, vs = [0.0], [V0]
    for k in range(steps):
        outcome = integrator.step(integrator.evaluate(q, v, k * integrator.dt), np.zeros(1))
        q, v = outcome.q, outcome.v
        qs.append(float(q[0]))
        vs.append(float(v[0]))
    return np.array(qs), np.array(vs)


def _friction() -> JointFriction:
    return JointFriction(viscous=np.array([D]), coulomb=np.zeros(1))


def _integrator(name: str, robot: RobotModel, dt: float):
    constraints = ConstraintSet(robot)
    if name == "event_driven":
        return EventDriven(robot, constraints, dt=dt, joint_friction=_friction())
    if name == "compliant":
        return Compliant(robot, constraints, dt=dt, joint_friction=_friction())
    return MoreauJean(robot, constraints, dt=dt, theta=0.5, joint_friction=_friction())


@pytest.mark.parametrize("kind", ["slider", "pendulum"])
@pytest.mark.parametrize(
    ("name", "tolerance"),
    # Measured: event_driven (DOP853, rtol 1e-10) 2.2e-16 in q and v, compliant (Radau,
    # rtol 1e-8) 9.2e-14.
    [("event_driven", 2e-15), ("compliant", 1e-12)],
)
def test_viscous_decay_matches_the_exponential(kind: str, name: str, tolerance: float) -> None:
    dt = 0.05  # [s], the sampling: not an accuracy parameter of these integrators
    steps = round(DURATION / dt)
    q, v = _run(_integrator(name, _one_joint(kind), dt), steps)
    q_ref, v_ref = _closed_form(dt * np.arange(steps + 1))
    assert np.max(np.abs(q - q_ref)) <= tolerance
    assert np.max(np.abs(v - v_ref)) <= tolerance


def test_moreau_jean_converges_to_the_event_driven_run() -> None:
    robot = _one_joint("pendulum")
    reference_q, reference_v = _run(_integrator("event_driven", robot, 1e-2), 100)
    errors = []
    for dt in (1e-2, 1e-3):
        q, v = _run(_integrator("moreau_jean", robot, dt), round(DURATION / dt))
        stride = round(1e-2 / dt)
        errors.append(
            max(
                np.max(np.abs(q[::stride] - reference_q)),
                np.max(np.abs(v[::stride] - reference_v)),
            )
        )
    # Measured errors 1.18e-5 and 1.18e-7 (theta = 1/2: order two, ratio 100).
    assert errors[1] <= 1e-6
    assert errors[0] / errors[1] >= 50.0


@pytest.mark.parametrize("name", ["event_driven", "compliant"])
def test_coulomb_joint_friction_is_refused(name: str) -> None:
    robot = _one_joint("slider")
    friction = JointFriction(viscous=np.zeros(1), coulomb=np.array([0.5]))
    cls = EventDriven if name == "event_driven" else Compliant
    with pytest.raises(InvalidParameterError, match=name):
        cls(robot, ConstraintSet(robot), dt=1e-3, joint_friction=friction)


def test_scene_with_viscous_joint_friction_builds_event_driven() -> None:
    import dataclasses

    from ucontrol.scene.integrator_settings import IntegratorSettings

    scene = _rod_scene({"viscous": 0.1}, 0.0)
    scene = dataclasses.replace(scene, integrator=IntegratorSettings(name="event_driven", dt=1e-3))
    integrator = scene.build_integrator()
    assert isinstance(integrator, EventDriven)
    assert integrator.joint_friction is scene.joint_friction
