/*
 * core_filter.c - the Core type: one att_ekf_t with its per-sample update and its batch
 * runner (see core.h). attekf.Filter (filter.py) wraps it; everything a user can pass
 * wrongly to update() is checked here, because update() is called straight from Python per
 * sample.
 */
#include "core.h"

#include <math.h>
#include <string.h>

typedef struct {
    PyObject_HEAD
    att_ekf_t f;
    core_frame_t frame;
    double dt;                  /* s, default step of update(); 0: none */
    int busy;                   /* a batch runs on f without the GIL */
    PyTypeObject *estimate_type; /* attekf.Estimate (a tuple subclass), set by bind() */
    PyObject *flag_type;        /* attekf.Flag */
    PyObject *flag_cache;       /* dict: flag bits -> Flag */
    PyObject *status_names;     /* tuple: ekf_status_t -> name */
} core_filter_obj;

static int not_busy(const core_filter_obj *self)
{
    if (self->busy) {
        PyErr_SetString(PyExc_RuntimeError, "this filter is running a batch in another thread");
        return 0;
    }
    return 1;
}

/* ------------------------------------------------------------------------------------
 * Creation and configuration
 * ------------------------------------------------------------------------------------ */
static PyObject *filter_new(PyTypeObject *type, PyObject *args, PyObject *kwds)
{
    PyObject *settings;
    core_filter_obj *self;
    ekf_status_t st;
    if (kwds != NULL && PyDict_GET_SIZE(kwds) != 0) {
        PyErr_SetString(PyExc_TypeError, "Core(settings) takes no keyword arguments");
        return NULL;
    }
    if (!PyArg_ParseTuple(args, "O!:Core", &core_settings_type, &settings)) {
        return NULL;
    }
    self = (core_filter_obj *)type->tp_alloc(type, 0);
    if (self == NULL) {
        return NULL;
    }
    st = att_init(&self->f, &((core_settings_obj *)settings)->s);
    if (st != EKF_OK) {
        Py_DECREF(self);
        PyErr_Format(PyExc_ValueError, "att_init: %s", ekf_status_str(st));
        return NULL;
    }
    return (PyObject *)self;
}

