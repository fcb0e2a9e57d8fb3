/*
 * att_align.h - the alignment: the first state and covariance from averaged accelerometer
 * (and magnetometer) samples. Not part of the public API.
 */
#ifndef ATT_ALIGN_H
#define ATT_ALIGN_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The alignment from one accelerometer sample with a usable gravity
 * direction (att_align_has_gravity) and a magnetometer sample (may be NULL). */
ekf_status_t att_stage_align(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3],
                             const ekf_scalar_t mag[3]);
/* 1 if |accel| is large enough to give the gravity direction (not free fall). */
int att_align_has_gravity(const att_settings_t *s, const ekf_scalar_t accel[3]);
/* One sample (with accelerometer) of the averaging phase before the alignment, which it
 * runs after align_samples of them: EKF_OK, or EKF_SKIPPED if the average has no usable
 * gravity direction (the averaging restarts, diag.accel_skipped). */
ekf_status_t att_stage_align_sample(att_vars_t *v, const att_settings_t *s, const att_sample_t *sm);

#ifdef __cplusplus
}
#endif

#endif /* ATT_ALIGN_H */
