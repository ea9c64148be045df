/* Compiled casadi calls without ctypes: a builtin of no arguments per compiled Function.
 *
 * Built with the package (setup.py, an optional extension: without a C compiler the package
 * installs and compiled calls go through ctypes); see ucontrol/model/native_call.py. */
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

static struct PyModuleDef module_def = {PyModuleDef_HEAD_INIT, "_native_call",
                                        "Compiled casadi calls without ctypes.", -1, methods};

PyMODINIT_FUNC PyInit__native_call(void) { return PyModule_Create(&module_def); }
