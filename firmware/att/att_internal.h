/*
 * att_internal.h - declarations shared by the att_*.c files of the attitude filter: the
 * stages and their helpers. Not part of the public API (att.h), not installed.
 *
 * A stage works on the filter's variables v under the settings s; the settings never
 * change after att_init, the variables only through the stages.
 */
#ifndef ATT_INTERNAL_H
#define ATT_INTERNAL_H

#include "att.h"
#include "att_cov.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Index of a sensor in att_vars_t.gated_time. */
enum { ATT_SENSOR_GYRO = 0, ATT_SENSOR_ACCEL = 1, ATT_SENSOR_MAG = 2 };

/* Smallest accepted LDL^T pivot relative to its variance. The factorisation computed in
 * the filter's scalar is the exact one of P + dP with |dP_ij| up to about n^2 eps
 * sqrt(P_ii P_jj): the margin must be well above that, or a float P that is indefinite by
 * 5e-5 of its diagonal passes. 10 n^2 eps is 1e-4 in float, far below the Euler-rate
 * pivots (~euler_rate_rel = 1e-3) that the model keeps by design (docs/derivation.md,
 * "Covariance bounds"). */
#define ATT_PD_MARGIN ekf_mul(EKF_C(10 * ATT_N * ATT_N), EKF_SCALAR_EPS)

/* ---- helpers (att.c) ---- */

/* Counts a refused call in the diagnostics and passes the status through. */
ekf_status_t att_note(att_vars_t *v, ekf_status_t st);
/* Finite, every component within +-range: EKF_OK, EKF_ERR_NULL, _NOT_FINITE or _RANGE. */
ekf_status_t att_check_vec(const ekf_scalar_t vec[3], ekf_scalar_t range);
/* A time step in (0, dt_max]: EKF_OK, EKF_ERR_NOT_FINITE, _DT_NONPOSITIVE or _DT_TOO_LARGE. */
ekf_status_t att_check_dt(const att_settings_t *s, ekf_scalar_t dt);
/* |vec|. */
ekf_scalar_t att_norm3(const ekf_scalar_t vec[3]);
/* ATT_FLAG_GIMBAL_LOCK from the pitch. */
void att_update_gimbal_flag(att_vars_t *v, const att_settings_t *s);
/* Angles into their ranges (att_model_normalise), the covariance remapped with them.
 * Returns 1 if the pitch passed +-90 deg (remap). */
int att_normalise(att_vars_t *v);
/* The definiteness guard at the end of a call (docs/derivation.md, "Covariance bounds"). */
void att_guard_covariance(att_vars_t *v, const att_settings_t *s);

/* ---- magnetic reference (att_update.c) ---- */

/* Sets the reference field norm (mag units) and dip (rad), and tan^2(dip). */
void att_set_mag_reference(att_vars_t *v, ekf_scalar_t norm, ekf_scalar_t dip);
/* Heading of a levelled field vector (att_gen_mag_level), rad in [-pi, pi). */
ekf_scalar_t att_mag_heading(const att_settings_t *s, const ekf_scalar_t lev[3]);
/* Dip of a levelled field vector, rad, positive when the field points down. */
ekf_scalar_t att_mag_dip(const ekf_scalar_t lev[3]);

/* ---- stages ---- */

/* att_align.c: alignment from one accelerometer (and magnetometer, may be NULL) sample,
 * and the averaging phase of att_step before it. */
ekf_status_t att_stage_align(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3],
                             const ekf_scalar_t mag[3]);
ekf_status_t att_stage_align_step(att_ekf_t *f, const att_sample_t *sm, att_step_report_t *rep);
/* att_predict.c */
ekf_status_t att_stage_predict(att_vars_t *v, const att_settings_t *s, ekf_scalar_t dt);
/* att_update.c */
ekf_status_t att_stage_gyro(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3]);
ekf_status_t att_stage_gyro_saturated(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3]);
ekf_status_t att_stage_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3]);
ekf_status_t att_stage_mag(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t mag[3]);

#ifdef __cplusplus
}
#endif

#endif /* ATT_INTERNAL_H */
