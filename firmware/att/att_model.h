/*
 * att_model.h - the 9-state attitude model as plain functions (no filter state).
 *
 * The transition and its Jacobians come from host_tools/attekf/codegen/attitude.py
 * (att_gen.c); this module adds what the symbolic part leaves out: trigonometry with the
 * gimbal-lock clamp, the transition itself, the Euler-angle normalisation and output
 * conversions. docs/derivation.md derives every formula used here.
 */
#ifndef ATT_MODEL_H
#define ATT_MODEL_H

#include "att_defs.h"
#include "ekf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* sin/cos of phi and theta and sec(theta), with |theta| clamped to theta_limit (rad,
 * in (0, pi/2)) so that sec(theta) stays finite near the gimbal-lock singularity.
 * Returns 1 if the clamp was active. */
int att_trig(ekf_scalar_t phi, ekf_scalar_t theta, ekf_scalar_t theta_limit, att_trig_t *t);

/*
 * Transition x+ = f(x, w, dt) (docs/derivation.md, "Transition"):
 *   omega+ = omega + w;  Theta_m = Theta + dt/2 Thetadot;
 *   Theta+ = Theta + dt W(Theta_m) omega;  Thetadot+ = W(Theta+) omega+.
 * w: body-rate increment over the step (rad/s), NULL for zero. tm and tn (may be NULL)
 * receive the trigonometry of the midpoint and of the advanced angles, which the Jacobian
 * needs too. xn must not alias x. Angles are returned unnormalised (see att_model_normalise).
 */
void att_model_transition(const ekf_scalar_t x[ATT_N], const ekf_scalar_t w[3], ekf_scalar_t dt,
                          ekf_scalar_t theta_limit, ekf_scalar_t xn[ATT_N], att_trig_t *tm,
                          att_trig_t *tn);

/*
 * Brings the Euler triple back to phi, psi in [-pi, pi), theta in [-pi/2, pi/2]. A pitch
 * beyond +-pi/2 (the body went over the top) is remapped to the same rotation
 * (phi + pi, +-pi - theta, psi + pi), with thetad -> -thetad. Returns 1 if the pitch
 * remap happened: the covariance then needs the same transformation, the rows and
 * columns of theta and thetad negated (att_cov_negate_state).
 */
int att_model_normalise(ekf_scalar_t x[ATT_N]);

/* Unit quaternion (w, x, y, z) of R = Rz(psi) Ry(theta) Rx(phi), body to ENU. */
void att_model_euler_to_quat(ekf_scalar_t phi, ekf_scalar_t theta, ekf_scalar_t psi, ekf_scalar_t q[4]);

#ifdef __cplusplus
}
#endif

#endif /* ATT_MODEL_H */
