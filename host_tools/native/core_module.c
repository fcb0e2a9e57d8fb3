/*
 * core_module.c - the extension module: its tables and the Settings type (see core.h).
 */
#define CORE_IMPORTS_NUMPY /* this file calls import_array */
#include "core.h"

#include <math.h>
#include <stddef.h>
#include <string.h>


/* ------------------------------------------------------------------------------------
 * Settings: the estimator's own table (att_setting_info, expanded from
 * att_settings_table.h) and the help text of the same rows.
 * ------------------------------------------------------------------------------------ */
#define HELP_ROW(name, type, def, def_fixed, lo, hi, check, live, unit, help) help,
static const char *const k_help[] = {
    ATT_SETTINGS_MAIN(HELP_ROW) ATT_SETTINGS_REST(HELP_ROW) ATT_SETTINGS_BIAS(HELP_ROW)};

#define N_HELP (sizeof k_help / sizeof k_help[0])

static size_t field_size(const att_setting_info_t *r)
{
    return (r->type == ATT_SETTING_U16) ? sizeof(uint16_t) : sizeof(ekf_scalar_t);
}

/* ((name, unit, help, is_count, lo, hi, live), ...) in table order. */
static PyObject *settings_table(PyObject *self, PyObject *unused)
{
    const size_t n = att_setting_count();
    PyObject *out;
    size_t i;
    (void)self;
    (void)unused;
    if (n != N_HELP) {
        PyErr_SetString(PyExc_RuntimeError, "att_setting_count differs from the rows of att_settings_table.h");
        return NULL;
    }
    out = PyTuple_New((Py_ssize_t)n);
    for (i = 0; out != NULL && i < n; ++i) {
        const att_setting_info_t *r = att_setting_info(i);
        PyObject *row = Py_BuildValue("(sssNddN)", r->name, r->unit, k_help[i],
                                      PyBool_FromLong(r->type == ATT_SETTING_U16), ekf_to_double(r->lo),
                                      ekf_to_double(r->hi), PyBool_FromLong(r->live));
        if (row == NULL) {
            Py_CLEAR(out);
            break;
        }
        PyTuple_SET_ITEM(out, (Py_ssize_t)i, row);
    }
    return out;
}

/* 1 if the rows tile att_settings_t in declaration order (no field left out, up to
 * alignment padding, which is smaller than the field that follows it). */
static int settings_table_complete(void)
{
    size_t i, end = 0;
    for (i = 0; i < att_setting_count(); ++i) {
        const att_setting_info_t *r = att_setting_info(i);
        if (r->offset < end || r->offset - end >= field_size(r)) {
            return 0;
        }
        end = r->offset + field_size(r);
    }
    return sizeof(att_settings_t) >= end && sizeof(att_settings_t) - end < sizeof(ekf_scalar_t);
}

/* ------------------------------------------------------------------------------------
 * Diagnostics: the uint32 counters and the other fields of att_diag_t (ekf_scalar_t,
 * arrays element by element), each table in declaration order, which
 * diag_tables_complete() relies on.
 * ------------------------------------------------------------------------------------ */
typedef struct {
    const char *name;
    size_t offset;
} diag_row_t;

#define DIAG_ROW(field) {#field, offsetof(att_diag_t, field)}

static const diag_row_t k_diag[] = {
    DIAG_ROW(steps),       DIAG_ROW(gyro_fused),     DIAG_ROW(accel_fused),   DIAG_ROW(mag_fused),
    DIAG_ROW(gyro_gated),  DIAG_ROW(accel_gated),    DIAG_ROW(mag_gated),     DIAG_ROW(accel_skipped),
    DIAG_ROW(mag_skipped), DIAG_ROW(rejected),       DIAG_ROW(numeric),       DIAG_ROW(remaps),
    DIAG_ROW(cov_repairs), DIAG_ROW(heading_resets), DIAG_ROW(gyro_saturated),
};

#define N_DIAG (sizeof k_diag / sizeof k_diag[0])

typedef struct {
    const char *name;
    size_t offset;
    size_t len; /* elements (ekf_scalar_t) */
    const char *unit;
} diag_value_row_t;

