/*
 * att_accel.h - the accelerometer stage. Not part of the public API.
 */
#ifndef ATT_ACCEL_H
#define ATT_ACCEL_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A stage runs on the filter's variables v under the settings s, after its caller (att.c)
 * has validated its inputs and saved v. It returns EKF_OK, EKF_GATED or EKF_SKIPPED, or
 * EKF_ERR_NUMERIC after which the caller puts the saved v back (v may be half-updated). */

/* Fuses a specific-force sample (m/s^2, finite) covering dt (s): aligned filter. A clipped
 * sample (att_accel_clipped) is not fused: EKF_SKIPPED, ATT_FLAG_ACCEL_REJECTED,
 * diag.accel_skipped. */
ekf_status_t att_stage_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt);

/* 1 if a component of a finite sample is within ATT_ACCEL_CLIP_MARGIN of accel_range or
 * beyond it: the sensor was at its full scale, and the vector's direction is not gravity's
 * plus the motion's (a clipped impact). Comparisons only: safe for any finite value. */
int att_accel_clipped(const att_settings_t *s, const ekf_scalar_t accel[3]);

#ifdef __cplusplus
}
#endif

#endif /* ATT_ACCEL_H */
