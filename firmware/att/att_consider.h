/*
 * att_consider.h - error sources the filter does not weight, carried into the reported
 * attitude covariance (a consider analysis; docs/derivation.md, "Reported covariance").
 *
 * The EKF's gains are chosen for accuracy under white-noise models. Two real error sources
 * do not fit those models, and weighting them would cost accuracy: the low-passed
 * accelerometer's linear-acceleration residual is strongly correlated in time, and the
 * gyroscope's scale-factor errors grow with the rate. This module propagates the variance
 * of the angle errors they cause through the filter's actual gains, per angle, without
 * touching P:
 *
 *   colored accelerometer error n (per tilt axis, AR(1) with correlation rho per step and
 *   variance N): after an update that reduces the axis' variance by the fraction K
 *       e' = (1 - K) e + K n',  so  B' = (1 - K) rho B + K N,
 *       A' = (1 - K)^2 A + 2 (1 - K) K rho B + K^2 N        (A = Var e, B = Cov(e, n));
 *   rate-proportional gyroscope error (per angle): grows by dt (k |w|)^2 |row of W|^2 in
 *   each prediction, shrinks by (1 - K)^2 in each update of that angle.
 */
#ifndef ATT_CONSIDER_H
#define ATT_CONSIDER_H

#include "ekf_scalar.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    ekf_scalar_t tilt[2];  /* rad^2: roll, pitch error variance from the colored accelerometer error */
    ekf_scalar_t cross[2]; /* rad^2: covariance of that error with the colored error itself */
    ekf_scalar_t rate[3];  /* rad^2: roll, pitch, yaw error variance from rate-proportional gyro errors */
} att_consider_t;

void att_consider_reset(att_consider_t *c);

/* Prediction of length dt (s): w2 = |w|^2 ((rad/s)^2), k = angle_walk_rate (sqrt(s)),
 * sec2 = sec^2(theta) (the squared norm of W's roll and yaw rows). */
void att_consider_predict(att_consider_t *c, ekf_scalar_t w2, ekf_scalar_t k, ekf_scalar_t sec2, ekf_scalar_t dt);

/* An accelerometer update that reduced the roll and pitch variances by the fractions
 * kf[2] (0..1), with a colored error of variance n_var (rad^2 per axis) and correlation
 * rho (0..1) from one sample to the next. */
void att_consider_accel(att_consider_t *c, const ekf_scalar_t kf[2], ekf_scalar_t n_var, ekf_scalar_t rho);

/* A heading update that reduced the yaw variance by the fraction k (0..1). */
void att_consider_heading(att_consider_t *c, ekf_scalar_t k);

/* The heading was reset to a measurement. */
void att_consider_heading_reset(att_consider_t *c);

/* var[3] (roll, pitch, yaw, rad^2) += the considered variances. */
void att_consider_add(const att_consider_t *c, ekf_scalar_t var[3]);

#ifdef __cplusplus
}
#endif

#endif /* ATT_CONSIDER_H */
