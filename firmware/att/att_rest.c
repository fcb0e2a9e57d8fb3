/*
 * att_rest.c - rest detection and gyroscope offset estimation (see att_rest.h).
 */
#include "att_rest.h"

void att_rest_reset(att_rest_t *r)
{
    int i;
    for (i = 0; i < 3; ++i) {
        r->gyro_lp[i] = EKF_C(0);
        r->acc_lp[i] = EKF_C(0);
        r->bias[i] = EKF_C(0);
    }
    r->still_time = EKF_C(0);
    r->bias_time = EKF_C(0);
    r->primed = 0u;
    r->at_rest = 0u;
}

void att_rest_motion(att_rest_t *r)
{
    r->still_time = EKF_C(0);
    r->at_rest = 0u;
}

int att_rest_update(att_rest_t *r, const att_rest_settings_t *s, const ekf_scalar_t gyro[3],
                    const ekf_scalar_t accel[3], ekf_scalar_t dt)
{
    const ekf_scalar_t g2 = ekf_sq(s->rest_gyro);
    ekf_scalar_t k, w, lp2 = EKF_C(0), dg2 = EKF_C(0), da2 = EKF_C(0);
    int still, i;

    if (!(s->bias_tau > EKF_C(0))) {
        r->at_rest = 0u;
        return 0;
    }
    if (!r->primed) {
        for (i = 0; i < 3; ++i) {
            r->gyro_lp[i] = gyro[i];
            r->acc_lp[i] = accel[i];
        }
        r->primed = 1u;
    }
    /* first-order low-pass, gain dt / (tau + dt) (stable for any dt); an axis that reads
     * exactly zero (a noise-free or quantised sensor at rest) decays to exactly zero rather
     * than to a subnormal number (ekf_flush_tiny) */
    k = ekf_div(dt, ekf_add(s->rest_tau, dt));
    for (i = 0; i < 3; ++i) {
        r->gyro_lp[i] = ekf_flush_tiny(ekf_mac(r->gyro_lp[i], k, ekf_sub(gyro[i], r->gyro_lp[i])));
        r->acc_lp[i] = ekf_flush_tiny(ekf_mac(r->acc_lp[i], k, ekf_sub(accel[i], r->acc_lp[i])));
        /* the squared norms of the low-passed rate and of both sensors' deviations from
         * their low-pass */
        lp2 = ekf_add(lp2, ekf_sq(r->gyro_lp[i]));
        dg2 = ekf_add(dg2, ekf_sq(ekf_sub(gyro[i], r->gyro_lp[i])));
        da2 = ekf_add(da2, ekf_sq(ekf_sub(accel[i], r->acc_lp[i])));
    }
    still = lp2 < g2 && dg2 < g2 && da2 < ekf_sq(s->rest_accel);
    if (!still) {
        r->still_time = EKF_C(0);
        r->at_rest = 0u;
        return 0;
    }
    r->still_time = ekf_min(ekf_add(r->still_time, dt), s->rest_time);
    /* half a sample of slack: a sum of dt's that should equal rest_time must not miss it
     * by a rounding error (float and double would then start learning a sample apart) */
    r->at_rest = (uint8_t)(ekf_mac(r->still_time, EKF_C(0.5), dt) >= s->rest_time);
    if (!r->at_rest) {
        return 0;
    }
    /* running mean over the rest seen so far, then an exponential average over bias_tau */
    r->bias_time = ekf_min(ekf_add(r->bias_time, dt), s->bias_tau);
    w = ekf_div(dt, r->bias_time);
    for (i = 0; i < 3; ++i) {
        const ekf_scalar_t b = ekf_flush_tiny(ekf_mac(r->bias[i], w, ekf_sub(gyro[i], r->bias[i])));
        r->bias[i] = ekf_max(ekf_neg(s->bias_max), ekf_min(s->bias_max, b));
    }
    return 1;
}
