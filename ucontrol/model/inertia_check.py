r"""Physical sanity of a robot's inertial parameters, checked when a scene is loaded.

Each body must have a finite mass :math:`m \ge 0` and principal moments of inertia about its
centre of mass :math:`I_1 \le I_2 \le I_3` that a rigid body can have: :math:`I_1 \ge 0` and
the triangle inequality :math:`I_1 + I_2 \ge I_3`; a massless body (an intermediate link of a
planar chain) has no inertia either. The mass matrix must then be positive definite at the
initial configuration: a chain whose joints move no mass cannot be integrated.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.exceptions import InvalidInertiaError, InvalidParameterError
from ucontrol.model.robot_model import RobotModel

#: Relative slack of the triangle inequality and of the zero moments, for rounding in URDFs.
_SLACK = 1e-9


def check_inertias(robot: RobotModel) -> None:
    """Check every body's mass and inertia.

    Raises:
        InvalidInertiaError: A body with a negative or non-finite mass, a negative principal
            moment, moments that break the triangle inequality, or inertia without mass.
    """
    model = robot.model
    for joint in range(1, model.njoints):
        inertia = model.inertias[joint]
        check_body(_body_name(model, joint), float(inertia.mass), inertia.inertia)


def check_body(body: str, mass: float, rotational: NDArray[np.float64]) -> list[float]:
    """Check one body's mass [kg] and rotational inertia about its centre of mass [kg m²].

    Args:
        body: The link's name, in errors.
        mass: Its mass in [kg].
        rotational: Its inertia about the centre of mass, shape (3, 3).

    Returns:
        The principal moments in [kg m²], ascending.

    Raises:
        InvalidInertiaError: As :func:`check_inertias`.
    """
    rotational = np.asarray(rotational, dtype=float)
    if not np.isfinite(mass) or not np.all(np.isfinite(rotational)):
        raise InvalidInertiaError(body, mass, [float("nan")] * 3, "finite")
    moments: list[float] = np.linalg.eigvalsh(0.5 * (rotational + rotational.T)).tolist()
    scale = max(float(moments[-1]), 1e-300)
    if mass < 0.0:
        raise InvalidInertiaError(body, mass, moments, "a mass >= 0")
    if moments[0] < -_SLACK * scale:
        raise InvalidInertiaError(body, mass, moments, "positive semi-definite")
    if moments[0] + moments[1] < moments[2] * (1.0 - _SLACK):
        raise InvalidInertiaError(
            body, mass, moments, "principal moments with I1 + I2 >= I3 (triangle inequality)"
        )
    if mass == 0.0 and moments[-1] > 0.0:
        raise InvalidInertiaError(body, mass, moments, "no inertia without mass")
    return moments


def check_mass_matrix(robot: RobotModel, q: NDArray[np.float64]) -> None:
    """Check that M(q) is positive definite (every joint moves some mass).

    Raises:
        InvalidParameterError: M(q) is singular; the message names the joints that move no
            mass (their diagonal entries vanish).
    """
    model = robot.model
    M = pin.crba(model, pin.Data(model), q)
    M = np.triu(M) + np.triu(M, 1).T
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        massless = np.diag(M) <= 1e-300
        names = []
        for j in range(1, model.njoints):
            joint = model.joints[j]
            if joint.nv and massless[joint.idx_v : joint.idx_v + joint.nv].all():
                names.append(model.names[j])
        raise InvalidParameterError(
            "mass matrix M(q0)",
            f"singular (no mass moved by joints {names})" if names else "not positive definite",
            "positive definite: every joint must move a body with mass",
        ) from None


def _body_name(model: pin.Model, joint: int) -> str:
    """The link a joint moves (its first BODY frame), or the joint's name."""
    for frame in model.frames:
        if frame.parentJoint == joint and frame.type == pin.FrameType.BODY:
            return str(frame.name)
    return str(model.names[joint])
