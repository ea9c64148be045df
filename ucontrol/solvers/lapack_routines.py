"""LAPACK routines of scipy's Fortran wrappers, loaded without ``scipy.linalg``'s package.

The small solves of the contact stage call LAPACK directly (``dsyev`` for an active set's
eigenvalues): numpy's wrappers cost more than the decomposition of a few rows. scipy keeps
these routines in one extension module, ``scipy.linalg._flapack``, whose functions
``scipy.linalg.lapack`` re-exports as they are. Importing ``scipy.linalg`` first runs the
package's ``__init__``, which loads scipy's array-API layer (and with it numpy's ``testing``
and ``f2py``), many times the cost of the extension module alone (docs/benchmarks.md, issue
30). :func:`lapack_routine` loads that module by itself, from the installed scipy's files,
and falls back on ``scipy.linalg.lapack`` where the module is not where scipy puts it. The
module registers itself in ``sys.modules`` under its name, where ``scipy.linalg``, imported
later, takes it as it is: the routines are the same functions either way, with the same
results bit for bit.
"""

from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

#: The extension module of scipy's LAPACK wrappers.
FLAPACK = "scipy.linalg._flapack"


def lapack_routine(name: str) -> Any:
    """The scipy wrapper of the LAPACK routine ``name`` (e.g. ``"dsyev"``), loaded on first use.

    Raises:
        AttributeError: scipy wraps no routine of that name.
    """
    return getattr(_flapack(), name)


@functools.cache
def _flapack() -> ModuleType:
    """``scipy.linalg._flapack``: the module already imported, else its file alone."""
    imported = sys.modules.get(FLAPACK)
    if imported is not None:
        return imported
    path = _flapack_file()
    if path is None:
        from scipy.linalg import lapack

        return lapack
    loader = importlib.machinery.ExtensionFileLoader(FLAPACK, str(path))
    spec = importlib.machinery.ModuleSpec(FLAPACK, loader, origin=str(path))
    return importlib.util.module_from_spec(spec)


def _flapack_file() -> Path | None:
    """The file of ``scipy.linalg._flapack`` in the installed scipy, or None."""
    spec = importlib.util.find_spec("scipy")  # finds the package without importing it
    locations = spec.submodule_search_locations if spec is not None else None
    for location in locations or ():
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = Path(location, "linalg", "_flapack" + suffix)
            if path.is_file():
                return path
    return None
