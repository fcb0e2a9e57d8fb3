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

/* |u|^2 below which the series of att_model_rotation are exact in the scalar: their first
 * omitted terms, |u|^8 / 9! and smaller, stay below its rounding. */
#if defined(EKF_SCALAR_DOUBLE)
#define SERIES_MAX_U2 EKF_C(2.5e-3)
#else
#define SERIES_MAX_U2 EKF_C(0.25)
#endif

void att_model_rotation(const ekf_scalar_t u[3], ekf_scalar_t s, ekf_scalar_t C[9], ekf_scalar_t J[9])
{
    /* C = I + a U + b U^2, Jr = I - b U + c U^2, U = [u]x, U^2 = u u^T - |u|^2 I, with
     * a = sin(th) / th, b = (1 - cos(th)) / th^2, c = (th - sin(th)) / th^3, th = |u| */
    const ekf_scalar_t th2 = ekf_add(ekf_add(ekf_sq(u[0]), ekf_sq(u[1])), ekf_sq(u[2]));
    ekf_scalar_t a, b, c;
    if (th2 < SERIES_MAX_U2) {
        a = ekf_sub(EKF_C(1), ekf_mul(ekf_div(th2, EKF_C(6)),
                                      ekf_sub(EKF_C(1), ekf_mul(ekf_div(th2, EKF_C(20)),
                                                                ekf_sub(EKF_C(1), ekf_div(th2, EKF_C(42)))))));
        b = ekf_sub(EKF_C(0.5), ekf_mul(ekf_div(th2, EKF_C(24)),
                                        ekf_sub(EKF_C(1), ekf_mul(ekf_div(th2, EKF_C(30)),
                                                                  ekf_sub(EKF_C(1), ekf_div(th2, EKF_C(56)))))));
        c = ekf_sub(EKF_C(1.0 / 6.0), ekf_mul(ekf_div(th2, EKF_C(120)),
                                              ekf_sub(EKF_C(1), ekf_mul(ekf_div(th2, EKF_C(42)),
                                                                        ekf_sub(EKF_C(1), ekf_div(th2, EKF_C(72)))))));
    } else {
        const ekf_scalar_t th = ekf_sqrt(th2);
        ekf_scalar_t sn, cs;
        ekf_sincos(th, &sn, &cs);
        a = ekf_div(sn, th);
        b = ekf_div(ekf_sub(EKF_C(1), cs), th2);
        c = ekf_div(ekf_sub(th, sn), ekf_mul(th2, th));
    }
    {
        /* U^2 = u u^T - th2 I: symmetric, U antisymmetric */
        const ekf_scalar_t q00 = ekf_sub(ekf_sq(u[0]), th2), q11 = ekf_sub(ekf_sq(u[1]), th2);
        const ekf_scalar_t q22 = ekf_sub(ekf_sq(u[2]), th2);
        const ekf_scalar_t q01 = ekf_mul(u[0], u[1]), q02 = ekf_mul(u[0], u[2]), q12 = ekf_mul(u[1], u[2]);
        const ekf_scalar_t a0 = ekf_mul(a, u[0]), a1 = ekf_mul(a, u[1]), a2 = ekf_mul(a, u[2]);
        const ekf_scalar_t b0 = ekf_mul(b, u[0]), b1 = ekf_mul(b, u[1]), b2 = ekf_mul(b, u[2]);
        const ekf_scalar_t cs = ekf_mul(c, s);
        C[0] = ekf_mac(EKF_C(1), b, q00);
        C[4] = ekf_mac(EKF_C(1), b, q11);
        C[8] = ekf_mac(EKF_C(1), b, q22);
        C[1] = ekf_mac(ekf_neg(a2), b, q01);
        C[3] = ekf_mac(a2, b, q01);
        C[2] = ekf_mac(a1, b, q02);
        C[6] = ekf_mac(ekf_neg(a1), b, q02);
        C[5] = ekf_mac(ekf_neg(a0), b, q12);
        C[7] = ekf_mac(a0, b, q12);
        /* J = (I - b U + c U^2) s */
        J[0] = ekf_mac(s, cs, q00);
        J[4] = ekf_mac(s, cs, q11);
        J[8] = ekf_mac(s, cs, q22);
        J[1] = ekf_mac(ekf_mul(b2, s), cs, q01);
        J[3] = ekf_mac(ekf_neg(ekf_mul(b2, s)), cs, q01);
        J[2] = ekf_mac(ekf_neg(ekf_mul(b1, s)), cs, q02);
        J[6] = ekf_mac(ekf_mul(b1, s), cs, q02);
        J[5] = ekf_mac(ekf_mul(b0, s), cs, q12);
        J[7] = ekf_mac(ekf_neg(ekf_mul(b0, s)), cs, q12);
    }
}

