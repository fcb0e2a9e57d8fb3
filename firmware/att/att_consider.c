/*
 * att_consider.c - considered error sources of the reported covariance (see att_consider.h).
 */
#include "att_consider.h"

void att_consider_reset(att_consider_t *c)
{
    int i;
    for (i = 0; i < 2; ++i) {
        c->tilt[i] = EKF_C(0);
        c->cross[i] = EKF_C(0);
    }
    for (i = 0; i < 3; ++i) {
        c->rate[i] = EKF_C(0);
    }
}

/* An angle error variance beyond that of a uniform angle (pi^2, rad^2) says nothing more. */
#define RATE_VAR_MAX EKF_C(9.869604401089358)

void att_consider_predict(att_consider_t *c, ekf_scalar_t w2, ekf_scalar_t k, ekf_scalar_t sec2, ekf_scalar_t dt)
{
    const ekf_scalar_t q = ekf_mul(ekf_mul(ekf_sq(k), w2), dt);
    const ekf_scalar_t qt = ekf_mul(q, sec2);
    c->rate[0] = ekf_min(ekf_add(c->rate[0], qt), RATE_VAR_MAX);
    c->rate[1] = ekf_min(ekf_add(c->rate[1], q), RATE_VAR_MAX);
    c->rate[2] = ekf_min(ekf_add(c->rate[2], qt), RATE_VAR_MAX);
}

static ekf_scalar_t unit(ekf_scalar_t k)
{
    return ekf_clamp(k, EKF_C(0), EKF_C(1));
}

void att_consider_accel(att_consider_t *c, const ekf_scalar_t kf[2], ekf_scalar_t n_var, ekf_scalar_t rho)
{
    int i;
    for (i = 0; i < 2; ++i) {
        const ekf_scalar_t k = unit(kf[i]);
        const ekf_scalar_t keep = ekf_sub(EKF_C(1), k);
        const ekf_scalar_t rb = ekf_mul(rho, c->cross[i]);  /* Cov(e, n') */
        const ekf_scalar_t kn = ekf_mul(k, n_var);
        c->tilt[i] = ekf_add(ekf_mac(ekf_mul(ekf_sq(keep), c->tilt[i]), ekf_mul(EKF_C(2), ekf_mul(keep, k)), rb),
                             ekf_mul(k, kn));
        c->cross[i] = ekf_mac(kn, keep, rb);
        c->rate[i] = ekf_mul(ekf_sq(keep), c->rate[i]);
    }
}

void att_consider_heading(att_consider_t *c, ekf_scalar_t k)
{
    c->rate[2] = ekf_mul(ekf_sq(ekf_sub(EKF_C(1), unit(k))), c->rate[2]);
}

void att_consider_heading_reset(att_consider_t *c)
{
    c->rate[2] = EKF_C(0);
}

void att_consider_add(const att_consider_t *c, ekf_scalar_t var[3])
{
    var[0] = ekf_add(var[0], ekf_add(c->tilt[0], c->rate[0]));
    var[1] = ekf_add(var[1], ekf_add(c->tilt[1], c->rate[1]));
    var[2] = ekf_add(var[2], c->rate[2]);
}
