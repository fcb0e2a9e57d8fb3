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

/* Repair rounds the guard accepts: one, a diagonal loading by ten times the margin above
 * (ekf_cov_ensure_pd's first round), the size of what rounding in one call can do. A P that
 * needs more was indefinite beyond rounding (a kernel's bug, a corrupted filter): the call
 * is refused rather than repaired (docs/derivation.md, "Covariance bounds"). */
#define ATT_REPAIR_ROUNDS 1

/* ---- helpers (att.c) ---- */

/* 1 if every setting that cannot change while the filter runs (live = 0 in
 * att_settings_table.h) is the same in a and b (att_settings.c). */
int att_settings_same_fixed_part(const att_settings_t *a, const att_settings_t *b);

/* *dst = *src byte for byte (padding included, so that a restored filter compares equal):
 * the one copy of the variables each call takes before its stages run. */
void att_vars_copy(att_vars_t *dst, const att_vars_t *src);

/* 1 if every state is finite (ekf_all_finite for n = ATT_N, unrolled: one multiply-add per
 * state on an FPU, no loop). */
int att_state_finite(const ekf_scalar_t x[ATT_N]);
/* |vec|. */
ekf_scalar_t att_norm3(const ekf_scalar_t vec[3]);
/* ATT_FLAG_GIMBAL_LOCK from the pitch. */
void att_update_gimbal_flag(att_vars_t *v, const att_settings_t *s);
/* Angles into their ranges (att_model_normalise), the covariance remapped with them.
 * Returns 1 if the pitch passed +-90 deg (remap). */
int att_normalise(att_vars_t *v);
/* The definiteness guard at the end of a call (docs/derivation.md, "Covariance bounds"):
 * floors the variances, repairs P if needed (counted, ATT_FLAG_COV_REPAIRED). EKF_OK, or
 * EKF_ERR_NUMERIC if P is not finite (the call is then refused). */
ekf_status_t att_guard_covariance(att_vars_t *v, const att_settings_t *s);

/* ---- magnetic reference (att_update.c) ---- */

/* Sets the reference field norm (mag units) and dip (rad), and tan^2(dip). */
void att_set_mag_reference(att_vars_t *v, ekf_scalar_t norm, ekf_scalar_t dip);
/* Heading of a levelled field vector (att_gen_mag_level), rad in [-pi, pi). */
ekf_scalar_t att_mag_heading(const att_settings_t *s, const ekf_scalar_t lev[3]);
/* Dip of a levelled field vector, rad, positive when the field points down. */
ekf_scalar_t att_mag_dip(const ekf_scalar_t lev[3]);

/* ---- stages ----
 * A stage's inputs are validated by its caller (att.c) before the stage runs, on the
 * call's working copy v. A stage returns EKF_OK, EKF_GATED or EKF_SKIPPED, or
 * EKF_ERR_NUMERIC after which v is discarded (it may be half-updated). */

/* att_align.c: the alignment from one accelerometer sample with a usable gravity
 * direction (att_align_has_gravity) and a magnetometer sample (may be NULL). */
ekf_status_t att_stage_align(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3],
                             const ekf_scalar_t mag[3]);
/* 1 if |accel| is large enough to give the gravity direction (not free fall). */
int att_align_has_gravity(const att_settings_t *s, const ekf_scalar_t accel[3]);
/* One sample (with accelerometer) of the averaging phase before the alignment, which it
 * runs after align_samples of them: EKF_OK, or EKF_SKIPPED if the average has no usable
 * gravity direction (the averaging restarts, diag.accel_skipped). */
ekf_status_t att_stage_align_sample(att_vars_t *v, const att_settings_t *s, const att_sample_t *sm);
/* att_predict.c: dt in (0, dt_max], aligned filter; trace (may be NULL) receives what the
 * prediction did (att_trace_t). */
ekf_status_t att_stage_predict(att_vars_t *v, const att_settings_t *s, ekf_scalar_t dt, att_trace_t *trace);
/* att_update.c: aligned filter, the vector finite and within its range. */
/* dt (s, > 0): the interval the sample covers; the noise densities give its variance. */
ekf_status_t att_stage_gyro(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3], ekf_scalar_t dt);
ekf_status_t att_stage_gyro_saturated(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3]);
ekf_status_t att_stage_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt);
ekf_status_t att_stage_mag(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t mag[3], ekf_scalar_t dt);

#ifdef __cplusplus
}
#endif

#endif /* ATT_INTERNAL_H */
