"""The flexible two-link arm of DESIGN §5 built in code, and its smooth plant (no contact)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from ucontrol.contact import Plane, PointContact
from ucontrol.control import (
    BrogliatoGains,
    CirclePath,
    ContactPhase,
    ContactState,
    DesiredCycle,
    FlexibleBrogliatoController,
    TaskCoordinates,
)
from ucontrol.model import FlexibleJoints, RobotModel

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
GROUND = "end_effector/ground"
#: The flexible one-constraint case: γ1 = 10, γ2 = 5; K = 2000, B = 0.1; q0 = (0.9, -1.5, ...).
GAINS = BrogliatoGains(gamma1=10.0, gamma2=5.0)
STIFFNESS = 2000.0  # [N m/rad]
MOTOR_INERTIA = 0.1  # [kg m²]
Q0 = np.array([0.9, -1.5])  # [rad]
#: τ0 of the first cycle: free motion before it, in [s].
TAU0 = 4.2


def robot() -> RobotModel:
    return RobotModel.from_urdf(ROBOTS / "two_link_flexible.urdf", gravity=[0.0, -9.81, 0.0])


def ground() -> PointContact:
    plane = Plane(point=np.zeros(3), normal=np.array([0.0, 1.0, 0.0]), name="ground")
    return PointContact(frame="end_effector", surface=plane, name=GROUND)


def task(arm: RobotModel) -> TaskCoordinates:
    return TaskCoordinates(arm, "end_effector", [ground()], [[1.0, 0.0, 0.0]])  # X = (y, x)


def cycle() -> DesiredCycle:
    """Circle of centre (0.4, 0), radius 0.3, period 10 s; its lower half on the ground."""
    path = CirclePath(centre=np.array([0.4, 0.0, 0.0]), radius=0.3, period=10.0)
    phase = ContactPhase(contact=GROUND, start=5.0, end=10.0, force=5.0)
    return DesiredCycle(path=path, contact_phases=(phase,))


def controller(
    joints: Sequence[str] = ("shoulder", "elbow"), stiffness: float = STIFFNESS
) -> FlexibleBrogliatoController:
    arm = robot()
    flexible = FlexibleJoints.from_robot(
        arm, joints, stiffness=stiffness, motor_inertia=MOTOR_INERTIA
    )
    return FlexibleBrogliatoController(arm, flexible, task(arm), cycle(), GAINS)


def contact_state(force: float = 0.0, dt: float = 1e-3) -> ContactState:
    """The ground contact with a constant force ``force`` [N] (closed at rest if > 0)."""
    zero = np.zeros(1)
    return ContactState([GROUND], zero, zero, np.array([force * dt]), zero < force, dt)


def initial_state(law: FlexibleBrogliatoController, rng: np.random.Generator) -> np.ndarray:
    """(q1, q2, dq1, dq2) near q0 with random deflections and velocities."""
    nv, nf = law.robot.nv, law.flexible.nf
    q1 = Q0 + 0.05 * rng.standard_normal(nv)
    q2 = q1[law.flexible.v_index] + 0.01 * rng.standard_normal(nf)
    return np.concatenate([q1, q2, 0.3 * rng.standard_normal(nv + nf)])


def plant(
    law: FlexibleBrogliatoController,
    input_of: Callable[[float, np.ndarray], np.ndarray],
    ground_force: Callable[[float], float] = lambda t: 0.0,
) -> Callable[[float, np.ndarray], np.ndarray]:
    """Right-hand side of the smooth flexible plant x = (q, v) under ``input_of(t, x)``.

    Spong's model from Pinocchio and :meth:`FlexibleJoints.spring_torque`; the ground pushes
    the end effector up with ``ground_force(t)`` [N] wherever it is (no impact, no constraint).
    """
    arm, flexible = law.robot, law.flexible
    model, data = arm.model, pin.Data(arm.model)
    nq = arm.nq + flexible.nf
    rigid = np.setdiff1d(np.arange(arm.nv), flexible.v_index)
    normal = ground().surface.normal

    def rhs(t: float, x: np.ndarray) -> np.ndarray:
        q, v = x[:nq], x[nq:]
        q1, dq1, q2, dq2 = flexible.split(q, v)
        u = input_of(t, x)
        spring = flexible.spring_torque(q1, dq1, q2, dq2)  # on the motors; the links get -
        tau = np.zeros(arm.nv)
        tau[rigid] = u[rigid]
        tau[flexible.v_index] -= spring
        tau += ground_force(t) * (normal @ arm.frame_jacobian(q1, "end_effector")[:3])
        M = pin.crba(model, data, q1)
        M = np.triu(M) + np.triu(M, 1).T
        ddq1 = np.linalg.solve(M, tau - pin.nonLinearEffects(model, data, q1, dq1))
        ddq2 = (u[flexible.input_index] + spring) / flexible.motor_inertia
        return np.concatenate([v, ddq1, ddq2])

    return rhs


def free_motion_input(
    law: FlexibleBrogliatoController,
) -> Callable[[float, np.ndarray], np.ndarray]:
    """The law as a function of (t, x) in the free phase (it is reset at every call)."""
    nq = law.robot.nq + law.flexible.nf
    contacts = contact_state()

    def input_of(t: float, x: np.ndarray) -> np.ndarray:
        law.reset()
        return law(t, x[:nq], x[nq:], contacts)

    return input_of


def task_position(arm: RobotModel, law: FlexibleBrogliatoController, q1: np.ndarray) -> np.ndarray:
    """Task coordinates of the end effector at the link configuration ``q1`` by Pinocchio."""
    return law.task.of_point(arm.frame_position(q1, "end_effector"))
