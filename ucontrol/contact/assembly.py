r"""Assembling a closed chain: a configuration guess projected onto :math:`h(q) = 0`.

A closed chain's initial configuration must satisfy its bilateral constraints
(:mod:`ucontrol.contact.bilateral`) to round-off, which few users can write by hand.
:func:`assemble` moves a guess :math:`q_0` onto the constraint manifold by damped
Gauss–Newton steps of least norm on the configuration space,

.. math::

    \delta = -J_f^T \big(J_f J_f^T + \mu_k I\big)^{+} h(q_k), \qquad
    q_{k+1} = \mathrm{integrate}(q_k, \alpha_k \delta), \qquad
    \mu_k = \|h(q_k)\|^2,

with :math:`J_f` the constraint Jacobian whose columns of the held coordinates are zeroed
(those coordinates do not move), the Levenberg–Marquardt damping :math:`\mu_k` of Yamashita
and Fukushima (2001), which keeps quadratic convergence where the rows are dependent (the
zero out-of-plane row of a planar closure), and :math:`\alpha_k` halved until the residual
decreases. Of the configurations that close the loops, the step of least norm picks one near
the guess; holding coordinates (a four-bar's crank angle) removes the remaining freedom.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NoReturn

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_int, as_positive
from ucontrol.contact.bilateral import BilateralConstraint, BilateralSet
from ucontrol.exceptions import AssemblyError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]
#: Halvings of a Gauss–Newton step before the residual is declared stuck at a minimum.
_MAX_HALVINGS = 40


def assemble(
    robot: RobotModel,
    constraints: BilateralSet | Sequence[BilateralConstraint],
    q_guess: object,
    *,
    fixed: Sequence[str] = (),
    tolerance: float = 1e-12,
    max_iter: int = 100,
    name: str = "q",
) -> Vector:
    """The configuration near ``q_guess`` where every bilateral constraint holds.

    Args:
        robot: The robot.
        constraints: Its bilateral constraints (a :class:`BilateralSet` or the constraints).
        q_guess: Approximate configuration, shape (nq,).
        fixed: Names of joints whose coordinates are held at their values in ``q_guess``
            (the input crank of a mechanism).
        tolerance: Largest residual accepted, in [m] or [rad] (the constraints' units), > 0.
        max_iter: Largest number of Gauss–Newton iterations, >= 1.
        name: The configuration's name in errors (``"q0"`` for a scene's).

    Returns:
        The assembled configuration, shape (nq,): every residual at most ``tolerance``, the
        coordinates of ``fixed`` equal to the guess's.

    Raises:
        ShapeError: ``q_guess`` does not have shape (nq,).
        JointNotFoundError: A ``fixed`` joint the robot does not have.
        AssemblyError: The residual does not reach ``tolerance``: no closure near the guess
            (an impossible loop, or held coordinates that forbid it); the error names the
            worst constraint row and its residual and keeps the best configuration reached.
    """
    bilateral = constraints if isinstance(constraints, BilateralSet) else None
    if bilateral is None:
        bilateral = BilateralSet(robot, constraints)  # type: ignore[arg-type]
    q = robot.check_configuration(name, q_guess)
    tolerance = as_positive("tolerance", tolerance)
    max_iter = as_int("max_iter", max_iter, 1)
    held = np.zeros(robot.nv, dtype=bool)
    for joint_name in fixed:
        joint = robot.model.joints[robot.joint_id(str(joint_name))]
        held[joint.idx_v : joint.idx_v + joint.nv] = True
    model, data = robot.model, pin.Data(robot.model)

    def residual(q: Vector) -> Vector:
        pin.framesForwardKinematics(model, data, q)
        return bilateral.residual(data, q)

    h = residual(q)
    for iteration in range(max_iter + 1):
        if bilateral.size == 0 or np.max(np.abs(h)) <= tolerance:
            return q
        if iteration == max_iter:
            break
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        J = bilateral.jacobian(data)
        J[:, held] = 0.0
        norm = float(h @ h)
        damped = J @ J.T + norm * np.eye(bilateral.size)  # [m²] (Yamashita–Fukushima)
        step = -J.T @ np.linalg.lstsq(damped, h, rcond=None)[0]
        for _ in range(_MAX_HALVINGS):
            trial = pin.integrate(model, q, step)
            h_trial = residual(trial)
            if float(h_trial @ h_trial) < norm:
                q, h = trial, h_trial
                break
            step = 0.5 * step
        else:
            _raise(bilateral, name, h, iteration, q, "stuck at a least-squares minimum")
    _raise(bilateral, name, h, max_iter, q, f"max_iter = {max_iter} reached")


def _raise(
    bilateral: BilateralSet, name: str, h: Vector, iterations: int, q: Vector, reason: str
) -> NoReturn:
    worst = int(np.argmax(np.abs(h)))
    raise AssemblyError(
        name, float(abs(h[worst])), bilateral.names[worst], iterations, q.copy(), reason
    )
