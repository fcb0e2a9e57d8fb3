/*
 * attekf_native.c - see attekf_native.h.
 */
#include "attekf_native.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

/* ------------------------------------------------------------------------------------
 * Settings: the estimator's own table (att_setting_info, expanded from
 * att_settings_table.h), and the help text of the same rows.
 * ------------------------------------------------------------------------------------ */
#define HELP_ROW(name, type, def, def_fixed, lo, hi, check, live, unit, help) help,
static const char *const k_help[] = {
    ATT_SETTINGS_MAIN(HELP_ROW) ATT_SETTINGS_REST(HELP_ROW) ATT_SETTINGS_BIAS(HELP_ROW)};

#define N_SETTINGS (sizeof k_help / sizeof k_help[0])

static int row_type(const att_setting_info_t *r)
{
    return (r->type == ATT_SETTING_U16) ? ATTEKF_SETTING_U16 : ATTEKF_SETTING_SCALAR;
}

static size_t type_size(int type)
{
    return (type == ATTEKF_SETTING_U16) ? sizeof(uint16_t) : sizeof(ekf_scalar_t);
}

static const att_setting_info_t *find_setting(const char *name)
{
    const int i = att_setting_index(name);
    return (i < 0) ? NULL : att_setting_info((size_t)i);
}

int attekf_api_version(void) { return ATTEKF_NATIVE_API_VERSION; }
const char *attekf_scalar_name(void) { return EKF_SCALAR_NAME; }
uint32_t attekf_scalar_saturations(void) { return ekf_scalar_saturations(); }
void attekf_scalar_saturations_reset(void) { ekf_scalar_saturations_reset(); }
size_t attekf_settings_size(void) { return sizeof(att_settings_t); }
size_t attekf_filter_size(void) { return sizeof(att_ekf_t); }

void attekf_settings_default(att_settings_t *s)
{
    if (s != NULL) {
        *s = att_default_settings;
    }
}

size_t attekf_setting_count(void) { return att_setting_count(); }
const char *attekf_setting_name(size_t i) { return (i < N_SETTINGS) ? att_setting_info(i)->name : NULL; }
const char *attekf_setting_unit(size_t i) { return (i < N_SETTINGS) ? att_setting_info(i)->unit : NULL; }
const char *attekf_setting_help(size_t i) { return (i < N_SETTINGS) ? k_help[i] : NULL; }
int attekf_setting_type(size_t i) { return (i < N_SETTINGS) ? row_type(att_setting_info(i)) : -1; }

int attekf_setting_set(att_settings_t *s, const char *name, double value)
{
    const att_setting_info_t *row = find_setting(name);
    unsigned char *base = (unsigned char *)s;
    if (s == NULL) {
        return ATTEKF_SETTING_NULL;
    }
    if (row == NULL) {
        return ATTEKF_SETTING_UNKNOWN;
    }
    if (!isfinite(value)) {
        return ATTEKF_SETTING_BAD_VALUE;
    }
    if (row_type(row) == ATTEKF_SETTING_U16) {
        uint16_t v;
        if (value < 0.0 || value > 65535.0 || floor(value) != value) {
            return ATTEKF_SETTING_BAD_VALUE;
        }
        v = (uint16_t)value;
        memcpy(base + row->offset, &v, sizeof v);
    } else {
        /* A double beyond float's range becomes inf in a float build (and beyond the Q
         * format's in the fixed-point build): refuse it here rather than let
         * att_settings_check report an unnamed setting. */
        const ekf_scalar_t v = ekf_from_double(value);
        if (!ekf_isfinite(v)) {
            return ATTEKF_SETTING_BAD_VALUE;
        }
        memcpy(base + row->offset, &v, sizeof v);
    }
    return ATTEKF_SETTING_OK;
}

int attekf_setting_get(const att_settings_t *s, const char *name, double *value)
{
    const att_setting_info_t *row = find_setting(name);
    const unsigned char *base = (const unsigned char *)s;
    if (s == NULL || value == NULL) {
        return ATTEKF_SETTING_NULL;
    }
    if (row == NULL) {
        return ATTEKF_SETTING_UNKNOWN;
    }
    if (row_type(row) == ATTEKF_SETTING_U16) {
        uint16_t v;
        memcpy(&v, base + row->offset, sizeof v);
        *value = (double)v;
    } else {
        ekf_scalar_t v;
        memcpy(&v, base + row->offset, sizeof v);
        *value = ekf_to_double(v);
    }
    return ATTEKF_SETTING_OK;
}

