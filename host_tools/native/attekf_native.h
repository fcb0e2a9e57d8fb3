/*
 * attekf_native.h - the C estimator (firmware/att) packaged for the host tools.
 *
 * Built as a shared library per scalar type (libattekf_native_f.so, _d.so, _x.so) and loaded by
 * host_tools/attekf/native.py through ctypes. Everything Python needs is reachable by
 * function call, so Python never mirrors a C struct layout:
 *   - sizes of the settings and filter structs (Python allocates opaque buffers);
 *   - the settings by name (a table name -> offset/type in attekf_native.c);
 *   - the names of the status codes and of the diagnostics;
 *   - attekf_run(): att_step over a block of samples in one call, every per-sample output
 *     written to caller-owned arrays (double precision whatever the scalar type).
 *
 * Host-side only (it is never linked into firmware), but written to the firmware rules:
 * C99, no allocation, caller owns memory.
 */
#ifndef ATTEKF_NATIVE_H
#define ATTEKF_NATIVE_H

#include <stddef.h>
#include <stdint.h>

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Bumped whenever a signature below changes; native.py refuses other versions. */
#define ATTEKF_NATIVE_API_VERSION 2

/* Per-sample status columns written by attekf_run (status[i * ATTEKF_STATUS_COLS + k]). */
enum {
    ATTEKF_STATUS_STEP = 0,    /* att_step's return value */
    ATTEKF_STATUS_PREDICT = 1, /* att_step_report_t fields */
    ATTEKF_STATUS_GYRO = 2,
    ATTEKF_STATUS_ACCEL = 3,
    ATTEKF_STATUS_MAG = 4,
    ATTEKF_STATUS_COLS = 5
};

/* Setting value types of the table. */
enum { ATTEKF_SETTING_SCALAR = 0, ATTEKF_SETTING_U16 = 1 };

/* attekf_setting_set / _get results. */
enum {
    ATTEKF_SETTING_OK = 0,
    ATTEKF_SETTING_UNKNOWN = -1,   /* no setting of that name */
    ATTEKF_SETTING_BAD_VALUE = -2, /* not finite, or not representable in the field's type */
    ATTEKF_SETTING_NULL = -3
};

int attekf_api_version(void);
/* "float", "double" or "fixed": the ekf_scalar_t this library was built with. */
const char *attekf_scalar_name(void);
/* Fixed-point build: operations that saturated the Q format since load or the last reset
 * (program-wide, docs/fixed_point.md); always 0 for float and double. */
uint32_t attekf_scalar_saturations(void);
void attekf_scalar_saturations_reset(void);
size_t attekf_settings_size(void); /* sizeof(att_settings_t) */
/* sizeof(att_ekf_t). A caller-allocated filter buffer must be aligned for att_ekf_t:
 * an array of doubles is, on every host ABI. */
size_t attekf_filter_size(void);

/* Copies att_default_settings into *s. */
void attekf_settings_default(att_settings_t *s);

/* The settings table: index 0..count-1 -> name, unit (text), type. NULL past the end. */
size_t attekf_setting_count(void);
const char *attekf_setting_name(size_t i);
const char *attekf_setting_unit(size_t i);
const char *attekf_setting_help(size_t i);
int attekf_setting_type(size_t i);
int attekf_setting_set(att_settings_t *s, const char *name, double value);
int attekf_setting_get(const att_settings_t *s, const char *name, double *value);
/* 1 if the table's entries tile att_settings_t (no field left out, up to alignment
 * padding), else 0: catches a setting added to att.h but not to the table. */
int attekf_settings_table_complete(void);

/* att_settings_check / att_init on caller-owned memory; return ekf_status_t. */
int attekf_settings_check(const att_settings_t *s);
int attekf_filter_init(att_ekf_t *f, const att_settings_t *s);

/* ekf_status_str. */
const char *attekf_status_name(int status);

/* Diagnostic counters of att_diag_t (uint32 fields) by index. */
size_t attekf_diag_count(void);
const char *attekf_diag_name(size_t i);
/* Writes the attekf_diag_count() counters of f into out. */
void attekf_diag_get(const att_ekf_t *f, uint32_t *out);
/* The other fields of att_diag_t (innovation test ratios, norm and dip errors) by index:
 * name, unit, number of elements (3 for an array of three). */
size_t attekf_diag_value_count(void);
const char *attekf_diag_value_name(size_t i);
const char *attekf_diag_value_unit(size_t i);
size_t attekf_diag_value_len(size_t i);
/* Writes every element of every value field of f, in table order, into out (as many
 * doubles as the sum of attekf_diag_value_len). */
void attekf_diag_values_get(const att_ekf_t *f, double *out);
/* 1 if the counter and value tables together tile att_diag_t (no field left out, up to
 * alignment padding), else 0: catches a diagnostic added to att.h but not to a table. */
int attekf_diag_table_complete(void);

/*
 * Runs att_step on n samples, in order, continuing from the filter's current state.
 *
 * Inputs (row-major, double; converted to ekf_scalar_t one value at a time):
 *   dt[n]       s, time since the previous sample (ignored by the filter while aligning)
 *   gyr[n*3]    rad/s; acc[n*3] m/s^2
 *   mag[n*3]    uT, or NULL without magnetometer. A row of three NaN means "no magnetometer
 *               sample at that time" (ATT_HAS_MAG cleared); any other non-finite row is
 *               passed to the filter, which refuses it (and counts it).
 * Outputs (each may be NULL when not wanted):
 *   state[n*9]  the state vector after the sample (att_defs.h order)
 *   var[n*9]    att_get_variances after the sample (the diagonal of P; for the angles that
 *               of the reported attitude covariance, att_get_angle_covariance)
 *   quat[n*4]   att_get_quaternion after the sample (w x y z, body to ENU)
 *   flags[n]    att_flags after the sample
 *   status[n*ATTEKF_STATUS_COLS]  ekf_status_t of the step and of each stage
 * Returns EKF_OK, or EKF_ERR_NULL if f or a required input is NULL (nothing run).
 * Never stops early: every sample is given to the filter and its outcome recorded.
 */
int attekf_run(att_ekf_t *f, size_t n, const double *dt, const double *gyr, const double *acc,
               const double *mag, double *state, double *var, double *quat, uint32_t *flags,
               uint8_t *status);

/* attekf_run, and angle_cov[n*6] (may be NULL) receives att_get_angle_covariance after each
 * sample: the reported roll/pitch/yaw covariance, packed (phi phi, theta theta, psi psi,
 * phi theta, phi psi, theta psi), rad^2. */
int attekf_run_cov(att_ekf_t *f, size_t n, const double *dt, const double *gyr, const double *acc,
                   const double *mag, double *state, double *var, double *quat, uint32_t *flags,
                   uint8_t *status, double *angle_cov);

#ifdef __cplusplus
}
#endif

#endif /* ATTEKF_NATIVE_H */