static void filter_dealloc(core_filter_obj *self)
{
    Py_XDECREF(self->estimate_type);
    Py_XDECREF(self->flag_type);
    Py_XDECREF(self->flag_cache);
    Py_XDECREF(self->status_names);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* bind(Estimate, Flag, status_names): the Python types update() builds its result with. */
static PyObject *filter_bind(core_filter_obj *self, PyObject *args)
{
    PyObject *est, *flag, *names, *cache;
    if (!PyArg_ParseTuple(args, "O!OO!:bind", &PyType_Type, &est, &flag, &PyTuple_Type, &names)) {
        return NULL;
    }
    if (!PyType_IsSubtype((PyTypeObject *)est, &PyTuple_Type)) {
        PyErr_SetString(PyExc_TypeError, "bind: Estimate must be a tuple type");
        return NULL;
    }
    if ((cache = PyDict_New()) == NULL) {
        return NULL;
    }
    Py_INCREF(est);
    Py_INCREF(flag);
    Py_INCREF(names);
    Py_XSETREF(self->estimate_type, (PyTypeObject *)est);
    Py_XSETREF(self->flag_type, flag);
    Py_XSETREF(self->status_names, names);
    Py_XSETREF(self->flag_cache, cache);
    Py_RETURN_NONE;
}

/* configure(dt, mount, ned): dt s (0: none), mount 9 floats row-major or None, ned 0/1.
 * attekf.Filter checks the values (a rotation matrix, a finite positive dt). */
static PyObject *filter_configure(core_filter_obj *self, PyObject *args)
{
    double dt, m[9];
    PyObject *mount;
    int ned, i;
    if (!PyArg_ParseTuple(args, "dOp:configure", &dt, &mount, &ned)) {
        return NULL;
    }
    if (mount != Py_None) {
        if (!PyTuple_Check(mount) || PyTuple_GET_SIZE(mount) != 9) {
            PyErr_SetString(PyExc_TypeError, "configure: mount must be a tuple of 9 floats or None");
            return NULL;
        }
        for (i = 0; i < 9; ++i) {
            m[i] = PyFloat_AsDouble(PyTuple_GET_ITEM(mount, i));
            if (m[i] == -1.0 && PyErr_Occurred()) {
                return NULL;
            }
        }
        memcpy(self->frame.mount, m, sizeof m);
    }
    self->frame.mounted = (mount != Py_None);
    self->frame.ned = ned;
    self->dt = dt;
    Py_RETURN_NONE;
}

/* ------------------------------------------------------------------------------------
 * One sample: update(gyr, acc, mag=None, dt=None) -> attekf.Estimate
 * ------------------------------------------------------------------------------------ */
static int not_three(PyObject *o, const char *name, const char *unit)
{
    PyErr_Clear();
    PyErr_Format(PyExc_TypeError, "%s: %R is not three numbers (%s)", name, o, unit);
    return 0;
}

/* Three numbers from a float64 array (any stride) or any sequence of three numbers. */
static int read3(PyObject *o, const char *name, const char *unit, double out[3])
{
    Py_ssize_t n, k;
    if (PyArray_Check(o)) {
        PyArrayObject *a = (PyArrayObject *)o;
        if (PyArray_NDIM(a) == 1 && PyArray_DIM(a, 0) == 3 && PyArray_TYPE(a) == NPY_DOUBLE) {
            const char *p = PyArray_BYTES(a);
            for (k = 0; k < 3; ++k) {
                memcpy(&out[k], p + k * PyArray_STRIDE(a, 0), sizeof out[k]);
            }
            return 1;
        }
        if (PyArray_NDIM(a) != 1) {
            PyObject *shape = PyObject_GetAttrString(o, "shape");
            if (shape != NULL) {
                PyErr_Format(PyExc_TypeError, "%s: an array of shape %R is not three numbers (%s)", name, shape, unit);
                Py_DECREF(shape);
            }
            return 0;
        }
    }
    if (PyUnicode_Check(o) || PyBytes_Check(o) || !PySequence_Check(o)) {
        return not_three(o, name, unit);
    }
    if ((n = PySequence_Size(o)) < 0) {
        return not_three(o, name, unit);
    }
    if (n != 3) {
        PyErr_Format(PyExc_ValueError, "%s: expected three numbers (%s), got %zd", name, unit, n);
        return 0;
    }
    for (k = 0; k < 3; ++k) {
        PyObject *item = PySequence_GetItem(o, k);
        if (item == NULL) {
            return not_three(o, name, unit);
        }
        out[k] = PyFloat_AsDouble(item);
        Py_DECREF(item);
        if (out[k] == -1.0 && PyErr_Occurred()) {
            return not_three(o, name, unit);
        }
    }
    return 1;
}

/* The time step: a positive finite number of seconds (the filter refuses one above dt_max
 * itself, with a status). */
static int read_dt(const core_filter_obj *self, PyObject *o, double *dt)
{
    if (o == Py_None) {
        if (self->dt > 0.0) {
            *dt = self->dt;
            return 1;
        }
        PyErr_SetString(PyExc_ValueError, "dt: give the time step in s (update(..., dt=0.01)) or Filter(dt=...) "
                                          "for a fixed sample rate");
        return 0;
    }
    *dt = PyFloat_AsDouble(o);
    if (*dt == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "dt: %R is not a number (s)", o);
        return 0;
    }
    if (!(isfinite(*dt) && *dt > 0.0)) {
        PyErr_Format(PyExc_ValueError, "dt: %R is not a positive, finite time step (s)", o);
        return 0;
    }
    return 1;
}

