r"""The designed cycle: nominal path, contact phases, approach, desired force and takeoff.

The *nominal path* is periodic and may cross the obstacles. During a declared contact phase
of a contact its gap coordinate is held on the surface (:math:`X_{1d} = 0`) with a desired
contact force :math:`\lambda_d(t)`, which is the projection of the nominal path on the surface;
everywhere else the nominal path must stay on the free side. Around each contact phase the
designer sets how the transition is made: the approach time before the nominal arrival
(:math:`\tau_0`), the depth of the virtual target (scaled by the Lyapunov function
:math:`V_1(\tau_0)`), how long the contact must stay closed to call the impacts accumulated,
the fall of :math:`\lambda_d` to 0 at the takeoff time :math:`t_d` and the takeoff itself.
"""

from __future__ import annotations

import hashlib
import json
import math
import pickle
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import (
    as_bool,
    as_float,
    as_in_interval,
    as_non_negative,
    as_positive,
)
from ucontrol.control.task_coordinates import TaskCoordinates
from ucontrol.control.trajectory_segment import smooth_step
from ucontrol.exceptions import (
    InvalidParameterError,
    NotFoundError,
    PathThroughSurfaceError,
    SceneError,
)

if TYPE_CHECKING:
    from ucontrol.control.spline_path import SplinePath

Vector = NDArray[np.float64]

#: A nominal path deeper than this inside an obstacle, in [m], needs a contact phase there.
PATH_TOLERANCE = 1e-6
#: Samples per period used to check the nominal path against the obstacles.
PATH_SAMPLES = 4000
#: Nominal paths whose samples :meth:`DesiredCycle.check` keeps (least recently used out).
PATH_SAMPLES_KEPT = 16
#: The samples of the nominal paths checked so far, by SHA-256 of the pickled path and times.
_path_samples: OrderedDict[str, NDArray[np.float64]] = OrderedDict()
_path_samples_lock = threading.Lock()
#: The values of ``DesiredCycle.force_profile``.
FORCE_PROFILES = ("state", "time")
#: The values of ``DesiredCycle.reference_after_impact``.
REFERENCES_AFTER_IMPACT = ("clipped", "virtual")


