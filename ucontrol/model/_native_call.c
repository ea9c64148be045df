/* Compiled casadi calls without ctypes: a builtin of no arguments per compiled Function.
 *
 * Built with the package (setup.py, an optional extension: without a C compiler the package
 * installs and compiled calls go through ctypes); see ucontrol/model/native_call.py. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

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
    Py_ssize_t n_copies; /* arguments of a call, each copied into an input before it */
    Py_ssize_t *slots;   /* the input each argument is copied into */
    Py_ssize_t *sizes;   /* its number of values */
    PyObject *targets;   /* the inputs' arrays: where other arguments are assigned by numpy */
} runner_t;

static const char *CAPSULE = "ucontrol.native_call.runner";

static void runner_free(PyObject *capsule) {
    runner_t *r = (runner_t *)PyCapsule_GetPointer(capsule, CAPSULE);
    if (r == NULL) return;
    Py_XDECREF(r->owner);
    Py_XDECREF(r->name);
    Py_XDECREF(r->error);
    Py_XDECREF(r->targets);
    PyMem_Free(r->slots);
    PyMem_Free(r->sizes);
    PyMem_Free(r);
}

/* Copy argument j into its input: a 1-d float64 array of the input's size (any stride) or, for
 * an input of one value, a float, copied here; anything else assigned by numpy (which converts
 * or raises as `input[...] = value` does). */
static int copy_in(runner_t *r, Py_ssize_t j, PyObject *value) {
    double *target = (double *)r->arg[r->slots[j]];
    Py_ssize_t size = r->sizes[j];
    if (size == 1 && PyFloat_Check(value)) {
        target[0] = PyFloat_AS_DOUBLE(value);
        return 0;
    }
    Py_buffer view;
    if (PyObject_GetBuffer(value, &view, PyBUF_STRIDES | PyBUF_FORMAT) == 0) {
        int plain = view.ndim == 1 && view.shape[0] == size && view.itemsize == 8 &&
                    view.format != NULL && strcmp(view.format, "d") == 0;
        if (plain) {
            const char *source = (const char *)view.buf;
            Py_ssize_t stride = view.strides[0];
            if (stride == 8) {
                memcpy(target, source, (size_t)size * sizeof(double));
            } else {
                for (Py_ssize_t k = 0; k < size; k++)
                    memcpy(target + k, source + k * stride, sizeof(double));
            }
        }
        PyBuffer_Release(&view);
        if (plain) return 0;
    } else {
        PyErr_Clear();
    }
    return PyObject_SetItem(PyTuple_GET_ITEM(r->targets, j), Py_Ellipsis, value);
}

static PyObject *run(PyObject *capsule, PyObject *const *args, Py_ssize_t nargs) {
    runner_t *r = (runner_t *)PyCapsule_GetPointer(capsule, CAPSULE);
    if (r == NULL) return NULL;
    if (nargs != r->n_copies) {
        PyErr_Format(PyExc_TypeError, "the runner of %U takes %zd arguments, got %zd", r->name,
                     r->n_copies, nargs);
        return NULL;
    }
    for (Py_ssize_t j = 0; j < nargs; j++)
        if (copy_in(r, j, args[j]) != 0) return NULL;
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

static PyMethodDef run_def = {"run", (PyCFunction)(void (*)(void))run, METH_FASTCALL,
                              "Copy the arguments into their inputs, then run the compiled "
                              "casadi function on its bound buffers."};

static PyObject *make_runner(PyObject *module, PyObject *args) {
    unsigned long long entry, arg, res, iw, w;
    PyObject *owner, *name, *error, *copies = NULL, *targets = NULL;
    if (!PyArg_ParseTuple(args, "KKKKKOUO|O!O!", &entry, &arg, &res, &iw, &w, &owner, &name,
                          &error, &PyTuple_Type, &copies, &PyTuple_Type, &targets))
        return NULL;
    if (entry == 0 || arg == 0 || res == 0 || iw == 0 || w == 0) {
        PyErr_SetString(PyExc_ValueError, "null pointer");
        return NULL;
    }
    Py_ssize_t n_copies = copies == NULL ? 0 : PyTuple_GET_SIZE(copies);
    if (n_copies && (targets == NULL || PyTuple_GET_SIZE(targets) != n_copies)) {
        PyErr_SetString(PyExc_ValueError, "one target array per copied input");
        return NULL;
    }
    Py_ssize_t *slots = PyMem_Calloc(n_copies ? n_copies : 1, sizeof(Py_ssize_t));
    Py_ssize_t *sizes = PyMem_Calloc(n_copies ? n_copies : 1, sizeof(Py_ssize_t));
    if (slots == NULL || sizes == NULL) {
        PyMem_Free(slots);
        PyMem_Free(sizes);
        return PyErr_NoMemory();
    }
    for (Py_ssize_t j = 0; j < n_copies; j++) {  /* (slot, size) pairs of non-negative ints */
        PyObject *pair = PyTuple_GET_ITEM(copies, j);
        if (!PyArg_ParseTuple(pair, "nn", &slots[j], &sizes[j]) || slots[j] < 0 ||
            sizes[j] < 0) {
            if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "negative slot or size");
            PyMem_Free(slots);
            PyMem_Free(sizes);
            return NULL;
        }
    }
    runner_t *r = (runner_t *)PyMem_Malloc(sizeof(runner_t));
    if (r == NULL) {
        PyMem_Free(slots);
        PyMem_Free(sizes);
        return PyErr_NoMemory();
    }
    r->n_copies = n_copies;
    r->slots = slots;
    r->sizes = sizes;
    r->targets = targets == NULL ? PyTuple_New(0) : targets;
    if (targets != NULL) Py_INCREF(targets);
    if (r->targets == NULL) {
        PyMem_Free(slots);
        PyMem_Free(sizes);
        PyMem_Free(r);
        return NULL;
    }
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
        Py_DECREF(r->targets);
        PyMem_Free(slots);
        PyMem_Free(sizes);
        PyMem_Free(r);
        return NULL;
    }
    PyObject *function = PyCFunction_New(&run_def, capsule);
    Py_DECREF(capsule);
    return function;
}

static PyMethodDef methods[] = {
    {"make_runner", make_runner, METH_VARARGS,
     "make_runner(entry, arg, res, iw, w, owner, name, error[, copies, targets]): a builtin "
     "taking one argument per (input slot, size) pair of copies (none without them)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module_def = {PyModuleDef_HEAD_INIT, "_native_call",
                                        "Compiled casadi calls without ctypes.", -1, methods};

PyMODINIT_FUNC PyInit__native_call(void) { return PyModule_Create(&module_def); }
