"""Metrics of a campaign run: ``summary.json`` keys, weak-stability verdicts, user functions.

A metric is named by a string:

- a key of ``summary.json``, dotted into its tables and arrays: ``max_penetration``,
  ``tracking.free_error_max``, ``weak_stability.n_complete_cycles``,
  ``weak_stability.V_tau0.1``;
- a verdict of :mod:`ucontrol.analysis.weak_stability` (runs of a phase-machine controller),
  see :data:`VERDICTS`;
- a user function ``module:function`` (``package.module:function``), called with the
  :class:`ucontrol.simulate.SimulationResult` and returning a number or a boolean. The module is
  imported from the campaign file's folder or from the installed packages.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

from ucontrol._validation import import_callable
from ucontrol.exceptions import UnknownMetricError, UserFunctionError


def _cycles(summary: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    return list(summary["weak_stability"]["cycles"])


def _V_tau0_decreasing(summary: Mapping[str, Any]) -> bool:
    values = summary["weak_stability"]["V_tau0"]
    return all(b <= a for a, b in pairwise(values))


def _cycles_complete(summary: Mapping[str, Any]) -> bool:
    cycles = _cycles(summary)
    return bool(cycles) and all(cycle["complete"] for cycle in cycles)


def _max_transition_rise(summary: Mapping[str, Any]) -> float:
    rises = [c["transition_rise"] for c in _cycles(summary) if c["transition_rise"] is not None]
    return max(rises, default=math.nan)


def _max_V_tau0_ratio(summary: Mapping[str, Any]) -> float:
    ratios = [r for r in summary["weak_stability"]["V_tau0_ratio"] if r is not None]
    return max(ratios, default=math.nan)


#: Verdicts computed from the ``weak_stability`` table of a phase-machine run's summary:
#: ``cycles_complete`` (at least one cycle, every contact settled and took off in each),
#: ``V_tau0_decreasing`` (V(τ0^{k+1}) <= V(τ0^k) for every k), ``weakly_stable`` (both),
#: ``max_transition_rise`` (largest rise of V over a transition I_k, [J]) and
#: ``max_V_tau0_ratio`` (largest V(τ0^{k+1}) / V(τ0^k); NaN with fewer than two cycles).
VERDICTS: dict[str, Callable[[Mapping[str, Any]], Any]] = {
    "weak_stability.cycles_complete": _cycles_complete,
    "weak_stability.V_tau0_decreasing": _V_tau0_decreasing,
    "weak_stability.weakly_stable": lambda s: _cycles_complete(s) and _V_tau0_decreasing(s),
    "weak_stability.max_transition_rise": _max_transition_rise,
    "weak_stability.max_V_tau0_ratio": _max_V_tau0_ratio,
}


@dataclass(frozen=True)
class Metric:
    """One column of the campaign table.

    Attributes:
        name: The column name.
        spec: What it measures: a dotted summary key, a verdict name or ``module:function``.
    """

    name: str
    spec: str

    @property
    def is_function(self) -> bool:
        """Whether the metric is a user function (``module:function``)."""
        return ":" in self.spec

    def evaluate(self, result: Any, python_path: tuple[str, ...] = ()) -> Any:
        """The metric's value for a finished run (None when the summary lacks it).

        Args:
            result: The run's :class:`ucontrol.simulate.SimulationResult`.
            python_path: Folders searched first for the module of a user function.
        """
        if self.is_function:
            value = import_function(self.spec, python_path)(result)
            return _scalar(self.spec, value)
        if self.spec in VERDICTS:
            if "weak_stability" not in result.summary:
                return None
            return _scalar(self.spec, VERDICTS[self.spec](result.summary))
        return _scalar(self.spec, resolve(result.summary, self.spec))


def import_function(spec: str, python_path: tuple[str, ...] = ()) -> Callable[[Any], Any]:
    """The function named ``module:function``.

    Raises:
        UnknownMetricError: The module cannot be imported or has no such callable.
    """
    try:
        return import_callable(spec, python_path)
    except UserFunctionError as error:
        raise UnknownMetricError(spec, error.reason) from error


def resolve(summary: Mapping[str, Any], path: str) -> Any:
    """The value of a dotted key in a summary, or None when a part is missing."""
    node: Any = summary
    for part in path.split("."):
        if isinstance(node, Mapping) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node


def check_metric(metric: Metric, summary: Mapping[str, Any], python_path: tuple[str, ...]) -> None:
    """Check that a metric exists for a scene whose (short-run) summary is ``summary``.

    Raises:
        UnknownMetricError: Naming the metric and listing the scalar keys available.
    """
    if metric.is_function:
        import_function(metric.spec, python_path)
        return
    if metric.spec in VERDICTS:
        if "weak_stability" not in summary:
            raise UnknownMetricError(
                metric.spec, "weak-stability verdicts need a phase-machine (brogliato) controller"
            )
        return
    node: Any = summary
    parts = metric.spec.split(".")
    for depth, part in enumerate(parts):
        if isinstance(node, list):  # array lengths depend on the run: indices are not checked
            if all(p.isdigit() for p in parts[depth:]):
                return
            break
        if not isinstance(node, Mapping) or part not in node:
            break
        node = node[part]
    else:
        if not isinstance(node, Mapping | list):
            return
        raise UnknownMetricError(
            metric.spec, "it is a table or an array, not a number", scalar_keys(summary)
        )
    raise UnknownMetricError(
        metric.spec, "not a summary.json key nor a verdict", [*scalar_keys(summary), *VERDICTS]
    )


def scalar_keys(summary: Mapping[str, Any], prefix: str = "") -> list[str]:
    """The dotted keys of the scalar entries of a summary (tables walked, arrays not)."""
    keys = []
    for key, value in summary.items():
        if isinstance(value, Mapping):
            keys.extend(scalar_keys(value, f"{prefix}{key}."))
        elif not isinstance(value, list):
            keys.append(f"{prefix}{key}")
    return keys


def _scalar(spec: str, value: Any) -> Any:
    """A metric value as a JSON scalar: bool, int, float, str or None."""
    if value is None or isinstance(value, bool | int | str):
        return value
    if hasattr(value, "item") and getattr(value, "size", 1) == 1:  # numpy scalar
        return value.item()
    if isinstance(value, float):
        return value
    raise TypeError(f"metric {spec!r} returned {type(value).__name__}, not a number")
