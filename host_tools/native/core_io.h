/*
 * core_io.h - what the Python extension (core_filter.c) does around att_step, in plain C:
 * the sample from the caller's double-precision inputs (rotated by the sensor's mounting
 * when one is set), and the outputs after a step in double precision, in the output frame
 * the caller chose, with "no estimate" before the filter has aligned.
 *
 * Frames. The filter estimates the rotation body -> ENU (att.h). The mounting rotation M
 * (sensor -> body, row-major) is applied to every input vector first: v_body = M v_sensor.
 * An NED output is the same attitude seen from NED: R_ned = T R_enu with
 * T = [[0 1 0], [1 0 0], [0 0 -1]] = Rz(90 deg) Rx(180 deg), so that (ZYX Euler angles)
 *     roll_ned = roll + pi,   pitch_ned = -pitch,   yaw_ned = pi/2 - yaw      (wrapped),
 * and the angle covariance changes sign in its roll-pitch and roll-yaw entries (the
 * Jacobian of that map is diag(1, -1, -1)). The body frame is the same in both.
 *
 * Before alignment (ATT_FLAG_ALIGNED clear) there is no estimate: quaternion, Euler angles,
 * state and body rates are NaN, variances +inf (off-diagonal covariances 0).
 *
 * Host-side only, written to the firmware rules (C99, no allocation, caller owns memory).
 */
#ifndef CORE_IO_H
#define CORE_IO_H

#include <stdint.h>

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int ned;          /* 1: outputs body -> NED; 0: body -> ENU (the filter's own) */
    int mounted;      /* 1: inputs are rotated by mount; 0: taken as body-frame values */
    double mount[9];  /* sensor -> body rotation, row-major (used when mounted) */
} core_frame_t;

/* att_sample_t from one sample: dt s, gyr rad/s, acc m/s^2, mag (NULL: no magnetometer
 * sample; a row of three NaN means the same). Values are converted one at a time. */
void core_sample(const core_frame_t *fr, double dt, const double gyr[3], const double acc[3], const double *mag,
                 att_sample_t *s);

/* 1 if the filter has its initial attitude. */
int core_aligned(const att_ekf_t *f);

/* Quaternion [w x y z] body -> output frame and ZYX Euler angles (roll, pitch, yaw) rad. */
void core_attitude(const core_frame_t *fr, const att_ekf_t *f, double q[4], double euler[3]);

/* Covariance of roll, pitch, yaw in the output frame, rad^2, packed like
 * att_get_angle_covariance (phi phi, theta theta, psi psi, phi theta, phi psi, theta psi). */
void core_angle_cov(const core_frame_t *fr, const att_ekf_t *f, double c[6]);

/* The packed covariance as a symmetric 3x3 matrix, row-major. */
void core_unpack_cov(const double c[6], double m[9]);

/* State vector x (att_defs.h order, the filter's ENU angles) and att_get_variances; either
 * may be NULL. */
void core_state(const att_ekf_t *f, double *x, double *var);

/* Gyroscope offset (rad/s, body frame) and its 1-sigma per axis (rad/s). */
void core_gyro_bias(const att_ekf_t *f, double b[3], double sigma[3]);

#ifdef __cplusplus
}
#endif

#endif /* CORE_IO_H */
