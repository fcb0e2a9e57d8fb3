/*
 * core.h - the C estimator (firmware/att) as a CPython extension module, one per scalar
 * build: attekf._core_f (float, what runs on the microcontroller), _core_d (double) and
 * _core_x (Q-format fixed point). host_tools/attekf/native.py loads it; users see it
 * through attekf.Filter and attekf.estimate (host_tools/attekf/filter.py).
 *
 * What it exports (everything Python needs is read from the C library, so Python never
 * mirrors a C struct layout or a table):
 *   core_module.c  the module: the settings table (att_setting_info, help texts expanded
 *                  from att_settings_table.h), status names, the diagnostics tables, the
 *                  state's size and layout tag, and the Settings type (an att_settings_t
 *                  set and read by table index through att_setting_set / att_setting_get);
 *   core_filter.c  the Core type: one att_ekf_t, its per-sample update (the fast path of
 *                  Filter.update), the batch runner over arrays (the C loop of
 *                  Filter.update_batch), reset, and the state as bytes.
 * core_io.c does the plain-C part of both (inputs, mounting, output frame, alignment).
 *
 * CMake compiles these files once per scalar build with CORE_MODULE set to the module's
 * name and CORE_LAYOUT to a digest of the estimator's headers (a state saved by another
 * build or version is refused: attekf/filter.py).
 */
#ifndef CORE_H
#define CORE_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>

/* numpy's C API, as of numpy 1.23 (the oldest numpy the module runs with); one file
 * (core_module.c) imports it, the other uses it through the same table. */
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#define NPY_TARGET_VERSION NPY_1_23_API_VERSION
#define PY_ARRAY_UNIQUE_SYMBOL attekf_core_ARRAY_API
#ifndef CORE_IMPORTS_NUMPY
#define NO_IMPORT_ARRAY
#endif
#include <numpy/arrayobject.h>

#include "att.h"
#include "core_io.h"

#ifndef CORE_MODULE
#error "CORE_MODULE (the module's name, e.g. _core_f) must be defined by the build"
#endif
#ifndef CORE_LAYOUT
#error "CORE_LAYOUT (digest of the estimator's headers) must be defined by the build"
#endif

/* Bumped when a function or type of the module changes; native.py refuses other versions. */
#define CORE_API_VERSION 3

/* Columns of the per-sample status array of Core.run (status[i * CORE_STATUS_COLS + k]). */
enum {
    CORE_STATUS_STEP = 0, /* att_step's return value */
    CORE_STATUS_PREDICT = 1, /* att_step_report_t fields */
    CORE_STATUS_GYRO = 2,
    CORE_STATUS_ACCEL = 3,
    CORE_STATUS_MAG = 4,
    CORE_STATUS_COLS = 5
};

/* An att_settings_t as a Python object (attekf.native keeps one per Filter). */
typedef struct {
    PyObject_HEAD
    att_settings_t s;
} core_settings_obj;

extern PyTypeObject core_settings_type;
extern PyTypeObject core_filter_type;

/* The fields of attekf.Estimate in the order core_filter.c fills them (exported as
 * ESTIMATE_FIELDS; native.py checks that the Python type has exactly these). */
#define CORE_ESTIMATE_FIELDS \
    "quaternion", "euler", "sigma", "rate", "flags", "status", "covariance", "gyro_bias", "gyro_bias_sigma"
#define CORE_ESTIMATE_LEN 9

/* Every counter of att_diag(f) (counters != 0: a tuple of ints) or every other diagnostic
 * (a tuple of floats, an array field element by element), in the order of diag_tables(). */
PyObject *core_diag_values(const att_ekf_t *f, int counters);

#endif /* CORE_H */
