/*
 * att_model.c - hand-written part of the attitude model (see att_model.h).
 */
#include "att_model.h"

#include <stddef.h>

#include "att_gen.h"

int att_trig(ekf_scalar_t phi, ekf_scalar_t theta, ekf_scalar_t theta_limit, att_trig_t *t)
{
    int clamped = 0;
    if (theta > theta_limit) {
        theta = theta_limit;
        clamped = 1;
    } else if (theta < ekf_neg(theta_limit)) {
        theta = ekf_neg(theta_limit);
        clamped = 1;
    }
    ekf_sincos(phi, &t->sphi, &t->cphi);
    ekf_sincos(theta, &t->sth, &t->cth);
    /* |theta| <= theta_limit < pi/2, so cth >= cos(theta_limit) > 0 */
    t->secth = ekf_div(EKF_C(1), t->cth);
    return clamped;
}

void att_model_transition(const ekf_scalar_t x[ATT_N], const ekf_scalar_t w[3], ekf_scalar_t dt,
                          ekf_scalar_t theta_limit, ekf_scalar_t xn[ATT_N], att_trig_t *tm,
                          att_trig_t *tn)
{
    const ekf_scalar_t half_dt = ekf_mul(EKF_C(0.5), dt);
    att_trig_t tmid, t;
    ekf_scalar_t rates[3];
    int i;
    (void)att_trig(ekf_mac(x[ATT_PHI], half_dt, x[ATT_PHID]), ekf_mac(x[ATT_THETA], half_dt, x[ATT_THETAD]),
                   theta_limit, &tmid);
    att_gen_euler_rates(&tmid, &x[ATT_P], rates);
    for (i = 0; i < 3; ++i) {
        xn[ATT_P + i] = (w != NULL) ? ekf_add(x[ATT_P + i], w[i]) : x[ATT_P + i];
        xn[ATT_PHI + i] = ekf_mac(x[ATT_PHI + i], dt, rates[i]);
    }
    (void)att_trig(xn[ATT_PHI], xn[ATT_THETA], theta_limit, &t);
    att_gen_euler_rates(&t, &xn[ATT_P], &xn[ATT_PHID]);
    if (tm != NULL) {
        *tm = tmid;
    }
    if (tn != NULL) {
        *tn = t;
    }
}

int att_model_normalise(ekf_scalar_t x[ATT_N])
{
    int remapped = 0;
    /* nearly always every angle is in range already: three comparisons (a NaN fails them
     * and takes the general path below, which returns the same for an angle in range) */
    if (ekf_abs(x[ATT_PHI]) < EKF_PI && ekf_abs(x[ATT_THETA]) <= EKF_HALF_PI && ekf_abs(x[ATT_PSI]) < EKF_PI) {
        return 0;
    }
    /* theta and theta + 2 pi are the same rotation (sin and cos unchanged) */
    x[ATT_THETA] = ekf_wrap_pi(x[ATT_THETA]);
    if (x[ATT_THETA] > EKF_HALF_PI || x[ATT_THETA] < ekf_neg(EKF_HALF_PI)) {
        /* (phi, theta, psi) and (phi + pi, pi - theta, psi + pi) are the same rotation;
         * theta -> pi - theta is an odd map, so theta's rate and covariance change sign */
        const ekf_scalar_t top = (x[ATT_THETA] > EKF_C(0)) ? EKF_PI : ekf_neg(EKF_PI);
        x[ATT_THETA] = ekf_sub(top, x[ATT_THETA]);
        x[ATT_PHI] = ekf_add(x[ATT_PHI], EKF_PI);
        x[ATT_PSI] = ekf_add(x[ATT_PSI], EKF_PI);
        x[ATT_THETAD] = ekf_neg(x[ATT_THETAD]);
        remapped = 1;
    }
    x[ATT_PHI] = ekf_wrap_pi(x[ATT_PHI]);
    x[ATT_PSI] = ekf_wrap_pi(x[ATT_PSI]);
    return remapped;
}

void att_model_euler_to_quat(ekf_scalar_t phi, ekf_scalar_t theta, ekf_scalar_t psi, ekf_scalar_t q[4])
{
    const ekf_scalar_t half = EKF_C(0.5);
    ekf_scalar_t cr, sr, cp, sp, cy, sy;
    ekf_sincos(ekf_mul(phi, half), &sr, &cr);
    ekf_sincos(ekf_mul(theta, half), &sp, &cp);
    ekf_sincos(ekf_mul(psi, half), &sy, &cy);
    /* q = qz(psi) * qy(theta) * qx(phi) */
    q[0] = ekf_add(ekf_mul(ekf_mul(cy, cp), cr), ekf_mul(ekf_mul(sy, sp), sr));
    q[1] = ekf_sub(ekf_mul(ekf_mul(cy, cp), sr), ekf_mul(ekf_mul(sy, sp), cr));
    q[2] = ekf_add(ekf_mul(ekf_mul(cy, sp), cr), ekf_mul(ekf_mul(sy, cp), sr));
    q[3] = ekf_sub(ekf_mul(ekf_mul(sy, cp), cr), ekf_mul(ekf_mul(cy, sp), sr));
}
