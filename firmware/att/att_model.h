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

/* What the transition computes besides x+, and its Jacobian needs: the trigonometry of the
 * angles before the step (t0) and after it (t; sec(theta) clamped at theta_limit), the
 * rotation over the step C = Exp([w dt]x) and Jr(w dt) dt (row-major), and whether the body
 * went over the top (phi and psi each turned by about pi: a remap of the representation). */
typedef struct {
    att_trig_t t0;
    att_trig_t t;
    ekf_scalar_t rot[9];
    ekf_scalar_t jd[9];
    int remapped;
} att_motion_t;

/* C = Exp([u]x) (the rotation by the vector u, rad) and J = Jr(u) s, Jr the right Jacobian of
 * SO(3) (d Exp(u + du) = Exp(u) Exp(Jr(u) du)), both row-major, s a scale (the step, s):
 * docs/derivation.md, "Transition". Series in |u|^2 where they are exact in the scalar,
 * sine and cosine beyond. */
void att_model_rotation(const ekf_scalar_t u[3], ekf_scalar_t s, ekf_scalar_t C[9], ekf_scalar_t J[9]);

/*
 * Transition x+ = f(x, w, dt) (docs/derivation.md, "Transition"): exact for a body rate
 * that is constant over the step,
 *   omega+ = omega + w;  R(Theta+) = R(Theta) Exp([omega dt]x);  Thetadot+ = W(Theta+) omega+.
 * Theta+ is read off the composed rotation with phi, psi in [-pi, pi), theta in
 * [-pi/2, pi/2]; within sqrt(eps) of +-90 deg pitch, where roll and heading are not
 * separable, roll keeps its value and the heading takes the rest of the rotation. w: body-rate
 * increment over the step (rad/s), NULL for zero. m receives what the Jacobian and the
 * low-pass need. xn must not alias x.
 */
void att_model_transition(const ekf_scalar_t x[ATT_N], const ekf_scalar_t w[3], ekf_scalar_t dt,
                          ekf_scalar_t theta_limit, ekf_scalar_t xn[ATT_N], att_motion_t *m);

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
