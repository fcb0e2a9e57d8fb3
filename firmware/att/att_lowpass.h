/*
 * att_lowpass.h - the accelerometer low-pass in a frame that turns with the body
 * (att_vars_t.accel_lp, accel_lp1). Not part of the public API.
 */
#ifndef ATT_LOWPASS_H
#define ATT_LOWPASS_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Carries the low-passed specific force into the body frame after a step whose rotation is
 * rot (row-major, the new body axes in the old ones). */
void att_lowpass_turn(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t rot[9]);

/* Blends one accelerometer sample (m/s^2, body frame) covering dt (s) into the low-pass. */
void att_lowpass_blend(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt);

#ifdef __cplusplus
}
#endif

#endif /* ATT_LOWPASS_H */
