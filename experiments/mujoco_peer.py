r"""MuJoCo as an optional peer of the step benchmarks: a Pinocchio model written as MJCF.

:func:`mjcf_of` writes a fixed-base Pinocchio model (revolute and prismatic joints) as an MJCF
model: each joint's body at its placement in the parent's joint frame, its inertia (mass,
centre of mass, full rotational inertia about it) and armature; joints without limits,
damping or friction, as the other loops of ``experiments/bench_step.py`` take them. The contacts
are spheres at the contact frames with the same radii, against a plane, frictionless
(``condim = 1``); no other geometry collides. :func:`mujoco_step` advances it with ``mj_step``
under the generalized forces of the benchmark (``qfrc_applied``).

MuJoCo's contacts are soft (a regularized, convex contact model solved by its Newton solver),
its integrator semi-implicit Euler: the trajectories differ from the rigid Moreau–Jean ones
(``max Δv`` says by how much); what is compared is the cost of a step of the same robot, forces
and contacts. ``mujoco`` is the extra ``peers`` (``pip install ucontrol[peers]``);
:func:`available` is False without it.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact import PointContact

Vector = NDArray[np.float64]


def available() -> bool:
    """Whether MuJoCo's Python package is installed."""
    return importlib.util.find_spec("mujoco") is not None


def mjcf_of(model: pin.Model, contacts: Sequence[PointContact], dt: float) -> str:
    """The MJCF text of ``model`` with sphere ``contacts`` on their plane, step ``dt`` in [s].

    Every joint has one degree of freedom, a hinge or a slide along its motion subspace S
    (Pinocchio's, constant for these joints); every contact is on the same plane (a
    :class:`~ucontrol.contact.Plane`).
    """
    plane = contacts[0].surface
    spheres: dict[int, list[str]] = {}
    for k, contact in enumerate(contacts):
        frame = model.frames[model.getFrameId(contact.frame)]
        spheres.setdefault(frame.parentJoint, []).append(
            f'<geom name="contact{k}" type="sphere" size="{float(contact.radius)!r}" '
            f'pos="{_vector(frame.placement.translation)}" contype="1" conaffinity="0" '
            'condim="1"/>'
        )
    children: dict[int, list[int]] = {}
    for joint in range(1, model.njoints):
        children.setdefault(model.parents[joint], []).append(joint)
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))  # each joint's motion subspace S

    def body(joint: int) -> str:
        placement, inertia = model.jointPlacements[joint], model.inertias[joint]
        if model.joints[joint].nv != 1:
            raise ValueError(f"joint {model.names[joint]!r}: one degree of freedom expected")
        S = np.asarray(data.joints[joint].S).ravel()  # (linear, angular) in the joint frame
        kind, axis = ("slide", S[:3]) if np.any(S[:3]) else ("hinge", S[3:])
        I_c = inertia.inertia
        full = (I_c[0, 0], I_c[1, 1], I_c[2, 2], I_c[0, 1], I_c[0, 2], I_c[1, 2])
        index = model.joints[joint].idx_v
        return "\n".join(
            [
                f'<body name="{model.names[joint]}" pos="{_vector(placement.translation)}" '
                f'quat="{_quaternion(placement.rotation)}">',
                f'<inertial mass="{float(inertia.mass)!r}" pos="{_vector(inertia.lever)}" '
                f'fullinertia="{_vector(full)}"/>',
                f'<joint name="{model.names[joint]}" type="{kind}" axis="{_vector(axis)}" '
                f'armature="{float(model.armature[index])!r}" limited="false"/>',
                *spheres.get(joint, []),
                *(body(child) for child in children.get(joint, [])),
                "</body>",
            ]
        )

    normal = np.asarray(plane.normal, dtype=float)
    return "\n".join(
        [
            '<mujoco model="bench">',
            f'<option timestep="{float(dt)!r}" gravity="{_vector(model.gravity.linear)}"/>',
            "<worldbody>",
            f'<geom name="plane" type="plane" size="0 0 1" pos="{_vector(plane.point)}" '
            f'zaxis="{_vector(normal)}" contype="0" conaffinity="1" condim="1"/>',
            *(body(child) for child in children.get(0, [])),
            "</worldbody>",
            "</mujoco>",
        ]
    )


def mujoco_step(model: pin.Model, contacts: Sequence[PointContact], dt: float) -> Any:
    """A step ``(q, v, tau) -> (q_next, v_next, any_contact)`` by MuJoCo's ``mj_step``.

    The state is written into ``qpos``, ``qvel`` and the forces into ``qfrc_applied`` before
    each ``mj_step`` (as the other loops take their state from the caller).
    """
    import mujoco

    mj_model = mujoco.MjModel.from_xml_string(mjcf_of(model, contacts, dt))
    data = mujoco.MjData(mj_model)
    step_once = mujoco.mj_step

    def step(q: Vector, v: Vector, tau: Vector) -> tuple[Vector, Vector, bool]:
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = q, v, tau
        step_once(mj_model, data)
        return data.qpos.copy(), data.qvel.copy(), data.ncon > 0

    return step


def _vector(values: Any) -> str:
    return " ".join(repr(float(x)) for x in values)


def _quaternion(rotation: Vector) -> str:
    """MuJoCo's (w, x, y, z) of a rotation matrix."""
    q = pin.Quaternion(np.asarray(rotation))
    return _vector((q.w, q.x, q.y, q.z))
