r"""Cartesian impedance control of one frame, with a desired contact force during contact phases.

The baseline an engineer tries first on a contact task: a task-space PD on the position of a
URDF frame with gravity compensation, plus a feedforward force pushing along the surface normal
during the declared contact phases,

.. math::

    \tau = g(q) + J^T\Big(K_p (x_d - x) + K_d (\dot x_d - \dot x)
           - \sum_c n_c\, f_{d,c}(t)\Big) - D\,\dot q
           + N^T\big(K_q (q_p \ominus q) - D_q \dot q\big),

with x the frame's position (its origin, world frame), J its translational Jacobian
(``LOCAL_WORLD_ALIGNED``), :math:`n_c` the outward unit normal of the surface of contact c,
:math:`f_{d,c} \ge 0` the desired force the surface exerts on the robot (the robot presses with
:math:`-n_c f_{d,c}`), D an optional joint damping and the last term an optional posture task in
the null space :math:`N = I - J^+ J` of the task (redundant arms). During a contact phase, the
desired position is the projection of the nominal path on the surface wherever the path is
below it (``project = True``), so that at rest in contact the normal force is :math:`f_d`; with
``project = False`` the desired point stays below the surface by a depth d and the force at rest
is :math:`f_d + n^T K_p n\, d` (a spring pressed by d).

With ``impact_invariant = True``, within a window around each nominal impact every velocity
fed back (:math:`\dot q` in the joint terms, :math:`J\dot q - \dot x_d` in the task term) is
first projected on the velocities an impact on the contacts does not change
(:meth:`ImpedanceController.invariant_projectors`, Yang & Posa), so that the torque does not
jump with the velocity at impact.

Unlike :class:`ucontrol.control.BrogliatoController` it has no phases and no transition design:
it lands with the velocity the nominal path has when it meets the surface, and the impacts
accumulate as the plant's restitution lets them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_positive
from ucontrol.contact.point_contact import PointContact
from ucontrol.control.controller import ContactState, Vector
from ucontrol.control.desired_cycle import PATH_SAMPLES, PATH_TOLERANCE, ContactPhase, NominalPath
from ucontrol.control.trajectory_segment import smooth_step
from ucontrol.exceptions import (
    InvalidParameterError,
    NonFiniteValueError,
    NotFoundError,
    PathThroughSurfaceError,
    ShapeError,
)
from ucontrol.model.robot_model import RobotModel

if TYPE_CHECKING:
    from ucontrol.log import Log

Matrix = NDArray[np.float64]
_LWA = pin.LOCAL_WORLD_ALIGNED

#: Per-sample fields written to the log (name: shape, with n declared contacts).
LOG_FIELDS = {
    "task_position": "(3,)",
    "task_desired": "(3,)",
    "lambda_d": "(n,)",
    "contact_force": "(n,)",
    "contact_window": "(n,)",
    "task_velocity_desired": "(3,)",
}


def as_gain_matrix(name: str, value: Any, *, positive: bool) -> Matrix:
    """A 3×3 gain from a scalar, a diagonal (3,) or a symmetric (3, 3) matrix.

    Args:
        name: Argument name used in error messages.
        value: The gain.
        positive: Require a positive definite matrix (else positive semidefinite).

    Raises:
        ShapeError: ``value`` is neither a scalar nor of shape (3,) or (3, 3).
        NonFiniteValueError: ``value`` holds NaN or infinity.
        InvalidParameterError: Not symmetric, or not positive (semi)definite.
    """
    if isinstance(value, bool):
        raise InvalidParameterError(name, value, "a number, a 3-vector or a 3×3 matrix")
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError(name, value, "a number, a 3-vector or a 3×3 matrix") from error
    if array.ndim == 0:
        matrix = float(array) * np.eye(3)
    elif array.shape == (3,):
        matrix = np.diag(array)
    elif array.shape == (3, 3):
        matrix = array
    else:
        raise ShapeError(name, (3, 3), array.shape)
    if not np.isfinite(matrix).all():
        raise NonFiniteValueError(name, value, np.flatnonzero(~np.isfinite(array)).tolist())
    if not np.allclose(matrix, matrix.T, rtol=0.0, atol=1e-12 * max(1.0, np.abs(matrix).max())):
        raise InvalidParameterError(name, value, "a symmetric matrix")
    smallest = float(np.linalg.eigvalsh(matrix).min())
    if smallest < 0.0 or (positive and smallest == 0.0):
        kind = "positive definite" if positive else "positive semidefinite"
        raise InvalidParameterError(name, value, f"{kind} (smallest eigenvalue {smallest:.3g})")
    return np.asarray(matrix, dtype=float)


@dataclass(frozen=True, kw_only=True)
class ImpedanceGains:
    r"""Gains of :class:`ImpedanceController`.

    Attributes:
        stiffness: :math:`K_p` in [N/m]: a number, a diagonal (3,) or a symmetric positive
            definite (3, 3) matrix in the world frame; stored as (3, 3).
        damping: :math:`K_d` in [N s/m], same forms, positive semidefinite.
        joint_damping: D in [N m s/rad], >= 0: damping of every joint velocity.
        posture_stiffness: :math:`K_q` in [N m/rad], >= 0: posture task in the null space.
        posture_damping: :math:`D_q` in [N m s/rad], >= 0: null-space damping.
    """

    stiffness: Any
    damping: Any
    joint_damping: float = 0.0
    posture_stiffness: float = 0.0
    posture_damping: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "stiffness", as_gain_matrix("stiffness", self.stiffness, positive=True)
        )
        object.__setattr__(self, "damping", as_gain_matrix("damping", self.damping, positive=False))
        for name in ("joint_damping", "posture_stiffness", "posture_damping"):
            value = as_float(name, getattr(self, name))
            if value < 0.0:
                raise InvalidParameterError(name, getattr(self, name), ">= 0")
            object.__setattr__(self, name, value)

    @property
    def has_posture(self) -> bool:
        """Whether the null-space posture task is on."""
        return self.posture_stiffness > 0.0 or self.posture_damping > 0.0


class ImpedanceController:
    """Task-space PD with gravity compensation and a desired contact force (module docstring).

    Call it as ``controller(t, q, v, contacts)`` (see :class:`ucontrol.control.Controller`);
    it is a :class:`ucontrol.control.LoggingController` (fields :data:`LOG_FIELDS`).

    Args:
        robot: The controller's model of the robot; fully actuated, rigid joints.
        frame: Name of the frame whose origin follows the path.
        path: The nominal path of the frame (period P, e.g. :class:`CirclePath`,
            :class:`SplinePath`).
        gains: Stiffness, damping and the optional joint / null-space gains.
        contacts: Point contacts of ``frame`` the contact phases refer to (their surface
            normals carry the desired force).
        contact_phases: Declared contact phases: during phase c, modulo P, the desired force
            :math:`f_{d,c}` rises smoothly from 0 to ``force`` over ``force_rise_time`` after
            ``start`` and falls back to 0 over ``force_fall_time`` before ``end``.
        posture: Posture :math:`q_p` of the null-space task, shape (nq,); default neutral.
        project: Project the desired point on the surface during a contact phase where the
            nominal path is below it.
        force_rise_time: Rise time of :math:`f_d` in [s], > 0.
        force_fall_time: Fall time of :math:`f_d` in [s], > 0.
        impact_invariant: Within ``invariant_window`` of a phase start, feed back only the
            velocities an impact on the contacts leaves unchanged
            (:meth:`invariant_projectors`, docs/impact_control.md).
        invariant_window: Half-width in [s], > 0, of that window around each phase start.

    Raises:
        InvalidParameterError: The robot is not fully actuated, a contact acts on another
            frame, a phase is longer than the period or shorter than its rise and fall,
            ``impact_invariant`` is not a bool or is on without contact phases.
        NotFoundError: A contact phase names a contact not in ``contacts``.
        PathThroughSurfaceError: The nominal path enters a surface of ``contacts`` deeper
            than :data:`ucontrol.control.desired_cycle.PATH_TOLERANCE` outside that
            contact's phase.
    """

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        path: NominalPath,
        gains: ImpedanceGains,
        *,
        contacts: Sequence[PointContact] = (),
        contact_phases: Sequence[ContactPhase] = (),
        posture: Vector | None = None,
        project: bool = True,
        force_rise_time: float = 0.1,
        force_fall_time: float = 0.5,
        impact_invariant: bool = False,
        invariant_window: float = 0.1,
    ) -> None:
        if robot.nu != robot.nv:
            raise InvalidParameterError("robot", robot.name, "a fully actuated robot (nu = nv)")
        self.robot = robot
        self.frame = frame
        self.frame_id = robot.frame_id(frame)
        self.path = path
        self.gains = gains
        self.posture = robot.check_configuration(
            "posture", robot.neutral() if posture is None else posture
        )
        self.project = bool(project)
        self.force_rise_time = as_positive("force_rise_time", force_rise_time)
        self.force_fall_time = as_positive("force_fall_time", force_fall_time)
        if not isinstance(impact_invariant, bool):
            raise InvalidParameterError("impact_invariant", impact_invariant, "true or false")
        self.impact_invariant = impact_invariant
        self.invariant_window = as_positive("invariant_window", invariant_window)
        if impact_invariant and not contact_phases:
            raise InvalidParameterError(
                "impact_invariant", impact_invariant, "contact phases whose impacts it ignores"
            )
        by_name = {contact.name: contact for contact in contacts}
        for contact in contacts:
            if contact.frame != frame:
                raise InvalidParameterError(
                    f"contact {contact.name!r} frame", contact.frame, f"the task frame {frame!r}"
                )
        period = float(path.period)
        self.contact_phases = tuple(contact_phases)
        names = [phase.contact for phase in self.contact_phases]
        if len(set(names)) != len(names):
            raise InvalidParameterError("contact_phases", names, "one phase per contact")
        for phase in self.contact_phases:
            if phase.contact not in by_name:
                raise NotFoundError("contact", phase.contact, by_name)
            length = phase.end - phase.start  # [s]
            if length > period:
                raise InvalidParameterError(
                    f"contact phase of {phase.contact!r}",
                    (phase.start, phase.end),
                    f"at most one period ({period} s) long",
                )
            if self.force_rise_time + self.force_fall_time > length:
                raise InvalidParameterError(
                    "force_rise_time + force_fall_time",
                    self.force_rise_time + self.force_fall_time,
                    f"<= the length {length} s of the contact phase of {phase.contact!r}",
                )
        self.contacts = tuple(by_name[name] for name in names)
        self._normals = np.array([c.surface.normal for c in self.contacts]).reshape(-1, 3)
        self._offsets = np.array(
            [c.surface.normal @ c.surface.point + c.radius for c in self.contacts]
        )
        _check_path(path, contacts, self.contact_phases)
        self._model = robot.model
        self._data = pin.Data(robot.model)
        self._position = self._data.oMf[self.frame_id].translation  # a view of the data
        self._identity = np.eye(robot.nv)
        self._actuated = (
            None if np.array_equal(robot.actuated, np.arange(robot.nv)) else robot.actuated
        )
        self._log_fields: tuple[Log, tuple[NDArray[Any], ...]] | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the run (plant contact indices, last values)."""
        n = len(self.contacts)
        self._plant_index: list[int] | None = None
        self.x = np.zeros(3)
        self.x_desired = np.zeros(3)
        self.force_desired = np.zeros(n)
        self.contact_force = np.zeros(n)
        self.window = np.zeros(n, dtype=bool)
        self.dx_desired = np.zeros(3)
        self.velocity_error = np.zeros(3)

    def desired(self, t: float) -> tuple[Vector, Vector, Vector, NDArray[np.bool_]]:
        r"""Desired position [m] and velocity [m/s] (3,), :math:`f_d` [N] (n,) and windows (n,).

        Args:
            t: Time in [s].
        """
        p, dp = self.path.derivatives(t, 1)
        period = float(self.path.period)
        forces = np.zeros(len(self.contacts))
        window = np.zeros(len(self.contacts), dtype=bool)
        for i, phase in enumerate(self.contact_phases):
            since = (t - phase.start) % period  # [s] since the phase started
            if since > phase.end - phase.start:
                continue
            window[i] = True
            n = self._normals[i]
            rise = smooth_step(since / self.force_rise_time)[0]
            fall = smooth_step((since - (phase.end - phase.start)) / self.force_fall_time + 1.0)
            forces[i] = phase.force * rise * (1.0 - fall[0])
            gap = n @ p - self._offsets[i]  # [m] of the nominal point
            if self.project and gap < 0.0:
                p = p - gap * n
                dp = dp - (n @ dp) * n
        return p, dp, forces, window

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Torques, shape (nu,), in [N m] (or [N] for prismatic joints)."""
        self._read_contacts(contacts)
        x_d, dx_d, f_d, window = self.desired(t)
        tau = self._task_torque(q, v, x_d, dx_d, f_d, self._invariant_at(t), damped=True)
        self.x_desired, self.force_desired, self.window = x_d, f_d, window
        return tau if self._actuated is None else tau[self._actuated]

    def _read_contacts(self, contacts: ContactState) -> list[int]:
        """Read the contacts' mean forces; returns their indices among the plant's."""
        if self._plant_index is None:
            self._plant_index = _find_contacts([c.name for c in self.contacts], contacts.names)
        impulse, dt, contact_force = contacts.impulse.tolist(), contacts.dt, self.contact_force
        for i, j in enumerate(self._plant_index):  # their ContactState.force, in place
            contact_force[i] = impulse[j] / dt  # [N]
        return self._plant_index

    def _invariant_at(self, t: float) -> bool:
        """Whether the impact-invariant projection acts at ``t`` [s] (near a phase start)."""
        if not self.impact_invariant:
            return False
        period = float(self.path.period)
        for phase in self.contact_phases:
            offset = (t - phase.start + 0.5 * period) % period - 0.5 * period  # [s]
            if abs(offset) <= self.invariant_window:
                return True
        return False

    def invariant_projectors(self, q: Vector) -> tuple[Matrix, Matrix]:
        r"""The impact-invariant projectors at ``q``: joint space (nv, nv) and task space (3, 3).

        :math:`P = I - M^{-1} J_c^T (J_c M^{-1} J_c^T)^{-1} J_c` with :math:`J_c = N J` (the
        normal rows of the controller's contacts, all on the task frame) and
        :math:`P_x = I - \Lambda^{-1} N^T (N \Lambda^{-1} N^T)^{-1} N`,
        :math:`\Lambda^{-1} = J M^{-1} J^T`, so that :math:`J P = P_x J`; both annihilate
        the velocity change :math:`M^{-1} J_c^T P_n` of any impact on these contacts.

        Args:
            q: Configuration, shape (nq,).
        """
        model, data = self._model, self._data
        pin.crba(model, data, q)  # upper triangle of M, before the world Jacobians
        M = np.triu(data.M) + np.triu(data.M, 1).T
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacement(model, data, self.frame_id)
        J = pin.getFrameJacobian(model, data, self.frame_id, _LWA)[:3]
        return self._projectors(M, J)

    def _projectors(self, M: Matrix, J: Matrix) -> tuple[Matrix, Matrix]:
        """:meth:`invariant_projectors` from M (nv, nv) and the task Jacobian J (3, nv)."""
        N = self._normals  # (n, 3)
        Minv_Jt = np.linalg.solve(M, J.T)  # (nv, 3)
        Lambda_inv = J @ Minv_Jt  # [m/(N s^2)] (3, 3)
        Lambda_inv_Nt = Lambda_inv @ N.T
        G = np.linalg.solve(N @ Lambda_inv_Nt, np.eye(len(N)))  # (n, n)
        P_x = np.eye(3) - Lambda_inv_Nt @ G @ N
        P = self._identity - Minv_Jt @ N.T @ G @ N @ J
        return P, P_x

    def _task_torque(
        self,
        q: Vector,
        v: Vector,
        x_d: Vector,
        dx_d: Vector,
        f_d: Vector,
        invariant: bool,
        *,
        damped: bool,
        ddx_d: Vector | None = None,
    ) -> Vector:
        r"""The law at (q, v) for one desired point, velocity and force; shape (nv,).

        Args:
            q: Configuration, shape (nq,).
            v: Velocity, shape (nv,).
            x_d: Desired position of the frame [m], (3,).
            dx_d: Desired velocity [m/s], (3,).
            f_d: Desired contact forces [N], (n,).
            invariant: Feed back only the impact-invariant part of the velocities.
            damped: Feed back the velocities at all (off: position terms and feedforward).
            ddx_d: Desired acceleration [m/s²] (3,) fed forward through the task inertia,
                :math:`J^T \Lambda \ddot x_d`, :math:`\Lambda = (J M^{-1} J^T)^+`; none
                when None.
        """
        model, data, gains = self._model, self._data, self.gains
        self.dx_desired = dx_d
        if invariant:
            P, P_x = self.invariant_projectors(q)
            v = P @ v  # the velocity an impact on the contacts leaves unchanged [rad/s]
            dx_d = P_x @ dx_d
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacement(model, data, self.frame_id)
        J = pin.getFrameJacobian(model, data, self.frame_id, _LWA)[:3]
        x = self._position  # the frame position in data, until the next call [m]
        self.velocity_error = J @ v - dx_d  # [m/s]
        force = gains.stiffness @ (x_d - x)  # [N]
        if damped:
            force -= gains.damping @ self.velocity_error
        force -= self._normals.T @ f_d
        if ddx_d is not None:
            pin.crba(model, data, q)  # upper triangle of M; the world Jacobians stay
            M = np.triu(data.M) + np.triu(data.M, 1).T
            Lambda = _pseudo_inverse(J @ np.linalg.solve(M, J.T), 1e-10)  # [kg] (planar: rank 2)
            force += Lambda @ ddx_d  # [N]
        tau = pin.computeGeneralizedGravity(model, data, q) + J.T @ force
        if damped and gains.joint_damping > 0.0:
            tau -= gains.joint_damping * v
        if gains.has_posture:
            N = self._identity - _pseudo_inverse(J, 1e-10) @ J  # symmetric projector
            posture = gains.posture_stiffness * pin.difference(model, q, self.posture)
            if damped:
                posture = posture - gains.posture_damping * v
            tau += N @ posture
        self.x = x
        return tau

    def prepare_log(self, log: Log) -> None:
        """Declare the fields of :data:`LOG_FIELDS` and the contact names (metadata)."""
        n = len(self.contacts)
        shapes = {"(3,)": (3,), "(n,)": (n,)}
        for name, shape in LOG_FIELDS.items():
            log.add_field(name, shapes[shape], np.int64 if name == "contact_window" else float)
        log.metadata["controller"] = "impedance"
        log.metadata["controller_contacts"] = [c.name for c in self.contacts]
        log.metadata["period"] = float(self.path.period)

    def record(self, log: Log) -> None:
        """Write the values of the last call into the current row."""
        if self._log_fields is None or self._log_fields[0] is not log:
            self._log_fields = (log, log.extra_fields(list(LOG_FIELDS)))
        k = len(log)
        fields = self._log_fields[1]  # in the order of LOG_FIELDS
        task_position, task_desired, lambda_d, contact_force, contact_window, dx_desired = fields
        task_position[k] = self.x
        task_desired[k] = self.x_desired
        lambda_d[k] = self.force_desired
        contact_force[k] = self.contact_force
        contact_window[k] = self.window  # as 0 / 1
        dx_desired[k] = self.dx_desired


def _find_contacts(wanted: list[str], names: list[str]) -> list[int]:
    """Indices of the controller's contacts among the plant's constraints."""
    for name in wanted:
        if name not in names:
            raise NotFoundError("plant contact", name, names)
    return [names.index(name) for name in wanted]


def _pseudo_inverse(A: Matrix, rcond: float) -> Matrix:
    """Moore-Penrose pseudo-inverse of ``A`` (m, n), shape (n, m): ``np.linalg.pinv(A, rcond)``.

    The same operations as numpy's (2.x) on a real matrix, bitwise, without its generality
    (stacks, complex, empty, hermitian): singular values below ``rcond`` times the largest
    are dropped.
    """
    u, s, vt = np.linalg.svd(A, full_matrices=False)
    large = s > rcond * s.max()
    inverse = np.divide(1.0, s, where=large, out=np.zeros_like(s))
    return np.asarray(vt.T @ (inverse[:, np.newaxis] * u.T), dtype=float)


def _check_path(
    path: NominalPath, contacts: Sequence[PointContact], phases: Sequence[ContactPhase]
) -> None:
    """Raise :class:`PathThroughSurfaceError` where the path enters a surface outside a phase."""
    if not contacts:
        return
    period = float(path.period)
    t = np.linspace(0.0, period, PATH_SAMPLES, endpoint=False)
    points = np.array([path(float(time))[0] for time in t])  # (N, 3) [m]
    for contact in contacts:
        n = contact.surface.normal
        gap = points @ n - (n @ contact.surface.point + contact.radius)  # [m]
        inside = gap < -PATH_TOLERANCE
        for phase in phases:
            if phase.contact == contact.name:
                inside &= ~phase.covers(t, period)
        if inside.any():
            worst = int(np.argmin(np.where(inside, gap, math.inf)))
            raise PathThroughSurfaceError(contact.name, float(t[worst]), float(gap[worst]))