#define DIAG_VALUE_ROW(field, unit) \
    {#field, offsetof(att_diag_t, field), sizeof(((att_diag_t *)0)->field) / sizeof(ekf_scalar_t), unit}

static const diag_value_row_t k_diag_values[] = {
    DIAG_VALUE_ROW(gyro_ratio, "1"),           DIAG_VALUE_ROW(accel_ratio, "1"),
    DIAG_VALUE_ROW(mag_ratio, "1"),            DIAG_VALUE_ROW(accel_norm_error, "m/s^2"),
    DIAG_VALUE_ROW(mag_norm_error, "1"),       DIAG_VALUE_ROW(mag_dip_error, "rad"),
};

#define N_DIAG_VALUES (sizeof k_diag_values / sizeof k_diag_values[0])

static int diag_tables_complete(void)
{
    size_t i, end = 0; /* first byte after the previous field */
    for (i = 0; i < N_DIAG; ++i) {
        if (k_diag[i].offset != end) {
            return 0; /* a counter missing (uint32 fields pack without padding) */
        }
        end += sizeof(uint32_t);
    }
    for (i = 0; i < N_DIAG_VALUES; ++i) {
        if (k_diag_values[i].offset < end || k_diag_values[i].offset - end >= sizeof(ekf_scalar_t)) {
            return 0;
        }
        end = k_diag_values[i].offset + k_diag_values[i].len * sizeof(ekf_scalar_t);
    }
    return sizeof(att_diag_t) >= end && sizeof(att_diag_t) - end < sizeof(ekf_scalar_t);
}

/* ((counter names...), ((value name, unit, elements), ...)) */
static PyObject *diag_tables(PyObject *self, PyObject *unused)
{
    PyObject *names = PyTuple_New((Py_ssize_t)N_DIAG);
    PyObject *values = PyTuple_New((Py_ssize_t)N_DIAG_VALUES);
    size_t i;
    (void)self;
    (void)unused;
    if (names == NULL || values == NULL) {
        goto fail;
    }
    for (i = 0; i < N_DIAG; ++i) {
        PyObject *s = PyUnicode_FromString(k_diag[i].name);
        if (s == NULL) {
            goto fail;
        }
        PyTuple_SET_ITEM(names, (Py_ssize_t)i, s);
    }
    for (i = 0; i < N_DIAG_VALUES; ++i) {
        PyObject *row = Py_BuildValue("(ssn)", k_diag_values[i].name, k_diag_values[i].unit,
                                      (Py_ssize_t)k_diag_values[i].len);
        if (row == NULL) {
            goto fail;
        }
        PyTuple_SET_ITEM(values, (Py_ssize_t)i, row);
    }
    return Py_BuildValue("(NN)", names, values);
fail:
    Py_XDECREF(names);
    Py_XDECREF(values);
    return NULL;
}

PyObject *core_diag_values(const att_ekf_t *f, int counters)
{
    const unsigned char *base = (const unsigned char *)att_diag(f);
    PyObject *out;
    size_t i, k, n = 0;
    if (counters) {
        out = PyTuple_New((Py_ssize_t)N_DIAG);
        for (i = 0; out != NULL && i < N_DIAG; ++i) {
            uint32_t v;
            PyObject *o;
            memcpy(&v, base + k_diag[i].offset, sizeof v);
            if ((o = PyLong_FromUnsignedLong(v)) == NULL) {
                Py_CLEAR(out);
                break;
            }
            PyTuple_SET_ITEM(out, (Py_ssize_t)i, o);
        }
        return out;
    }
    for (i = 0; i < N_DIAG_VALUES; ++i) {
        n += k_diag_values[i].len;
    }
    out = PyTuple_New((Py_ssize_t)n);
    n = 0;
    for (i = 0; out != NULL && i < N_DIAG_VALUES; ++i) {
        for (k = 0; k < k_diag_values[i].len; ++k) {
            ekf_scalar_t v;
            PyObject *o;
            memcpy(&v, base + k_diag_values[i].offset + k * sizeof v, sizeof v);
            if ((o = PyFloat_FromDouble(ekf_to_double(v))) == NULL) {
                Py_CLEAR(out);
                break;
            }
            PyTuple_SET_ITEM(out, (Py_ssize_t)n++, o);
        }
    }
    return out;
}

/* (settings table complete, diagnostics tables complete): catches a field added to
 * att_settings_t or att_diag_t but not to its table. */
static PyObject *tables_complete(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return Py_BuildValue("(NN)", PyBool_FromLong(settings_table_complete()), PyBool_FromLong(diag_tables_complete()));
}

static PyObject *status_name(PyObject *self, PyObject *arg)
{
    const long code = PyLong_AsLong(arg);
    (void)self;
    if (code == -1 && PyErr_Occurred()) {
        return NULL;
    }
    return PyUnicode_FromString(ekf_status_str((ekf_status_t)code));
}

/* ------------------------------------------------------------------------------------
 * Settings type: an att_settings_t, the defaults when created.
 * ------------------------------------------------------------------------------------ */
static PyObject *settings_new(PyTypeObject *type, PyObject *args, PyObject *kwds)
{
    core_settings_obj *self;
    if (PyTuple_GET_SIZE(args) != 0 || (kwds != NULL && PyDict_GET_SIZE(kwds) != 0)) {
        PyErr_SetString(PyExc_TypeError, "Settings() takes no arguments");
        return NULL;
    }
    self = (core_settings_obj *)type->tp_alloc(type, 0);
    if (self != NULL) {
        self->s = att_default_settings;
    }
    return (PyObject *)self;
}

static int index_arg(PyObject *arg, size_t *i)
{
    const Py_ssize_t v = PyLong_AsSsize_t(arg);
    if (v == -1 && PyErr_Occurred()) {
        return 0;
    }
    if (v < 0 || (size_t)v >= att_setting_count()) {
        PyErr_Format(PyExc_IndexError, "no setting %zd", v);
        return 0;
    }
    *i = (size_t)v;
    return 1;
}

/* set(i, value) -> ekf_status_t of att_setting_set (EKF_OK, or the settings unchanged). A
 * value the build's scalar cannot hold (beyond float's range, the Q format's) is refused
 * like one out of range. */
static PyObject *settings_set(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    size_t i;
    double value;
    ekf_scalar_t v;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "set(index, value)");
        return NULL;
    }
    if (!index_arg(args[0], &i)) {
        return NULL;
    }
    value = PyFloat_AsDouble(args[1]);
    if (value == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    v = ekf_from_double(value);
    if (!isfinite(value) || !ekf_isfinite(v)) {
        return PyLong_FromLong((long)EKF_ERR_SETTINGS);
    }
    return PyLong_FromLong((long)att_setting_set(&((core_settings_obj *)self)->s, i, v));
}

