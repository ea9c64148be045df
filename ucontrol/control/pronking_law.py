r"""The pronking controller's law, written once over array operations: numpy and casadi.

:class:`~ucontrol.control.pronking_controller.PronkingController` evaluates the law below on
numpy arrays (:data:`NUMPY_LAW_OPS`, the readable reference, ``compiled=False``) and, built
from the same functions on casadi expressions, as two casadi Functions with named inputs and
outputs compiled to C by :class:`~ucontrol.model.compiled_function.CompiledFunction` on
buffers bound to the Pinocchio data the controller reads (``tests/control/test_pronking.py``
checks one against the other). Most of the reference's time per call is the Python overhead of
some hundred small numpy operations; there each stage is one compiled call.

- :func:`law_measures`, :func:`height_acceleration`, :func:`stance_wrench` and
  :func:`distribute_forces`, composed in
  :func:`force_law_function` (``"pronk_forces"``): the height h, its rate :math:`\dot h` and
  the number of feet in contact (gap at most ``contact_gap``), the desired centroidal wrench
  (F, T) of the module docstring of :mod:`~ucontrol.control.pronking_controller`, its matrix
  A over all the feet, and the unconstrained optimum of the force QP on the feet in contact,

  .. math::

      f = D A^T (A D A^T + \epsilon I)^{-1} w, \qquad
      D = \operatorname{diag}(\text{touching}_i\, I_3),

  with a flag saying whether it lies in the friction pyramids. When it does not, the
  controller solves the QP with proxsuite.
- :func:`joint_torques`, in :func:`torque_function` (``"pronk_torques"``): the joint torques
  from the feet's forces, :math:`\tau_\text{leg} = g_\text{leg} - J_{i,\text{leg}}^T f_i` for a
  stance leg with :math:`J_{i,\text{leg}} = J^{v}_{\text{leg}} - [p_i]_\times
  J^{\omega}_{\text{leg}}` (the foot's linear Jacobian in LOCAL_WORLD_ALIGNED from the joints'
  world Jacobian ``data.J``), the joint PD toward the posture for the others.

Structure (the number of feet, the legs' joints) is part of each Function; targets and gains are
inputs, so that one compiled library serves every setting of a robot. The two kinds of numbers
differ only in their primitives (:class:`LawOps`): the attitude's logarithm is Pinocchio's
``log3`` on numpy and :func:`_log3` on casadi, the 6 × 6 solve LAPACK's on numpy and an
unrolled Cholesky on casadi; the paths agree to round-off.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

Index = NDArray[np.int64]

#: Below this rotation angle [rad] the factor θ / sin θ of the attitude's logarithm is its
#: Taylor series 1 + θ²/6 + 7θ⁴/360 (error below 1e-20 there).
_LOG3_TAYLOR = 1e-4

#: Inputs of "pronk_forces" besides the feet ("foot_0", ...): what they hold.
FORCE_LAW_INPUTS = (
    "com",  # centre of mass c [m], (3,)
    "momentum",  # linear momentum m ċ [kg m/s], (3,)
    "Ag",  # centroidal momentum matrix (6, nv): I_c = Ag[3:6, 3:6] R^T [kg m²]
    "rotation",  # base orientation R (world from base), (3, 3)
    "v",  # velocity, (nv,); v[3:6] the base's angular velocity in its frame [rad/s]
    "gaps",  # the feet's gaps [m], (n_feet,): a foot is in contact at most contact_gap
    "state",  # c_0 (3) [m], 1 in thrust (phase TAKEOFF) else 0, v_to [m/s]
    "gains",  # k_xy, d_xy, k_R, d_R, k_h, d_h
    "constants",  # m [kg], |g| [m/s²], h_s [m], h_td [m], ε, the least stroke [m], contact_gap
    "up",  # upward unit vector (3,)
    "attitude",  # desired orientation R_d, (3, 3)
    "pyramids",  # each foot's rows (t1 - μn, -t1 - μn, t2 - μn, -t2 - μn, n), (5, 3 n_feet)
    "lower",  # lower bounds of the rows, (5 n_feet,)
    "upper",  # upper bounds of the rows, (5 n_feet,)
)
#: Outputs of "pronk_forces".
FORCE_LAW_OUTPUTS = ("measures", "wrench", "A", "forces", "feasible")
#: Inputs of "pronk_torques" besides the feet ("foot_0", ...).
TORQUE_INPUTS = ("forces", "J", "g", "q", "v", "gaps", "supported", "gains", "posture")


class LawOps(NamedTuple):
    """The operations the law uses beyond arithmetic and ``@``, for one kind of array.

    Attributes:
        dot: Inner product of two vectors.
        fmax: Larger of two scalars.
        where: ``where(condition, x, y)`` on a scalar condition.
        logical_and: And of two scalar conditions.
        skew: The cross-product matrix of a 3-vector.
        log3: The rotation vector of a rotation matrix, in [rad].
        vertcat: Arrays stacked along their first axis.
        horzcat: Matrices side by side.
        eye: The identity of a size.
        spd_solve: ``spd_solve(M, b)``: M⁻¹ b for a symmetric positive definite M.
        total: Sum of a vector's entries.
        smallest: Smallest entry of a vector.
        zeros: A zero vector of a size.
    """

    dot: Callable[[Any, Any], Any]
    fmax: Callable[[Any, Any], Any]
    where: Callable[[Any, Any, Any], Any]
    logical_and: Callable[[Any, Any], Any]
    skew: Callable[[Any], Any]
    log3: Callable[[Any], Any]
    vertcat: Callable[..., Any]
    horzcat: Callable[..., Any]
    eye: Callable[[int], Any]
    spd_solve: Callable[[Any, Any], Any]
    total: Callable[[Any], Any]
    smallest: Callable[[Any], Any]
    zeros: Callable[[int], Any]


#: The law on numpy arrays and floats (the reference, ``compiled=False``), in the fields' order.
NUMPY_LAW_OPS = LawOps(
    np.dot, max, lambda condition, x, y: x if condition else y, lambda a, b: a and b,
    pin.skew, pin.log3, lambda *arrays: np.concatenate(arrays),
    lambda *arrays: np.concatenate(arrays, axis=1), np.eye, np.linalg.solve,
    lambda x: float(np.sum(x)), np.min, np.zeros,
)  # fmt: skip


def casadi_law_ops() -> LawOps:
    """The law on casadi SX expressions (the compiled path), in the fields' order."""
    import casadi as ca

    return LawOps(
        ca.dot, ca.fmax, ca.if_else, ca.logic_and, ca.skew, _log3, ca.vertcat, ca.horzcat,
        ca.SX.eye, _spd_solve, ca.sum1, ca.mmin, ca.SX.zeros,
    )  # fmt: skip


