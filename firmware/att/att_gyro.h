/*
 * att_gyro.h - the gyroscope stage. Not part of the public API.
 */
#ifndef ATT_GYRO_H
#define ATT_GYRO_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A stage runs on the filter's variables v under the settings s, after its caller (att.c)
 * has validated its inputs and saved v. It returns EKF_OK, EKF_GATED or EKF_SKIPPED, or
 * EKF_ERR_NUMERIC after which the caller puts the saved v back (v may be half-updated). */

/* Fuses a body-rate sample (rad/s, within gyro_range) covering dt (s): aligned filter. */
ekf_status_t att_stage_gyro(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3], ekf_scalar_t dt);

/* A clamped sample (ATT_GYRO_SATURATED): not fused; the body-rate variances raised to cover
 * the rate it could not measure. EKF_SKIPPED. */
ekf_status_t att_stage_gyro_saturated(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3]);

#ifdef __cplusplus
}
#endif

#endif /* ATT_GYRO_H */
