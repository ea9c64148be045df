"""A ``[controller.path]`` table -> a nominal path (circle, segment, polyline, spline).

And a ``[controller]`` table's whole cycle: that path and its contact phases, or a designed
cycle file (:func:`cycle_from_table`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ucontrol._validation import check_keys, require_key
from ucontrol.control.circle_path import CirclePath
from ucontrol.control.controller_table import contact_phases
from ucontrol.control.desired_cycle import ContactPhase, NominalPath, read_designed_cycle
from ucontrol.control.polyline_path import PolylinePath
from ucontrol.control.segment_path import SegmentPath
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


def _spline(**arguments: Any) -> NominalPath:
    # scipy.interpolate comes with SplinePath: imported by the scenes that declare one
    from ucontrol.control.spline_path import SplinePath

    return SplinePath(**arguments)


_CLASSES: dict[str, Callable[..., NominalPath]] = {
    "circle": CirclePath,
    "segment": SegmentPath,
    "polyline": PolylinePath,
    "spline": _spline,
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


def cycle_from_table(
    table: Mapping[str, Any], base_dir: Path | None, section: str = "[controller]"
) -> tuple[NominalPath, tuple[ContactPhase, ...]]:
    """The nominal path and contact phases of a controller table.

    Either from a designed cycle file, ``designed_cycle = "cycle.npz"`` (written by
    ``ucontrol design``, path relative to ``base_dir``, the scene's folder;
    :func:`ucontrol.control.desired_cycle.read_designed_cycle`), or from the
    ``[controller.path]`` table (:func:`path_from_table`) and the
    ``[[controller.contact_phases]]`` entries, never both.

    Args:
        table: The parsed ``[controller]`` table.
        base_dir: Folder relative paths start from (None: the working directory).
        section: The table's name in error messages.

    Raises:
        InvalidParameterError: ``designed_cycle`` beside ``path`` or ``contact_phases``, or
            not a string.
        SceneError: The cycle file is missing or malformed, or ``path`` is missing.
    """
    file = table.get("designed_cycle")
    if file is None:
        return path_from_table(require_key(table, section, "path")), contact_phases(table)
    if not isinstance(file, str):
        raise InvalidParameterError(f"{section} designed_cycle", file, "a file path (string)")
    for key in ("path", "contact_phases"):
        if key in table:
            raise InvalidParameterError(
                f"{section} {key}",
                "given",
                f"absent: designed_cycle = {file!r} gives the path and the contact phase",
            )
    cycle_file = Path(file)
    if not cycle_file.is_absolute() and base_dir is not None:
        cycle_file = base_dir / cycle_file
    path, phase = read_designed_cycle(cycle_file)
    return path, (phase,)
