"""A ``[controller.path]`` table -> a nominal path (circle, segment, polyline, spline)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from ucontrol._validation import check_keys, require_key
from ucontrol.control.circle_path import CirclePath
from ucontrol.control.desired_cycle import NominalPath
from ucontrol.control.polyline_path import PolylinePath
from ucontrol.control.segment_path import SegmentPath
from ucontrol.control.spline_path import SplinePath
from ucontrol.exceptions import InvalidParameterError

#: Keys of each path type: (required, optional).
PATH_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "circle": (("centre", "radius", "period"), ("axes", "start_angle")),
    "segment": (("start", "end", "period"), ("rest_time",)),
    "polyline": (("waypoints", "period"), ("times", "rest_time")),
    "spline": (("waypoints", "period"), ("times",)),
}
#: Path types a table may declare.
PATH_TYPES = tuple(PATH_KEYS)

_CLASSES: dict[str, Callable[..., NominalPath]] = {
    "circle": CirclePath,
    "segment": SegmentPath,
    "polyline": PolylinePath,
    "spline": SplinePath,
}


def path_from_table(table: Mapping[str, Any], section: str = "[controller.path]") -> NominalPath:
    """Build the nominal path a table declares (keys in docs/task_paths.md).

    ``type`` is one of :data:`PATH_TYPES` (default ``"circle"``); the other keys are the
    arguments of :class:`CirclePath`, :class:`SegmentPath`, :class:`PolylinePath` or
    :class:`SplinePath`. Values are checked by the path classes, whose errors name the key.

    Args:
        table: The parsed TOML table.
        section: The table's name in error messages.

    Raises:
        SceneError: ``table`` is not a table, or a required key is missing.
        InvalidParameterError: ``type`` is not a known path type, or a value is invalid
            (:class:`ShapeError`, :class:`NonFiniteValueError` for arrays).
        UnknownKeyError: The table holds keys its type does not define.
    """
    check_keys(section, table, {"type", *(k for keys in PATH_KEYS.values() for k in sum(keys, ()))})
    kind = table.get("type", "circle")
    if kind not in PATH_KEYS:
        raise InvalidParameterError(
            f"{section} type", kind, "one of " + ", ".join(repr(k) for k in PATH_TYPES)
        )
    required, optional = PATH_KEYS[kind]
    check_keys(f"{section} (type = {kind!r})", table, {"type", *required, *optional})
    arguments = {key: require_key(table, section, key) for key in required}
    arguments |= {key: table[key] for key in optional if key in table}
    return _CLASSES[kind](**arguments)
