"""Initial guesses of the design: the scene's hand-made cycle, sampled and inverted.

The hand-made cycle is the scene's ``[controller.path]`` circle with its
``[[controller.contact_phases]]``: the flight follows the circle from the takeoff to the
nominal arrival, the contact phase its projection on the surface. Each sample is inverted by
damped least squares (from the previous solution, the first from the scene's ``q0``), the
velocities are finite differences and the torques come from inverse dynamics with the
desired contact force. Without a circle, the flight is a half ellipse from the task's
``takeoff`` up and over to its ``landing`` point and the contact phase the straight slide back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.control.circle_path import CirclePath
from ucontrol.design.design_task import DesignTask
from ucontrol.exceptions import DesignError

Vector = NDArray[np.float64]
#: Samples of each phase of the hand-made cycle.
_SAMPLES = 81


@dataclass(frozen=True)
class PhaseGuess:
    """Initial guess of one phase: states (m, 2 nv), torques (m - 1, nv), duration [s]."""

    x: NDArray[np.float64]
    tau: NDArray[np.float64]
    duration: float


@dataclass(frozen=True)
class WarmStart:
    """Guesses per phase kind: ``"flight"``, ``"bounce"`` and ``"contact"``."""

    phases: dict[str, PhaseGuess]


def hand_made_warm_start(task: DesignTask, layout: list[tuple[str, str, int]]) -> WarmStart:
    """The warm start from the scene's hand-made cycle (see the module docstring).

    Raises:
        DesignError: The scene has no circle path and the task no landing and takeoff points.
    """
    flight_p, flight_T, contact_p, contact_T = _task_samples(task)
    flight = _invert(task, flight_p, flight_T, 0.0, task.scene.q0)
    contact = _invert(
        task, contact_p, contact_T, task.contact_phase.force, flight.x[-1, : task.scene.robot.nv]
    )
    q_land = contact.x[0, : task.scene.robot.nv]
    nv = task.scene.robot.nv
    rest = np.concatenate((q_land, np.zeros(nv)))
    gravity = task.scene.robot.gravity_torque(q_land)
    bounce = PhaseGuess(np.tile(rest, (3, 1)), np.tile(gravity, (2, 1)), 0.05)
    return WarmStart({"flight": flight, "contact": contact, "bounce": bounce})


def _task_samples(task: DesignTask) -> tuple[Vector, float, Vector, float]:
    """Frame positions along the flight and the contact phase, and their durations [s]."""
    table = task.scene.controller
    contact = task.contact
    normal, point = contact.surface.normal, contact.surface.point
    on_surface = lambda p: p - ((p - point) @ normal - contact.radius) * normal  # noqa: E731
    path_table = table.get("path") if table.get("type") == "brogliato" else None
    phases = [p for p in table.get("contact_phases", []) if p.get("contact") == contact.name]
    if path_table is not None and path_table.get("type", "circle") == "circle" and phases:
        path = CirclePath(
            centre=path_table["centre"],
            radius=path_table["radius"],
            period=path_table["period"],
            **{key: path_table[key] for key in ("axes", "start_angle") if key in path_table},
        )
        start, end, period = float(phases[0]["start"]), float(phases[0]["end"]), path.period
        t_flight = np.linspace(end, start + period, _SAMPLES)
        t_contact = np.linspace(start, end, _SAMPLES)
        flight = np.array([path(float(t))[0] for t in t_flight])
        contact_p = np.array([on_surface(path(float(t))[0]) for t in t_contact])
        return flight, start + period - end, contact_p, end - start
    spec = task.contact_phase
    if spec.landing is None or spec.takeoff is None:
        raise DesignError(
            "no warm start: the scene has no circle path with a contact phase on "
            f"{contact.name!r} and the task gives no `landing` and `takeoff` points"
        )
    landing, takeoff = on_surface(spec.landing), on_surface(spec.takeoff)
    height = max(task.flight.clearance, 0.05)  # [m]
    s = np.linspace(0.0, np.pi, _SAMPLES)
    middle = 0.5 * (landing + takeoff)
    half = 0.5 * (takeoff - landing)
    flight = middle + np.cos(s)[:, None] * half + np.sin(s)[:, None] * height * normal
    contact_p = landing + np.linspace(0.0, 1.0, _SAMPLES)[:, None] * (takeoff - landing)
    total = task.period if task.period is not None else 2.0 * task.flight.duration_min + 2.0
    return flight, 0.5 * total, contact_p, 0.5 * total


def _invert(
    task: DesignTask, positions: Vector, duration: float, force: float, q_start: Vector
) -> PhaseGuess:
    """Damped least-squares inverse kinematics, finite-difference velocities, torques."""
    robot = task.scene.robot
    frame = task.frame
    q = np.array(q_start, dtype=float)
    qs = []
    for target in positions:
        for _ in range(50):
            error = target - robot.frame_position(q, frame)
            if np.linalg.norm(error) < 1e-10:
                break
            J = robot.frame_jacobian(q, frame)[:3]
            step = J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(3), error)
            q = robot.integrate(q, step)
        if task.joint_limits is not None:
            q = np.clip(q, task.joint_limits[0], task.joint_limits[1])
        qs.append(q.copy())
    Q = np.array(qs)
    t = np.linspace(0.0, duration, len(Q))
    V = np.gradient(Q, t, axis=0)
    A = np.gradient(V, t, axis=0)
    contact = task.contact
    taus = []
    for k in range(len(Q) - 1):
        tau = pin.rnea(robot.model, robot.data, Q[k], V[k], A[k]).copy()
        if force > 0.0:
            J_n = contact.surface.normal @ robot.frame_jacobian(Q[k], contact.frame)[:3]
            tau -= J_n * force
        taus.append(tau)
    return PhaseGuess(np.hstack((Q, V)), np.array(taus), duration)