static PyObject *new_array(const double *v, int rows, int cols)
{
    npy_intp dims[2];
    PyObject *a;
    dims[0] = rows;
    dims[1] = cols;
    a = PyArray_SimpleNew(cols > 0 ? 2 : 1, dims, NPY_DOUBLE);
    if (a != NULL) {
        memcpy(PyArray_DATA((PyArrayObject *)a), v, sizeof(double) * (size_t)rows * (size_t)(cols > 0 ? cols : 1));
    }
    return a;
}

static PyObject *flag_object(core_filter_obj *self, uint32_t bits)
{
    PyObject *key = PyLong_FromUnsignedLong(bits);
    PyObject *flag;
    if (key == NULL) {
        return NULL;
    }
    flag = PyDict_GetItemWithError(self->flag_cache, key); /* borrowed */
    if (flag != NULL) {
        Py_INCREF(flag);
    } else if (!PyErr_Occurred()) {
        flag = PyObject_CallFunctionObjArgs(self->flag_type, key, NULL);
        if (flag != NULL && PyDict_SetItem(self->flag_cache, key, flag) < 0) {
            Py_CLEAR(flag);
        }
    }
    Py_DECREF(key);
    return flag;
}

static PyObject *status_object(const core_filter_obj *self, ekf_status_t st)
{
    const Py_ssize_t code = (Py_ssize_t)st;
    if (code >= 0 && code < PyTuple_GET_SIZE(self->status_names)) {
        PyObject *s = PyTuple_GET_ITEM(self->status_names, code);
        Py_INCREF(s);
        return s;
    }
    return PyUnicode_FromString(ekf_status_str(st));
}

/* The Estimate after a step, fields in the order of CORE_ESTIMATE_FIELDS. */
static PyObject *make_estimate(core_filter_obj *self, ekf_status_t st)
{
    double q[4], e[3], c[6], cov[9], x[ATT_N], sigma[3], b[3], bs[3];
    PyObject *items, *args, *est;
    int k;
    core_attitude(&self->frame, &self->f, q, e);
    core_angle_cov(&self->frame, &self->f, c);
    core_unpack_cov(c, cov);
    core_state(&self->f, x, NULL);
    core_gyro_bias(&self->f, b, bs);
    for (k = 0; k < 3; ++k) {
        sigma[k] = sqrt(c[k]);
    }
    items = PyTuple_New(CORE_ESTIMATE_LEN);
    if (items == NULL) {
        return NULL;
    }
    PyTuple_SET_ITEM(items, 0, new_array(q, 4, 0));
    PyTuple_SET_ITEM(items, 1, new_array(e, 3, 0));
    PyTuple_SET_ITEM(items, 2, new_array(sigma, 3, 0));
    PyTuple_SET_ITEM(items, 3, new_array(&x[ATT_P], 3, 0));
    PyTuple_SET_ITEM(items, 4, flag_object(self, att_flags(&self->f)));
    PyTuple_SET_ITEM(items, 5, status_object(self, st));
    PyTuple_SET_ITEM(items, 6, new_array(cov, 3, 3));
    PyTuple_SET_ITEM(items, 7, new_array(b, 3, 0));
    PyTuple_SET_ITEM(items, 8, new_array(bs, 3, 0));
    if (PyErr_Occurred()) {
        Py_DECREF(items);
        return NULL;
    }
    /* tuple.__new__(Estimate, items), what a named tuple's own _make does */
    args = PyTuple_Pack(1, items);
    Py_DECREF(items);
    if (args == NULL) {
        return NULL;
    }
    est = PyTuple_Type.tp_new(self->estimate_type, args, NULL);
    Py_DECREF(args);
    return est;
}

