"""Dotted keys into a scene table: ``contacts.0.restitution``, ``surfaces.ground.point.2``.

A dotted key walks the parsed TOML table of a scene: a part that is a whole number indexes an
array (``contacts.0`` is the first ``[[contacts]]`` entry, ``point.2`` the third coordinate), any
other part names a key of a table. :func:`apply_overrides` returns a new table, the base table
being left untouched, so one base table serves every run of a campaign.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ucontrol._validation import toml_error_message
from ucontrol.exceptions import ParameterKeyError


def split_key(key: str) -> list[str | int]:
    """The parts of a dotted key, whole numbers as ints.

    Raises:
        ParameterKeyError: The key is empty or has an empty part (``"a..b"``).
    """
    if not isinstance(key, str) or not key:
        raise ParameterKeyError(str(key), "a dotted key must be a non-empty string")
    parts: list[str | int] = []
    for part in key.split("."):
        if not part:
            raise ParameterKeyError(key, "empty part in the dotted key")
        parts.append(int(part) if part.isdigit() else part)
    return parts


def lookup(table: Mapping[str, Any], key: str) -> Any:
    """The value a dotted key addresses in ``table``.

    Raises:
        ParameterKeyError: A part of the key does not exist.
    """
    node: Any = table
    for depth, part in enumerate(split_key(key)):
        node = child(node, part, key, depth)
    return node


def apply_overrides(table: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A deep copy of ``table`` with each dotted key of ``overrides`` set to its value.

    Missing intermediate tables are created (a scene may declare a table the base scene lacks,
    e.g. a sensor); array indices must exist. Whether the scene accepts the result is checked by
    building it (:meth:`ucontrol.scene.Scene.from_dict`).

    Raises:
        ParameterKeyError: An index is out of range, or a part walks into a number or string.
    """
    result: dict[str, Any] = copy.deepcopy(dict(table))
    for key, value in overrides.items():
        parts = split_key(key)
        node: Any = result
        for depth, part in enumerate(parts[:-1]):
            if isinstance(part, str) and isinstance(node, dict) and part not in node:
                node[part] = {}
            node = child(node, part, key, depth)
        last = parts[-1]
        if isinstance(node, list):
            if not isinstance(last, int) or last >= len(node):
                raise ParameterKeyError(key, f"index {last!r} is out of range (length {len(node)})")
            node[last] = copy.deepcopy(value)
        elif isinstance(node, dict):
            if isinstance(last, int):
                raise ParameterKeyError(key, f"{last} indexes a table, not an array")
            old = node.get(last)
            if isinstance(old, dict) and not isinstance(value, dict):
                raise ParameterKeyError(key, f"{last!r} is a table, not a value")
            node[last] = copy.deepcopy(value)
        else:
            raise ParameterKeyError(key, f"{_path(parts[:-1])!r} is a value, not a table or array")
    return result


def child(node: Any, part: str | int, key: str, depth: int) -> Any:
    """The entry ``part`` of ``node``, reached by the first ``depth`` parts of ``key``.

    Raises:
        ParameterKeyError: Naming ``key`` and what ``node`` holds.
    """
    parts = split_key(key)
    where = _path(parts[:depth]) or "the scene"
    if isinstance(node, list):
        if not isinstance(part, int):
            raise ParameterKeyError(key, f"{where!r} is an array: index it with a number")
        if part >= len(node):
            raise ParameterKeyError(
                key, f"{where!r} has {len(node)} entries, index {part} is out of range"
            )
        return node[part]
    if isinstance(node, Mapping):
        if part not in node:
            raise ParameterKeyError(
                key, f"{where!r} has no key {part!r}; it holds: {', '.join(map(str, node))}"
            )
        return node[part]
    raise ParameterKeyError(key, f"{where!r} is a value, not a table or array")


def _path(parts: list[str | int]) -> str:
    return ".".join(str(part) for part in parts)


def parse_assignment(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` (``ucontrol run --set``) as a dotted key and a TOML value.

    The value is read as TOML (``0.93``, ``true``, ``[0.0, 0.005, 0.0]``, ``"name"``); a bare
    word that is not TOML is taken as a string.

    Raises:
        ParameterKeyError: No ``=`` or an empty key.
    """
    import tomllib

    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ParameterKeyError(text, "expected KEY=VALUE, e.g. contacts.0.restitution=0.5")
    split_key(key)
    try:
        parsed = tomllib.loads(f"value = {value.strip()}")["value"]
    except tomllib.TOMLDecodeError:
        parsed = value.strip()
    return key, parsed


def format_assignment(key: str, value: Any) -> str:
    """The ``KEY=VALUE`` text :func:`parse_assignment` reads back to ``(key, value)``."""
    return f"{key}={_toml_value(value)}"


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    return '"' + str(value).replace("\\", "\\\\").replace('"', '\\"') + '"'


def scene_with_overrides(scene: str | Path | None, assignments: Sequence[str]) -> Any:
    """Load a scene with ``KEY=VALUE`` overrides (``ucontrol run --set``).

    Args:
        scene: A scene file, a built-in scene name (``"ball"``), or None for the default
            scene, as :func:`ucontrol.scene.load_scene` takes them.
        assignments: ``KEY=VALUE`` texts (:func:`parse_assignment`), applied in order.

    Returns:
        The :class:`ucontrol.scene.Scene`, its ``source`` the file.

    Raises:
        ParameterKeyError: A malformed assignment or a key that does not walk the table.
        NotFoundError: A name that is no file and no built-in scene.
        SceneError: The file is not TOML; UnknownKeyError and the scene's other errors for
            keys or values it rejects.
    """
    import dataclasses
    import tomllib

    from ucontrol.exceptions import SceneError
    from ucontrol.scene import Scene, builtin_scene

    if scene is None:
        path = builtin_scene()
    elif Path(scene).is_file():
        path = Path(scene)
    elif isinstance(scene, str) and "/" not in scene:
        path = builtin_scene(scene)
    else:
        raise SceneError(f"scene file {str(scene)!r} does not exist")
    text = path.read_text()
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        reason = toml_error_message(error, text)
        raise SceneError(f"scene file {str(path)!r} is not valid TOML: {reason}") from error
    overrides = dict(parse_assignment(text) for text in assignments)
    result = Scene.from_dict(
        apply_overrides(table, overrides), base_dir=path.parent, default_name=path.stem
    )
    return dataclasses.replace(result, source=path.resolve())
