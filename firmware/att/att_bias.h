/*
 * att_bias.h - gyroscope offset in motion: a bias filter beside the 9-state EKF.
 *
 * The rest detector (att_rest.h) learns the gyroscope offset while the sensor is still.
 * This module estimates what is left of it (the residual offset b, rad/s, body frame)
 * while the sensor moves, from the accelerometer's and the magnetometer's innovations,
 * without adding states to the EKF: a bias-separated ("two-stage") Kalman filter
 * (Friedland 1969; docs/derivation.md, "Gyroscope offset in motion").
 *
 * The EKF runs as if the offset were exactly known. Beside it this module keeps
 *   V    (3x3, s): how the EKF's roll, pitch and yaw errors depend on the residual offset
 *        (d angles / d b), propagated with the EKF's own transition and gains;
 *   Pb   (3x3 symmetric, in ATT_BIAS_UNIT^2): the covariance of the residual offset;
 *   b    (3, rad/s): the estimate, added to the rest offset by the gyro update.
 * Each accelerometer or magnetometer scalar update with row h over the angles has the
 * sensitivity g = -h V to the offset: the offset is updated with the EKF's own innovation
 * and its variance S + g Pb g^T, only in the directions that measurement sees (tilt from the
 * accelerometer, heading from the magnetometer; from the accelerometer only at right angles to
 * gravity, since the offset along it turns the heading alone), and the angles follow by -V db. The
 * attitude covariance including the offset's uncertainty is P + V Pb V^T (att_bias_cov).
 *
 * At rest the rest offset takes over: b decays with the rest detector's averaging weight
 * and Pb with it towards the rest average's own variance.
 */
#ifndef ATT_BIAS_H
#define ATT_BIAS_H

#include <stdint.h>

#include "att_defs.h"
#include "att_gen.h"
#include "att_settings_table.h"
#include "ekf_scalar.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Its settings (rows ATT_SETTINGS_BIAS of att_settings_table.h; names "bias.*"). */
typedef struct {
    ATT_SETTINGS_BIAS(ATT_SETTING_FIELD)
} att_bias_settings_t;

/* Unit of Pb, rad/s: the offset's variance spans 1e-9..1e-4 (rad/s)^2 and its growth per
 * step walk^2 dt is about 1e-11, below the fixed-point build's resolution in (rad/s)^2. */
#define ATT_BIAS_UNIT EKF_C(1e-3)

typedef struct {
    ekf_scalar_t b[3];  /* rad/s, body frame: residual offset learned in motion */
    ekf_scalar_t Pb[6]; /* ATT_BIAS_UNIT^2 ((mrad/s)^2), packed: 00, 11, 22, 01, 02, 12 */
    ekf_scalar_t V[9];  /* s: d(phi, theta, psi) / d b, row-major (rows: angles) */
    ekf_scalar_t hold;  /* s: no learning until this has run out (att_bias_hold) */
} att_bias_t;

/* Offset zero, covariance sigma_init^2 I, no sensitivity. */
void att_bias_reset(att_bias_t *bf, const att_bias_settings_t *s);

/* The angles' error no longer depends on the past offset: at alignment (angles measured
 * afresh) and after a saturated gyro sample (the error is then the unmeasured rotation's). */
void att_bias_restart(att_bias_t *bf);

/* One prediction of length dt (s) with D1 = F1 - I, the angle rows of the transition's
 * first factor (att_gen_transition_factors, d1 in the order of att_gen_f1_pattern): V
 * follows the angles' dependence on the body rates, which carry the offset, and on the
 * angles; Pb grows by walk^2 dt; the hold runs down. */
void att_bias_predict(att_bias_t *bf, const att_bias_settings_t *s, const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                      ekf_scalar_t dt);

/* No learning for the next t seconds (evidence the offset cannot explain). */
void att_bias_hold(att_bias_t *bf, ekf_scalar_t t);

/* After an EKF scalar update with row h over the angles (h[3]: its entries at phi, theta,
 * psi) was fused: pht[3] = the angle rows of P h^T before the update, nu the innovation,
 * s_var its variance S = h P h^T + R. Advances V with the update's gain pht / S; when learn
 * is set, updates b and Pb from the innovation with the sensitivity g = -h V (V from before
 * the update) and the variance S derate + g Pb g^T (derate >= 1 for innovations correlated
 * across samples), unless nu is beyond 3 sigma of it (not the offset's doing), and moves the
 * angles x_ang[3] (phi, theta, psi) by -V db. up (unit vector, body frame, or NULL): db is
 * kept at right angles to it (the accelerometer's: up is the gravity direction, along which
 * an offset turns only the heading). Returns 1 if the offset changed. */
int att_bias_update(att_bias_t *bf, int learn, const ekf_scalar_t h[3], const ekf_scalar_t pht[3], ekf_scalar_t nu,
                    ekf_scalar_t s_var, ekf_scalar_t derate, const ekf_scalar_t up[3], ekf_scalar_t x_ang[3]);

/* A sample at rest whose offset the rest detector averaged with weight w (0..1) of a gyro
 * with white noise gyro_var ((rad/s)^2): the residual decays with it. */
void att_bias_rest(att_bias_t *bf, ekf_scalar_t w, ekf_scalar_t gyro_var);

/* The angle rows of a state remap (theta -> +-pi - theta): the pitch row of V changes sign. */
void att_bias_remap(att_bias_t *bf);

/* The heading was reset to a measurement: it no longer depends on the past offset. */
void att_bias_heading_reset(att_bias_t *bf);

/* c[6] += the angles' covariance due to the offset's uncertainty, V Pb V^T, packed
 * (phi phi, theta theta, psi psi, phi theta, phi psi, theta psi), rad^2. */
void att_bias_cov(const att_bias_t *bf, ekf_scalar_t c[6]);

#ifdef __cplusplus
}
#endif

#endif /* ATT_BIAS_H */
