/*
 * att_lowpass.c - the accelerometer low-pass, carried with the body: turned by every
 * prediction, blended with every accelerometer sample (docs/derivation.md, "Linear
 * acceleration").
 */
#include "att_lowpass.h"

/* vec <- C^T vec: an earth-fixed vector seen from the body after it turned by C. */
static void turn_vector(const ekf_scalar_t C[9], ekf_scalar_t vec[3])
{
    const ekf_scalar_t v0 = vec[0], v1 = vec[1], v2 = vec[2];
    int i;
    for (i = 0; i < 3; ++i) {
        vec[i] = ekf_mac(ekf_mac(ekf_mul(C[i], v0), C[3 + i], v1), C[6 + i], v2);
    }
}

/* The accelerometer low-pass (accel_lpf_tau, accel_lpf_order stages) lives in a frame that
 * turns with the body: every prediction carries the filtered specific force into the new body frame with the
 * step's rotation C (a vector fixed in the earth frame is C^T v in the new body axes), every
 * accelerometer sample is blended in (att_lowpass_blend). Gravity is earth-fixed, so it passes
 * without lag; linear acceleration that averages to zero in the earth frame (shaking,
 * vibration) is filtered out (docs/derivation.md, "Linear acceleration"). */
void att_lowpass_turn(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t rot[9])
{
    if (!v->accel_lp_valid) {
        return;
    }
    turn_vector(rot, v->accel_lp);
    if (s->accel_lpf_order > 1u) {
        turn_vector(rot, v->accel_lp1);
    }
}

/* Blends a sample into the low-passed specific force (see att_lowpass_turn):
 * the first stage follows the sample, the second (accel_lpf_order 2) the first stage; a
 * restarted low-pass takes the sample in every stage. */
void att_lowpass_blend(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt)
{
    const ekf_scalar_t k = ekf_div(dt, ekf_add(s->accel_lpf_tau, dt));
    ekf_scalar_t *first = (s->accel_lpf_order > 1u) ? v->accel_lp1 : v->accel_lp;
    int i;
    for (i = 0; i < 3; ++i) {
        first[i] = v->accel_lp_valid ? ekf_mac(first[i], k, ekf_sub(accel[i], first[i])) : accel[i];
    }
    if (first != v->accel_lp) {
        for (i = 0; i < 3; ++i) {
            v->accel_lp[i] = v->accel_lp_valid ? ekf_mac(v->accel_lp[i], k, ekf_sub(first[i], v->accel_lp[i]))
                                               : first[i];
        }
    }
    v->accel_lp_valid = 1u;
}
