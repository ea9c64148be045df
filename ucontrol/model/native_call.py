r"""A compiled casadi call as a Python builtin without arguments: the call without ctypes.

Through ``ctypes``, calling a compiled casadi Function on bound buffers converts its five
arguments from Python to C at every call, work of the order of the arithmetic of the small laws
and rows of the closed loop, which makes several such calls per step. A small CPython extension
built when the package is installed (``ucontrol/model/_native_call.c``, about 60 lines of C;
setup.py) lets :func:`native_runner` wrap the C entry point of a compiled Function and its
bound argument, result and work arrays into a builtin function: one call is one Python builtin
call, without conversions, plus the Function's own work; its arguments, if it takes any, are
copied into inputs of the call by C (instead of one numpy assignment each) (measured in
docs/benchmarks.md, "Compiled laws: cache and fallback": ctypes' conversions cost more than
5 % of a two-link step, three calls a step).

Where the extension was not built (an install without a C compiler or Python headers: the
extension is optional), :func:`native_runner` returns None and callers keep the ``ctypes``
call (with ``UCONTROL_NO_COMPILE`` nothing is compiled and casadi's virtual machine runs the
Functions).
"""

from __future__ import annotations

import functools
import importlib
import logging
from collections.abc import Callable, Sequence
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import CompiledCallError

_logger = logging.getLogger(__name__)


def native_runner(
    entry: int,
    arg: int,
    res: int,
    iw: int,
    w: int,
    owner: object,
    name: str,
    copies: Sequence[tuple[int, int, NDArray[np.float64]]] = (),
) -> Callable[..., None] | None:
    """A builtin calling ``entry(arg, res, iw, w, 0)``, or None if unavailable.

    Args:
        entry: Address of the compiled Function's C entry point (casadi's calling convention).
        arg: Address of its array of argument pointers (read at every call, so rebinding an
            entry is seen by the runner).
        res: Address of its array of result pointers (likewise).
        iw: Address of its integer work array (``long long``).
        w: Address of its real work array.
        owner: Object kept alive as long as the runner is (the holder of those buffers).
        name: The Function's name, for the error of a non-zero status.
        copies: What the runner's arguments are copied into before each call, one
            (argument slot, number of values, the input's array) triple per argument, in
            order: none by default (a builtin of no arguments).

    The runner raises :class:`~ucontrol.exceptions.CompiledCallError` when the entry returns
    a non-zero status. Its arguments are copied by C into the memory the argument slots
    point to at the call: a float for an input of one value, a one-dimensional float64
    array of the input's size (any stride); any other value is assigned to the input's array
    by numpy (``array[...] = value``, which converts it or raises as it does). The four
    arguments of a one-contact Panda step, copied this way, cost about 3,600 instructions
    fewer than numpy's assignments (docs/benchmarks.md, "Issue 30: the one-contact step
    against ``mj_step``").
    """
    module = _extension()
    if module is None:
        return None
    runner: Callable[..., None] = module.make_runner(
        entry,
        arg,
        res,
        iw,
        w,
        owner,
        name,
        CompiledCallError,
        tuple((slot, size) for slot, size, _ in copies),
        tuple(array for _, _, array in copies),
    )
    return runner


@functools.cache
def _extension() -> ModuleType | None:
    """The extension module built with the package, or None where it was not built."""
    try:
        return importlib.import_module("ucontrol.model._native_call")
    except ImportError as error:  # installed without a C compiler (an optional extension)
        _logger.info(
            "native call extension not installed (%s): compiled calls through ctypes", error
        )
        return None
