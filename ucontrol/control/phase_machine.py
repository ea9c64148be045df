r"""The phase machine: detects the events of each contact and builds the desired trajectory.

Per declared contact (a gap coordinate :math:`X_{1,i}`) and per cycle k:

- FREE until :math:`\tau_0 = kP + t_{start} - T_a`: the coordinate follows the nominal path;
- APPROACH from :math:`\tau_0`: a cubic from the current desired value and velocity to the
  virtual target :math:`-d` below the surface, reached at rest after :math:`T_a`, with
  :math:`d` scaled by :math:`V_1(\tau_0)`; the other free coordinates are frozen (they stop
  with a constant deceleration over :math:`T_a`);
- TRANSITION from the first impact :math:`t_0` (first positive impulse), same target;
- CONSTRAINED from :math:`t_f`, when the contact has stayed closed for the rest time: the
  coordinate is held at 0 with the desired force :math:`\lambda_d(t)`; frozen coordinates blend
  back into the nominal path;
- TAKEOFF from :math:`t_d = kP + t_{end}`: :math:`\tfrac12 a (t - t_d)^2` blended into the
  nominal path, then FREE again for cycle k + 1.

If the contact is not reached or not settled by :math:`t_d`, the takeoff starts anyway (the
cycle is then reported without :math:`t_f`).

With the takeoff rule (:attr:`DesiredCycle.ends_on_opening`, on with the state-based
:math:`\lambda_d`) a constrained contact stays constrained only while it is measured closed:
if it opens once :math:`\lambda_d` has started its fall (:math:`t \ge t_d - T_f`), the
takeoff starts then (:math:`t_d` is that time); if it opens before, it goes back to TRANSITION,
its gap target stepping to the virtual depth :math:`-d_{min}` (the step of :math:`t_f`,
reversed; the other coordinates keep their course), until it has been closed for the rest time
again. Every sample the machine spends in CONSTRAINED then has a positive measured force
(docs/impact_control.md, "Takeoff on opening").

The pieces depend on the ``order`` k of the machine (the number of derivatives its law holds,
see :mod:`ucontrol.control.trajectory_segment`). For k = 2 (the rigid law) they are those above
(cubic, parabola, quintic blends): :math:`C^1` joins. For k > 2 (the flexible-joint law,
k = 4) every join is :math:`C^k`: the approach and the stops are the Hermite polynomials of
degree 2k + 1 to their end at rest (:class:`RestHermite`), the takeoff parabola starts with
zero acceleration and its acceleration rises to a along the smooth step of continuity k - 2
(:class:`SmoothParabola`), and the blends use the smooth step of continuity k. Only the gap
target of a contact jumps, from the virtual target to the surface at :math:`t_f` (and back at an
opening under the takeoff rule), by design.

The machine only keeps times and segment parameters, so every cycle is built from the same
declared values: nothing of cycle k leaks into cycle k + 1 except the state of the robot.
"""

from __future__ import annotations

import math
import operator
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ucontrol.control.circle_path import CirclePath
from ucontrol.control.desired_cycle import DesiredCycle
from ucontrol.control.phase import TRANSITION_PHASES, Event, Phase, overall_phase
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.control.trajectory_segment import (
    BlendToNominal,
    Constant,
    Nominal,
    Parabola,
    RestCubic,
    RestHermite,
    SmoothParabola,
    TrajectorySegment,
)
from ucontrol.exceptions import InvalidParameterError

Vector = NDArray[np.float64]

#: Times closer than this are equal, in [s] (sample times are sums of steps).
TIME_TOLERANCE = 1e-9

#: Segments whose sample depends on the nominal sample's length only, not on its values.
_BLIND_SEGMENTS = frozenset({RestCubic, RestHermite, Parabola, SmoothParabola, Constant})


