/*
 * att_defs.h - state layout of the 9-state attitude model and the trigonometric terms
 * its generated functions take.
 *
 * State x = [p q r  phi theta psi  phid thetad psid]
 *   p, q, r              body angular rates (rad/s), body frame axes x, y, z
 *   phi, theta, psi      ZYX Euler angles (rad): roll, pitch, yaw; R = Rz(psi) Ry(theta)
 *                        Rx(phi) maps body to the ENU earth frame (x east, y north, z up);
 *                        psi = 0 points body x east, positive counter-clockwise seen from above
 *   phid, thetad, psid   Euler-angle rates (rad/s)
 * Ranges kept by the filter: phi, psi in [-pi, pi), theta in [-pi/2, pi/2].
 */
#ifndef ATT_DEFS_H
#define ATT_DEFS_H

#include "ekf_scalar.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    ATT_P = 0,
    ATT_Q = 1,
    ATT_R = 2,
    ATT_PHI = 3,
    ATT_THETA = 4,
    ATT_PSI = 5,
    ATT_PHID = 6,
    ATT_THETAD = 7,
    ATT_PSID = 8,
    ATT_N = 9
};

/* Entries of the lower triangle of a symmetric ATT_N x ATT_N matrix (the packed covariance). */
#define ATT_COV_NP (ATT_N * (ATT_N + 1) / 2)

/* sin/cos of roll and pitch at which a generated function is evaluated, and
 * sec(theta) = 1/cos(theta). Filled by att_trig() in att_model.c, which clamps pitch
 * to the gimbal limit so that secth stays finite. */
typedef struct {
    ekf_scalar_t sphi;
    ekf_scalar_t cphi;
    ekf_scalar_t sth;
    ekf_scalar_t cth;
    ekf_scalar_t secth;
} att_trig_t;

#ifdef __cplusplus
}
#endif

#endif /* ATT_DEFS_H */