static PyObject *filter_update(core_filter_obj *self, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    static const char *const names[4] = {"gyr", "acc", "mag", "dt"};
    PyObject *a[4] = {NULL, NULL, Py_None, Py_None};
    double g[3], acc[3], m[3], dt;
    const Py_ssize_t nkw = (kwnames == NULL) ? 0 : PyTuple_GET_SIZE(kwnames);
    Py_ssize_t i;
    int k;
    att_sample_t s;
    ekf_status_t st;
    if (nargs > 4) {
        PyErr_Format(PyExc_TypeError, "update() takes at most 4 arguments (%zd given)", nargs);
        return NULL;
    }
    for (i = 0; i < nargs; ++i) {
        a[i] = args[i];
    }
    for (i = 0; i < nkw; ++i) {
        PyObject *kw = PyTuple_GET_ITEM(kwnames, i);
        for (k = 0; k < 4 && PyUnicode_CompareWithASCIIString(kw, names[k]) != 0; ++k) {
        }
        if (k == 4 || (k < nargs)) {
            PyErr_Format(PyExc_TypeError, "update() got %s keyword argument %R",
                         (k == 4) ? "an unexpected" : "a repeated", kw);
            return NULL;
        }
        a[k] = args[nargs + i];
    }
    if (a[0] == NULL || a[1] == NULL) {
        PyErr_SetString(PyExc_TypeError, "update() needs gyr (rad/s) and acc (m/s^2)");
        return NULL;
    }
    if (self->estimate_type == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "Core.update: bind() was not called");
        return NULL;
    }
    if (!read3(a[0], "gyr", "rad/s", g) || !read3(a[1], "acc", "m/s^2", acc) ||
        (a[2] != Py_None && !read3(a[2], "mag", "uT", m)) || !read_dt(self, a[3], &dt) || !not_busy(self)) {
        return NULL;
    }
    core_sample(&self->frame, dt, g, acc, (a[2] != Py_None) ? m : NULL, &s);
    st = att_step(&self->f, &s, NULL);
    return make_estimate(self, st);
}

/* ------------------------------------------------------------------------------------
 * A batch: run(dt, gyr, acc, mag, state, var, quat, euler, angle_cov, flags, status,
 *              gyro_bias, gyro_bias_sigma)
 * ------------------------------------------------------------------------------------ */
enum { IN_DT, IN_GYR, IN_ACC, IN_MAG, OUT_STATE, OUT_VAR, OUT_QUAT, OUT_EULER, OUT_COV, OUT_FLAGS,
       OUT_STATUS, OUT_BIAS, OUT_BIAS_SIGMA, RUN_NARGS };

/* The array of argument k: C-contiguous, aligned, of the given type and shape (n, cols) or
 * (n,) for cols 0, writeable for an output; NULL for None where allowed. */
static int run_array(PyObject *o, int k, npy_intp n, int type, npy_intp cols, void **out)
{
    static const char *const names[RUN_NARGS] = {"dt", "gyr", "acc", "mag", "state", "var", "quat", "euler",
                                                 "angle_cov", "flags", "status", "gyro_bias", "gyro_bias_sigma"};
    PyArrayObject *a = (PyArrayObject *)o;
    const int ndim = (cols > 0) ? 2 : 1;
    *out = NULL;
    if (o == Py_None && k != IN_DT && k != IN_GYR && k != IN_ACC) {
        return 1;
    }
    if (!PyArray_Check(o) || PyArray_TYPE(a) != type || PyArray_NDIM(a) != ndim || !PyArray_IS_C_CONTIGUOUS(a) ||
        !PyArray_ISALIGNED(a) || PyArray_DIM(a, 0) != n || (cols > 0 && PyArray_DIM(a, 1) != cols) ||
        (k >= OUT_STATE && !PyArray_ISWRITEABLE(a))) {
        PyErr_Format(PyExc_ValueError, "run: %s must be a C-contiguous %s array of shape (%zd%s%zd)", names[k],
                     (type == NPY_DOUBLE) ? "float64" : (type == NPY_UINT32) ? "uint32" : "uint8", (Py_ssize_t)n,
                     (cols > 0) ? ", " : ",", (Py_ssize_t)cols);
        return 0;
    }
    *out = PyArray_DATA(a);
    return 1;
}

