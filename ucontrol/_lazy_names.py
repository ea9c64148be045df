"""Names of a package imported from their modules on first use (PEP 562).

A package lists each public name's module; its ``__getattr__`` imports the module when the
name is first asked for, so that importing the package loads none of them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module
from typing import Any


def lazy_names(package: str, modules: Mapping[str, str]) -> Callable[[str], Any]:
    """The module ``__getattr__`` of ``package`` for the names of ``modules`` (name: module).

    The function raises :class:`AttributeError` for any other name, as a module does.
    """

    def __getattr__(name: str) -> Any:
        module = modules.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(import_module(module), name)

    return __getattr__