def foot_inputs(n_feet: int) -> list[str]:
    """Names of the feet's position inputs [m], each (3,): ``foot_0``, ``foot_1``, ..."""
    return [f"foot_{i}" for i in range(n_feet)]


def law_measures(
    ops: LawOps,
    c: Any,
    momentum: Any,
    gaps: Any,
    feet: Sequence[Any],
    up: Any,
    constants: Any,
) -> tuple[Any, Any, Any]:
    """The height h [m], its rate [m/s] and the feet in contact (1 or 0 each, (n_feet,)).

    Args:
        ops: The operations of the arrays given.
        c: Centre of mass [m], (3,).
        momentum: Linear momentum [kg m/s], (3,).
        gaps: The feet's gaps [m], (n_feet,).
        feet: Each foot's position [m], (3,).
        up: Upward unit vector, (3,).
        constants: As the input ``constants`` of :func:`force_law_function`.
    """
    mass, contact_gap = constants[0], constants[6]
    c_dot = momentum / mass  # [m/s]
    ground = sum(ops.dot(p, up) - gaps[i] for i, p in enumerate(feet)) / len(feet)  # [m]
    return ops.dot(c, up) - ground, ops.dot(c_dot, up), gaps <= contact_gap


def height_acceleration(
    ops: LawOps, h: Any, h_dot: Any, takeoff: Any, v_to: Any, gains: Any, constants: Any
) -> Any:
    """The desired vertical acceleration of the centre of mass, in [m/s²].

    Thrust (``takeoff`` = 1, toward the take-off speed ``v_to`` [m/s]) or the height's
    spring-damper, from ``h`` [m] and ``h_dot`` [m/s] as :func:`law_measures` gives them
    (``gains`` and ``constants`` as in :data:`FORCE_LAW_INPUTS`).
    """
    k_h, d_h = gains[4], gains[5]
    h_s, h_td, min_stroke = constants[2], constants[3], constants[5]
    stroke = ops.fmax(h_td - h, min_stroke)  # [m]
    thrust = ops.fmax((v_to * v_to - h_dot * h_dot) / (2.0 * stroke), 0.0)
    return ops.where(takeoff > 0.5, thrust, k_h * (h_s - h) - d_h * h_dot)