typedef struct {
    const double *dt, *gyr, *acc, *mag;
    double *state, *var, *quat, *euler, *cov, *bias, *bias_sigma;
    uint32_t *flags;
    uint8_t *status;
} run_io_t;

static void run_loop(att_ekf_t *f, const core_frame_t *fr, size_t n, const run_io_t *io)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        att_sample_t s;
        att_step_report_t rep;
        ekf_status_t st;
        double q[4], e[3], b[3], bs[3];
        core_sample(fr, io->dt[i], &io->gyr[3 * i], &io->acc[3 * i], (io->mag != NULL) ? &io->mag[3 * i] : NULL, &s);
        st = att_step(f, &s, &rep);
        if (io->state != NULL || io->var != NULL) {
            core_state(f, (io->state != NULL) ? &io->state[(size_t)ATT_N * i] : NULL,
                       (io->var != NULL) ? &io->var[(size_t)ATT_N * i] : NULL);
        }
        if (io->quat != NULL || io->euler != NULL) {
            core_attitude(fr, f, (io->quat != NULL) ? &io->quat[4 * i] : q, (io->euler != NULL) ? &io->euler[3 * i] : e);
        }
        if (io->cov != NULL) {
            core_angle_cov(fr, f, &io->cov[6 * i]);
        }
        if (io->bias != NULL || io->bias_sigma != NULL) {
            core_gyro_bias(f, (io->bias != NULL) ? &io->bias[3 * i] : b,
                           (io->bias_sigma != NULL) ? &io->bias_sigma[3 * i] : bs);
        }
        if (io->flags != NULL) {
            io->flags[i] = att_flags(f);
        }
        if (io->status != NULL) {
            uint8_t *row = &io->status[(size_t)CORE_STATUS_COLS * i];
            row[CORE_STATUS_STEP] = (uint8_t)st;
            row[CORE_STATUS_PREDICT] = (uint8_t)rep.predict;
            row[CORE_STATUS_GYRO] = (uint8_t)rep.gyro;
            row[CORE_STATUS_ACCEL] = (uint8_t)rep.accel;
            row[CORE_STATUS_MAG] = (uint8_t)rep.mag;
        }
    }
}

static PyObject *filter_run(core_filter_obj *self, PyObject *const *args, Py_ssize_t nargs)
{
    run_io_t io;
    void *p[RUN_NARGS];
    npy_intp n;
    if (nargs != RUN_NARGS) {
        PyErr_Format(PyExc_TypeError, "run() takes %d arguments (%zd given)", (int)RUN_NARGS, nargs);
        return NULL;
    }
    if (!PyArray_Check(args[IN_DT]) || PyArray_NDIM((PyArrayObject *)args[IN_DT]) != 1) {
        PyErr_SetString(PyExc_ValueError, "run: dt must be a float64 array of shape (n,)");
        return NULL;
    }
    n = PyArray_DIM((PyArrayObject *)args[IN_DT], 0);
    if (!run_array(args[IN_DT], IN_DT, n, NPY_DOUBLE, 0, &p[IN_DT]) ||
        !run_array(args[IN_GYR], IN_GYR, n, NPY_DOUBLE, 3, &p[IN_GYR]) ||
        !run_array(args[IN_ACC], IN_ACC, n, NPY_DOUBLE, 3, &p[IN_ACC]) ||
        !run_array(args[IN_MAG], IN_MAG, n, NPY_DOUBLE, 3, &p[IN_MAG]) ||
        !run_array(args[OUT_STATE], OUT_STATE, n, NPY_DOUBLE, ATT_N, &p[OUT_STATE]) ||
        !run_array(args[OUT_VAR], OUT_VAR, n, NPY_DOUBLE, ATT_N, &p[OUT_VAR]) ||
        !run_array(args[OUT_QUAT], OUT_QUAT, n, NPY_DOUBLE, 4, &p[OUT_QUAT]) ||
        !run_array(args[OUT_EULER], OUT_EULER, n, NPY_DOUBLE, 3, &p[OUT_EULER]) ||
        !run_array(args[OUT_COV], OUT_COV, n, NPY_DOUBLE, 6, &p[OUT_COV]) ||
        !run_array(args[OUT_FLAGS], OUT_FLAGS, n, NPY_UINT32, 0, &p[OUT_FLAGS]) ||
        !run_array(args[OUT_STATUS], OUT_STATUS, n, NPY_UINT8, CORE_STATUS_COLS, &p[OUT_STATUS]) ||
        !run_array(args[OUT_BIAS], OUT_BIAS, n, NPY_DOUBLE, 3, &p[OUT_BIAS]) ||
        !run_array(args[OUT_BIAS_SIGMA], OUT_BIAS_SIGMA, n, NPY_DOUBLE, 3, &p[OUT_BIAS_SIGMA]) || !not_busy(self)) {
        return NULL;
    }
    io.dt = p[IN_DT];
    io.gyr = p[IN_GYR];
    io.acc = p[IN_ACC];
    io.mag = p[IN_MAG];
    io.state = p[OUT_STATE];
    io.var = p[OUT_VAR];
    io.quat = p[OUT_QUAT];
    io.euler = p[OUT_EULER];
    io.cov = p[OUT_COV];
    io.flags = p[OUT_FLAGS];
    io.status = p[OUT_STATUS];
    io.bias = p[OUT_BIAS];
    io.bias_sigma = p[OUT_BIAS_SIGMA];
    /* the arrays stay alive (the caller holds them); the filter is guarded by busy */
    self->busy = 1;
    Py_BEGIN_ALLOW_THREADS
    run_loop(&self->f, &self->frame, (size_t)n, &io);
    Py_END_ALLOW_THREADS
    self->busy = 0;
    Py_RETURN_NONE;
}

