r"""Event-driven hops of a one-foot robot in closed loop: flight, touchdown, stance, lift-off.

The closed loop of a robot with one point foot and a state-feedback law
:math:`u = \kappa(q, v, \text{stance})` (such as
:meth:`~ucontrol.control.raibert_controller.RaibertController.torque`) alternates two smooth
flows, integrated by :func:`scipy.integrate.solve_ivp` (DOP853) with the law evaluated inside
the right-hand side (no zero-order hold):

- **flight**: :math:`M \dot v + h = S^T u`;
- **stance**: the foot pinned (normal and tangential rows, the KKT system of
  :class:`~ucontrol.analysis.stance_flow.StanceFlow` with the input), until its normal force
  falls to 0 (lift-off, back to flight), or its friction margin
  :math:`\mu \lambda_n - \|\lambda_t\|` does while the normal force is above ``slip_force``
  (a slip: refused, :class:`StrideError`).

Touchdown (the foot's gap closing to 0) is a plastic sticking impact,
:math:`M (v^+ - v^-) = J^T \Lambda`, :math:`J v^+ = 0`, refused outside the friction cone. Two
Poincaré sections: :meth:`HopFlow.apex` runs to the next **apex**, the body's vertical velocity
crossing 0 downwards in flight after a stance; :meth:`HopFlow.stride` to the next
**touchdown**, just after the impact. Either is an argument of
:func:`~ucontrol.analysis.gait.find_gait` (``section="apex"`` or ``"heel_strike"``). A section
not crossed within ``max_duration`` is a :class:`~ucontrol.exceptions.StrideError`, never a
hang. The law's own switches inside a flow (the thrust starting at the bottom of the stance)
are crossed by the step-size control, with no event: rtol = atol = 1e-11 keeps the apex map's
finite-difference Jacobian accurate to about 1e-6 (docs/legged.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_non_negative, as_positive
from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import InvalidParameterError, StrideError

Vector = NDArray[np.float64]


class HoppingLaw(Protocol):
    """A state-feedback law with a flight and a stance branch."""

    def torque(self, q: Vector, v: Vector, stance: bool) -> Vector:
        """Actuator inputs, shape (nu,), at (q (nq,), v (nv,)) in flight or stance."""


@dataclass(frozen=True)
class Hop:
    """One flow from a start to a section crossing.

    Attributes:
        duration: Time to the crossing in [s].
        q: Configuration at the crossing, shape (nq,).
        v: Velocity at the crossing (after the impact at a touchdown), shape (nv,).
        stance_time: Duration of the last stance in [s] (0 when none was completed).
    """

    duration: float
    q: Vector
    v: Vector
    stance_time: float


class HopFlow:
    """The closed loop of a one-foot robot and its law, event-driven (module docstring).

    Args:
        constraints: The robot's contacts: one sticking point contact (a
            :class:`~ucontrol.analysis.stance_flow.StanceFlow`'s conditions).
        law: The controller's law, ``torque(q, v, stance)``.
        height_joint: The joint whose velocity is the body's vertical velocity (apex section).
        rtol: Relative tolerance of solve_ivp.
        atol: Absolute tolerance of solve_ivp.
        max_duration: Longest flow in [s] before a section crossing.
        slip_force: Normal force [N] below which the friction cone is not checked; default 1 %
            of the robot's weight. As the foot unloads at the end of a stance, any tangential
            force leaves the cone just before the normal force reaches 0: the foot slips in
            the last instant of the stance, with forces this small, and this flow takes it as
            the lift-off.

    Raises:
        InvalidParameterError: Not exactly one contact, or the height joint is not prismatic.
        JointNotFoundError: The height joint does not exist.
    """

    def __init__(
        self,
        constraints: ConstraintSet,
        law: HoppingLaw,
        *,
        height_joint: str = "z",
        rtol: float = 1e-11,
        atol: float = 1e-11,
        max_duration: float = 5.0,
        slip_force: float | None = None,
    ) -> None:
        if constraints.size != 1:
            raise InvalidParameterError(
                "constraints", constraints.names, "exactly one point contact (the foot)"
            )
        self.stance = StanceFlow(constraints, rtol=rtol, atol=atol, max_duration=max_duration)
        robot = constraints.robot
        joint = robot.model.joints[robot.joint_id(height_joint)]
        if not joint.shortname().startswith("JointModelP"):  # PX, PY, PZ, PrismaticUnaligned
            raise InvalidParameterError("height_joint", height_joint, "a prismatic joint")
        self._height = int(joint.idx_v)
        self.constraints = constraints
        self.robot = robot
        self.law = law
        self.rtol = as_positive("rtol", rtol)
        self.atol = as_positive("atol", atol)
        self.max_duration = as_positive("max_duration", max_duration)
        self._data = pin.Data(robot.model)
        pin.computeSubtreeMasses(robot.model, self._data)
        weight = float(self._data.mass[0] * np.linalg.norm(robot.gravity))  # [N]
        self.slip_force = (
            0.01 * weight if slip_force is None else as_non_negative("slip_force", slip_force)
        )
        self._selection = np.zeros((robot.nv, robot.nu))
        self._selection[robot.actuated, np.arange(robot.nu)] = 1.0

    def apex(self, q: Vector, v: Vector) -> Hop:
        """Flow from a flight state to the next apex (after a stance).

        Raises:
            StrideError: No apex within :attr:`max_duration`, or the foot slips or strikes
                outside the friction cone.
        """
        return self._flow(q, v, "apex")

    def stride(self, q: Vector, v: Vector) -> Hop:
        """Flow from a flight state to the next touchdown, the impact included.

        Raises:
            StrideError: No touchdown within :attr:`max_duration`, or a strike outside the
                friction cone.
        """
        return self._flow(q, v, "touchdown")

    def _tau(self, q: Vector, v: Vector, stance: bool) -> Vector:
        return self._selection @ np.asarray(self.law.torque(q, v, stance), dtype=float)

    def _flight_rate(self, _: float, y: Vector) -> Vector:
        nv = self.robot.nv
        q, v = y[:nv], y[nv:]
        a = pin.aba(self.robot.model, self._data, q, v, self._tau(q, v, False))
        return np.concatenate((v, a))

    def _stance_force(self, y: Vector) -> tuple[Vector, Vector]:
        nv = self.robot.nv
        q, v = y[:nv], y[nv:]
        return self.stance.acceleration(q, v, 0, self._tau(q, v, True))

    def _flow(self, q: Vector, v: Vector, section: str) -> Hop:
        q = self.robot.check_configuration("q", q)
        v = self.robot.check_velocity("v", v)
        nv, mu = self.robot.nv, float(self.constraints.friction[0])
        y, t, stance_time = np.concatenate((q, v)), 0.0, 0.0
        landed = False

        def touchdown(_: float, y: Vector) -> float:
            return float(self.constraints.gaps(y[:nv])[0])

        def apex(_: float, y: Vector) -> float:
            return float(y[nv + self._height])

        def lift_off(_: float, y: Vector) -> float:
            return float(self._stance_force(y)[1][0])

        def slip(_: float, y: Vector) -> float:
            force = self._stance_force(y)[1]
            margin = mu * force[0] - np.linalg.norm(force[1:])  # [N]
            return float(max(margin, self.slip_force - force[0]))

        for event in (touchdown, apex, lift_off, slip):
            event.terminal, event.direction = True, -1.0  # type: ignore[attr-defined]

        def stance_rate(_: float, y: Vector) -> Vector:
            return np.concatenate((y[nv:], self._stance_force(y)[0]))

        while t < self.max_duration:
            # flight: to the apex after a stance, or to a touchdown
            if landed and section == "apex":
                solution = self.stance.solve(self._flight_rate, t, y, [apex, touchdown])
                if solution.t_events[0].size:
                    q_end, v_end = self._split(solution.y_events[0][0])
                    return Hop(float(solution.t_events[0][0]), q_end, v_end, stance_time)
                fired = solution.t_events[1]
                y_event = solution.y_events[1]
            else:
                solution = self.stance.solve(self._flight_rate, t, y, [touchdown])
                fired, y_event = solution.t_events[0], solution.y_events[0]
            if not fired.size:
                break
            t, y = float(fired[0]), y_event[0]
            v_plus, impulse = self.stance.heel_strike(y[:nv], y[nv:], 0)
            if impulse[0] < 0.0 or np.linalg.norm(impulse[1:]) > mu * impulse[0]:
                raise StrideError(t, f"the touchdown is not a sticking one ({impulse.tolist()})")
            y = np.concatenate((y[:nv], v_plus))
            if section == "touchdown":
                return Hop(t, y[:nv].copy(), v_plus, stance_time)
            # stance: to the lift-off
            start = t
            solution = self.stance.solve(stance_rate, t, y, [lift_off, slip])
            if solution.t_events[1].size:
                raise StrideError(float(solution.t_events[1][0]), "the foot would slip")
            if not solution.t_events[0].size:
                break
            t, y = float(solution.t_events[0][0]), solution.y_events[0][0]
            stance_time, landed = t - start, True
        raise StrideError(self.max_duration, f"no {section} (the section is never crossed)")

    def _split(self, y: Vector) -> tuple[Vector, Vector]:
        nv = self.robot.nv
        return y[:nv].copy(), y[nv:].copy()


def logged_apexes(height: Vector, rate: Vector) -> tuple[Vector, NDArray[np.int64]]:
    """The apexes of a logged run: the body's height where its vertical rate crosses 0 down.

    Args:
        height: The body's height at each sample in [m], shape (n,).
        rate: Its vertical velocity in [m/s], shape (n,).

    Returns:
        The heights at the crossings [m], linear between the two samples around each, and the
        index of the sample before each crossing.
    """
    height, rate = np.asarray(height, dtype=float), np.asarray(rate, dtype=float)
    k = np.flatnonzero((rate[:-1] > 0.0) & (rate[1:] <= 0.0))
    share = rate[k] / (rate[k] - rate[k + 1])
    return height[k] + share * (height[k + 1] - height[k]), k
