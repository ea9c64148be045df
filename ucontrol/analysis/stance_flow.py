r"""Event-driven strides of a passive walker whose feet stick: stance flow and heel strike.

A walker here is a robot whose contacts are points (radius 0) against fixed planes, with
friction large enough that a foot on the ground never slips. One foot (the stance foot, a
contact :math:`s`) is on the ground; it is held fully, its normal and tangential rows
:math:`J_s` together, as a pin:

.. math::

    M \dot v + h = J_s^T \lambda, \qquad J_s \dot v + \dot J_s v = 0,

solved as a KKT system at every evaluation and integrated by :func:`scipy.integrate.solve_ivp`
(DOP853) with terminal events on the gap of every other foot (decreasing zero: the heel
strike), on the stance foot's normal force (decreasing zero: it would lift off) and on its
friction margin :math:`\mu \lambda_n - \|\lambda_t\|` (decreasing zero: it would slip).
The heel strike of foot :math:`b` is plastic and without slip,

.. math::

    M (v^+ - v^-) = J_b^T \Lambda, \qquad J_b v^+ = 0,

after which :math:`b` is the stance foot; the old stance foot must leave (its normal velocity
:math:`\ge 0` after the strike) and :math:`\Lambda` must lie in the friction cone, or the
stride is refused (:class:`~ucontrol.exceptions.StrideError`) rather than continued with a
model that does not hold. This is the reference stride map of the walkers run with Coulomb
friction by Moreau–Jean and by the event-driven integrator
(:mod:`ucontrol.integrators.event_driven`; docs/legged.md compares their strikes). Robots
with ``nq == nv`` only (planar walkers on prismatic and revolute joints). The joints receive
no input, or those of a state-feedback law given the stance foot (``law``, e.g.
:meth:`~ucontrol.control.hzd_controller.HZDController.torque`), evaluated inside the
right-hand side (no zero-order hold): the stride map of a walker in closed loop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ucontrol._validation import as_positive
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import InvalidParameterError, StrideError

Vector = NDArray[np.float64]

_LWA = pin.LOCAL_WORLD_ALIGNED
#: Gap in [m] below which a foot counts as on the ground at the start of a stride (a designed
#: start carries its transcription's drift, a few 1e-7 m, between the two feet).
STANCE_GAP_TOLERANCE = 1e-6


class WalkingLaw(Protocol):
    """A state-feedback law given the stance foot."""

    def torque(self, q: Vector, v: Vector, contact: int) -> Vector:
        """Actuator inputs, shape (nu,), at (q (nq,), v (nv,)) on the foot ``contact``."""


@dataclass(frozen=True)
class Stride:
    """One stride: from a post-strike state to the next heel strike, the strike included.

    Attributes:
        duration: Time from the start to the heel strike in [s].
        q: Configuration at the strike, shape (nq,).
        v: Velocity just after the strike, shape (nv,).
        v_minus: Velocity just before it, shape (nv,).
        stance: Index of the new stance contact (the foot that struck).
        impulse: The strike's impulse on that foot (normal, then tangential rows) in [N s].
    """

    duration: float
    q: Vector
    v: Vector
    v_minus: Vector
    stance: int
    impulse: Vector


class StanceFlow:
    r"""The stance flow and heel-strike map of a passive walker with sticking feet.

    Args:
        constraints: The walker's contacts (a scene's :attr:`~ucontrol.scene.Scene.constraints`):
            point contacts only, radius 0, fixed planes, friction > 0, no stops.
        rtol: Relative tolerance of solve_ivp.
        atol: Absolute tolerance of solve_ivp.
        max_duration: Longest stride in [s]: a foot that has not struck by then is an error.
        law: The actuators' law given the stance contact's index, or None (a passive walker).

    The scuffing rule is the scene's: a contact declared with ``closes_ahead_of``
    (:class:`~ucontrol.contact.PointContact`; a point foot passing through the slope as the
    legs cross, ignored as in Garcia et al. 1998) has no strike event while
    :meth:`~ucontrol.contact.ConstraintSet.closure_barred` bars it, but an event on its margin
    :math:`a \cdot (p_\text{ahead} - p_\text{other})` rising to 0; from there on its strike
    is the next crossing of its gap downwards (a foot under the slope when its bar lifts
    strikes only after coming back above it), as under the event-driven integrator. (An
    ``ahead`` argument of its own is not kept: every walker analysed here is a scene's, which
    declares the rule, and one rule for the flow and the integrators keeps their strides
    alike.)

    Raises:
        InvalidParameterError: The robot has nq != nv, or a constraint is not a sticking point
            contact against a fixed plane.
    """

    def __init__(
        self,
        constraints: ConstraintSet,
        *,
        rtol: float = 1e-12,
        atol: float = 1e-12,
        max_duration: float = 10.0,
        law: WalkingLaw | None = None,
    ) -> None:
        robot = constraints.robot
        if robot.nq != robot.nv:
            raise InvalidParameterError(
                "robot", robot.name, f"a robot with nq == nv (got nq = {robot.nq}, nv = {robot.nv})"
            )
        if constraints.size == 0 or constraints.size != len(constraints.contacts):
            raise InvalidParameterError(
                "constraints", constraints.names, "point contacts only (no stops or pairs)"
            )
        for contact in constraints.contacts:
            if contact.radius != 0.0 or contact.friction <= 0.0 or contact.surface.motion:
                raise InvalidParameterError(
                    f"contact {contact.name!r}",
                    f"radius {contact.radius}, friction {contact.friction}",
                    "a point (radius 0) with friction > 0 against a fixed plane",
                )
        self.constraints = constraints
        self.robot = robot
        self.rtol = as_positive("rtol", rtol)
        self.atol = as_positive("atol", atol)
        self.max_duration = as_positive("max_duration", max_duration)
        self._data = pin.Data(robot.model)
        self._drift_data = pin.Data(robot.model)
        self._frames = [robot.frame_id(contact.frame) for contact in constraints.contacts]
        self.law = law
        self._selection = np.zeros((robot.nv, robot.nu))
        self._selection[robot.actuated, np.arange(robot.nu)] = 1.0

    def stance_of(self, q: Vector, v: Vector) -> int:
        """The stance foot at (q, v): of the feet on the ground, the one moving least upwards.

        Just after a heel strike two feet touch the ground: the one that struck (normal
        velocity 0) and the one that leaves (positive normal velocity).

        Raises:
            InvalidParameterError: No foot is within :data:`STANCE_GAP_TOLERANCE` of the ground.
        """
        gaps = self.constraints.gaps(q)
        on_ground = np.flatnonzero(np.abs(gaps) <= STANCE_GAP_TOLERANCE)
        if on_ground.size == 0:
            raise InvalidParameterError(
                "q",
                q.tolist(),
                f"a foot on the ground (smallest gap {np.min(gaps):.3e} m)",
            )
        model, data = self.robot.model, self._data
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        normal_velocity = self.constraints.jacobian(data, on_ground) @ v
        return int(on_ground[np.argmin(normal_velocity)])

    def _rows(self, q: Vector, v: Vector, foot: int) -> tuple[Vector, Vector, Vector, Vector]:
        """M, h, the foot's rows (normal then tangents) and their drift J̇v at (q, v)."""
        model, data = self.robot.model, self._data
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        M = np.triu(data.M) + np.triu(data.M, 1).T
        normal = self.constraints.jacobian(data, [foot])
        tangent, directions = self.constraints.tangent_rows(data, [foot])
        drift_data = self._drift_data
        pin.forwardKinematics(model, drift_data, q, v, np.zeros(model.nv))
        pin.updateFramePlacements(model, drift_data)
        acceleration = pin.getFrameClassicalAcceleration(
            model, drift_data, self._frames[foot], _LWA
        ).linear
        drift = np.concatenate(
            (self.constraints.normal_drift(drift_data, [foot]), directions @ acceleration)
        )
        return M, data.nle.copy(), np.vstack((normal, tangent)), drift

    def acceleration(
        self, q: Vector, v: Vector, stance: int, tau: Vector | None = None
    ) -> tuple[Vector, Vector]:
        """Joint acceleration (nv,) and the stance foot's force (normal, tangents) in [N].

        ``tau`` (nv,) is a generalized force [N m] or [N] on the joints, default none.
        """
        M, h, J, drift = self._rows(q, v, stance)
        k = J.shape[0]
        kkt = np.block([[M, -J.T], [J, np.zeros((k, k))]])
        force = -h if tau is None else tau - h
        solution = np.linalg.solve(kkt, np.concatenate((force, -drift)))
        return solution[: self.robot.nv], solution[self.robot.nv :]

    def heel_strike(self, q: Vector, v_minus: Vector, foot: int) -> tuple[Vector, Vector]:
        r"""Plastic, sticking strike of ``foot``: the velocity after it and its impulse [N s].

        Solves :math:`M (v^+ - v^-) = J_b^T \Lambda`, :math:`J_b v^+ = 0`.
        """
        M, _, J, _ = self._rows(q, v_minus, foot)
        k = J.shape[0]
        kkt = np.block([[M, -J.T], [J, np.zeros((k, k))]])
        solution = np.linalg.solve(kkt, np.concatenate((M @ v_minus, np.zeros(k))))
        return solution[: self.robot.nv], solution[self.robot.nv :]

    def stride(self, q: Vector, v: Vector) -> Stride:
        """Flow from a state with one foot on the ground to the next heel strike, then strike.

        Args:
            q: Configuration with the stance foot on the ground, shape (nq,).
            v: Velocity, shape (nv,); its component that moves the stance foot is removed
                first (the strike map of that foot, a projection in the metric of M).

        Raises:
            InvalidParameterError: No foot on the ground at ``q``.
            StrideError: The stance foot would lift off or slip, no other foot strikes within
                :attr:`max_duration` (the section is never crossed), or the strike is not a
                plastic sticking one with the old foot leaving.
        """
        q = self.robot.check_configuration("q", q)
        v = self.robot.check_velocity("v", v)
        stance = self.stance_of(q, v)
        v, _ = self.heel_strike(q, v, stance)
        nv, mu = self.robot.nv, self.constraints.friction[stance]
        others = [i for i in range(self.constraints.size) if i != stance]

        def pinned(y: Vector) -> tuple[Vector, Vector]:
            q, v = y[:nv], y[nv:]
            return self.acceleration(q, v, stance, self.law_input(q, v, stance))

        def rate(_: float, y: Vector) -> Vector:
            return np.concatenate((y[nv:], pinned(y)[0]))

        def gap_event(i: int) -> Callable[[float, Vector], float]:
            def event(_: float, y: Vector) -> float:
                return float(self.constraints.gaps(y[:nv])[i])

            event.terminal, event.direction = True, -1.0  # type: ignore[attr-defined]
            return event

        def bar_event(i: int) -> Callable[[float, Vector], float]:
            def event(_: float, y: Vector) -> float:
                return float(self.constraints.closure_margins(y[:nv])[i])

            event.terminal, event.direction = True, 1.0  # type: ignore[attr-defined]
            return event

        def lift_off(_: float, y: Vector) -> float:
            return float(pinned(y)[1][0])

        def slip(_: float, y: Vector) -> float:
            force = pinned(y)[1]
            return float(mu * force[0] - np.linalg.norm(force[1:]))

        y0 = np.concatenate((q, v))
        for name, margin in (("lift off", lift_off), ("slip", slip)):
            if margin(0.0, y0) < 0.0:
                raise StrideError(
                    0.0, f"the stance foot {self.constraints.names[stance]!r} would {name}"
                )
        lift_off.terminal, lift_off.direction = True, -1.0  # type: ignore[attr-defined]
        slip.terminal, slip.direction = True, -1.0  # type: ignore[attr-defined]
        margins = self.constraints.closure_margins(q)
        barred = [i for i in others if margins[i] < 0.0]
        t_end, y_end = 0.0, y0
        while True:
            allowed = [i for i in others if i not in barred]
            events = [gap_event(i) for i in allowed] + [bar_event(i) for i in barred]
            solution = self.solve(rate, t_end, y_end, [*events, lift_off, slip])
            fired = [k for k, times in enumerate(solution.t_events) if len(times)]
            if not fired:
                raise StrideError(
                    self.max_duration, "no foot struck the ground (the section is never crossed)"
                )
            event = fired[0]
            t_end, y_end = float(solution.t_events[event][0]), solution.y_events[event][0]
            if event >= len(events):
                kind = "lift off" if event == len(events) else "slip"
                raise StrideError(
                    t_end, f"the stance foot {self.constraints.names[stance]!r} would {kind}"
                )
            if event < len(allowed):
                break
            barred.remove(barred[event - len(allowed)])  # its bar lifts: its gap is watched
        foot = allowed[event]
        q_end, v_minus = y_end[:nv], y_end[nv:]
        v_plus, impulse = self.heel_strike(q_end, v_minus, foot)
        self._check_strike(q_end, v_plus, impulse, stance, foot, t_end)
        return Stride(t_end, q_end, v_plus, v_minus, foot, impulse)

    def solve(
        self, rate: Callable[[float, Vector], Vector], t: float, y: Vector, events: list[Any]
    ) -> Any:
        """solve_ivp (DOP853) from (t [s], y) to :attr:`max_duration` or a terminal event.

        Raises:
            StrideError: solve_ivp failed.
        """
        solution = solve_ivp(
            rate,
            (t, self.max_duration),
            y,
            method="DOP853",
            rtol=self.rtol,
            atol=self.atol,
            events=events,
        )
        if solution.status == -1:
            raise StrideError(float(solution.t[-1]), f"solve_ivp failed: {solution.message}")
        return solution

    def law_input(self, q: Vector, v: Vector, stance: int) -> Vector | None:
        """The law's generalized force (nv,) with the foot ``stance`` down, or None."""
        if self.law is None:
            return None
        return self._selection @ np.asarray(self.law.torque(q, v, stance), dtype=float)

    def _check_strike(
        self, q: Vector, v: Vector, impulse: Vector, old: int, new: int, t: float
    ) -> None:
        """Refuse a strike that pulls, slips, or leaves the old foot pressing the ground."""
        name = self.constraints.names[new]
        if (
            impulse[0] < 0.0
            or np.linalg.norm(impulse[1:]) > self.constraints.friction[new] * impulse[0]
        ):
            raise StrideError(
                t, f"the strike of {name!r} is not a sticking one (impulse {impulse.tolist()})"
            )
        J_old = self._rows(q, v, old)[2]
        if J_old[0] @ v < -self.atol:
            raise StrideError(
                t,
                f"the old stance foot {self.constraints.names[old]!r} keeps pressing after the "
                f"strike of {name!r} (double support is not modelled)",
            )