def stance_wrench(
    ops: LawOps,
    h_ddot: Any,
    c: Any,
    momentum: Any,
    Ag: Any,
    R: Any,
    v: Any,
    state: Any,
    gains: Any,
    constants: Any,
    up: Any,
    R_d: Any,
) -> Any:
    """The desired centroidal wrench (F [N], T [N m]), (6,) (inputs of :data:`FORCE_LAW_INPUTS`).

    ``h_ddot`` [m/s²] as :func:`height_acceleration` gives it.
    """
    k_xy, d_xy, k_R, d_R = (gains[i] for i in range(4))
    mass, g = constants[0], constants[1]
    c0 = state[:3]
    c_dot = momentum / mass  # [m/s]
    horizontal = -k_xy * (c - c0) - d_xy * c_dot
    horizontal = horizontal - ops.dot(horizontal, up) * up
    force = mass * (h_ddot * up + horizontal + g * up)  # [N]
    omega = R @ v[3:6]  # [rad/s], world
    inertia = Ag[3:6, 3:6] @ R.T  # [kg m²], the angular momentum of the base's rotation
    torque = inertia @ (-k_R * ops.log3(R @ R_d.T) - d_R * omega)  # [N m]
    return ops.vertcat(force, torque)


def distribute_forces(
    ops: LawOps,
    wrench: Any,
    c: Any,
    feet: Sequence[Any],
    touching: Any,
    pyramids: Any,
    lower: Any,
    upper: Any,
    constants: Any,
) -> tuple[Any, Any, Any]:
    """The wrench matrix A (6, 3 n_feet), the optimum f (3 n_feet,) [N] and its feasibility.

    ``touching`` as :func:`law_measures` gives it; f is 0 on the feet not in contact.
    """
    n_feet, eps = len(feet), constants[4]
    # A = [I ... I; [r_1]x ... [r_n]x], r_i = p_i - c, and its columns on the touching feet.
    A = ops.horzcat(*(ops.vertcat(ops.eye(3), ops.skew(p - c)) for p in feet))
    A_touching = ops.horzcat(*(A[:, 3 * i : 3 * i + 3] * touching[i] for i in range(n_feet)))
    f = A_touching.T @ ops.spd_solve(A_touching @ A_touching.T + eps * ops.eye(6), wrench)
    rows = ops.vertcat(
        *(pyramids[:, 3 * i : 3 * i + 3] @ f[3 * i : 3 * i + 3] for i in range(n_feet))
    )
    feasible = ops.smallest(ops.vertcat(rows - lower, upper - rows)) >= 0.0  # 1 or 0
    return A, f, feasible


def joint_torques(
    ops: LawOps,
    forces: Any,
    J: Any,
    g: Any,
    q: Any,
    v: Any,
    gaps: Any,
    supported: Any,
    gains: Any,
    posture: Any,
    feet: Sequence[Any],
    structure: tuple[Sequence[Index], Index, Index],
) -> Any:
    """The torques of every velocity coordinate (nv,) (inputs of :data:`TORQUE_INPUTS`).

    ``structure``: each foot's actuated velocity indices (its leg), the actuated ones on no
    leg, and the configuration index of each velocity index.
    """
    legs, others, q_of_v = structure
    kp, kd, contact_gap = gains[0], gains[1], gains[2]

    def hold(joints: Index) -> Any:
        rows = [int(r) for r in q_of_v[joints]]
        cols = [int(j) for j in joints]
        return kp * (posture[rows] - q[rows]) - kd * v[cols]

    tau = ops.zeros(g.shape[0])
    for i, leg in enumerate(legs):
        cols = [int(j) for j in leg]
        J_leg = J[:3, cols] - ops.skew(feet[i]) @ J[3:, cols]  # [m/rad], LOCAL_WORLD_ALIGNED
        pushing = g[cols] - J_leg.T @ forces[3 * i : 3 * i + 3]  # [N m]
        free = ops.where(supported > 0.5, hold(leg) + g[cols], hold(leg))
        stance = ops.logical_and(supported > 0.5, gaps[i] <= contact_gap)
        tau[cols] = ops.where(stance, pushing, free)
    if len(others):
        cols = [int(j) for j in others]
        tau[cols] = hold(others) + g[cols]
    return tau