static PyObject *settings_get(PyObject *self, PyObject *arg)
{
    size_t i;
    ekf_scalar_t v;
    if (!index_arg(arg, &i)) {
        return NULL;
    }
    (void)att_setting_get(&((core_settings_obj *)self)->s, i, &v);
    return PyFloat_FromDouble(ekf_to_double(v));
}

static PyObject *settings_check(PyObject *self, PyObject *unused)
{
    (void)unused;
    return PyLong_FromLong((long)att_settings_check(&((core_settings_obj *)self)->s));
}

static PyObject *settings_copy(PyObject *self, PyObject *unused)
{
    core_settings_obj *out = PyObject_New(core_settings_obj, &core_settings_type);
    (void)unused;
    if (out != NULL) {
        out->s = ((core_settings_obj *)self)->s;
    }
    return (PyObject *)out;
}

static PyMethodDef settings_methods[] = {
    {"set", (PyCFunction)(void (*)(void))settings_set, METH_FASTCALL,
     "set(index, value) -> ekf_status_t of att_setting_set (0: set; else unchanged)"},
    {"get", settings_get, METH_O, "get(index) -> the value (a count as a float)"},
    {"check", settings_check, METH_NOARGS, "check() -> ekf_status_t of att_settings_check"},
    {"copy", settings_copy, METH_NOARGS, "an independent copy"},
    {NULL, NULL, 0, NULL}};

PyTypeObject core_settings_type = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "attekf." Py_STRINGIFY(CORE_MODULE) ".Settings",
    .tp_basicsize = sizeof(core_settings_obj),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "att_settings_t: the defaults (att_default_settings) when created; set and read by "
              "table index (settings_table()).",
    .tp_new = settings_new,
    .tp_methods = settings_methods,
};

