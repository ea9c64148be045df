"""Checks applied at the public boundary; each raises a typed error naming the value."""

from __future__ import annotations

import importlib
import math
import re
import sys
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import (
    InvalidParameterError,
    NonFiniteValueError,
    NotFoundError,
    SceneError,
    ShapeError,
    UnknownKeyError,
    UserFunctionError,
)


def as_vector(name: str, value: Any, size: int | None = None) -> NDArray[np.float64]:
    """Return ``value`` as a finite float vector, optionally of a given size.

    Args:
        name: Argument name used in error messages.
        value: Array-like input.
        size: Required length, or None for any.

    Raises:
        ShapeError: ``value`` is not one-dimensional of length ``size``.
        NonFiniteValueError: ``value`` holds NaN or infinity.
    """
    try:
        if np.asarray(value).dtype.kind in "USObV":  # text, booleans: not numbers
            raise TypeError(f"{name} holds non-numbers")
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError(name, value, "a vector of numbers") from error
    if array.ndim != 1 or (size is not None and array.shape[0] != size):
        raise ShapeError(name, (size if size is not None else -1,), array.shape)
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        raise NonFiniteValueError(name, value, bad.tolist())
    return array


def as_positive(name: str, value: Any) -> float:
    """Return ``value`` as a finite float > 0, or raise :class:`InvalidParameterError`."""
    number = as_float(name, value)
    if not number > 0.0:
        raise InvalidParameterError(name, value, "> 0")
    return number


def as_non_negative(name: str, value: Any) -> float:
    """Return ``value`` as a finite float >= 0, or raise :class:`InvalidParameterError`."""
    number = as_float(name, value)
    if number < 0.0:
        raise InvalidParameterError(name, value, ">= 0")
    return number


def as_float(name: str, value: Any) -> float:
    """Return ``value`` as a finite float, or raise :class:`InvalidParameterError`.

    Booleans and strings are refused (``"0.5"`` in a scene file is a mistake, not a number).
    """
    if isinstance(value, bool | str | bytes):
        raise InvalidParameterError(name, value, "a finite number")
    try:
        number = float(value)
    except (TypeError, ValueError) as error:
        raise InvalidParameterError(name, value, "a finite number") from error
    if not math.isfinite(number):
        raise InvalidParameterError(name, value, "a finite number")
    return number


def as_int(name: str, value: Any, low: int | None = None) -> int:
    """Return ``value`` as an integer (a float only when whole), optionally >= ``low``.

    Raises:
        InvalidParameterError: ``value`` is not a whole number, or is below ``low``.
    """
    number = as_float(name, value)
    if not number.is_integer():
        raise InvalidParameterError(name, value, "a whole number")
    if low is not None and number < low:
        raise InvalidParameterError(name, value, f"a whole number >= {low}")
    return int(number)


def as_bool(name: str, value: Any) -> bool:
    """Return ``value`` if it is a boolean (``true``/``false`` in TOML; no strings, no 0/1)."""
    if not isinstance(value, bool | np.bool_):
        raise InvalidParameterError(name, value, "true or false")
    return bool(value)


def as_in_interval(name: str, value: Any, low: float, high: float) -> float:
    """Return ``value`` as a float in the closed interval [low, high]."""
    number = as_float(name, value)
    if not low <= number <= high:
        raise InvalidParameterError(name, value, f"in [{low:g}, {high:g}]")
    return number


def check_keys(section: str, table: Any, allowed: set[str]) -> None:
    """Check that ``table`` is a mapping whose keys all belong to ``allowed``.

    Args:
        section: The table's name in messages, e.g. ``"[robot]"``.
        table: The parsed TOML table.
        allowed: The keys the table accepts.

    Raises:
        SceneError: ``table`` is not a table.
        UnknownKeyError: ``table`` holds keys outside ``allowed``.
    """
    if not isinstance(table, Mapping):
        raise SceneError(f"{section} must be a table, got {table!r}")
    unknown = set(table) - allowed
    if unknown:
        raise UnknownKeyError(section, unknown, allowed)


def require_key(table: Mapping[str, Any], section: str, key: str) -> Any:
    """The value of a key the table must hold.

    Raises:
        SceneError: ``key`` is missing from ``section``.
    """
    if key not in table:
        raise SceneError(f"{section} needs the key {key!r}")
    return table[key]


def table_type(section: str, table: Any, keys: Mapping[str, set[str]], what: str) -> str:
    """The ``type`` of a table that has one set of keys per type, its keys checked.

    Args:
        section: The table's name in messages, e.g. ``"[[bilateral]]"``.
        table: The parsed TOML table.
        keys: The keys each type accepts (``type`` included).
        what: What the type names, e.g. ``"bilateral type"``.

    Raises:
        SceneError: ``table`` is not a table or has no ``type``.
        NotFoundError: An unknown type (the message lists the known ones).
        UnknownKeyError: A key the type does not accept.
    """
    if not isinstance(table, Mapping):
        raise SceneError(f"{section} must be a table, got {table!r}")
    kind = require_key(table, section, "type")
    if kind not in keys:
        raise NotFoundError(what, str(kind), list(keys))
    check_keys(section, table, keys[kind])
    return str(kind)


def toml_error_message(error: ValueError, text: str) -> str:
    """The message of a ``tomllib.TOMLDecodeError`` with the line it points at.

    A key or table given twice is named (tomllib says only "Cannot overwrite a value").

    Args:
        error: The error ``tomllib.loads(text)`` raised.
        text: The TOML text.
    """
    found = re.search(r"at line (\d+), column \d+", str(error))
    lines = text.splitlines()
    if found is None or not 1 <= int(found.group(1)) <= len(lines):
        return str(error)
    line = lines[int(found.group(1)) - 1].strip()
    message = f"{error}: {line!r}"
    if str(error).startswith("Cannot overwrite a value"):
        name = line.strip("[]") if line.startswith("[") else line.partition("=")[0].strip()
        message += f" (the key {name!r} is given twice)"
    return message


def import_callable(spec: Any, python_path: tuple[str, ...] = ()) -> Callable[..., Any]:
    """The callable named ``module:name``, its module imported by name.

    Args:
        spec: ``"module:name"`` (``"my_package.motions:shaker"``).
        python_path: Folders searched first for the module (put at the front of ``sys.path``).

    Raises:
        UserFunctionError: ``spec`` is not of the form ``module:name``, the module cannot be
            imported, or it has no callable of that name.
    """
    module_name, colon, name = str(spec).partition(":")
    if not isinstance(spec, str) or not colon or not module_name or not name:
        raise UserFunctionError(str(spec), "expected 'module:name'")
    for folder in reversed(python_path):
        if folder not in sys.path:
            sys.path.insert(0, folder)
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise UserFunctionError(spec, f"cannot import module {module_name!r}: {error}") from error
    function = getattr(module, name, None)
    if not callable(function):
        raise UserFunctionError(spec, f"module {module_name!r} has no callable {name!r}")
    return function  # type: ignore[no-any-return]
