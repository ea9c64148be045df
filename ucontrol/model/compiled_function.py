r"""Casadi Functions compiled to C, cached on disk, with the casadi virtual machine as fallback.

A law written as a casadi expression (the flexible-joint law, the link reference of
:class:`~ucontrol.control.FlexibleBrogliatoController`) called through casadi's Python
interface spends most of each call converting numbers to and from ``casadi.DM``.
:class:`CompiledFunction` generates the C code of the Function once
(``casadi.CodeGenerator``), compiles it with the system C compiler into a shared library and
calls it on preallocated numpy buffers, without conversions (the figures are in
docs/benchmarks.md, "Compiled laws: cache and fallback").

- Cache: one library per Function in the cache of :mod:`ucontrol.model.compile_cache`, named
  by the SHA-256 of the Function's serialized form, the casadi version and the compiler
  command, so a changed law is rebuilt and an unchanged one never is; built once by
  concurrent processes, never loaded partial.
- Definitions: :meth:`CompiledFunction.cached` looks the library up by what the Function is
  built from (a definition key of :mod:`ucontrol.model.compile_cache`); found, it is loaded
  and its signature (names, shapes, work sizes) read from the library's own exports, without
  building the Function or importing casadi. Not found, the Function is built, compiled (or
  found by its serialized form) and recorded under the definition.
- Fallback: without a C compiler, when compilation or loading fails, or with the environment
  variable ``UCONTROL_NO_COMPILE=1``, the same interface calls the casadi Function itself
  (same results to round-off; slower). ``$CC`` chooses the compiler (default ``cc``).

Every input and output is a dense column vector (matrices are passed column-major and
flattened); the outputs are densified at construction.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os
import subprocess
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import CompiledCallError
from ucontrol.model.compile_cache import (
    build_library,
    compiler_command,
    find_library,
    record_library,
)
from ucontrol.model.native_call import native_runner

if TYPE_CHECKING:  # casadi is imported by the functions that build (compilation_possible: not)
    import casadi as ca

Vector = NDArray[np.float64]

#: Set to 1 to use the casadi virtual machine instead of compiled code.
NO_COMPILE_ENV = "UCONTROL_NO_COMPILE"

_logger = logging.getLogger(__name__)


def compilation_disabled() -> bool:
    """Whether ``UCONTROL_NO_COMPILE`` asks for the casadi fallback."""
    return os.environ.get(NO_COMPILE_ENV, "").strip() not in ("", "0")


def compilation_possible() -> bool:
    """Whether a :class:`CompiledFunction` built now can compile: a C compiler, not disabled.

    For callers whose only gain is the compiled call, so that they skip building the casadi
    Function at all where it would run in casadi's virtual machine.
    """
    if compilation_disabled():
        return False
    try:
        compiler_command()
    except OSError:
        return False
    return True


class CompiledFunction:
    """A casadi Function called on numpy vectors, compiled to C when possible.

    Args:
        function: A casadi Function of dense vector inputs.
        compile: Try to compile it (default: unless ``UCONTROL_NO_COMPILE`` is set).

    Attributes:
        compiled: Whether calls run the compiled library (False: casadi's virtual machine).
        library_path: The shared library used, or None.
    """

    def __init__(self, function: ca.Function, *, compile: bool | None = None) -> None:
        self._function: ca.Function | None = _densified(function)
        self._build_function: Callable[[], ca.Function] | None = None
        f = self._function
        self._setup(_Signature.of_function(f))
        self.compiled = False
        self.library_path: Path | None = None
        if compile is None:
            compile = not compilation_disabled()
        if compile:
            try:
                self.library_path = _build(f)
                self._bind(ctypes.CDLL(str(self.library_path)))
                self.compiled = True
            except (OSError, RuntimeError, subprocess.SubprocessError) as error:
                _logger.info("casadi function %s not compiled (%s): fallback", self.name, error)

    @classmethod
    def cached(
        cls, name: str, definition: str, build: Callable[[], ca.Function]
    ) -> CompiledFunction:
        """The Function ``build()`` returns, compiled, found by its ``definition`` if cached.

        Args:
            name: The Function's name (``build().name()``).
            definition: What the Function is built from
                (:func:`~ucontrol.model.compile_cache.definition_key`): equal definitions
                must build equal Functions.
            build: Builds the Function; called on a miss, or when :attr:`function` is read.

        A library recorded under ``definition`` is loaded without calling ``build`` (nor
        importing casadi); otherwise ``CompiledFunction(build())``, whose library is recorded
        under ``definition`` for later processes.
        """
        if not compilation_disabled():
            library = find_library(name, definition)
            if library is not None:
                try:
                    return cls._loaded(library, name, build)
                except (OSError, AttributeError, ValueError) as error:  # not our library
                    _logger.info("library %s not loaded (%s): built again", library, error)
        made = cls(build())
        if made.library_path is not None:
            record_library(name, definition, made.library_path)
        return made

    @classmethod
    def _loaded(
        cls, library: Path, name: str, build: Callable[[], ca.Function]
    ) -> CompiledFunction:
        """The compiled Function ``name`` of ``library``, its signature read from the library."""
        made = cls.__new__(cls)
        loaded = ctypes.CDLL(str(library))
        made._function, made._build_function = None, build
        made._setup(_Signature.of_library(loaded, name))
        made.library_path, made.compiled = library, True
        made._bind(loaded)
        return made

    @property
    def function(self) -> ca.Function:
        """The casadi Function (outputs densified); built on first read for a loaded library."""
        if self._function is None:
            assert self._build_function is not None
            self._function = _densified(self._build_function())
        return self._function

    def names_in(self) -> list[str]:
        """The inputs' names, in order."""
        return list(self._in_names)

    def index_in(self, name: str) -> int:
        """Index of the input called ``name``."""
        return self._in_names.index(name)

    def index_out(self, name: str) -> int:
        """Index of the output called ``name``."""
        return self._out_names.index(name)

    def _setup(self, signature: _Signature) -> None:
        """The buffers of a Function of ``signature``."""
        self.name = signature.name
        self._signature = signature
        self._in_names, self._out_names = signature.in_names, signature.out_names
        self._in_sizes = list(signature.in_sizes)
        self._out_sizes = list(signature.out_sizes)
        self._outputs = [np.zeros(n) for n in self._out_sizes]
        self._results = tuple(self._outputs)  # what every call returns
        self._output_owners: list[NDArray[np.float64]] = []  # arrays of bind_output
        self._in_buffers = [np.zeros(n) for n in self._in_sizes]
        self._in_shapes = list(signature.in_shapes)
        self._in_views = [  # column-major views of the buffers in the inputs' shapes
            buffer if shape[1] == 1 else buffer.reshape(shape, order="F")
            for buffer, shape in zip(self._in_buffers, self._in_shapes, strict=True)
        ]

    def __call__(self, *inputs: Vector | None) -> tuple[Vector, ...]:
        """Outputs, each a dense vector of shape (nnz,), for ``inputs``.

        Each input is an array of the input's shape (a matrix may be given in any memory
        order; it is read column-major as casadi does), or None for an input already written
        in place into :meth:`input_buffer`. The arrays returned are buffers reused by the next
        call: copy what must be kept.

        Raises:
            CompiledCallError: The compiled code returned a non-zero status, or casadi's
                virtual machine raised (e.g. an embedded root finder that failed).
        """
        buffers, views = self._in_buffers, self._in_views
        for i, x in enumerate(inputs):
            if x is not None:
                views[i][...] = x
        if not self.compiled:
            try:
                values: Any = self.function(
                    *(b.reshape(shape, order="F") for b, shape in zip(buffers, self._in_shapes))
                )
            except RuntimeError as error:  # casadi's, e.g. an embedded solver that failed
                raise CompiledCallError(self.name, str(error)) from error
            if self.function.n_out() == 1:
                values = (values,)
            for out, value in zip(self._outputs, values, strict=True):
                out[:] = np.asarray(value).ravel(order="F")
            return self._results
        self._run_bound()
        return self._results

    def runner(self, inputs: Sequence[int] = ()) -> Callable[..., None]:
        """A call on the inputs as they are: bound, or written through :meth:`input_view`.

        The call writes :meth:`output_buffer` and returns nothing. For hot loops: it skips
        :meth:`__call__`'s handling of arguments and results and, where the extension of
        :mod:`ucontrol.model.native_call` builds, ``ctypes`` (a call of the compiled library
        is then one builtin call besides its arithmetic, without ctypes' conversions);
        without the compiled library it runs the casadi Function as :meth:`__call__` does.
        The runner keeps this object alive, and raises
        :class:`~ucontrol.exceptions.CompiledCallError` as :meth:`__call__` does.

        Args:
            inputs: The inputs the call's arguments are written into first, one argument
                each, in this order (an input of one value also takes a float); as
                ``input_view(i)[...] = value`` does, copied by the extension where it is
                built. Their memory is the one they are bound to when the runner is made.
        """
        views = tuple(self._in_views[i] for i in inputs)
        if not self.compiled:
            nothing = (None,) * len(self._in_buffers)

            def interpreted(*values: Vector | float) -> None:
                for view, value in zip(views, values, strict=True):
                    view[...] = value
                self(*nothing)

            return interpreted
        return self._bound_runner(owner=self, inputs=inputs)

    def _bound_runner(self, owner: object, inputs: Sequence[int] = ()) -> Callable[..., None]:
        """The compiled call on the bound buffers, natively where possible; keeps ``owner``.

        Its arguments are written into ``inputs`` first (:meth:`runner`).
        """
        views = tuple(self._in_views[i] for i in inputs)
        native = native_runner(
            self._entry,
            ctypes.addressof(self._arg),
            ctypes.addressof(self._res),
            self._iw_buffer.ctypes.data,
            self._w_buffer.ctypes.data,
            owner,
            self.name,
            [(i, self._in_sizes[i], view) for i, view in zip(inputs, views, strict=True)],
        )
        if native is not None:
            return native
        call, name = self._call, self.name

        def through_ctypes(*values: Vector | float) -> None:
            for view, value in zip(views, values, strict=True):
                view[...] = value
            _check(name, call())

        return through_ctypes

    def output_buffer(self, i: int) -> Vector:
        """The buffer of output ``i``, shape (nnz,), rewritten by every call."""
        return self._outputs[i]

    def bind_input(self, i: int, array: NDArray[np.float64]) -> None:
        """Read input ``i`` from ``array``'s memory at every call, without a copy.

        For buffers whose memory stays put (e.g. the matrices of a ``pinocchio.Data``): pass
        None for that input at each call. ``array`` is kept alive by this object.

        Raises:
            ValueError: ``array`` is not a column-major float64 array of the input's size.
        """
        flat = self._flat_view(array, self._in_sizes[i], f"input {i}")
        self._in_buffers[i] = flat
        self._in_views[i] = array
        if self.compiled:
            self._arg[i] = flat.ctypes.data_as(ctypes.POINTER(ctypes.c_double))

    def bind_output(self, i: int, array: NDArray[np.float64]) -> None:
        """Write output ``i`` into ``array``'s memory at every call, without a copy.

        For buffers whose memory stays put (e.g. the matrices of a ``pinocchio.Data``), like
        :meth:`bind_input`; :meth:`output_buffer` ``i`` becomes a flat view of ``array``.

        Raises:
            ValueError: ``array`` is not a column-major float64 array of the output's size.
        """
        flat = self._flat_view(array, self._out_sizes[i], f"output {i}")
        self._outputs[i] = flat
        self._results = tuple(self._outputs)
        self._output_owners.append(array)  # keeps the memory alive
        if self.compiled:
            self._res[i] = flat.ctypes.data_as(ctypes.POINTER(ctypes.c_double))

    def _flat_view(self, array: NDArray[np.float64], size: int, what: str) -> Vector:
        """``array`` as a flat column-major view of ``size`` values, or a ValueError."""
        flat = np.ravel(array, order="F")
        if array.dtype != np.float64 or flat.size != size or not np.shares_memory(flat, array):
            raise ValueError(
                f"{what} of {self.name} needs a column-major float64 array of {size} values, "
                f"got {array.dtype} {array.shape}"
            )
        return flat

    def input_buffer(self, i: int) -> Vector:
        """The buffer of input ``i`` (shape (nnz,), column-major), to be written in place."""
        return self._in_buffers[i]

    def input_view(self, i: int) -> NDArray[np.float64]:
        """:meth:`input_buffer` ``i`` in the input's shape (a column-major view of it)."""
        return self._in_views[i]

    def _bind(self, library: ctypes.CDLL) -> None:
        call = getattr(library, self.name)
        call.restype = ctypes.c_int
        self._entry = int(ctypes.cast(call, ctypes.c_void_p).value or 0)  # the entry's address
        sz_arg, sz_res, sz_iw, sz_w = self._signature.work
        double_p = ctypes.POINTER(ctypes.c_double)
        self._library = library  # keeps it loaded
        self._arg = (double_p * max(sz_arg, 1))()
        for i, buffer in enumerate(self._in_buffers):
            self._arg[i] = buffer.ctypes.data_as(double_p)
        self._res = (double_p * max(sz_res, 1))()
        for i, out in enumerate(self._outputs):
            self._res[i] = out.ctypes.data_as(double_p)
        self._iw_buffer = np.zeros(max(sz_iw, 1), dtype=np.int64)
        self._w_buffer = np.zeros(max(sz_w, 1))
        self._iw = self._iw_buffer.ctypes.data_as(ctypes.POINTER(ctypes.c_longlong))
        self._w = self._w_buffer.ctypes.data_as(double_p)
        # No argtypes: ctypes passes the pointer arrays as they are and 0 as a C int
        # (argtypes would convert and check all five arguments at every call).
        call.argtypes = None
        self._call = functools.partial(call, self._arg, self._res, self._iw, self._w, 0)
        self._run_bound = self._bound_runner(owner=None)  # owned by self: no cycle


class _Signature(NamedTuple):
    """What a call needs of a Function: names, shapes and work sizes (inputs dense)."""

    name: str
    in_names: list[str]
    out_names: list[str]
    in_shapes: list[tuple[int, int]]
    in_sizes: list[int]  # non-zeros
    out_sizes: list[int]
    work: tuple[int, int, int, int]  # sz_arg, sz_res, sz_iw, sz_w

    @classmethod
    def of_function(cls, f: ca.Function) -> _Signature:
        """The signature of casadi Function ``f``."""
        return cls(
            f.name(),
            list(f.name_in()),
            list(f.name_out()),
            [f.size_in(i) for i in range(f.n_in())],
            [f.nnz_in(i) for i in range(f.n_in())],
            [f.nnz_out(i) for i in range(f.n_out())],
            (f.sz_arg(), f.sz_res(), f.sz_iw(), f.sz_w()),
        )

    @classmethod
    def of_library(cls, library: ctypes.CDLL, name: str) -> _Signature:
        """The signature of Function ``name`` from the exports of its generated C code.

        Raises:
            AttributeError: The library does not export ``name``'s functions.
            ValueError: An input or output is not dense (casadi's compact form
                ``(rows, columns, 1)``), or ``casadi_int`` is not 64 bits.
        """
        integer = ctypes.c_longlong
        if getattr(library, f"{name}_casadi_int_size")() != ctypes.sizeof(integer):
            raise ValueError(f"{name}: casadi_int is not {ctypes.sizeof(integer)} bytes")
        pointer = ctypes.POINTER(integer)
        exported = {}
        for suffix, restype in (
            ("n_in", integer), ("n_out", integer), ("name_in", ctypes.c_char_p),
            ("name_out", ctypes.c_char_p), ("sparsity_in", pointer), ("sparsity_out", pointer),
        ):  # fmt: skip
            function = getattr(library, f"{name}_{suffix}")
            function.restype = restype
            function.argtypes = [] if suffix.startswith("n_") else [integer]
            exported[suffix] = function

        def shape(suffix: str, i: int) -> tuple[int, int]:
            pattern = exported[suffix](i)
            rows, columns, dense = pattern[0], pattern[1], pattern[2]
            if dense != 1:
                raise ValueError(f"{name}: {suffix} {i} is not dense")
            return int(rows), int(columns)

        n_in, n_out = int(exported["n_in"]()), int(exported["n_out"]())
        work = (integer * 4)()
        size = ctypes.sizeof(integer)
        getattr(library, f"{name}_work")(*(ctypes.byref(work, size * k) for k in range(4)))
        in_shapes = [shape("sparsity_in", i) for i in range(n_in)]
        out_shapes = [shape("sparsity_out", i) for i in range(n_out)]
        return cls(
            name,
            [exported["name_in"](i).decode() for i in range(n_in)],
            [exported["name_out"](i).decode() for i in range(n_out)],
            in_shapes,
            [rows * columns for rows, columns in in_shapes],
            [rows * columns for rows, columns in out_shapes],
            (work[0], work[1], work[2], work[3]),
        )


def _check(name: str, status: int) -> None:
    """A compiled call's casadi status: 0, or a :class:`CompiledCallError`."""
    if status != 0:
        raise CompiledCallError(name, f"returned status {status}")


def _densified(function: ca.Function) -> ca.Function:
    """``function`` with dense outputs (SX or MX Functions), its inputs' and outputs' names kept."""
    import casadi as ca

    if all(function.sparsity_out(i).is_dense() for i in range(function.n_out())):
        return function
    symbols: Any = function.sx_in() if function.is_a("SXFunction") else function.mx_in()
    outputs = [ca.densify(o) for o in function.call(symbols)]
    return ca.Function(function.name(), symbols, outputs, function.name_in(), function.name_out())


def _build(function: ca.Function) -> Path:
    """Path of the compiled library of ``function``, built (once) if absent."""
    import casadi as ca

    def source() -> str:
        generator = ca.CodeGenerator(f"{function.name()}.c", {"with_header": False})
        generator.add(function)
        return str(generator.dump())

    key = function.serialize() + ca.CasadiMeta.version()
    return build_library(function.name(), key, source)
