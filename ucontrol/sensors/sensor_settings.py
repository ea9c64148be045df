"""The ``[sensors]`` and ``[actuators]`` tables of a scene: what the controller sees and does.

Declared only by scenes that want them: without the tables the controller reads the plant's
true state and its torques are applied as they are (nothing of :mod:`ucontrol.sensors` is
imported then).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_non_negative, as_positive, as_vector, check_keys
from ucontrol.exceptions import InvalidParameterError, ShapeError

#: How the controller's velocity is obtained (see :class:`SensorSettings`).
VELOCITY_SOURCES = ("true", "difference", "observer")

#: What tells the controller about its contacts (see :class:`SensorSettings`).
CONTACT_OBSERVERS = ("oracle", "momentum")

_SENSOR_KEYS = {
    "position_noise",
    "quantisation",
    "velocity",
    "velocity_cutoff",
    "delay",
    "force_noise",
    "seed",
    "observer",
    "observer_gain",
    "impact_threshold",
    "contact_gap",
    "force_threshold",
}
_ACTUATOR_KEYS = {"torque_limit", "rate_limit"}


def _non_negative(name: str, value: Any) -> float | NDArray[np.float64]:
    """A number or a vector of numbers, each finite and >= 0."""
    array = (
        np.array(as_float(name, value))
        if np.isscalar(value) and not isinstance(value, bool)
        else as_vector(name, value)
    )
    if isinstance(value, bool) or not np.all(array >= 0.0):
        raise InvalidParameterError(name, value, "a number >= 0 or a list of them")
    return float(array) if array.ndim == 0 else array


def _check_size(name: str, value: float | NDArray[np.float64] | None, size: int) -> None:
    """A vector ``value`` has ``size`` entries (a number or None applies to all)."""
    if isinstance(value, np.ndarray) and value.shape != (size,):
        raise ShapeError(name, (size,), value.shape)


@dataclass(frozen=True, kw_only=True)
class SensorSettings:
    r"""What the controller measures, and how.

    The controller is called with measured signals; the log keeps them (``measured_q``,
    ``measured_v``) beside the true ``q`` and ``v``.

    Attributes:
        position_noise: Standard deviation of a white Gaussian noise on the position
            measurement, in [rad] or [m]: one number or one per velocity coordinate
            (nv, + nf motors with flexible joints), applied in the tangent space
            (:math:`q_m = q \oplus \delta`).
        quantisation: Encoder resolution in [rad] or [m] (one number or one per velocity
            coordinate): positions of one-coordinate joints (revolute, prismatic) and motors
            are rounded to a multiple of it; 0 for none.
        velocity: ``"true"`` (the plant's velocity, with no noise), ``"difference"`` (finite
            difference of the measured positions over the control period, low-pass filtered),
            or ``"observer"`` (the same filter re-initialised at impacts: those of the plant
            with ``observer = "oracle"``, those the momentum observer flags with
            ``"momentum"``; see :class:`~ucontrol.sensors.measurement.Sensors`).
        velocity_cutoff: Cut-off frequency of the velocity filter in [Hz]; None: no filter.
        delay: Measurement delay in control periods (an integer >= 0): the controller at
            period k sees the measurement of period k - delay.
        force_noise: Standard deviation of a white Gaussian noise on each constraint's
            measured mean force, in [N] (the impulses the controller sees get it times the
            period).
        seed: Seed of the noise generator (the same seed gives the same noise).
        observer: Where the contact information the controller sees (each constraint's impulse
            over the period and its active flag) comes from. ``"oracle"``: the plant's own
            impulses and active sets (with ``force_noise``), which no real robot has.
            ``"momentum"``: a generalized-momentum observer
            (:class:`~ucontrol.sensors.momentum_observer.MomentumObserver`) on the measured
            positions, the velocity of ``velocity`` (the raw difference of the measured
            positions with ``"observer"``) and the torque applied, on the
            controller's own model; the constraints whose measured gap is at most
            ``contact_gap`` share its residual by least squares, and those whose estimated
            force exceeds ``force_threshold`` are active and carry it times the period.
        observer_gain: Bandwidth K_o of the momentum observer in [1/s].
        impact_threshold: Jump of the momentum observer's residual over one period above which
            an impact is declared, in [N m].
        contact_gap: Largest measured gap in [m] (or [rad] for stops) of a constraint the
            momentum observer may find closed.
        force_threshold: Smallest estimated force in [N] (or [N m] on stops) of a constraint
            the momentum observer finds closed: above the residual's bias and noise (the
            two-link arm approaching the ground at 0.11 m/s shows 3.5e-4 N, noiseless).
    """

    position_noise: float | NDArray[np.float64] = 0.0
    quantisation: float | NDArray[np.float64] = 0.0
    velocity: str = "true"
    velocity_cutoff: float | None = None
    delay: int = 0
    force_noise: float = 0.0
    seed: int = 0
    observer: str = "oracle"
    observer_gain: float = 50.0
    impact_threshold: float = 1.0
    contact_gap: float = 1e-4
    force_threshold: float = 0.1

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "position_noise", _non_negative("position_noise", self.position_noise)
        )
        object.__setattr__(self, "quantisation", _non_negative("quantisation", self.quantisation))
        if self.velocity not in VELOCITY_SOURCES:
            raise InvalidParameterError("velocity", self.velocity, f"one of {VELOCITY_SOURCES}")
        if self.velocity_cutoff is not None:
            cutoff = as_float("velocity_cutoff", self.velocity_cutoff)
            if not cutoff > 0.0:
                raise InvalidParameterError("velocity_cutoff", cutoff, "a frequency > 0 in [Hz]")
            object.__setattr__(self, "velocity_cutoff", cutoff)
        if isinstance(self.delay, bool) or not isinstance(self.delay, int) or self.delay < 0:
            raise InvalidParameterError("delay", self.delay, "a whole number of periods >= 0")
        force_noise = _non_negative("force_noise", self.force_noise)
        if not isinstance(force_noise, float):
            raise InvalidParameterError("force_noise", self.force_noise, "one number >= 0 in [N]")
        object.__setattr__(self, "force_noise", force_noise)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidParameterError("seed", self.seed, "a whole number >= 0")
        self._check_observer()

    def _check_observer(self) -> None:
        """The contact observer's settings, and what it cannot be combined with."""
        if self.observer not in CONTACT_OBSERVERS:
            raise InvalidParameterError("observer", self.observer, f"one of {CONTACT_OBSERVERS}")
        object.__setattr__(self, "observer_gain", as_positive("observer_gain", self.observer_gain))
        object.__setattr__(
            self, "impact_threshold", as_positive("impact_threshold", self.impact_threshold)
        )
        object.__setattr__(self, "contact_gap", as_non_negative("contact_gap", self.contact_gap))
        object.__setattr__(
            self, "force_threshold", as_non_negative("force_threshold", self.force_threshold)
        )
        if self.observer != "momentum":
            return
        if self.force_noise > 0.0:
            raise InvalidParameterError(
                "force_noise", self.force_noise, "0 with observer = 'momentum' (no force sensor)"
            )

    def check_sizes(self, n_measured: int) -> None:
        """Each per-coordinate vector holds ``n_measured`` values (nv, + nf motors).

        Raises:
            ShapeError: ``position_noise`` or ``quantisation`` has another length.
        """
        _check_size("position_noise", self.position_noise, n_measured)
        _check_size("quantisation", self.quantisation, n_measured)

    def check_delay(self, periods: int) -> None:
        """The delay is shorter than a run of ``periods`` control periods.

        Raises:
            InvalidParameterError: ``delay`` >= ``periods`` (the controller would only ever
                see the initial measurement).
        """
        if self.delay >= periods:
            raise InvalidParameterError(
                "delay", self.delay, f"fewer control periods than the run holds ({periods})"
            )

    @classmethod
    def from_table(cls, table: Mapping[str, Any]) -> SensorSettings:
        """The settings of a ``[sensors]`` table (keys as the attributes)."""
        check_keys("[sensors]", table, _SENSOR_KEYS)
        return cls(**table)