class NominalPath(Protocol):
    """A periodic path of the tracked frame in the world frame (e.g. :class:`CirclePath`)."""

    @property
    def period(self) -> float:
        """Period P in [s]."""
        ...

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at ``t`` [s], each (3,)."""
        ...

    def derivatives(self, t: float, order: int) -> tuple[Vector, ...]:
        """Position [m] and its first ``order`` time derivatives at ``t`` [s], each (3,)."""
        ...


@dataclass(frozen=True, kw_only=True)
class ContactPhase:
    r"""A declared contact of the cycle.

    Attributes:
        contact: Name of the point contact (a :class:`ucontrol.contact.PointContact` name).
        start: Nominal arrival on the surface, in [s] from the start of the period.
        end: Takeoff time :math:`t_d`, in [s] from the start of the period.
        force: Plateau of the desired contact force :math:`\lambda_d` in [N], > 0.
    """

    contact: str
    start: float
    end: float
    force: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "start", as_float("start", self.start))
        object.__setattr__(self, "end", as_float("end", self.end))
        object.__setattr__(self, "force", as_positive("force", self.force))
        if not self.end > self.start:
            raise InvalidParameterError("end", self.end, f"> start = {self.start}")

    def covers(self, t: NDArray[np.float64], period: float) -> NDArray[np.bool_]:
        """Whether times ``t`` [s] (any shape) fall in this phase, modulo ``period``."""
        return np.mod(t - self.start, period) <= self.end - self.start


@dataclass(frozen=True, kw_only=True)
class DesiredCycle:
    r"""Everything the phase machine needs to build the desired trajectory.

    Attributes:
        path: The nominal path; its period is the cycle's period P.
        contact_phases: One declared contact phase per contact that is touched in a cycle.
        approach_time: :math:`t_{start} - \tau_0` in [s]: the approach starts this long before
            the nominal arrival and reaches the virtual target at rest after as long.
        depth_gain: α of the virtual depth :math:`d = \alpha V_1(\tau_0)^p`, in [m J^-p].
        depth_exponent: p of the virtual depth, in (0, 1] (1: the book's φ V1, 1/2: α √V1).
        depth_min: Smallest virtual depth :math:`d_{min}` in [m], >= 0: above 0, contact is
            reached in finite time even after perfect tracking; with 0 (the book's
            :math:`d = \alpha V_1(\tau_0)^p` unclipped below) a cycle tracked perfectly
            reaches the surface only asymptotically, and the takeoff at :math:`t_d` then
            starts without a constrained phase.
        depth_max: Largest virtual depth in [m].
        rest_time: The impacts have accumulated (:math:`t_f`) once the contact stayed closed
            (a positive impulse every step) for this long, in [s].
        force_fall_time: :math:`\lambda_d` falls smoothly from its plateau to 0 over the
            last ``force_fall_time`` [s] before :math:`t_d`.
        takeoff_acceleration: Second derivative [m/s²] > 0 of the normal desired coordinate at
            :math:`t_d` (where it is 0 with zero velocity).
        takeoff_time: Duration in [s] of the blend from the takeoff parabola into the nominal
            path.
        takeoff_ramp_time: For a law that holds more than 2 derivatives of the desired
            trajectory (the flexible-joint law), the takeoff parabola starts with zero
            acceleration at :math:`t_d` and its acceleration rises smoothly to
            ``takeoff_acceleration`` over this time, in [s]
            (:class:`ucontrol.control.trajectory_segment.SmoothParabola`).
        blend_time: Duration in [s] of the blend of coordinates frozen during a transition
            back into the nominal path, from :math:`t_f`.
        force_profile: How :math:`\lambda_d` of the constrained phase is made:
            ``"time"`` (default), the profile of :meth:`desired_force` (plateau, then a
            smooth fall to 0 at :math:`t_d`); ``"state"``, designed from the state at each
            call so that the contact force the law produces is that profile (book §8.1.4,
            and the flexible-joint law on its link law; docs/controller.md, "The desired
            contact force").
        reference_after_impact: What the rigid law builds :math:`\dot q_r` on from the first
            impact to :math:`t_f`: ``"virtual"`` (default), the virtual target, as
            :math:`\bar s`; ``"clipped"``, the target clipped at the surface, as the book does
            (docs/controller.md, "After the first impact").
        takeoff_on_opening: Whether the constrained phase ends when its contact is measured
            open (no positive force over the last control period): during the fall of
            :math:`\lambda_d` the takeoff starts then, before it back to the transition
            (docs/impact_control.md, "Takeoff on opening"). None (default): on with the state
            profile, off with the time profile (see :attr:`ends_on_opening`).
    """

    path: NominalPath
    contact_phases: tuple[ContactPhase, ...]
    approach_time: float = 0.8
    depth_gain: float = 10.0
    depth_exponent: float = 0.5
    depth_min: float = 0.01
    depth_max: float = 0.05
    rest_time: float = 0.01
    force_fall_time: float = 0.5
    takeoff_acceleration: float = 1.0
    takeoff_time: float = 0.4
    takeoff_ramp_time: float = 0.1
    blend_time: float = 0.8
    force_profile: str = "time"
    reference_after_impact: str = "virtual"
    takeoff_on_opening: bool | None = None

    def __post_init__(self) -> None:
        for name in (
            "approach_time",
            "depth_gain",
            "depth_max",
            "rest_time",
            "force_fall_time",
            "takeoff_acceleration",
            "takeoff_time",
            "takeoff_ramp_time",
            "blend_time",
        ):
            object.__setattr__(self, name, as_positive(name, getattr(self, name)))
        object.__setattr__(self, "depth_min", as_non_negative("depth_min", self.depth_min))
        if self.reference_after_impact not in REFERENCES_AFTER_IMPACT:
            raise InvalidParameterError(
                "reference_after_impact",
                self.reference_after_impact,
                f"one of {list(REFERENCES_AFTER_IMPACT)}",
            )
        if self.force_profile not in FORCE_PROFILES:
            raise InvalidParameterError(
                "force_profile", self.force_profile, f"one of {list(FORCE_PROFILES)}"
            )
        if self.takeoff_on_opening is not None:
            opening = as_bool("takeoff_on_opening", self.takeoff_on_opening)
            object.__setattr__(self, "takeoff_on_opening", opening)
        object.__setattr__(
            self, "depth_exponent", as_in_interval("depth_exponent", self.depth_exponent, 0, 1)
        )
        if self.depth_exponent == 0.0:
            raise InvalidParameterError("depth_exponent", 0.0, "in (0, 1]")
        if self.depth_max < self.depth_min:
            raise InvalidParameterError("depth_max", self.depth_max, f">= {self.depth_min}")
        phases = tuple(self.contact_phases)
        object.__setattr__(self, "contact_phases", phases)
        if not phases:
            raise InvalidParameterError("contact_phases", phases, "at least one contact phase")
        names = [phase.contact for phase in phases]
        if len(set(names)) != len(names):
            raise InvalidParameterError("contact_phases", names, "one phase per contact")
        period = self.period
        for phase in phases:
            if phase.start < self.approach_time or phase.end > period:
                raise InvalidParameterError(
                    f"contact phase of {phase.contact!r}",
                    (phase.start, phase.end),
                    f"approach_time = {self.approach_time} <= start < end <= period = {period}",
                )
            gap = period + phase.start - self.approach_time - phase.end - self.takeoff_time
            if gap < 0.0:
                raise InvalidParameterError(
                    f"contact phase of {phase.contact!r}",
                    (phase.start, phase.end),
                    "a takeoff that ends before the next approach starts "
                    f"(end + takeoff_time <= period + start - approach_time; short by {-gap} s)",
                )

    @property
    def period(self) -> float:
        """Period P of the cycle in [s]."""
        return float(self.path.period)

    @property
    def ends_on_opening(self) -> bool:
        """Whether the takeoff rule is on: ``takeoff_on_opening``, or the state profile's."""
        if self.takeoff_on_opening is None:
            return self.force_profile == "state"
        return self.takeoff_on_opening

    def depth(self, V1: float) -> float:
        r"""Virtual depth :math:`d = \mathrm{clip}(\alpha V_1^p, d_{min}, d_{max})` in [m].

        Args:
            V1: :math:`V_1(\tau_0) = \tfrac12 s^T \bar M s` in [J].
        """
        raw = self.depth_gain * max(V1, 0.0) ** self.depth_exponent
        return min(max(raw, self.depth_min), self.depth_max)

    def desired_force(self, phase: ContactPhase, t: float, t_d: float) -> float:
        r""":math:`\lambda_d(t)` in [N]: the plateau, then a smooth fall to 0 at ``t_d``.

        Args:
            phase: The contact phase.
            t: Time in [s].
            t_d: Takeoff time of the current cycle in [s].
        """
        return self.desired_force_derivatives(phase, t, t_d, 0)[0]

    def desired_force_derivatives(
        self, phase: ContactPhase, t: float, t_d: float, order: int
    ) -> tuple[float, ...]:
        r""":math:`\lambda_d` [N] and its first ``order`` time derivatives [N/s^k] at ``t`` [s].

        :math:`\lambda_d = F (1 - \beta(\sigma))`, :math:`\sigma = (t - t_d)/T_f + 1`, so
        :math:`\lambda_d^{(k)} = -F \beta^{(k)}(\sigma) / T_f^k` (see :func:`smooth_step`).

        Args:
            phase: The contact phase.
            t: Time in [s].
            t_d: Takeoff time of the current cycle in [s].
            order: Number of derivatives, >= 0.
        """
        T, force = self.force_fall_time, phase.force
        beta = smooth_step((t - t_d) / T + 1.0, order)
        return (force * (1.0 - beta[0]), *[-force * beta[k] / T**k for k in range(1, order + 1)])

    def check(self, task: TaskCoordinates) -> None:
        """Check the cycle against the task: known contacts, no path through an obstacle.

        The path is sampled at :data:`PATH_SAMPLES` times over a period; the samples are kept
        per path content (:func:`sampled_positions`), so that an equal path (a controller built
        again from the same table) is not sampled again.

        Raises:
            NotFoundError: A contact phase names a contact that is not a task constraint.
            PathThroughSurfaceError: The nominal path enters an obstacle deeper than
                :data:`PATH_TOLERANCE` outside the contact phases of that obstacle.
        """
        gap_names = task.names[: task.n_gaps]
        for phase in self.contact_phases:
            if phase.contact not in gap_names:
                raise NotFoundError("contact", phase.contact, gap_names)
        t = np.linspace(0.0, self.period, PATH_SAMPLES, endpoint=False)
        X = sampled_positions(self.path, t) @ task.A.T - task.b  # task.of_point of each sample
        for i, name in enumerate(gap_names):
            inside = X[:, i] < -PATH_TOLERANCE
            for phase in self.contact_phases:
                if phase.contact == name:
                    inside &= ~phase.covers(t, self.period)
            if inside.any():
                worst = int(np.argmin(np.where(inside, X[:, i], math.inf)))
                raise PathThroughSurfaceError(name, float(t[worst]), float(X[worst, i]))


def sampled_positions(path: NominalPath, t: NDArray[np.float64]) -> NDArray[np.float64]:
    """Positions in [m] of ``path`` at the times ``t`` [s], shape (len(t), 3).

    Kept per path content and times: a path equal to one sampled before (the same pickled
    form: its class and every attribute, arrays bit for bit) reuses its samples, so that the
    controllers a campaign builds run after run from one scene table sample their cycle once
    per process (at most :data:`PATH_SAMPLES_KEPT` paths kept, the least recently used out).
    The array returned is read-only. A path that cannot be pickled is sampled at every call.
    """
    try:
        content = pickle.dumps(path, protocol=pickle.HIGHEST_PROTOCOL)
    except (pickle.PicklingError, TypeError, AttributeError):
        key = None
    else:
        key = hashlib.sha256(content + t.tobytes()).hexdigest()
        with _path_samples_lock:
            found = _path_samples.get(key)
            if found is not None:
                _path_samples.move_to_end(key)
                return found
    positions = np.array([path(float(time))[0] for time in t], dtype=float).reshape(t.size, 3)
    positions.flags.writeable = False
    if key is not None:
        with _path_samples_lock:
            _path_samples[key] = positions
            while len(_path_samples) > PATH_SAMPLES_KEPT:
                _path_samples.popitem(last=False)
    return positions


def read_designed_cycle(path: str | Path) -> tuple[SplinePath, ContactPhase]:
    """The nominal path and contact phase of a designed cycle file.

    The file is the one :meth:`ucontrol.design.DesignedCycle.save` writes (``NAME.npz`` with
    the arrays beside ``NAME.json``); read here, below the design layer, so that a scene's
    controller takes it without casadi. The nominal path is the periodic quintic spline
    (:class:`SplinePath`, :math:`C^4`) through the tracked frame's positions at the design's
    nodes, the contact phase runs from the first landing to the end of the period (the takeoff)
    with the task's force plateau: what :meth:`ucontrol.design.DesignedCycle.desired_cycle`
    gives.

    Args:
        path: The ``.npz`` file, the ``.json`` file or their common stem.

    Returns:
        The nominal path and the contact phase.

    Raises:
        SceneError: A file is missing or does not hold a designed cycle.
    """
    npz = Path(path).with_suffix(".npz")
    meta_path = npz.with_suffix(".json")
    if not npz.is_file() or not meta_path.is_file():
        raise SceneError(f"designed cycle {str(npz)!r} (and its .json) does not exist")
    try:
        meta = json.loads(meta_path.read_text())
        with np.load(npz) as data:
            phases = range(len(meta["phases"]))
            times = [np.asarray(data[f"phase{i}_t"], dtype=float) for i in phases]
            positions = [np.asarray(data[f"phase{i}_position"], dtype=float) for i in phases]
        contact, force = str(meta["contact"]), float(meta["force"])
    except (KeyError, ValueError, TypeError, OSError) as error:
        raise SceneError(f"{str(npz)!r} is not a designed cycle: {error!r}") from error
    period = float(times[-1][-1] - times[0][0])
    from ucontrol.control.spline_path import SplinePath  # scipy.interpolate: on first use

    path_ = SplinePath(
        waypoints=np.vstack([p[:-1] for p in positions]),
        times=np.concatenate([t[:-1] for t in times]) - times[0][0],
        period=period,
    )
    landing = float(times[0][-1] - times[0][0])
    return path_, ContactPhase(contact=contact, start=landing, end=period, force=force)
