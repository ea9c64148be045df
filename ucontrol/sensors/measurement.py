r"""Sensors in the loop: what the controller sees of the plant at each control period.

Position: :math:`q_m = \operatorname{quantise}(q \oplus \delta)`, with :math:`\delta` white
Gaussian noise in the tangent space and the rounding applied to one-coordinate joints
(revolute, prismatic) and motors.

Velocity, with control period :math:`T`: ``"difference"`` is the finite difference
:math:`d_k = (q_{m,k} \ominus q_{m,k-1}) / T` through a first-order low-pass filter of cut-off
:math:`f_c` (backward Euler, :math:`\hat v_k = \hat v_{k-1} + \alpha (d_k - \hat v_{k-1})`,
:math:`\alpha = \omega_c T / (1 + \omega_c T)`, :math:`\omega_c = 2\pi f_c`).
At an impact the true velocity jumps; such a filter then lags the jump by about
:math:`1/\omega_c` and the controller acts on a velocity the robot no longer has (a
transition controller reads it as a persisting approach speed). ``"observer"`` re-initialises
the filter at impacts: when a constraint closes (it carries an impulse after a period
without, as the contact switches tell: the true impulses, before any force noise), the
estimate is set to the raw difference for that period and the next one, so the period that
spans the jump is not carried forward. It is the simplest
of the observers designed for jumps (book §8.5.4 points at observers for complementarity
systems): it needs no model of the plant, and costs the accuracy of one unfiltered period per
impact. The velocity of the first period is the true initial velocity (the robot starts at
rest or from a known state). With ``observer = "momentum"`` the impacts that re-initialise
the filter are the momentum observer's flags instead of the plant's impulses; that observer
then runs on the raw difference, whose jump no filter has spread.

Contacts: with ``observer = "oracle"`` the controller receives the plant's own impulses and
active sets (with the force noise), which a real robot has no access to. With ``"momentum"`` a
:class:`~ucontrol.sensors.momentum_observer.MomentumObserver` on the controller's model reads
the measured position, the velocity estimate above and the torque applied over the period
(after the actuators; with flexible joints the observer watches the links' momentum, driven
by the rigid joints' inputs and the transmission torque at the measured link and motor
states); the gaps and normal velocities it reports are those of the measured state against
the surfaces of the controller's model (``[controller.model.surfaces]``,
:meth:`~ucontrol.scene.scene.Scene.believed_constraints`), never the plant's; the constraints
whose measured gap is at most ``contact_gap`` are candidates, their normal rows :math:`J_c`
share the residual by least squares (:math:`J_c^T \hat\lambda = r`), and a candidate with
:math:`\hat\lambda_i` above ``force_threshold`` is active with the impulse
:math:`\hat\lambda_i T`; every other constraint carries none. Nothing of the plant's
impulses reaches the controller then.

Delay: the controller at period k receives the whole measurement (positions, velocity,
contact information) of period :math:`k - d`; before :math:`d` periods have passed it receives
the first one.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.control.controller import ContactState
from ucontrol.exceptions import InvalidParameterError
from ucontrol.log import Log
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.robot_model import RobotModel
from ucontrol.sensors.momentum_observer import MomentumObserver
from ucontrol.sensors.sensor_settings import SensorSettings

Vector = NDArray[np.float64]


class Sensors:
    """The measurement chain of a run (built by the closed loop when a scene declares it).

    Args:
        settings: What is measured and how.
        robot: The robot (its joints tell which coordinates are quantised).
        constraints: The constraints whose gaps and normal velocities at the measured state
            are reported: the plant's with the oracle, the controller's believed ones with
            ``observer = "momentum"`` (as :func:`ucontrol.simulate` passes them).
        flexible: Flexible joints (their motor coordinates are measured too), or None.
        period: Control period T in [s].
        believed: The robot as the controller believes it (the momentum observer's model),
            or None for ``robot``.

    Raises:
        InvalidParameterError: ``observer = "momentum"`` with a believed robot of another
            velocity dimension.
    """

    def __init__(
        self,
        settings: SensorSettings,
        robot: RobotModel,
        constraints: ConstraintSet,
        flexible: FlexibleJoints | None,
        period: float,
        believed: RobotModel | None = None,
    ) -> None:
        self.settings = settings
        self.period = period
        self._robot, self._constraints = robot, constraints
        self._data = pin.Data(robot.model)
        self._nq, self._nv = robot.nq, robot.nv
        nf = 0 if flexible is None else flexible.nf
        self._rng = np.random.default_rng(settings.seed)
        self._noise = np.broadcast_to(settings.position_noise, (robot.nv + nf,)).copy()
        model = robot.model
        one_coordinate = [
            (joint.idx_q, joint.idx_v)
            for joint in model.joints[1:]
            if joint.nq == 1 and joint.nv == 1
        ]
        q_index = [iq for iq, _ in one_coordinate] + list(range(robot.nq, robot.nq + nf))
        v_index = [iv for _, iv in one_coordinate] + list(range(robot.nv, robot.nv + nf))
        resolution = np.broadcast_to(settings.quantisation, (robot.nv + nf,))[v_index]
        keep = resolution > 0.0
        self._quantised = np.array(q_index, dtype=np.intp)[keep]
        self._resolution = resolution[keep]
        cutoff = settings.velocity_cutoff
        omega_t = 0.0 if cutoff is None else 2.0 * np.pi * cutoff * period
        self._alpha = 1.0 if cutoff is None else omega_t / (1.0 + omega_t)
        self._last_q: Vector | None = None
        self._estimate: Vector | None = None
        self._was_carrying: NDArray[np.bool_] | None = None
        self._raw_periods = 0  # periods left whose velocity is the raw difference
        self._queue: deque[tuple[Vector, Vector, ContactState]] = deque()
        self._momentum = None
        self._flexible = flexible
        self._last_transmission: Vector | None = None  # on the links, shape (nv,) [N m]
        if settings.observer == "momentum":
            self._momentum = _momentum_observer(settings, robot, period, believed)

    def measure(
        self,
        q: Vector,
        v: Vector,
        contacts: ContactState,
        t: float | None = None,
        tau: Vector | None = None,
    ) -> tuple[Vector, Vector, ContactState]:
        """The measurement the controller receives now (delayed), from the true signals.

        Args:
            q: True configuration, shape (nq,) (+ nf motors).
            v: True velocity, shape (nv,) (+ nf motors).
            contacts: True contact information of the period that ends now (only its names
                and period with ``observer = "momentum"``).
            t: Time of the measurement in [s] (the gaps of moving surfaces depend on it).
            tau: Generalized torque applied over the period that ends now, shape (nv,)
                (needed by ``observer = "momentum"`` only).

        Returns:
            Measured configuration, velocity and contact information.

        Raises:
            InvalidParameterError: ``tau`` is None with ``observer = "momentum"``.
        """
        momentum = self._momentum
        if momentum is not None and tau is None:
            raise InvalidParameterError("tau", tau, "the torque applied (observer = 'momentum')")
        q_m = self._position(q)
        v_m = self._velocity(q_m, v, contacts, tau)
        if momentum is None:
            seen = self._contacts(q_m, v_m, contacts, t)
        else:
            if self.settings.velocity != "observer":  # else updated on the raw difference
                assert tau is not None
                self._update_momentum(q_m, v_m, tau)
            seen = self._observed_contacts(q_m, v_m, contacts, t)
        self._queue.append((q_m, v_m, seen))
        if len(self._queue) > self.settings.delay + 1:
            self._queue.popleft()
        return self._queue[0]

    def record_observer(self, log: Log) -> None:
        """The momentum observer's residual and impact flag in the open row of ``log``.

        Nothing without ``observer = "momentum"``; the fields ``momentum_residual`` (nv,)
        [N m] and ``impact_detected`` are declared by the closed loop.
        """
        if self._momentum is not None:
            log.record_extra("momentum_residual", self._momentum.residual)
            log.record_extra("impact_detected", self._momentum.impact)

    def _position(self, q: Vector) -> Vector:
        q_m = q.copy()
        if np.any(self._noise > 0.0):
            delta = self._noise * self._rng.standard_normal(self._noise.size)
            q_m[: self._nq] = pin.integrate(self._robot.model, q[: self._nq], delta[: self._nv])
            q_m[self._nq :] += delta[self._nv :]
        if self._quantised.size:
            values = q_m[self._quantised] / self._resolution
            q_m[self._quantised] = np.round(values) * self._resolution
        return q_m

    def _velocity(
        self, q_m: Vector, v: Vector, contacts: ContactState, tau: Vector | None
    ) -> Vector:
        source = self.settings.velocity
        if source == "true":
            return v.copy()
        last, self._last_q = self._last_q, q_m
        if last is None or self._estimate is None:
            self._estimate = v.copy()
            if source == "observer":
                self._closed(q_m, v, contacts, tau)  # the first sample of either observer
            return self._estimate.copy()
        raw = np.empty_like(v)
        raw[: self._nv] = pin.difference(self._robot.model, last[: self._nq], q_m[: self._nq])
        raw[self._nv :] = q_m[self._nq :] - last[self._nq :]
        raw /= self.period  # [rad/s] or [m/s]
        if source == "observer" and self._closed(q_m, raw, contacts, tau):
            self._raw_periods = 2
        if self._raw_periods > 0:
            self._raw_periods -= 1
            self._estimate = raw
        else:
            self._estimate = self._estimate + self._alpha * (raw - self._estimate)
        return self._estimate.copy()

    def _update_momentum(self, q_m: Vector, v_m: Vector, tau: Vector) -> None:
        """Update the momentum observer with the links' torque over the period that ends now.

        With flexible joints the links receive, besides the inputs of rigid joints, the
        transmission torque :math:`-S^T f` of the springs and dampers at the measured link and
        motor states, averaged over the period by the trapezoid rule.
        """
        assert self._momentum is not None
        nq, nv, flexible = self._nq, self._nv, self._flexible
        torque = tau[:nv]
        if flexible is not None:
            on_links = np.zeros(nv)
            on_links[flexible.v_index] = -flexible.spring_torque(
                q_m[:nq], v_m[:nv], q_m[nq:], v_m[nv:]
            )
            last = on_links if self._last_transmission is None else self._last_transmission
            torque = torque + 0.5 * (last + on_links)  # [N m]
            self._last_transmission = on_links
        self._momentum.update(q_m[:nq], v_m[:nv], torque)

    def _closed(self, q_m: Vector, raw: Vector, contacts: ContactState, tau: Vector | None) -> bool:
        """Whether a constraint closed over the period that ends now: an impact.

        The momentum observer's impact flag, the observer updated on the raw velocity
        ``raw`` (unfiltered: a filter would spread the jump it looks for), or, for the oracle,
        a constraint that carries an impulse after a period without.
        """
        if self._momentum is not None:
            assert tau is not None
            self._update_momentum(q_m, raw, tau)
            return self._momentum.impact
        carrying = contacts.impulse > 0.0
        was_carrying, self._was_carrying = self._was_carrying, carrying
        return was_carrying is not None and bool(np.any(carrying & ~was_carrying))

    def _geometry(self, q_m: Vector, v_m: Vector, t: float | None) -> tuple[Vector, Vector]:
        """Gaps and normal velocities at the measured state (its kinematics left in the data)."""
        model, data = self._robot.model, self._data
        pin.forwardKinematics(model, data, q_m[: self._nq], v_m[: self._nv])
        pin.updateFramePlacements(model, data)
        return self._constraints.evaluate(data, q_m[: self._nq], v_m[: self._nv], t)

    def _contacts(
        self, q_m: Vector, v_m: Vector, contacts: ContactState, t: float | None
    ) -> ContactState:
        """Gaps and normal velocities at the measured state, noisy impulses."""
        gap, normal_velocity = self._geometry(q_m, v_m, t)
        impulse = contacts.impulse
        sigma = self.settings.force_noise
        if sigma > 0.0:  # a force noise of σ [N] on the mean force over the period
            noise = self._rng.standard_normal(impulse.size)
            impulse = impulse + (sigma * contacts.dt) * noise
        return ContactState(
            contacts.names, gap, normal_velocity, impulse, contacts.active.copy(), contacts.dt
        )

    def _observed_contacts(
        self, q_m: Vector, v_m: Vector, contacts: ContactState, t: float | None
    ) -> ContactState:
        """Gaps and normal velocities at the measured state, impulses of the momentum observer."""
        assert self._momentum is not None
        gap, normal_velocity = self._geometry(q_m, v_m, t)
        candidates = np.flatnonzero(gap <= self.settings.contact_gap)
        impulse = np.zeros(gap.size)
        if candidates.size:
            pin.computeJointJacobians(self._robot.model, self._data, q_m[: self._nq])
            J = self._constraints.jacobian(self._data, candidates)  # (m, nv)
            force = self._momentum.contact_forces(J)  # [N] (or [N m] on stops)
            closed = force > self.settings.force_threshold
            impulse[candidates[closed]] = force[closed] * contacts.dt  # [N s]
        return ContactState(
            contacts.names, gap, normal_velocity, impulse, impulse > 0.0, contacts.dt
        )


def _momentum_observer(
    settings: SensorSettings, robot: RobotModel, period: float, believed: RobotModel | None
) -> MomentumObserver:
    """The momentum observer of ``settings`` on the believed robot (``robot`` if None)."""
    model = robot.model if believed is None else believed.model
    if model.nv != robot.nv:
        raise InvalidParameterError(
            "believed robot", believed, f"a model with nv = {robot.nv} (the plant's)"
        )
    return MomentumObserver(model, settings.observer_gain, period, settings.impact_threshold)
