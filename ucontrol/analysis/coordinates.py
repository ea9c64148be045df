"""Names and units of a model's configuration and velocity coordinates, after its joints.

What the figures label their curves and axes with: ``panda_joint1`` in [rad] and
``panda_finger_joint1`` in [m] are never drawn against one axis, and an error measured over
both says so.
"""

from __future__ import annotations

import pinocchio as pin

#: Coordinate suffixes of Pinocchio joints of several coordinates: (of q, of v).
_SUFFIXES = {
    "JointModelFreeFlyer": (
        ("x", "y", "z", "qx", "qy", "qz", "qw"),
        ("vx", "vy", "vz", "wx", "wy", "wz"),
    ),
    "JointModelPlanar": (("x", "y", "cos", "sin"), ("vx", "vy", "w")),
    "JointModelSpherical": (("qx", "qy", "qz", "qw"), ("wx", "wy", "wz")),
}

_ANGLE = (("rad",), ("rad/s",))
_LENGTH = (("m",), ("m/s",))
#: Units of the coordinates of each Pinocchio joint type, (of q, of v); "1" for the
#: dimensionless ones (unit quaternions, cosine and sine of unbounded revolute joints).
_UNITS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    **{f"JointModelR{axis}": _ANGLE for axis in "XYZ"},
    **{f"JointModelH{axis}": _ANGLE for axis in "XYZ"},
    "JointModelRevoluteUnaligned": _ANGLE,
    "JointModelHelicalUnaligned": _ANGLE,
    **{f"JointModelP{axis}": _LENGTH for axis in "XYZ"},
    "JointModelPrismaticUnaligned": _LENGTH,
    **{f"JointModelRUB{axis}": (("1", "1"), ("rad/s",)) for axis in "XYZ"},
    "JointModelRevoluteUnboundedUnaligned": (("1", "1"), ("rad/s",)),
    "JointModelFreeFlyer": (("m",) * 3 + ("1",) * 4, ("m/s",) * 3 + ("rad/s",) * 3),
    "JointModelPlanar": (("m", "m", "1", "1"), ("m/s", "m/s", "rad/s")),
    "JointModelSpherical": (("1",) * 4, ("rad/s",) * 3),
    "JointModelSphericalZYX": (("rad",) * 3, ("rad/s",) * 3),
    "JointModelTranslation": (("m",) * 3, ("m/s",) * 3),
    "JointModelUniversal": (("rad",) * 2, ("rad/s",) * 2),
}
#: Unit of a coordinate whose joint type has no entry in the table above.
UNKNOWN_UNIT = "?"


def coordinate_names(model: pin.Model | None, nq: int, nv: int) -> tuple[list[str], list[str]]:
    """Names of the configuration and velocity coordinates, after the model's joints.

    A joint of one coordinate gives its name (``panda_joint1``); a joint of several gives one
    name per coordinate with a suffix: ``root_joint.x`` … ``root_joint.qw`` and
    ``root_joint.vx`` … ``root_joint.wz`` for a free flyer, ``name[k]`` otherwise. Without a
    model (or with one of other sizes) the names are ``q[i]`` and ``v[i]``.

    Args:
        model: The Pinocchio model of the run's robot, or None.
        nq: Number of configuration coordinates of the log.
        nv: Number of velocity coordinates of the log.

    Returns:
        The names of q, length nq, and of v, length nv.
    """
    if model is None or model.nq != nq or model.nv != nv:
        return [f"q[{i}]" for i in range(nq)], [f"v[{i}]" for i in range(nv)]
    q_names, v_names = [""] * nq, [""] * nv
    for joint, name in zip(model.joints[1:], model.names[1:], strict=True):
        suffixes = _SUFFIXES.get(joint.shortname(), ((), ()))
        for names, start, size, known in (
            (q_names, joint.idx_q, joint.nq, suffixes[0]),
            (v_names, joint.idx_v, joint.nv, suffixes[1]),
        ):
            for k in range(size):
                if size == 1:
                    names[start + k] = name
                elif len(known) == size:
                    names[start + k] = f"{name}.{known[k]}"
                else:
                    names[start + k] = f"{name}[{k}]"
    return q_names, v_names


def coordinate_units(model: pin.Model | None, nq: int, nv: int) -> tuple[list[str], list[str]]:
    """Units of the configuration and velocity coordinates, after the model's joint types.

    Revolute (and helical) joints give ``rad`` and ``rad/s``, prismatic ones ``m`` and
    ``m/s``; a free flyer ``m`` for its position, ``1`` (dimensionless) for its unit
    quaternion, ``m/s`` and ``rad/s`` for its velocity. A joint type the table does not know,
    or no model (or one of other sizes), gives :data:`UNKNOWN_UNIT`. The arguments are those
    of :func:`coordinate_names`.

    Returns:
        The units of q, length nq, and of v, length nv.
    """
    q_units, v_units = [UNKNOWN_UNIT] * nq, [UNKNOWN_UNIT] * nv
    if model is None or model.nq != nq or model.nv != nv:
        return q_units, v_units
    for joint in model.joints[1:]:
        known = _UNITS.get(joint.shortname())
        if known is None or len(known[0]) != joint.nq or len(known[1]) != joint.nv:
            continue
        q_units[joint.idx_q : joint.idx_q + joint.nq] = known[0]
        v_units[joint.idx_v : joint.idx_v + joint.nv] = known[1]
    return q_units, v_units