@dataclass(frozen=True, kw_only=True)
class ActuatorSettings:
    """What the actuators can do: torque saturation and rate limits.

    The plant receives the limited torque (the log's ``u``); the controller's output is kept
    as ``commanded_u``.

    Attributes:
        torque_limit: Largest magnitude of u per input in [N m] or [N]: ``"urdf"`` (the joints'
            ``effort`` limits), one number, or one per input (nu,); None: no saturation.
        rate_limit: Largest change of the torque in [N m/s] (or [N/s]), one number or one per
            input; None: no limit. Applied per control period, from zero torque at t = 0.
    """

    torque_limit: str | float | NDArray[np.float64] | None = None
    rate_limit: float | NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        if self.torque_limit is not None and self.torque_limit != "urdf":
            object.__setattr__(
                self, "torque_limit", _non_negative("torque_limit", self.torque_limit)
            )
        if self.rate_limit is not None:
            rate_limit = _non_negative("rate_limit", self.rate_limit)
            if not np.all(np.asarray(rate_limit) > 0.0):  # 0 would hold every torque at 0
                raise InvalidParameterError(
                    "rate_limit", self.rate_limit, "a number > 0 or a list of them"
                )
            object.__setattr__(self, "rate_limit", rate_limit)

    def check_sizes(self, nu: int) -> None:
        """Each per-input vector holds ``nu`` values.

        Raises:
            ShapeError: ``torque_limit`` or ``rate_limit`` has another length.
        """
        if not isinstance(self.torque_limit, str):
            _check_size("torque_limit", self.torque_limit, nu)
        _check_size("rate_limit", self.rate_limit, nu)

    @classmethod
    def from_table(cls, table: Mapping[str, Any]) -> ActuatorSettings:
        """The settings of an ``[actuators]`` table (keys as the attributes)."""
        check_keys("[actuators]", table, _ACTUATOR_KEYS)
        return cls(**table)