class DesiredState(NamedTuple):
    r"""The desired trajectory at one time, in task coordinates (an immutable record).

    Every call of :meth:`PhaseMachine.desired` returns fresh ``target`` arrays; ``reference``
    shares them where nothing is clipped.

    Attributes:
        target: Position and its first k time derivatives tracked by the law (k = the
            machine's ``order``; with the virtual target below the surface during
            transitions), each shape (m,).
        reference: Position and velocity on which V is built: the target with the gaps of
            transiting contacts clipped at the surface (0, at rest), each shape (m,).
        force: Desired contact force :math:`\lambda_d` of each declared contact in [N],
            shape (n,) (0 outside the constrained phase). When no contact is constrained, or
            while every constrained one holds its plateau, this and ``force_derivatives`` are
            read-only values shared between calls.
        constrained: Whether each declared contact is in its constrained phase, shape (n,);
            read-only, shared between the calls made in the same phases.
        force_derivatives: The first k - 2 time derivatives of ``force`` [N/s^i], each
            shape (n,): the law's force term has as many derivatives as its ``target[2]`` term.
        stacked: The ``target`` arrays as the views of one flat array, ((k + 1) m,)
            (derivative i at [i m, (i + 1) m)), so that a law copies them at once; None when
            they are separate arrays.
    """

    target: tuple[Vector, ...]
    reference: tuple[Vector, Vector]
    force: Vector
    constrained: NDArray[np.bool_]
    force_derivatives: tuple[Vector, ...] = ()
    stacked: Vector | None = None

    @classmethod
    def zeros(cls, m: int, n: int, order: int = 2) -> DesiredState:
        """Everything 0 for m task coordinates, n contacts and ``order`` derivatives."""
        return cls(
            tuple(np.zeros(m) for _ in range(order + 1)),
            (np.zeros(m), np.zeros(m)),
            np.zeros(n),
            np.zeros(n, dtype=bool),
            tuple(np.zeros(n) for _ in range(order - 2)),
        )