int attekf_settings_table_complete(void)
{
    size_t i;
    size_t end = 0; /* first byte after the previous field */
    if (att_setting_count() != N_SETTINGS) {
        return 0;
    }
    for (i = 0; i < N_SETTINGS; ++i) {
        const att_setting_info_t *r = att_setting_info(i);
        const size_t size = type_size(row_type(r));
        /* In declaration order, a gap can only be alignment padding, which is smaller
         * than the field that follows it (fields are aligned to their own size here). */
        if (r->offset < end || r->offset - end >= size) {
            return 0;
        }
        end = r->offset + size;
    }
    /* Tail padding is smaller than the largest member. */
    return (sizeof(att_settings_t) >= end && sizeof(att_settings_t) - end < sizeof(ekf_scalar_t)) ? 1 : 0;
}

int attekf_settings_check(const att_settings_t *s) { return (int)att_settings_check(s); }
int attekf_filter_init(att_ekf_t *f, const att_settings_t *s) { return (int)att_init(f, s); }
const char *attekf_status_name(int status) { return ekf_status_str((ekf_status_t)status); }

/* ------------------------------------------------------------------------------------
 * Diagnostics: the uint32 counters and the other fields of att_diag_t (ekf_scalar_t,
 * arrays element by element), each table in declaration order, which
 * attekf_diag_table_complete() relies on.
 * ------------------------------------------------------------------------------------ */
typedef struct {
    const char *name;
    size_t offset;
} diag_row_t;

#define DIAG_ROW(field) { #field, offsetof(att_diag_t, field) }