/* ------------------------------------------------------------------------------------
 * Reset, settings, diagnostics, state
 * ------------------------------------------------------------------------------------ */
static PyObject *filter_reset(core_filter_obj *self, PyObject *unused)
{
    (void)unused;
    if (!not_busy(self)) {
        return NULL;
    }
    (void)att_reset(&self->f);
    Py_RETURN_NONE;
}

static PyObject *filter_settings(core_filter_obj *self, PyObject *unused)
{
    core_settings_obj *out = PyObject_New(core_settings_obj, &core_settings_type);
    (void)unused;
    if (out != NULL) {
        out->s = *att_settings(&self->f);
    }
    return (PyObject *)out;
}

static PyObject *filter_diag(core_filter_obj *self, PyObject *unused)
{
    (void)unused;
    return not_busy(self) ? core_diag_values(&self->f, 1) : NULL;
}

static PyObject *filter_diag_values(core_filter_obj *self, PyObject *unused)
{
    (void)unused;
    return not_busy(self) ? core_diag_values(&self->f, 0) : NULL;
}

/* The filter's memory (att_ekf_t: settings and variables) as bytes. */
static PyObject *filter_state_bytes(core_filter_obj *self, PyObject *unused)
{
    (void)unused;
    return not_busy(self) ? PyBytes_FromStringAndSize((const char *)&self->f, (Py_ssize_t)sizeof self->f) : NULL;
}

/* 1 if what a state's bytes hold can be a filter of this build: settings that pass
 * att_settings_check, a finite state and covariance. attekf.Filter.set_state checks the
 * bytes' origin (scalar, layout, checksum) before. */
static int state_usable(const att_ekf_t *f)
{
    ekf_scalar_t P[ATT_N * ATT_N];
    const ekf_scalar_t *x = att_state(f);
    int k;
    if (att_settings_check(att_settings(f)) != EKF_OK) {
        return 0;
    }
    att_get_covariance(f, P);
    for (k = 0; k < ATT_N * ATT_N; ++k) {
        if (!ekf_isfinite(P[k]) || (k < ATT_N && !ekf_isfinite(x[k]))) {
            return 0;
        }
    }
    return 1;
}