class PhaseMachine:
    """Phases, events and desired trajectory of the declared contacts of a cycle.

    Args:
        task: The task coordinates (the declared contacts are among its gaps).
        cycle: The designed cycle; checked against ``task``.
        order: Number of time derivatives of the desired trajectory, >= 2 (2 for a rigid
            law, 4 for the flexible-joint law); above 2 the pieces join :math:`C^{order}`.

    Raises:
        InvalidParameterError: ``order`` is not an integer >= 2.
        NotFoundError: A contact phase names a contact that is not a task constraint.
        PathThroughSurfaceError: The nominal path crosses an obstacle outside its contact
            phases.
    """

    def __init__(self, task: TaskCoordinates, cycle: DesiredCycle, *, order: int = 2) -> None:
        if isinstance(order, bool) or not isinstance(order, int) or order < 2:
            raise InvalidParameterError("order", order, "an integer >= 2")
        cycle.check(task)
        self.order = order
        self.task = task
        self.cycle = cycle
        self.contacts = [phase.contact for phase in cycle.contact_phases]
        self.coordinates = np.array([task.names.index(name) for name in self.contacts])
        self._ends_on_opening = cycle.ends_on_opening  # the takeoff rule
        self._coordinate_list = [int(j) for j in self.coordinates]
        self._A_t = np.ascontiguousarray(task.A.T)  # (3, m)
        # The samples of the desired trajectory are one flat array, ((order + 1) m,): derivative
        # k of the task coordinates at [k m, (k + 1) m), coordinate j at [j::m].
        m = task.m
        rows = [slice(k * m, (k + 1) * m) for k in range(order + 1)]
        self._split_rows = operator.itemgetter(*rows)
        self._columns = [slice(j, None, m) for j in range(m)]
        # A path in a plane (u, w) around c whose samples are a constant table applied to
        # (cos φ, sin φ): that table in task coordinates, ((order + 1) m, 2), and c - b.
        self._plane: tuple[Any, NDArray[np.float64], NDArray[np.float64]] | None = None
        path: Any = cycle.path
        if hasattr(path, "plane_table"):
            basis = path.axes @ self._A_t  # (2, m): task components of u and w
            table = np.einsum("kli,lj->kji", path.plane_table(order), basis)
            offset = path.centre @ self._A_t - task.b  # [m]
            self._plane = (path, np.ascontiguousarray(table.reshape(-1, 2)), offset)
            self._cos_sin = np.zeros(2)
        # For a circle, what desired() reads to sample it without calls: the table with the
        # offset on the positions as a third column, padded with -0.0 (x + (-0.0) is x for
        # every float, -0.0 included), so that one product with (cos φ, sin φ, 1) gives the
        # samples (bit for bit the product with (cos φ, sin φ) plus the offset), the angle
        # φ0 + ω t in the operations of CirclePath.angle and the buffer of (cos φ, sin φ, 1).
        self._circle: tuple[Any, ...] | None = None
        if type(path) is CirclePath and self._plane is not None:
            offset_padded = np.full((order + 1) * m, -0.0)
            offset_padded[:m] = self._plane[2]
            table = np.ascontiguousarray(np.column_stack((self._plane[1], offset_padded)))
            omega = 2.0 * math.pi / path.period  # [rad/s]
            self._circle = (table, path.start_angle, omega, np.array([0.0, 0.0, 1.0]))
        self.reset()

    def reset(self) -> None:
        """Back to the state at t = 0: every contact free, first approach in cycle 0."""
        n = len(self.contacts)
        # DesiredState's force and force derivatives when no contact is constrained.
        self._no_force = _read_only(np.zeros(n))
        self._no_force_derivatives = tuple(_read_only(np.zeros(n)) for _ in range(self.order - 2))
        # DesiredState's ``constrained`` when no contact is constrained (one shared value, so
        # that a law can tell it by identity).
        self.none_constrained = _read_only(np.zeros(n, dtype=bool))
        #: Whether ``events`` may hold a bit set since it was last cleared.
        self.events_pending = False
        self.phases = [Phase.FREE] * n
        self.depth = np.zeros(n)
        self.events = np.zeros(n, dtype=np.int64)
        self._cycle_index = [0] * n
        self._closed_since: list[float | None] = [None] * n
        self._takeoff_started = np.zeros(n)
        self._segments: list[TrajectorySegment] = [Nominal()] * self.task.m
        self._frozen = [False] * self.task.m
        self._schedule()

    def _schedule(self) -> None:
        """Cache what :meth:`desired` and :meth:`update` read from the phases and segments.

        Called whenever they may have changed (reset, end of an :meth:`update` that ran its
        checks): the coordinates off the nominal path, the contacts whose reference may be
        clipped, the constrained ones, and the time before which :meth:`update` has nothing to
        do while the contacts stay as they are (see :meth:`_due_time`).
        """
        size = self.order + 1
        self._off_nominal = [  # with the samples of a constant segment, computed once
            (
                self._columns[j],
                segment,
                segment(0.0, (0.0,) * size) if type(segment) is Constant else None,
                type(segment) not in _BLIND_SEGMENTS,
            )
            for j, segment in enumerate(self._segments)
            if type(segment) is not Nominal
        ]
        self._blind_nominal = (0.0,) * size  # what a segment blind to the nominal sample gets
        self._phase = overall_phase(self.phases)
        self.phase_value = int(self._phase)  # what a log records, computed once per change
        self.phase_values = _read_only(np.array(self.phases, dtype=np.int64))
        self._transiting_coordinates = [
            j for j, phase in zip(self._coordinate_list, self.phases) if phase in TRANSITION_PHASES
        ]
        held = [phase is Phase.CONSTRAINED for phase in self.phases]
        self._constrained = (
            _read_only(np.array(held, dtype=bool)) if any(held) else self.none_constrained
        )
        self._held = [  # each constrained contact, its phase and its takeoff time [s]
            (i, self.cycle.contact_phases[i], self.takeoff_time(i))
            for i, is_held in enumerate(held)
            if is_held
        ]
        # Before the first fall of a held contact's force starts, every force is its plateau:
        # the same values at every call (the smooth step is 0 there, see
        # DesiredCycle.desired_force_derivatives), computed once.
        self._plateau_until = -math.inf
        if self._held:
            fall_time = self.cycle.force_fall_time
            self._plateau_until = min(t_d for _, _, t_d in self._held) - fall_time
            self._plateau_until -= TIME_TOLERANCE
            force, derivatives = self._forces(self._plateau_until)
            self._plateau = (_read_only(force), tuple(map(_read_only, derivatives)))
        self._due, self._watched, self._expected = self._due_time()

    def _due_time(self) -> tuple[float, list[int], list[bool]]:
        """When :meth:`update` may next act, and on which contact closures it depends.

        Returns:
            The earliest time [s], up to :data:`TIME_TOLERANCE`, at which a time-triggered
            transition is due (an approach, a takeoff, the end of the rest time, of a takeoff
            or of a blend); the contacts whose closure matters and the closures that keep the
            phases as they are: an approaching contact that closes has its first impact, a
            transiting one that opens or closes restarts or starts its rest time, and with the
            takeoff rule a constrained one that opens leaves its constrained phase.
        """
        cycle = self.cycle
        times = [
            segment.t0 + segment.duration
            for segment in self._segments
            if type(segment) is BlendToNominal
        ]
        watched: list[int] = []
        expected: list[bool] = []
        for i, phase in enumerate(self.phases):
            if phase is Phase.FREE:
                times.append(self.approach_time(i))
            elif phase is Phase.TAKEOFF:
                times.append(float(self._takeoff_started[i]) + cycle.takeoff_time)
            else:
                times.append(self.takeoff_time(i))
            if phase is Phase.CONSTRAINED and self._ends_on_opening:
                watched.append(i)
                expected.append(True)
            elif phase is Phase.APPROACH:
                watched.append(i)
                expected.append(False)
            elif phase is Phase.TRANSITION:
                since = self._closed_since[i]
                watched.append(i)
                expected.append(since is not None)
                if since is not None:
                    times.append(since + cycle.rest_time)
        return min(times) - TIME_TOLERANCE, watched, expected

    @property
    def phase(self) -> Phase:
        """Phase of the cycle as a whole (see :func:`ucontrol.control.phase.overall_phase`)."""
        return self._phase

    def approach_time(self, i: int) -> float:
        r""":math:`\tau_0` of the current cycle of contact ``i`` in [s]."""
        phase = self.cycle.contact_phases[i]
        return self._cycle_index[i] * self.cycle.period + phase.start - self.cycle.approach_time

    def takeoff_time(self, i: int) -> float:
        """:math:`t_d` of the current cycle of contact ``i`` in [s]."""
        phase = self.cycle.contact_phases[i]
        return self._cycle_index[i] * self.cycle.period + phase.end

    def desired(self, t: float) -> DesiredState:
        """The desired trajectory at time ``t`` [s] in the current phases."""
        circle = self._circle
        if circle is not None:  # _nominal for a circle, inlined
            table, start_angle, omega, cos_sin_one = circle
            angle = start_angle + omega * t  # [rad]
            cos_sin_one[0], cos_sin_one[1] = math.cos(angle), math.sin(angle)
            samples = table.dot(cos_sin_one)  # (the method, without np.dot's dispatch)
        else:
            samples = self._nominal(t)
        for column, segment, fixed, reads_nominal in self._off_nominal:  # others stay nominal
            if fixed is not None:
                samples[column] = fixed
            elif reads_nominal:
                values = samples[column]
                values[:] = segment(t, tuple(values.tolist()))
            else:  # it reads only the sample's length
                samples[column] = segment(t, self._blind_nominal)
        target = self._split_rows(samples)
        reference = (target[0], target[1])
        if self._transiting_coordinates:  # gaps below the surface are clipped
            reference = self._reference(target)
        if not self._held:  # no force: shared read-only zeros
            force, force_derivatives = self._no_force, self._no_force_derivatives
        elif t < self._plateau_until:
            force, force_derivatives = self._plateau
        else:
            force, force_derivatives = self._forces(t)
        return DesiredState(target, reference, force, self._constrained, force_derivatives, samples)

    def _nominal(self, t: float) -> NDArray[np.float64]:
        r"""The nominal path and its derivatives at ``t`` [s] in task coordinates, ((order + 1) m,).

        A fresh flat array (derivative k at [k m, (k + 1) m)); for a planar path, one product of
        its constant table with :math:`(\cos\varphi, \sin\varphi)`.
        """
        if self._plane is not None:
            path, table, offset = self._plane
            angle = path.angle(t)
            cos_sin = self._cos_sin
            cos_sin[0], cos_sin[1] = math.cos(angle), math.sin(angle)
            samples = np.dot(table, cos_sin)
            position = samples[: self.task.m]
            position += offset
        else:
            samples = (np.array(self.cycle.path.derivatives(t, self.order)) @ self._A_t).ravel()
            position = samples[: self.task.m]
            position -= self.task.b
        return samples

    def _reference(self, target: tuple[Vector, ...]) -> tuple[Vector, Vector]:
        """Position and velocity of ``target``, the gaps of transiting contacts clipped at 0."""
        position, velocity = target[0], target[1]
        clipped = [j for j in self._transiting_coordinates if position[j] < 0.0]
        if clipped:
            position, velocity = position.copy(), velocity.copy()
            for j in clipped:
                position[j] = velocity[j] = 0.0
        return position, velocity

    def _forces(self, t: float) -> tuple[Vector, tuple[Vector, ...]]:
        """Desired forces [N] and their derivatives [N/s^k] at ``t`` [s], some contact held."""
        order, cycle = self.order, self.cycle
        if order == 2:  # λ_d alone, on Python floats (the values of the general branch)
            values = [0.0] * len(self.phases)
            for i, phase, t_d in self._held:
                values[i] = cycle.desired_force(phase, t, t_d)
            return np.array(values), ()
        rows = np.zeros((order - 1, len(self.phases)))  # λ_d and its k - 2 derivatives
        for i, phase, t_d in self._held:
            rows[:, i] = cycle.desired_force_derivatives(phase, t, t_d, order - 2)
        force, *derivatives = rows
        return force, tuple(derivatives)

    def update(self, t: float, closed: NDArray[np.bool_], V1: float, now: DesiredState) -> bool:
        r"""Advance the phases to time ``t``; return whether any event happened or phase changed.

        Returns at once while ``t`` is before every due time and no contact that matters has
        opened or closed (see :meth:`_due_time`).

        Args:
            t: Time in [s] (non-decreasing from call to call).
            closed: Whether each declared contact had a positive impulse over the last step,
                shape (n,).
            V1: The kinetic part of the law's Lyapunov function at ``t`` in [J] (sets the
                virtual depth at :math:`\tau_0`): :math:`\tfrac12 s^T \bar M s` for the rigid
                law, :math:`\tfrac12 s_1^T M s_1 + \tfrac12 s_2^T B s_2` for flexible joints.
            now: :meth:`desired` at ``t`` before the update (segments start from it).
        """
        if t < self._due:
            if not self._watched:
                return False
            flags = closed.tolist()
            if [flags[i] for i in self._watched] == self._expected:
                return False
        happened = self._advance(t, closed, V1, now)
        self._schedule()
        return happened

    def _advance(self, t: float, closed: NDArray[np.bool_], V1: float, now: DesiredState) -> bool:
        """The checks of :meth:`update`, one contact after the other."""
        cycle = self.cycle
        happened = False
        for j, segment in enumerate(self._segments):  # an ended blend is the nominal path
            if type(segment) is BlendToNominal and (t - segment.t0) / segment.duration >= 1.0:
                self._segments[j] = Nominal()
        for i, phase in enumerate(self.phases):
            j = self.coordinates[i]
            event = Event.NONE
            if phase is Phase.FREE and _reached(t, self.approach_time(i)):
                self.depth[i] = cycle.depth(V1)
                self._segments[j] = self._stop(t, now, j, -self.depth[i])
                self._frozen[j] = False  # its own transition now drives it
                self.phases[i] = Phase.APPROACH
                self._freeze(t, now)
                event = Event.TAU0
            elif phase in TRANSITION_PHASES and _reached(t, self.takeoff_time(i)):
                self._take_off(i, t)  # the contact was not reached or not settled in time
                event = Event.TAKEOFF
            elif phase is Phase.APPROACH and closed[i]:
                self.phases[i] = Phase.TRANSITION
                self._closed_since[i] = t
                event = Event.FIRST_IMPACT
            elif phase is Phase.TRANSITION:
                since = self._closed_since[i]
                if not closed[i]:
                    self._closed_since[i] = None
                elif since is None:
                    self._closed_since[i] = t
                elif _reached(t, since + cycle.rest_time):
                    self.phases[i] = Phase.CONSTRAINED
                    self._segments[j] = Constant(0.0)
                    self.depth[i] = 0.0
                    self._release(t)
                    event = Event.ACCUMULATION_END
            elif phase is Phase.CONSTRAINED and _reached(t, self.takeoff_time(i)):
                self._take_off(i, t)
                event = Event.TAKEOFF
            elif phase is Phase.CONSTRAINED and self._ends_on_opening and not closed[i]:
                if _reached(t, self.takeoff_time(i) - cycle.force_fall_time):  # λ_d falls
                    self._take_off(i, t)
                    event = Event.TAKEOFF
                else:  # lost before the fall: a new transition towards a virtual target
                    self.phases[i] = Phase.TRANSITION
                    self._closed_since[i] = None
                    self.depth[i] = cycle.depth_min
                    self._segments[j] = Constant(-self.depth[i])
                    happened = True
            elif phase is Phase.TAKEOFF and _reached(
                t, self._takeoff_started[i] + cycle.takeoff_time
            ):
                self.phases[i] = Phase.FREE
                self._segments[j] = Nominal()
                self._cycle_index[i] += 1
                self._freeze(t, now)
            if event:
                self.events[i] |= event
                self.events_pending = happened = True
        return happened

    def take_events(self) -> NDArray[np.int64]:
        """Events flagged since the last call, one :class:`Event` bit set per contact, (n,)."""
        events = self.events.copy()
        self.events[:] = 0
        self.events_pending = False
        return events

    def _take_off(self, i: int, t: float) -> None:
        was_transiting = self.phases[i] in TRANSITION_PHASES
        self.phases[i] = Phase.TAKEOFF
        self.depth[i] = 0.0
        self._takeoff_started[i] = t
        cycle = self.cycle
        if self.order == 2:
            parabola: TrajectorySegment = Parabola(t, cycle.takeoff_acceleration)
        else:
            parabola = SmoothParabola(
                t, cycle.takeoff_acceleration, cycle.takeoff_ramp_time, self.order - 2
            )
        self._segments[self.coordinates[i]] = self._blend(parabola, t, cycle.takeoff_time)
        if was_transiting:
            self._release(t)

    def _transiting(self) -> bool:
        return any(phase in TRANSITION_PHASES for phase in self.phases)

    def _freeze(self, t: float, now: DesiredState) -> None:
        """While a contact transits, stop every coordinate that follows the nominal path."""
        if not self._transiting():
            return
        busy = {self.coordinates[i] for i, ph in enumerate(self.phases) if ph is not Phase.FREE}
        for j in range(self.task.m):
            if j in busy or self._frozen[j]:
                continue
            p, dp = now.target[0][j], now.target[1][j]
            self._segments[j] = self._stop(t, now, j, p + 0.5 * dp * self.cycle.approach_time)
            self._frozen[j] = True

    def _release(self, t: float) -> None:
        """Once no contact transits, blend the frozen coordinates back into the nominal path."""
        if self._transiting():
            return
        for j, frozen in enumerate(self._frozen):
            if frozen:
                self._segments[j] = self._blend(self._segments[j], t, self.cycle.blend_time)
                self._frozen[j] = False

    def _stop(self, t: float, now: DesiredState, j: int, p1: float) -> TrajectorySegment:
        """Coordinate ``j`` from its sample in ``now`` to ``p1`` at rest over the approach time."""
        T = self.cycle.approach_time
        if self.order == 2:
            return RestCubic(t, float(now.target[0][j]), float(now.target[1][j]), float(p1), T)
        return RestHermite(t, tuple(float(x[j]) for x in now.target), p1, T)

    def _blend(self, base: TrajectorySegment, t: float, duration: float) -> BlendToNominal:
        """``base`` into the nominal path from ``t`` over ``duration`` [s], :math:`C^{order}`."""
        return BlendToNominal(base, t, duration, continuity=self.order)


def _read_only(array: NDArray[Any]) -> NDArray[Any]:
    """``array``, made read-only (a value shared between calls)."""
    array.flags.writeable = False
    return array


def _reached(t: float, time: float) -> bool:
    """Whether ``t`` [s] has reached ``time`` [s], up to :data:`TIME_TOLERANCE`."""
    return t >= time - TIME_TOLERANCE
