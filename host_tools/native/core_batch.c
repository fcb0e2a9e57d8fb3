/*
 * core_batch.c - the batch calls of the Core type (see core.h): run, att_step over arrays
 * (Filter.update_batch, attekf.estimate), and smooth, the filter and its Rauch-Tung-Striebel
 * smoother over arrays (attekf.smooth; smooth_att.c, docs/derivation.md "Smoother"). Both
 * release the GIL while the C loop runs.
 */
#include "core.h"

#include "smooth_att.h"

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

static void run_loop(att_ekf_t *f, const core_frame_t *fr, size_t n, const core_run_io_t *io)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        att_sample_t s;
        att_step_report_t rep;
        ekf_status_t st;
        core_run_sample(fr, io, i, &s);
        st = att_step(f, &s, &rep);
        core_write_row(fr, f, i, st, &rep, io);
    }
}

/* The arrays of a batch call (the first RUN_NARGS arguments) into io and n; 0 with an
 * exception set if any is wrong. */
static int run_arrays(core_filter_obj *self, PyObject *const *args, core_run_io_t *io, npy_intp *count)
{
    void *p[RUN_NARGS];
    npy_intp n;
    if (!PyArray_Check(args[IN_DT]) || PyArray_NDIM((PyArrayObject *)args[IN_DT]) != 1) {
        PyErr_SetString(PyExc_ValueError, "run: dt must be a float64 array of shape (n,)");
        return 0;
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
        !run_array(args[OUT_BIAS_SIGMA], OUT_BIAS_SIGMA, n, NPY_DOUBLE, 3, &p[OUT_BIAS_SIGMA]) || !core_not_busy(self)) {
        return 0;
    }
    io->dt = p[IN_DT];
    io->gyr = p[IN_GYR];
    io->acc = p[IN_ACC];
    io->mag = p[IN_MAG];
    io->state = p[OUT_STATE];
    io->var = p[OUT_VAR];
    io->quat = p[OUT_QUAT];
    io->euler = p[OUT_EULER];
    io->cov = p[OUT_COV];
    io->flags = p[OUT_FLAGS];
    io->status = p[OUT_STATUS];
    io->bias = p[OUT_BIAS];
    io->bias_sigma = p[OUT_BIAS_SIGMA];
    *count = n;
    return 1;
}

PyObject *core_filter_run(core_filter_obj *self, PyObject *const *args, Py_ssize_t nargs)
{
    core_run_io_t io;
    npy_intp n;
    if (nargs != RUN_NARGS) {
        PyErr_Format(PyExc_TypeError, "run() takes %d arguments (%zd given)", (int)RUN_NARGS, nargs);
        return NULL;
    }
    if (!run_arrays(self, args, &io, &n)) {
        return NULL;
    }
    /* the arrays stay alive (the caller holds them); the filter is guarded by busy */
    self->busy = 1;
    Py_BEGIN_ALLOW_THREADS
    run_loop(&self->f, &self->frame, (size_t)n, &io);
    Py_END_ALLOW_THREADS
    self->busy = 0;
    Py_RETURN_NONE;
}


/* ------------------------------------------------------------------------------------
 * smooth(<the arguments of run>, seg_len, progress) -> dict of the smoother's counts
 * ------------------------------------------------------------------------------------ */
typedef struct {
    PyObject *callback; /* progress(k) or None */
} progress_ctx_t;

/* The smoother's progress callback, called without the GIL: takes it, calls progress(done),
 * and stops the run on an exception (that of the callback, or a signal such as Ctrl-C). */
static int call_progress(void *ctx, size_t done)
{
    const progress_ctx_t *p = (const progress_ctx_t *)ctx;
    PyGILState_STATE g = PyGILState_Ensure();
    int stop = 0;
    if (p->callback != Py_None) {
        PyObject *r = PyObject_CallFunction(p->callback, "n", (Py_ssize_t)done);
        stop = (r == NULL);
        Py_XDECREF(r);
    }
    if (!stop && PyErr_CheckSignals() < 0) {
        stop = 1;
    }
    PyGILState_Release(g);
    return stop;
}