def force_law_function(n_feet: int, nv: int) -> Any:
    """The stance law's Function ``pronk_forces`` (module docstring), outputs dense.

    Args:
        n_feet: Number of feet.
        nv: Velocity dimension of the robot.
    """
    import casadi as ca

    ops, sym = casadi_law_ops(), ca.SX.sym
    c, momentum, Ag = sym("com", 3), sym("momentum", 3), sym("Ag", 6, nv)
    R, v = sym("rotation", 3, 3), sym("v", nv)
    gaps, state = sym("gaps", n_feet), sym("state", 5)
    gains, constants, up = sym("gains", 6), sym("constants", 7), sym("up", 3)
    R_d, pyramids = sym("attitude", 3, 3), sym("pyramids", 5, 3 * n_feet)
    lower, upper = sym("lower", 5 * n_feet), sym("upper", 5 * n_feet)
    feet = [sym(name, 3) for name in foot_inputs(n_feet)]
    h, h_dot, touching = law_measures(ops, c, momentum, gaps, feet, up, constants)
    h_ddot = height_acceleration(ops, h, h_dot, state[3], state[4], gains, constants)
    wrench = stance_wrench(ops, h_ddot, c, momentum, Ag, R, v, state, gains, constants, up, R_d)
    A, f, feasible = distribute_forces(
        ops, wrench, c, feet, touching, pyramids, lower, upper, constants
    )
    inputs = [c, momentum, Ag, R, v, gaps, state, gains, constants, up, R_d]
    inputs += [pyramids, lower, upper, *feet]
    return ca.Function(
        "pronk_forces",
        inputs,
        [ca.vertcat(h, h_dot, ca.sum1(touching)), wrench, A, f, feasible],
        [*FORCE_LAW_INPUTS, *foot_inputs(n_feet)],
        list(FORCE_LAW_OUTPUTS),
    )


def torque_function(
    nq: int,
    nv: int,
    legs: Sequence[Index],
    others: Index,
    q_of_v: Index,
    actuated: Index,
) -> Any:
    """The joint torques' Function ``pronk_torques`` (module docstring), output ``tau`` (nu,).

    Args:
        nq: Configuration dimension.
        nv: Velocity dimension.
        legs: Each foot's actuated velocity indices (its leg).
        others: Actuated velocity indices on no leg.
        q_of_v: Configuration index of each velocity index (of the legs and the others).
        actuated: Actuated velocity indices, in the order of the output.
    """
    import casadi as ca

    sym = ca.SX.sym
    n_feet = len(legs)
    forces, J, g = sym("forces", 3 * n_feet), sym("J", 6, nv), sym("g", nv)
    q, v, gaps, supported = sym("q", nq), sym("v", nv), sym("gaps", n_feet), sym("s", 1)
    gains, posture = sym("gains", 3), sym("posture", nq)
    feet = [sym(name, 3) for name in foot_inputs(n_feet)]
    tau = joint_torques(
        casadi_law_ops(),
        forces,
        J,
        g,
        q,
        v,
        gaps,
        supported,
        gains,
        posture,
        feet,
        (legs, others, q_of_v),
    )
    inputs = [forces, J, g, q, v, gaps, supported, gains, posture, *feet]
    return ca.Function(
        "pronk_torques",
        inputs,
        [tau[[int(j) for j in actuated]]],
        [*TORQUE_INPUTS, *foot_inputs(n_feet)],
        ["tau"],
    )


def _log3(R: Any) -> Any:
    r"""The rotation vector :math:`\log(R)^\vee` [rad] of a rotation by less than π (casadi)."""
    import casadi as ca

    cos_angle = ca.fmin(ca.fmax(0.5 * (ca.trace(R) - 1.0), -1.0), 1.0)
    angle = ca.acos(cos_angle)
    square = angle * angle
    factor = ca.if_else(
        angle < _LOG3_TAYLOR,
        1.0 + square / 6.0 + 7.0 * square * square / 360.0,
        angle / ca.sin(angle),
    )
    return 0.5 * factor * ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])


def _spd_solve(M: Any, b: Any) -> Any:
    """``M⁻¹ b`` for a symmetric positive definite M (n, n) by Cholesky, unrolled (casadi)."""
    import casadi as ca

    n = M.shape[0]
    L = [[ca.SX(0.0)] * n for _ in range(n)]
    for j in range(n):
        diagonal = M[j, j] - sum((L[j][k] * L[j][k] for k in range(j)), ca.SX(0.0))
        L[j][j] = ca.sqrt(diagonal)
        for i in range(j + 1, n):
            off = M[i, j] - sum((L[i][k] * L[j][k] for k in range(j)), ca.SX(0.0))
            L[i][j] = off / L[j][j]
    y = [ca.SX(0.0)] * n
    for i in range(n):  # L y = b
        y[i] = (b[i] - sum((L[i][k] * y[k] for k in range(i)), ca.SX(0.0))) / L[i][i]
    x = [ca.SX(0.0)] * n
    for i in reversed(range(n)):  # L^T x = y
        x[i] = (y[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), ca.SX(0.0))) / L[i][i]
    return ca.vertcat(*x)