static PyObject *filter_load_state(core_filter_obj *self, PyObject *arg)
{
    att_ekf_t f;
    Py_buffer view;
    if (!not_busy(self) || PyObject_GetBuffer(arg, &view, PyBUF_SIMPLE) < 0) {
        return NULL;
    }
    if (view.len != (Py_ssize_t)sizeof f) {
        PyErr_Format(PyExc_ValueError, "state of %zd bytes, this build's filter has %zd", view.len,
                     (Py_ssize_t)sizeof f);
        PyBuffer_Release(&view);
        return NULL;
    }
    memcpy(&f, view.buf, sizeof f);
    PyBuffer_Release(&view);
    if (!state_usable(&f)) {
        PyErr_SetString(PyExc_ValueError, "state refused: its settings fail att_settings_check or its state or "
                                          "covariance is not finite");
        return NULL;
    }
    self->f = f;
    Py_RETURN_NONE;
}

/* An independent copy: the same filter memory, configuration and bound types. */
static PyObject *filter_copy(core_filter_obj *self, PyObject *unused)
{
    core_filter_obj *out;
    (void)unused;
    if (!not_busy(self)) {
        return NULL;
    }
    out = (core_filter_obj *)core_filter_type.tp_alloc(&core_filter_type, 0);
    if (out == NULL) {
        return NULL;
    }
    out->f = self->f;
    out->frame = self->frame;
    out->dt = self->dt;
    Py_XINCREF(self->estimate_type);
    Py_XINCREF(self->flag_type);
    Py_XINCREF(self->flag_cache);
    Py_XINCREF(self->status_names);
    out->estimate_type = self->estimate_type;
    out->flag_type = self->flag_type;
    out->flag_cache = self->flag_cache;
    out->status_names = self->status_names;
    return (PyObject *)out;
}

static PyMethodDef filter_methods[] = {
    {"bind", (PyCFunction)filter_bind, METH_VARARGS, "bind(Estimate, Flag, status_names)"},
    {"configure", (PyCFunction)filter_configure, METH_VARARGS, "configure(dt s or 0, mount (9 floats) or None, ned)"},
    {"update", (PyCFunction)(void (*)(void))filter_update, METH_FASTCALL | METH_KEYWORDS,
     "update(gyr, acc, mag=None, dt=None) -> Estimate (attekf.Filter.update)"},
    {"run", (PyCFunction)(void (*)(void))filter_run, METH_FASTCALL,
     "run(dt, gyr, acc, mag, state, var, quat, euler, angle_cov, flags, status, gyro_bias, gyro_bias_sigma): "
     "att_step over the rows, outputs (None: not wanted) written per row"},
    {"reset", (PyCFunction)filter_reset, METH_NOARGS, "att_reset: not aligned, the same settings"},
    {"settings", (PyCFunction)filter_settings, METH_NOARGS, "a copy of the settings in force (Settings)"},
    {"diag", (PyCFunction)filter_diag, METH_NOARGS, "the counters of att_diag_t (diag_tables() order)"},
    {"diag_values", (PyCFunction)filter_diag_values, METH_NOARGS, "the other fields of att_diag_t"},
    {"state_bytes", (PyCFunction)filter_state_bytes, METH_NOARGS, "the att_ekf_t as bytes"},
    {"load_state", (PyCFunction)filter_load_state, METH_O, "load_state(bytes): the filter from state_bytes()"},
    {"copy", (PyCFunction)filter_copy, METH_NOARGS, "an independent copy"},
    {NULL, NULL, 0, NULL}};

PyTypeObject core_filter_type = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "attekf." Py_STRINGIFY(CORE_MODULE) ".Core",
    .tp_basicsize = sizeof(core_filter_obj),
    .tp_dealloc = (destructor)filter_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Core(settings): one att_ekf_t initialised with the settings (attekf.Filter wraps it).",
    .tp_new = filter_new,
    .tp_methods = filter_methods,
};