/* The Euler angles of Rz(psi) A, A = Ry(theta) Rx(phi) C (the body's turn C after the
 * angles (phi, theta), the heading taken out): phi+ and theta+ from A's last row, the
 * heading's change from A's first column brought back through Ry(theta+) Rx(phi+), so that
 * it is consistent with the roll chosen (docs/derivation.md, "Transition"). */
static void compose(const att_trig_t *t0, ekf_scalar_t phi, const ekf_scalar_t C[9], ekf_scalar_t ang[3],
                    ekf_scalar_t *dpsi, att_trig_t *tn)
{
    /* rows of M = Ry(theta) Rx(phi) */
    const ekf_scalar_t M[9] = {t0->cth, ekf_mul(t0->sth, t0->sphi), ekf_mul(t0->sth, t0->cphi),
                               EKF_C(0), t0->cphi, ekf_neg(t0->sphi),
                               ekf_neg(t0->sth), ekf_mul(t0->cth, t0->sphi), ekf_mul(t0->cth, t0->cphi)};
    ekf_scalar_t A[9], s, v[3];
    int i, j;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            A[3 * i + j] = ekf_mac(ekf_mac(ekf_mul(M[3 * i], C[j]), M[3 * i + 1], C[3 + j]), M[3 * i + 2], C[6 + j]);
        }
    }
    s = ekf_sqrt(ekf_add(ekf_sq(A[7]), ekf_sq(A[8]))); /* cos(theta+) */
    /* within sqrt(eps) of +-90 deg the last row does not give the roll (its sine and cosine
     * are rounding): keep the roll, the heading takes the rest */
    ang[0] = (s > ekf_sqrt(EKF_SCALAR_EPS)) ? ekf_atan2(A[7], A[8]) : phi;
    ang[1] = ekf_atan2(ekf_neg(A[6]), s);
    ekf_sincos(ang[0], &tn->sphi, &tn->cphi);
    ekf_sincos(ang[1], &tn->sth, &tn->cth);
    /* A Rx(phi+)^T Ry(theta+)^T = Rz(dpsi): its first column is A v */
    v[0] = tn->cth;
    v[1] = ekf_mul(tn->sth, tn->sphi);
    v[2] = ekf_mul(tn->sth, tn->cphi);
    *dpsi = ekf_atan2(ekf_mac(ekf_mac(ekf_mul(A[3], v[0]), A[4], v[1]), A[5], v[2]),
                      ekf_mac(ekf_mac(ekf_mul(A[0], v[0]), A[1], v[1]), A[2], v[2]));
}

void att_model_transition(const ekf_scalar_t x[ATT_N], const ekf_scalar_t w[3], ekf_scalar_t dt,
                          ekf_scalar_t theta_limit, ekf_scalar_t xn[ATT_N], att_motion_t *m)
{
    ekf_scalar_t u[3], ang[3], dpsi;
    int i;
    for (i = 0; i < 3; ++i) {
        u[i] = ekf_mul(x[ATT_P + i], dt);
    }
    att_model_rotation(u, dt, m->rot, m->jd);
    /* the angles before the step as they are (no clamp: only sines and cosines) */
    ekf_sincos(x[ATT_PHI], &m->t0.sphi, &m->t0.cphi);
    ekf_sincos(x[ATT_THETA], &m->t0.sth, &m->t0.cth);
    m->t0.secth = EKF_C(0);
    compose(&m->t0, x[ATT_PHI], m->rot, ang, &dpsi, &m->t);
    xn[ATT_PHI] = ekf_wrap_pi(ang[0]);
    xn[ATT_THETA] = ang[1];
    xn[ATT_PSI] = ekf_wrap_pi(ekf_add(x[ATT_PSI], dpsi));
    m->remapped = ekf_abs(ekf_wrap_pi(ekf_sub(ang[0], x[ATT_PHI]))) > EKF_HALF_PI &&
                   ekf_abs(ekf_wrap_pi(dpsi)) > EKF_HALF_PI;
    for (i = 0; i < 3; ++i) {
        xn[ATT_P + i] = (w != NULL) ? ekf_add(x[ATT_P + i], w[i]) : x[ATT_P + i];
    }
    /* the new angles' trigonometry from the composition (the wrap of phi changes none of it),
     * with the gimbal clamp of att_trig where the pitch is beyond the limit */
    if (ekf_abs(xn[ATT_THETA]) > theta_limit) {
        (void)att_trig(xn[ATT_PHI], xn[ATT_THETA], theta_limit, &m->t);
    } else {
        m->t.secth = ekf_div(EKF_C(1), m->t.cth);
    }
    att_gen_euler_rates(&m->t, &xn[ATT_P], &xn[ATT_PHID]);
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
