/*
 * att_mag.h - the magnetometer: its reference field and its stage. Not part of the public
 * API.
 */
#ifndef ATT_MAG_H
#define ATT_MAG_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Sets the reference field norm (mag units) and dip (rad), and tan^2(dip). */
void att_mag_set_reference(att_vars_t *v, ekf_scalar_t norm, ekf_scalar_t dip);

/* Heading of a levelled field vector (att_gen_mag_level), rad in [-pi, pi). */
ekf_scalar_t att_mag_heading(const att_settings_t *s, const ekf_scalar_t lev[3]);

/* Dip of a levelled field vector, rad, positive when the field points down. */
ekf_scalar_t att_mag_dip(const ekf_scalar_t lev[3]);

/* A stage runs on the filter's variables v under the settings s, after its caller (att.c)
 * has validated its inputs and saved v. It returns EKF_OK, EKF_GATED or EKF_SKIPPED, or
 * EKF_ERR_NUMERIC after which the caller puts the saved v back (v may be half-updated). */

/* Fuses the heading of a field sample (mag units, finite, within mag_range) covering dt (s):
 * aligned filter; held (EKF_SKIPPED) near the gimbal lock. */
ekf_status_t att_stage_mag(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t mag[3], ekf_scalar_t dt);

#ifdef __cplusplus
}
#endif

#endif /* ATT_MAG_H */