/* ------------------------------------------------------------------------------------
 * The module
 * ------------------------------------------------------------------------------------ */
static PyMethodDef module_methods[] = {
    {"settings_table", settings_table, METH_NOARGS,
     "settings_table() -> ((name, unit, help, is_count, lo, hi, live), ...) in table order"},
    {"diag_tables", diag_tables, METH_NOARGS,
     "diag_tables() -> ((counter names), ((value name, unit, elements), ...)) of att_diag_t"},
    {"tables_complete", tables_complete, METH_NOARGS,
     "tables_complete() -> (settings table tiles att_settings_t, diagnostics tables tile att_diag_t)"},
    {"status_name", status_name, METH_O, "status_name(code) -> ekf_status_str(code)"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, Py_STRINGIFY(CORE_MODULE),
    "The C estimator (firmware/att), " EKF_SCALAR_NAME " build: see attekf.Filter.", -1, module_methods,
    NULL, NULL, NULL, NULL};

static int add_constants(PyObject *m)
{
    static const char *const estimate_fields[] = {CORE_ESTIMATE_FIELDS};
    static const char *const status_cols[] = {"step", "predict", "gyro", "accel", "mag"};
    PyObject *fields = PyTuple_New(CORE_ESTIMATE_LEN);
    PyObject *cols = PyTuple_New(CORE_STATUS_COLS);
    Py_ssize_t i;
    if (fields == NULL || cols == NULL) {
        Py_XDECREF(fields);
        Py_XDECREF(cols);
        return -1;
    }
    for (i = 0; i < CORE_ESTIMATE_LEN; ++i) {
        PyTuple_SET_ITEM(fields, i, PyUnicode_FromString(estimate_fields[i]));
    }
    for (i = 0; i < CORE_STATUS_COLS; ++i) {
        PyTuple_SET_ITEM(cols, i, PyUnicode_FromString(status_cols[i]));
    }
    if (PyErr_Occurred() || PyModule_AddObject(m, "ESTIMATE_FIELDS", fields) < 0) {
        Py_DECREF(fields);
        Py_DECREF(cols);
        return -1;
    }
    if (PyModule_AddObject(m, "STATUS_COLUMNS", cols) < 0) {
        Py_DECREF(cols);
        return -1;
    }
    return (PyModule_AddIntConstant(m, "API_VERSION", CORE_API_VERSION) < 0 ||
            PyModule_AddStringConstant(m, "SCALAR", EKF_SCALAR_NAME) < 0 ||
            PyModule_AddStringConstant(m, "LAYOUT", CORE_LAYOUT) < 0 ||
            PyModule_AddIntConstant(m, "N_STATES", ATT_N) < 0 ||
            PyModule_AddIntConstant(m, "STATE_SIZE", (long)sizeof(att_ekf_t)) < 0 ||
            PyModule_AddIntConstant(m, "VARS_SIZE", (long)sizeof(att_vars_t)) < 0 ||
            PyModule_AddIntConstant(m, "TRACE_SIZE", (long)sizeof(att_trace_t)) < 0 ||
            PyModule_AddIntConstant(m, "FLAG_ALIGNED", (long)ATT_FLAG_ALIGNED) < 0)
               ? -1
               : 0;
}

#define CORE_PASTE(a, b) a##b
#define CORE_INIT(name) CORE_PASTE(PyInit_, name)

PyMODINIT_FUNC CORE_INIT(CORE_MODULE)(void);
PyMODINIT_FUNC CORE_INIT(CORE_MODULE)(void)
{
    PyObject *m;
    import_array();
    if (PyType_Ready(&core_settings_type) < 0 || PyType_Ready(&core_filter_type) < 0) {
        return NULL;
    }
    m = PyModule_Create(&module_def);
    if (m == NULL) {
        return NULL;
    }
    Py_INCREF(&core_settings_type);
    Py_INCREF(&core_filter_type);
    if (PyModule_AddObject(m, "Settings", (PyObject *)&core_settings_type) < 0 ||
        PyModule_AddObject(m, "Core", (PyObject *)&core_filter_type) < 0 || add_constants(m) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
