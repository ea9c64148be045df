r"""A compiled casadi call as a Python builtin without arguments: the call without ctypes.

Through ``ctypes``, calling a compiled casadi Function on bound buffers converts its five
arguments from Python to C at every call, work of the order of the arithmetic of the small laws
and rows of the closed loop, which makes several such calls per step. This module builds, once
per Python and compiler, a small CPython extension (about 60 lines of C, cached beside the
compiled laws) whose :func:`native_runner` wraps the C entry point of a compiled Function and
its bound argument, result and work arrays into a builtin function of no arguments: one call is
one Python builtin call, without conversions, plus the Function's own work (measured in
docs/benchmarks.md, "Compiled laws: cache and fallback").

Where the extension cannot be built (no Python headers, no compiler, a failed build),
:func:`native_runner` returns None and callers keep the ``ctypes`` call (with
``UCONTROL_NO_COMPILE`` nothing is compiled and casadi's virtual machine runs the Functions).
"""

from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import logging
import subprocess
import sys
import sysconfig
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from ucontrol.exceptions import CompiledCallError
from ucontrol.model.compile_cache import build_library

_logger = logging.getLogger(__name__)

#: Name of the extension module (its ``PyInit_`` symbol).
MODULE_NAME = "_ucontrol_native_call"

_SOURCE = r"""
#define PY_SSIZE_T_CLEAN
#include <Python.h>

typedef int (*casadi_entry)(const double **arg, double **res, long long *iw, double *w, int mem);

typedef struct {
    casadi_entry entry;
    const double **arg;
    double **res;
    long long *iw;
    double *w;
    PyObject *owner; /* keeps the buffers behind the pointers alive */
    PyObject *name;
    PyObject *error; /* error(name, failure) -> the exception raised on a non-zero status */
} runner_t;

static const char *CAPSULE = "ucontrol.native_call.runner";

static void runner_free(PyObject *capsule) {
    runner_t *r = (runner_t *)PyCapsule_GetPointer(capsule, CAPSULE);
    if (r == NULL) return;
    Py_XDECREF(r->owner);
    Py_XDECREF(r->name);
    Py_XDECREF(r->error);
    PyMem_Free(r);
}

static PyObject *run(PyObject *capsule, PyObject *unused) {
    runner_t *r = (runner_t *)PyCapsule_GetPointer(capsule, CAPSULE);
    if (r == NULL) return NULL;
    int status = r->entry(r->arg, r->res, r->iw, r->w, 0);
    if (status != 0) {
        PyObject *failure = PyUnicode_FromFormat("returned status %d", status);
        if (failure == NULL) return NULL;
        PyObject *error = PyObject_CallFunctionObjArgs(r->error, r->name, failure, NULL);
        Py_DECREF(failure);
        if (error == NULL) return NULL;
        PyErr_SetObject((PyObject *)Py_TYPE(error), error);
        Py_DECREF(error);
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef run_def = {"run", run, METH_NOARGS,
                              "Run the compiled casadi function on its bound buffers."};

static PyObject *make_runner(PyObject *module, PyObject *args) {
    unsigned long long entry, arg, res, iw, w;
    PyObject *owner, *name, *error;
    if (!PyArg_ParseTuple(args, "KKKKKOUO", &entry, &arg, &res, &iw, &w, &owner, &name, &error))
        return NULL;
    if (entry == 0 || arg == 0 || res == 0 || iw == 0 || w == 0) {
        PyErr_SetString(PyExc_ValueError, "null pointer");
        return NULL;
    }
    runner_t *r = (runner_t *)PyMem_Malloc(sizeof(runner_t));
    if (r == NULL) return PyErr_NoMemory();
    r->entry = (casadi_entry)(uintptr_t)entry;
    r->arg = (const double **)(uintptr_t)arg;
    r->res = (double **)(uintptr_t)res;
    r->iw = (long long *)(uintptr_t)iw;
    r->w = (double *)(uintptr_t)w;
    Py_INCREF(owner);
    Py_INCREF(name);
    Py_INCREF(error);
    r->owner = owner;
    r->name = name;
    r->error = error;
    PyObject *capsule = PyCapsule_New(r, CAPSULE, runner_free);
    if (capsule == NULL) {
        Py_DECREF(owner);
        Py_DECREF(name);
        Py_DECREF(error);
        PyMem_Free(r);
        return NULL;
    }
    PyObject *function = PyCFunction_New(&run_def, capsule);
    Py_DECREF(capsule);
    return function;
}

static PyMethodDef methods[] = {
    {"make_runner", make_runner, METH_VARARGS,
     "make_runner(entry, arg, res, iw, w, owner, name, error): a builtin of no arguments."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module_def = {PyModuleDef_HEAD_INIT, "_ucontrol_native_call",
                                        "Compiled casadi calls without ctypes.", -1, methods};

PyMODINIT_FUNC PyInit__ucontrol_native_call(void) { return PyModule_Create(&module_def); }
"""


def native_runner(
    entry: int, arg: int, res: int, iw: int, w: int, owner: object, name: str
) -> Callable[[], None] | None:
    """A builtin of no arguments calling ``entry(arg, res, iw, w, 0)``, or None if unavailable.

    Args:
        entry: Address of the compiled Function's C entry point (casadi's calling convention).
        arg: Address of its array of argument pointers (read at every call, so rebinding an
            entry is seen by the runner).
        res: Address of its array of result pointers (likewise).
        iw: Address of its integer work array (``long long``).
        w: Address of its real work array.
        owner: Object kept alive as long as the runner is (the holder of those buffers).
        name: The Function's name, for the error of a non-zero status.

    The runner raises :class:`~ucontrol.exceptions.CompiledCallError` when the entry returns
    a non-zero status.
    """
    module = _extension()
    if module is None:
        return None
    runner: Callable[[], None] = module.make_runner(
        entry, arg, res, iw, w, owner, name, CompiledCallError
    )
    return runner


@functools.cache
def _extension() -> ModuleType | None:
    """The extension module, built into the cache on first use; None where it cannot be."""
    include = Path(sysconfig.get_paths()["include"])
    if not (include / "Python.h").is_file():
        _logger.info("no Python headers at %s: compiled calls through ctypes", include)
        return None
    key = "\n".join([sys.version, sysconfig.get_config_var("EXT_SUFFIX") or "", _SOURCE])
    try:
        path = build_library("native_call", key, _SOURCE, flags=("-O2", f"-I{include}"))
        loader = importlib.machinery.ExtensionFileLoader(MODULE_NAME, str(path))
        spec = importlib.util.spec_from_file_location(MODULE_NAME, path, loader=loader)
        if spec is None:
            return None
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
    except (OSError, ImportError, RuntimeError, subprocess.SubprocessError) as error:
        _logger.info("native call extension not built (%s): compiled calls through ctypes", error)
        return None
    return module