static const diag_row_t k_diag[] = {
    DIAG_ROW(steps),       DIAG_ROW(gyro_fused),    DIAG_ROW(accel_fused),
    DIAG_ROW(mag_fused),   DIAG_ROW(gyro_gated),    DIAG_ROW(accel_gated),
    DIAG_ROW(mag_gated),   DIAG_ROW(accel_skipped), DIAG_ROW(mag_skipped),
    DIAG_ROW(rejected),    DIAG_ROW(numeric),       DIAG_ROW(remaps),
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
    { #field, offsetof(att_diag_t, field), sizeof(((att_diag_t *)0)->field) / sizeof(ekf_scalar_t), unit }

static const diag_value_row_t k_diag_values[] = {
    DIAG_VALUE_ROW(gyro_ratio, "1"),
    DIAG_VALUE_ROW(accel_ratio, "1"),
    DIAG_VALUE_ROW(mag_ratio, "1"),
    DIAG_VALUE_ROW(accel_norm_error, "m/s^2"),
    DIAG_VALUE_ROW(mag_norm_error, "1"),
    DIAG_VALUE_ROW(mag_dip_error, "rad"),
};

#define N_DIAG_VALUES (sizeof k_diag_values / sizeof k_diag_values[0])

size_t attekf_diag_count(void) { return N_DIAG; }
const char *attekf_diag_name(size_t i) { return (i < N_DIAG) ? k_diag[i].name : NULL; }

void attekf_diag_get(const att_ekf_t *f, uint32_t *out)
{
    size_t i;
    const unsigned char *base;
    if (f == NULL || out == NULL) {
        return;
    }
    base = (const unsigned char *)att_diag(f);
    for (i = 0; i < N_DIAG; ++i) {
        memcpy(&out[i], base + k_diag[i].offset, sizeof out[i]);
    }
}

size_t attekf_diag_value_count(void) { return N_DIAG_VALUES; }
const char *attekf_diag_value_name(size_t i) { return (i < N_DIAG_VALUES) ? k_diag_values[i].name : NULL; }
const char *attekf_diag_value_unit(size_t i) { return (i < N_DIAG_VALUES) ? k_diag_values[i].unit : NULL; }
size_t attekf_diag_value_len(size_t i) { return (i < N_DIAG_VALUES) ? k_diag_values[i].len : 0u; }

void attekf_diag_values_get(const att_ekf_t *f, double *out)
{
    size_t i, k, n = 0;
    const unsigned char *base;
    if (f == NULL || out == NULL) {
        return;
    }
    base = (const unsigned char *)att_diag(f);
    for (i = 0; i < N_DIAG_VALUES; ++i) {
        for (k = 0; k < k_diag_values[i].len; ++k) {
            ekf_scalar_t v;
            memcpy(&v, base + k_diag_values[i].offset + k * sizeof v, sizeof v);
            out[n++] = ekf_to_double(v);
        }
    }
}

int attekf_diag_table_complete(void)
{
    size_t i;
    size_t end = 0; /* first byte after the previous field */
    for (i = 0; i < N_DIAG; ++i) {
        if (k_diag[i].offset != end) {
            return 0; /* a counter missing (uint32 fields pack without padding) */
        }
        end += sizeof(uint32_t);
    }
    for (i = 0; i < N_DIAG_VALUES; ++i) {
        /* alignment padding before a field is smaller than the field's element */
        if (k_diag_values[i].offset < end || k_diag_values[i].offset - end >= sizeof(ekf_scalar_t)) {
            return 0;
        }
        end = k_diag_values[i].offset + k_diag_values[i].len * sizeof(ekf_scalar_t);
    }
    return (sizeof(att_diag_t) >= end && sizeof(att_diag_t) - end < sizeof(ekf_scalar_t)) ? 1 : 0;
}

/* ------------------------------------------------------------------------------------
 * Batch run
 * ------------------------------------------------------------------------------------ */
static void to_scalar3(const double *in, ekf_scalar_t out[3])
{
    out[0] = ekf_from_double(in[0]);
    out[1] = ekf_from_double(in[1]);
    out[2] = ekf_from_double(in[2]);
}

int attekf_run(att_ekf_t *f, size_t n, const double *dt, const double *gyr, const double *acc,
               const double *mag, double *state, double *var, double *quat, uint32_t *flags,
               uint8_t *status)
{
    return attekf_run_cov(f, n, dt, gyr, acc, mag, state, var, quat, flags, status, NULL);
}

int attekf_run_cov(att_ekf_t *f, size_t n, const double *dt, const double *gyr, const double *acc,
                   const double *mag, double *state, double *var, double *quat, uint32_t *flags,
                   uint8_t *status, double *angle_cov)
{
    size_t i;
    int k;
    if (f == NULL || (n > 0u && (dt == NULL || gyr == NULL || acc == NULL))) {
        return (int)EKF_ERR_NULL;
    }
    for (i = 0; i < n; ++i) {
        att_sample_t s;
        att_step_report_t rep;
        ekf_status_t st;
        memset(&s, 0, sizeof s);
        s.dt = ekf_from_double(dt[i]);
        to_scalar3(&gyr[3 * i], s.gyro);
        to_scalar3(&acc[3 * i], s.accel);
        s.valid = (uint8_t)(ATT_HAS_GYRO | ATT_HAS_ACCEL);
        if (mag != NULL) {
            const double *m = &mag[3 * i];
            /* all three NaN: the magnetometer did not sample at this time */
            if (!(isnan(m[0]) && isnan(m[1]) && isnan(m[2]))) {
                to_scalar3(m, s.mag);
                s.valid = (uint8_t)(s.valid | ATT_HAS_MAG);
            }
        }
        st = att_step(f, &s, &rep);
        if (state != NULL) {
            const ekf_scalar_t *x = att_state(f);
            for (k = 0; k < ATT_N; ++k) {
                state[(size_t)ATT_N * i + (size_t)k] = ekf_to_double(x[k]);
            }
        }
        if (var != NULL) {
            ekf_scalar_t v[ATT_N];
            att_get_variances(f, v);
            for (k = 0; k < ATT_N; ++k) {
                var[(size_t)ATT_N * i + (size_t)k] = ekf_to_double(v[k]);
            }
        }
        if (angle_cov != NULL) {
            ekf_scalar_t c[6];
            att_get_angle_covariance(f, c);
            for (k = 0; k < 6; ++k) {
                angle_cov[6u * i + (size_t)k] = ekf_to_double(c[k]);
            }
        }
        if (quat != NULL) {
            ekf_scalar_t q[4];
            att_get_quaternion(f, q);
            for (k = 0; k < 4; ++k) {
                quat[4u * i + (size_t)k] = ekf_to_double(q[k]);
            }
        }
        if (flags != NULL) {
            flags[i] = att_flags(f);
        }
        if (status != NULL) {
            uint8_t *row = &status[(size_t)ATTEKF_STATUS_COLS * i];
            row[ATTEKF_STATUS_STEP] = (uint8_t)st;
            row[ATTEKF_STATUS_PREDICT] = (uint8_t)rep.predict;
            row[ATTEKF_STATUS_GYRO] = (uint8_t)rep.gyro;
            row[ATTEKF_STATUS_ACCEL] = (uint8_t)rep.accel;
            row[ATTEKF_STATUS_MAG] = (uint8_t)rep.mag;
        }
    }
    return (int)EKF_OK;
}
