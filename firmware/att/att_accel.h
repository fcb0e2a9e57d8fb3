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

/* Fuses a specific-force sample (m/s^2, finite, within accel_range) covering dt (s):
 * aligned filter. */
ekf_status_t att_stage_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt);

#ifdef __cplusplus
}
#endif

#endif /* ATT_ACCEL_H */
