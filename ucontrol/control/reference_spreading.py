r"""Reference spreading: ante- and post-impact references that overlap at the nominal impact.

A task-space impedance law (:class:`ImpedanceController`: PD on the position of a frame,
gravity compensation, desired contact force, posture in the null space) that tracks, around
each landing of cycle k (nominal impact time :math:`t_i = s + kP`, s the start of the contact
phase, P the period), one of two references (after Steen et al., arXiv 2411.06319 and
2411.09870):

- the **ante-impact** reference :math:`x_a`: the nominal path p up to :math:`t_i`, extended past
  it at the velocity it has there, :math:`x_a(t) = p(t_i) + \dot p(t_i)(t - t_i)`, so that a
  late impact still finds the frame moving towards the surface;
- the **post-impact** reference :math:`x_p`: after :math:`t_i`, the contact-phase reference c
  (the path projected on the surface) plus a correction that starts the motion with the
  velocity the rigid impact map predicts and fades over ``blend_time`` :math:`T_b`,

  .. math::

      x_p(t) = c(t) + \Delta v\,(t - t_i)\,w\big((t - t_i)/T_b\big),\qquad
      \Delta v = \dot x^+ - \dot c(t_i),\qquad w = 1 - \beta,

  with β the quintic smooth step; before :math:`t_i` it is extended backwards at the
  velocity :math:`\dot x^+`, :math:`x_p(t) = c(t_i) + \dot x^+ (t - t_i)`.

The post-impact velocity is the ante-impact one through the impact map of the controller's
model with the declared restitution e: on the frame's contacts :math:`J_c = N J` (N their
normals), :math:`v^+ = v^- - (1 + e) M^{-1} J_c^T (J_c M^{-1} J_c^T)^{-1} J_c v^-`, so that in
task space

.. math::

    \dot x^+ = \big(I - (1 + e)\,\Lambda^{-1} N^T (N \Lambda^{-1} N^T)^{-1} N\big)\,\dot x^-,
    \qquad \Lambda^{-1} = J M^{-1} J^T,

whatever the null-space part of :math:`v^-`; :math:`\Lambda^{-1}` is taken at the measured
configuration of the call that detects the first impact.

Modes, per landing: ``ANTE`` tracks :math:`x_a` without contact force, its acceleration fed
forward through the task inertia (:math:`J^T \Lambda \ddot x_a`); an impact detected from
the contact state the controller receives (a contact within ``contact_gap`` of its surface
whose normal velocity rose by more than ``impact_speed`` since the previous call; never the
plant's impulses) starts the ``INTERIM`` mode: the position term on :math:`x_p` and the
desired force, no velocity feedback, while impacts keep coming; ``interim_time`` after the
last one, ``POST`` tracks :math:`x_p` with the full law. The landing ends at the end of its
contact phase (the takeoff follows c, the path), and the next one starts in ``ANTE``.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ucontrol._validation import as_in_interval, as_positive
from ucontrol.contact.point_contact import PointContact
from ucontrol.control.controller import ContactState, Vector
from ucontrol.control.desired_cycle import ContactPhase, NominalPath
from ucontrol.control.impedance_controller import ImpedanceController, ImpedanceGains
from ucontrol.control.trajectory_segment import smooth_step
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

if TYPE_CHECKING:
    from ucontrol.log import Log


class SpreadingMode(enum.IntEnum):
    """Mode of :class:`ReferenceSpreadingController` (logged as ``spreading_mode``)."""

    ANTE = 0
    INTERIM = 1
    POST = 2


@dataclass(frozen=True, kw_only=True)
class SpreadingSettings:
    """Settings of :class:`ReferenceSpreadingController`.

    Attributes:
        restitution: Declared restitution e in [0, 1] of the impact map that gives the
            post-impact velocity.
        blend_time: :math:`T_b` in [s], > 0: the impact-map correction of the post-impact
            reference fades over this time after :math:`t_i`.
        interim_time: The interim mode ends this long in [s], > 0, after the last impact.
        impact_speed: A rise of a contact's normal velocity between two calls larger than this,
            in [m/s] > 0, is an impact.
        contact_gap: ... where the contact's gap is below this, in [m] > 0.
    """

    restitution: float = 0.0
    blend_time: float = 0.3
    interim_time: float = 0.001
    impact_speed: float = 0.05
    contact_gap: float = 1e-3

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "restitution", as_in_interval("restitution", self.restitution, 0.0, 1.0)
        )
        for name in ("blend_time", "interim_time", "impact_speed", "contact_gap"):
            object.__setattr__(self, name, as_positive(name, getattr(self, name)))


class ReferenceSpreadingController(ImpedanceController):
    """Impedance law switching from an ante- to a post-impact reference (module docstring).

    Call it as ``controller(t, q, v, contacts)`` with non-decreasing times (it is stateful:
    :meth:`reset` before reusing it); it logs the fields of :class:`ImpedanceController` and
    ``spreading_mode`` (:class:`SpreadingMode`).

    Args:
        robot: The controller's model of the robot; fully actuated, rigid joints.
        frame: Name of the frame whose origin follows the path.
        path: The nominal path of the frame (period P).
        gains: Stiffness, damping and the optional joint / null-space gains.
        contacts: Point contacts of ``frame``.
        contact_phases: Exactly one contact phase: its start is the nominal impact time.
        settings: Restitution, blend and interim times, impact detection.
        **options: The other keyword arguments of :class:`ImpedanceController` (posture,
            project, force_rise_time, force_fall_time, impact_invariant, invariant_window);
            with ``impact_invariant`` the interim mode feeds back the impact-invariant
            velocities instead of none.

    Raises:
        InvalidParameterError: Not exactly one contact phase, or what
            :class:`ImpedanceController` raises.
    """

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        path: NominalPath,
        gains: ImpedanceGains,
        *,
        contacts: Sequence[PointContact],
        contact_phases: Sequence[ContactPhase],
        settings: SpreadingSettings | None = None,
        **options: Any,
    ) -> None:
        if len(contact_phases) != 1:
            raise InvalidParameterError(
                "contact_phases", [p.contact for p in contact_phases], "exactly one phase"
            )
        self.settings = SpreadingSettings() if settings is None else settings
        super().__init__(
            robot, frame, path, gains, contacts=contacts, contact_phases=contact_phases, **options
        )

    def reset(self) -> None:
        """Forget the run: the next landing starts in the ante-impact mode."""
        super().reset()
        self.mode = SpreadingMode.ANTE
        self._landing = -1  # index k of the current landing
        self._last_impact = -math.inf  # [s]
        self._normal_velocity: Vector | None = None  # of the previous call [m/s]
        self.post_velocity = np.zeros(3)  # the impact map's post-impact velocity [m/s]

    def impact_time(self, k: int) -> float:
        """Nominal impact time :math:`t_i = s + kP` of landing k, in [s]."""
        phase = self.contact_phases[0]
        return phase.start + k * float(self.path.period)

    def landing(self, t: float) -> int:
        """Index k of the landing at ``t`` [s]: the one whose contact phase ends next."""
        phase = self.contact_phases[0]
        return math.floor((t - phase.end) / float(self.path.period)) + 1

    def ante_reference(self, t: float, k: int) -> tuple[Vector, Vector, Vector]:
        """Ante-impact reference of landing k at ``t`` [s]: position, velocity, acceleration."""
        t_i = self.impact_time(k)
        if t <= t_i:
            p, dp, ddp = self.path.derivatives(t, 2)
            return p, dp, ddp
        p, dp = self.path.derivatives(t_i, 1)
        return p + dp * (t - t_i), dp, np.zeros(3)

    def post_velocity_map(self, q: Vector, dx_ante: Vector) -> Vector:
        r"""Task velocity [m/s] (3,) after an impact at ``q`` from ``dx_ante`` [m/s] (3,).

        :math:`\dot x^+ = \dot x^- - (1 + e)(I - P_x)\dot x^-` with the task-space projector
        :math:`P_x` of :meth:`invariant_projectors` (module docstring).
        """
        _, P_x = self.invariant_projectors(q)
        e = self.settings.restitution
        return np.asarray(dx_ante - (1.0 + e) * (dx_ante - P_x @ dx_ante), dtype=float)

    def post_reference(self, t: float, k: int) -> tuple[Vector, Vector, Vector]:
        """Post-impact reference of landing k at ``t`` [s]: position, velocity, force.

        Uses :attr:`post_velocity` (set at the first impact); the force is :math:`f_d(t)`.
        """
        t_i = self.impact_time(k)
        c, dc, f_d, _ = self.desired(max(t, t_i))
        if t <= t_i:
            return c + self.post_velocity * (t - t_i), self.post_velocity.copy(), f_d
        sigma = (t - t_i) / self.settings.blend_time
        if sigma >= 1.0:
            return c, dc, f_d
        beta, dbeta = smooth_step(sigma, 1)
        delta_v = self.post_velocity - self._contact_velocity(t_i)  # [m/s]
        x = c + delta_v * (t - t_i) * (1.0 - beta)
        dx = dc + delta_v * ((1.0 - beta) - sigma * dbeta)
        return x, dx, f_d

    def _contact_velocity(self, t_i: float) -> Vector:
        """Velocity [m/s] (3,) of the contact-phase reference c just after ``t_i`` [s].

        The path arrives on the surface at :math:`t_i`; with ``project`` its part into the
        surface is removed, as :meth:`desired` does once the path is below it.
        """
        _, dp = self.path.derivatives(t_i, 1)
        n = self._normals[0]
        if self.project and n @ dp < 0.0:
            return np.asarray(dp - (n @ dp) * n, dtype=float)
        return np.asarray(dp, dtype=float)

    def __call__(self, t: float, q: Vector, v: Vector, contacts: ContactState) -> Vector:
        """Torques, shape (nu,), in [N m] (or [N] for prismatic joints)."""
        index = self._read_contacts(contacts)
        k = self.landing(t)
        if k != self._landing:
            self._landing, self.mode = k, SpreadingMode.ANTE
        if self._impact(contacts, index):
            if self.mode is SpreadingMode.ANTE:
                _, dx_ante, _ = self.ante_reference(self.impact_time(k), k)
                self.post_velocity = self.post_velocity_map(q, dx_ante)
            self.mode, self._last_impact = SpreadingMode.INTERIM, t
        elif self.mode is SpreadingMode.INTERIM and t - self._last_impact >= (
            self.settings.interim_time
        ):
            self.mode = SpreadingMode.POST
        ddx_d: Vector | None
        if self.mode is SpreadingMode.ANTE:
            x_d, dx_d, ddx_d = self.ante_reference(t, k)
            f_d = np.zeros(len(self.contacts))
        else:
            x_d, dx_d, f_d = self.post_reference(t, k)
            ddx_d = None
        invariant = self._invariant_at(t) or (
            self.impact_invariant and self.mode is SpreadingMode.INTERIM
        )
        damped = self.mode is not SpreadingMode.INTERIM or self.impact_invariant
        tau = self._task_torque(q, v, x_d, dx_d, f_d, invariant, damped=damped, ddx_d=ddx_d)
        self.x_desired, self.force_desired = x_d, f_d
        self.window = np.full(len(self.contacts), self.mode is not SpreadingMode.ANTE)
        return tau if self._actuated is None else tau[self._actuated]

    def _impact(self, contacts: ContactState, index: list[int]) -> bool:
        """Whether a contact (plant ``index``) closed with a jump of its normal velocity."""
        u_n = contacts.normal_velocity[index]  # [m/s]
        previous, self._normal_velocity = self._normal_velocity, u_n
        if previous is None:
            return False
        near = contacts.gap[index] <= self.settings.contact_gap
        return bool(np.any(near & (u_n - previous > self.settings.impact_speed)))

    def prepare_log(self, log: Log) -> None:
        """Declare the impedance fields and ``spreading_mode``."""
        super().prepare_log(log)
        log.add_field("spreading_mode", (), np.int64)
        log.metadata["controller"] = "reference_spreading"

    def record(self, log: Log) -> None:
        """Write the values of the last call into the current row."""
        super().record(log)
        log.extra_fields(["spreading_mode"])[0][len(log)] = int(self.mode)
