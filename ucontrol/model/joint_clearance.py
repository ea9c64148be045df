r"""Revolute joints given radial play: each becomes two prismatic joints and the revolute one.

A revolute joint with clearance (a journal in a bearing, Brogliato's *Nonsmooth Mechanics*
§8.5.3) lets the journal's centre move in the plane normal to the joint axis :math:`a`, within a
circle of radius c (the radial clearance) about the bearing's centre. :func:`with_joint_clearance`
gives the robot these two degrees of freedom: joint ``J`` (parent P, placement
:math:`{}^P M_J`, axis a) is replaced by

- ``J/x``, prismatic along :math:`e_1`, with J's placement in P,
- ``J/y``, prismatic along :math:`e_2 = a \times e_1`,
- ``J``, the revolute joint itself (its name, axis, limits and body unchanged),

where :math:`(e_1, e_2, a)` is a right-handed orthonormal basis of J's frame. The two new
coordinates :math:`(x, y)` are the journal's offset from the bearing's centre in J's frame, in
[m]; they are passive (no input acts on them) and zero at the neutral configuration (the
journal centred). The bodies of ``J/x`` and ``J/y`` have no mass: the child's mass moves them.
The circle itself, :math:`\sqrt{x^2 + y^2} \le c`, is the unilateral constraint of
:class:`~ucontrol.contact.clearance_joint.ClearanceJoint`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]

#: Suffixes of the two prismatic joints that carry a clearance joint's play.
PLAY_SUFFIXES = ("/x", "/y")
#: Bound of the play coordinates in [m]: they are held by the clearance constraint instead.
_PLAY_LIMIT = 1e3
#: Per-velocity-coordinate arrays of a Pinocchio model, copied to the new model.
_V_ARRAYS = ("effortLimit", "velocityLimit", "armature", "damping", "friction")
#: Per-configuration-coordinate arrays.
_Q_ARRAYS = ("lowerPositionLimit", "upperPositionLimit")


def play_joints(joint: str) -> tuple[str, str]:
    """Names of the two prismatic joints that carry the play of clearance joint ``joint``."""
    return joint + PLAY_SUFFIXES[0], joint + PLAY_SUFFIXES[1]


def revolute_axis(model: pin.Model, joint_id: int) -> Vector | None:
    """Unit axis of revolute joint ``joint_id`` in its own frame, shape (3,), else None.

    A joint is revolute when it has one degree of freedom whose motion is a pure rotation
    (Pinocchio's RX, RY, RZ, unaligned and unbounded revolute joints).
    """
    joint = model.joints[joint_id]
    if joint.nv != 1:
        return None
    data = joint.createData()
    joint.calc(data, pin.neutral(model)[joint.idx_q : joint.idx_q + joint.nq])
    motion = np.asarray(data.S).reshape(6)
    if np.linalg.norm(motion[:3]) > 1e-12:  # a prismatic or helical joint
        return None
    return motion[3:] / np.linalg.norm(motion[3:])


def with_joint_clearance(robot: RobotModel, joints: Sequence[str]) -> RobotModel:
    """A copy of ``robot`` where each revolute joint of ``joints`` has radial play.

    The kinematics at zero play equal the original's; the play joints are passive (module
    docstring). Frames keep their names and parents (a frame on J's body stays on J).

    Args:
        robot: The robot.
        joints: Names of revolute joints, each at most once.

    Raises:
        JointNotFoundError: A name is not a joint of the robot.
        InvalidParameterError: A joint is not revolute, or is named twice.
    """
    names = [str(joint) for joint in joints]
    for name in names:
        robot.joint_id(name)  # JointNotFoundError listing the joints
        if names.count(name) > 1:
            raise InvalidParameterError("clearance joint", name, "each joint named once")
    old = robot.model
    axes = {}
    for name in names:
        axis = revolute_axis(old, old.getJointId(name))
        if axis is None:
            kind = old.joints[old.getJointId(name)].shortname()
            raise InvalidParameterError(
                "clearance joint", name, f"a revolute joint (it is a {kind})"
            )
        axes[name] = axis
    model = pin.Model()
    model.name = old.name
    model.gravity = old.gravity
    joint_map = {0: 0}
    for j in range(1, old.njoints):
        name = old.names[j]
        parent = joint_map[old.parents[j]]
        placement = old.jointPlacements[j]
        if name in axes:
            first, second = _plane_basis(axes[name])
            for suffix, direction in zip(PLAY_SUFFIXES, (first, second), strict=True):
                parent = _add_joint(
                    model,
                    parent,
                    pin.JointModelPrismaticUnaligned(direction),
                    placement,
                    name + suffix,
                    np.full(1, _PLAY_LIMIT),
                )
                placement = pin.SE3.Identity()
        new = model.addJoint(parent, old.joints[j], placement, name)
        model.appendBodyToJoint(new, old.inertias[j], pin.SE3.Identity())
        joint_map[j] = new
    _copy_coordinate_arrays(old, model, joint_map)
    frame_map = {0: 0}
    for f in range(1, old.nframes):
        frame = old.frames[f]
        copy = pin.Frame(
            frame.name,
            joint_map[frame.parentJoint],
            frame_map[frame.parentFrame],
            frame.placement,
            frame.type,
            frame.inertia,
        )
        frame_map[f] = model.addFrame(copy, False)  # the bodies' inertias are appended above
    passive = [*robot.passive_joints, *(joint for name in names for joint in play_joints(name))]
    return RobotModel(
        model,
        floating_base=robot.floating_base,
        urdf_path=robot.urdf_path,
        mjcf_path=robot.mjcf_path,
        passive_joints=passive,
    )


def ideal_to_play(
    ideal: RobotModel, robot: RobotModel, q: Vector, v: Vector
) -> tuple[Vector, Vector]:
    """The state (q, v) of ``ideal`` as a state of ``robot``, its copy with play: centred, at rest.

    Each coordinate keeps its joint's value; the play coordinates are zero.

    Args:
        ideal: The robot without play.
        robot: :func:`with_joint_clearance` of ``ideal``.
        q: Configuration of ``ideal``, shape (ideal.nq,).
        v: Velocity of ``ideal``, shape (ideal.nv,).
    """
    q_new, v_new = robot.neutral(), np.zeros(robot.nv)
    for j in range(1, ideal.model.njoints):
        old = ideal.model.joints[j]
        new = robot.model.joints[robot.model.getJointId(ideal.model.names[j])]
        q_new[new.idx_q : new.idx_q + new.nq] = q[old.idx_q : old.idx_q + old.nq]
        v_new[new.idx_v : new.idx_v + new.nv] = v[old.idx_v : old.idx_v + old.nv]
    return q_new, v_new


def _plane_basis(axis: Vector) -> tuple[Vector, Vector]:
    """Unit vectors e1, e2 with (e1, e2, axis) right-handed and orthonormal."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    first = np.cross(helper, axis)
    first /= np.linalg.norm(first)
    return first, np.cross(axis, first)


def _add_joint(
    model: pin.Model,
    parent: int,
    joint: pin.JointModel,
    placement: pin.SE3,
    name: str,
    limit: Vector,
) -> int:
    """Add a massless one-coordinate joint bounded by ``limit`` (both signs); its id."""
    zero = np.zeros(1)
    return int(model.addJoint(parent, joint, placement, name, zero, zero, -limit, limit))


def _copy_coordinate_arrays(old: pin.Model, model: pin.Model, joint_map: dict[int, int]) -> None:
    """Limits, armature, damping and friction of the old joints onto their copies."""
    for attribute, size in ((name, "v") for name in _V_ARRAYS):
        _remap(old, model, joint_map, attribute, size)
    for attribute in _Q_ARRAYS:
        _remap(old, model, joint_map, attribute, "q")


def _remap(
    old: pin.Model, model: pin.Model, joint_map: dict[int, int], attribute: str, size: str
) -> None:
    """Copy the per-coordinate array ``attribute`` joint by joint (kept where it is absent)."""
    if not hasattr(old, attribute):
        return
    source = np.asarray(getattr(old, attribute), dtype=float)
    target = np.array(getattr(model, attribute), dtype=float)
    for j_old, j_new in joint_map.items():
        if j_old == 0:
            continue
        a, b = old.joints[j_old], model.joints[j_new]
        if size == "v":
            target[b.idx_v : b.idx_v + b.nv] = source[a.idx_v : a.idx_v + a.nv]
        else:
            target[b.idx_q : b.idx_q + b.nq] = source[a.idx_q : a.idx_q + a.nq]
    setattr(model, attribute, target)