/* The smoother's buffers for n samples in segments of seg_len (PyMem_Raw: usable without the
 * GIL); 0 with MemoryError set if they do not fit. */
static int alloc_buffers(smooth_buffers_t *b, size_t n, size_t seg_len)
{
    const size_t ck = smooth_checkpoints(n, seg_len);
    memset(b, 0, sizeof *b);
    b->seg_len = seg_len;
    if (seg_len > PY_SSIZE_T_MAX / sizeof(att_trace_t) || ck > PY_SSIZE_T_MAX / sizeof(att_ekf_t)) {
        PyErr_NoMemory();
        return 0;
    }
    b->trace = PyMem_RawMalloc(seg_len * sizeof(att_trace_t));
    b->trace_sample = PyMem_RawMalloc(seg_len * sizeof(size_t));
    b->trace_event = PyMem_RawMalloc(seg_len);
    b->ckpt = PyMem_RawMalloc((ck > 0 ? ck : 1) * sizeof(att_ekf_t));
    if (b->trace == NULL || b->trace_sample == NULL || b->trace_event == NULL || b->ckpt == NULL) {
        PyErr_NoMemory();
        return 0;
    }
    return 1;
}

static void free_buffers(smooth_buffers_t *b)
{
    PyMem_RawFree(b->trace);
    PyMem_RawFree(b->trace_sample);
    PyMem_RawFree(b->trace_event);
    PyMem_RawFree(b->ckpt);
}

PyObject *core_filter_smooth(core_filter_obj *self, PyObject *const *args, Py_ssize_t nargs)
{
    core_run_io_t io;
    smooth_buffers_t buf;
    smooth_report_t rep;
    progress_ctx_t ctx;
    npy_intp n;
    Py_ssize_t seg_len;
    int stopped;
    if (nargs != RUN_NARGS + 2) {
        PyErr_Format(PyExc_TypeError, "smooth() takes %d arguments (%zd given)", (int)RUN_NARGS + 2, nargs);
        return NULL;
    }
    seg_len = PyLong_AsSsize_t(args[RUN_NARGS]);
    if (seg_len == -1 && PyErr_Occurred()) {
        return NULL;
    }
    if (seg_len < 1) {
        PyErr_Format(PyExc_ValueError, "smooth: seg_len %zd, must be at least 1 (samples)", seg_len);
        return NULL;
    }
    if (!run_arrays(self, args, &io, &n)) {
        return NULL;
    }
    if (io.state == NULL || io.var == NULL || io.quat == NULL || io.euler == NULL || io.cov == NULL ||
        io.flags == NULL || io.status == NULL || io.bias == NULL || io.bias_sigma == NULL) {
        PyErr_SetString(PyExc_ValueError, "smooth: every output array is needed (None given)");
        return NULL;
    }
    if (!alloc_buffers(&buf, (size_t)n, (size_t)seg_len)) {
        free_buffers(&buf);
        return NULL;
    }
    ctx.callback = args[RUN_NARGS + 1];
    buf.ckpt[0] = self->f; /* the filter as it was: put back if the run is stopped */
    self->busy = 1;
    Py_BEGIN_ALLOW_THREADS
    stopped = smooth_run(&self->f, &self->frame, (size_t)n, &io, &buf, call_progress, &ctx, &rep);
    if (stopped) {
        self->f = buf.ckpt[0]; /* the first checkpoint is the filter before the run */
    }
    Py_END_ALLOW_THREADS
    self->busy = 0;
    free_buffers(&buf);
    if (stopped) {
        if (!PyErr_Occurred()) {
            PyErr_SetString(PyExc_RuntimeError, "smooth: stopped");
        }
        return NULL;
    }
    return Py_BuildValue("{sIsIsIsIsIsI}", "epochs", rep.epochs, "heading_cuts", rep.heading_cuts, "rate_cuts",
                         rep.rate_cuts, "not_pd", rep.not_pd, "branch_flips", rep.branch_flips, "recomputed",
                         rep.recomputed);
}
