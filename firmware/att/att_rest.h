/*
 * att_rest.h - rest detection and gyroscope offset (bias) estimation.
 *
 * The 9-state model has no gyroscope-bias state, and a MEMS gyroscope's offset (a few
 * tenths of a deg/s on the BROAD recordings) integrates into tilt and heading error whenever
 * the accelerometer or magnetometer cannot be trusted. Like Fusion's offset module, this
 * estimates the offset outside the filter, from the raw gyroscope while the sensor is at
 * rest, and the filter fuses the corrected rates (docs/derivation.md, "Gyroscope offset").
 *
 * Rest: the low-passed rate is below rest_gyro, and the raw rate and the accelerometer
 * stay within rest_gyro and rest_accel of their low-passed values, continuously for
 * rest_time. At rest, the offset follows the raw rate with a running mean over the rest
 * time, turning into an exponential average with time constant bias_tau.
 */
#ifndef ATT_REST_H
#define ATT_REST_H

#include <stdint.h>

#include "att_settings_table.h"
#include "ekf_scalar.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Its settings (rows ATT_SETTINGS_REST of att_settings_table.h; names "rest.*"). */
typedef struct {
    ATT_SETTINGS_REST(ATT_SETTING_FIELD)
} att_rest_settings_t;

typedef struct {
    ekf_scalar_t gyro_lp[3]; /* rad/s */
    ekf_scalar_t acc_lp[3];  /* m/s^2 */
    ekf_scalar_t still_time; /* s of continuous rest so far */
    ekf_scalar_t bias[3];    /* rad/s, subtracted from the gyroscope */
    ekf_scalar_t bias_time;  /* s of rest averaged into bias (capped at bias_tau) */
    uint8_t primed;          /* the low-pass filters hold a sample */
    uint8_t at_rest;         /* rest for at least rest_time */
} att_rest_t;

/* Clears the detector and the offset. */
void att_rest_reset(att_rest_t *r);

/* A sample that shows motion but has no values to average (a clipped accelerometer): not at
 * rest, and the still time starts again. */
void att_rest_motion(att_rest_t *r);

/* One sample (finite, checked by the caller): gyro rad/s, accel m/s^2, dt s > 0.
 * Returns 1 while at rest. */
int att_rest_update(att_rest_t *r, const att_rest_settings_t *s, const ekf_scalar_t gyro[3],
                    const ekf_scalar_t accel[3], ekf_scalar_t dt);

#ifdef __cplusplus
}
#endif

#endif /* ATT_REST_H */
