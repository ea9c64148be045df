r"""Distributions of Monte Carlo parameters: uniform, normal, log-uniform, choice.

Each run draws its parameters from its own generator,
``numpy.random.default_rng([seed, index])``, in the order the parameters are declared: the
values of run ``index`` depend only on the seed, the index and the declarations, so a campaign
extended with more runs keeps the values of the runs it had.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ucontrol.exceptions import DistributionError

#: Distribution names accepted in the ``type`` key of a ``[distributions]`` entry.
DISTRIBUTIONS = ("uniform", "normal", "log_uniform", "choice")
_KEYS = {
    "uniform": {"type", "low", "high"},
    "normal": {"type", "mean", "std", "low", "high"},
    "log_uniform": {"type", "low", "high"},
    "choice": {"type", "values", "weights"},
}


@dataclass(frozen=True)
class Distribution:
    r"""One parameter's distribution.

    Attributes:
        key: The dotted scene key it sets.
        kind: One of :data:`DISTRIBUTIONS`.
        low: Lower bound (uniform, log-uniform: support; normal: optional truncation).
        high: Upper bound, likewise.
        mean: Mean of a normal distribution.
        std: Standard deviation of a normal distribution (> 0).
        values: The values of a choice.
        weights: Probabilities of the values of a choice (normalised), or None: equal.
    """

    key: str
    kind: str
    low: float = -math.inf
    high: float = math.inf
    mean: float = 0.0
    std: float = 1.0
    values: tuple[Any, ...] = ()
    weights: tuple[float, ...] | None = None

    def sample(self, rng: np.random.Generator) -> Any:
        """One value drawn with ``rng`` (a float, or one of the choice's values)."""
        if self.kind == "uniform":
            return float(rng.uniform(self.low, self.high))
        if self.kind == "log_uniform":  # ln X ~ U[ln low, ln high]
            return float(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))
        if self.kind == "normal":  # truncated by rejection when bounds are given
            for _ in range(10_000):
                value = float(rng.normal(self.mean, self.std))
                if self.low <= value <= self.high:
                    return value
            raise DistributionError(self.key, "low/high", (self.low, self.high), "not so narrow")
        index = int(rng.choice(len(self.values), p=self.weights))
        return self.values[index]

    def representative(self) -> Any:
        """A value inside the support (to check the key before any run)."""
        if self.kind == "choice":
            return self.values[0]
        if self.kind == "normal":
            return float(min(max(self.mean, self.low), self.high))
        if self.kind == "log_uniform":
            return math.sqrt(self.low * self.high)
        return 0.5 * (self.low + self.high)


def parse_distribution(key: str, spec: Any) -> Distribution:
    """A checked :class:`Distribution` from its TOML table.

    Raises:
        DistributionError: Unknown type or keys, or parameters out of range (low >= high, a
            non-positive std or log-uniform bound, empty choice, bad weights).
    """
    if not isinstance(spec, Mapping):
        raise DistributionError(key, "distribution", spec, "a table with a `type` key")
    kind = spec.get("type")
    if kind == "log-uniform" or kind == "loguniform":
        kind = "log_uniform"
    if kind not in DISTRIBUTIONS:
        raise DistributionError(key, "type", spec.get("type"), f"one of {list(DISTRIBUTIONS)}")
    unknown = sorted(set(spec) - _KEYS[kind])
    if unknown:
        raise DistributionError(key, "keys", unknown, f"among {sorted(_KEYS[kind])}")
    if kind == "choice":
        values = spec.get("values")
        if not isinstance(values, Sequence) or isinstance(values, str) or not values:
            raise DistributionError(key, "values", values, "a non-empty list")
        weights = spec.get("weights")
        if weights is not None:
            w = np.array([_number(key, "weights", x) for x in _sequence(key, "weights", weights)])
            if w.shape != (len(values),) or (w < 0).any() or not w.sum() > 0:
                raise DistributionError(
                    key, "weights", weights, f"{len(values)} numbers >= 0 with a positive sum"
                )
            weights = tuple((w / w.sum()).tolist())
        return Distribution(key, kind, values=tuple(values), weights=weights)
    if kind == "normal":
        mean = _number(key, "mean", _require(key, spec, "mean"))
        std = _number(key, "std", _require(key, spec, "std"))
        if not std > 0:
            raise DistributionError(key, "std", std, "> 0")
        low = _number(key, "low", spec.get("low", -math.inf), finite=False)
        high = _number(key, "high", spec.get("high", math.inf), finite=False)
        if not low < high:
            raise DistributionError(key, "high", high, f"> low = {low!r}")
        if not low <= mean <= high:
            raise DistributionError(key, "mean", mean, f"in [low, high] = [{low!r}, {high!r}]")
        return Distribution(key, kind, mean=mean, std=std, low=low, high=high)
    low = _number(key, "low", _require(key, spec, "low"))
    high = _number(key, "high", _require(key, spec, "high"))
    if kind == "log_uniform" and not low > 0:
        raise DistributionError(key, "low", low, "> 0 for a log-uniform distribution")
    if not high > low:
        raise DistributionError(key, "high", high, f"> low = {low!r}")
    return Distribution(key, kind, low=low, high=high)


def _require(key: str, spec: Mapping[str, Any], name: str) -> Any:
    if name not in spec:
        raise DistributionError(key, name, None, f"given for a {spec['type']} distribution")
    return spec[name]


def _sequence(key: str, name: str, value: Any) -> Sequence[Any]:
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise DistributionError(key, name, value, "a list")
    return value


def _number(key: str, name: str, value: Any, *, finite: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise DistributionError(key, name, value, "a number")
    number = float(value)
    if math.isnan(number) or (finite and not math.isfinite(number)):
        raise DistributionError(key, name, value, "a finite number")
    return number
