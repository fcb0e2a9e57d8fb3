/*
 * att_align.c - alignment: the initial attitude from gravity (and the magnetometer), and
 * the averaging phase of att_step before it (docs/derivation.md, "Alignment").
 */
#include "att_align.h"

#include "att_accel.h"

#include <stddef.h>

#include "att_gen.h"
#include "att_mag.h"
#include "att_model.h"
#include "att_state.h"
#include "ekf_util.h"

ekf_status_t att_stage_align(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3],
                             const ekf_scalar_t mag[3])
{
    ekf_scalar_t x[ATT_N] = {0};
    ekf_scalar_t var0[ATT_N] = {0};
    att_trig_t t;
    ekf_scalar_t g[9];
    ekf_scalar_t lev[3];
    ekf_scalar_t heading_var;
    int i, use_mag = 0;

    /* roll and pitch from the gravity direction: a = g (-sin th, sin ph cos th, cos ph cos th) */
    x[ATT_PHI] = ekf_atan2(accel[1], accel[2]);
    x[ATT_THETA] = ekf_atan2(ekf_neg(accel[0]), ekf_sqrt(ekf_add(ekf_sq(accel[1]), ekf_sq(accel[2]))));
    (void)att_trig(x[ATT_PHI], x[ATT_THETA], s->gimbal_limit, &t);
    heading_var = s->heading_var_max;
    if (mag != NULL && att_norm3(mag) > EKF_C(0)) {
        att_gen_mag_level(&t, mag, lev);
        if (ekf_add(ekf_sq(lev[0]), ekf_sq(lev[1])) > EKF_C(0)) {
            use_mag = 1;
            x[ATT_PSI] = att_mag_heading(s, lev);
            heading_var = ekf_min(ekf_sq(s->init_heading_sigma), s->heading_var_max);
        }
    }

    for (i = 0; i < ATT_N; ++i) {
        v->x[i] = x[i];
    }
    var0[ATT_PHI] = ekf_sq(s->init_tilt_sigma);
    var0[ATT_THETA] = ekf_sq(s->init_tilt_sigma);
    var0[ATT_PSI] = heading_var;
    att_cov_set_diag(&v->cov, var0);
    /* rates: zero with the rate uncertainty mapped into the Euler rates, plus their own
     * relative error, so that P starts positive definite */
    att_gen_noise_jacobian(&t, g);
    {
        const ekf_scalar_t r = ekf_sq(s->init_rate_sigma), var[3] = {r, r, r};
        att_cov_add_rate_noise(&v->cov, g, var);
    }
    att_cov_scale_diag(&v->cov, ATT_PHID, 3, s->euler_rate_rel);
    /* the initial sigmas may be set below the variance floor: the floor holds from the
     * first step, like after every update */
    (void)att_cov_floor_diag(&v->cov, s->var_floor); /* every variance >= 0 here */
    /* atan2 can return +pi itself (a = (0, +0, -g), upside down): into [-pi, pi) like after
     * every other stage */
    (void)att_normalise(v);
    /* the angles are measured afresh: their errors no longer depend on the past offset */
    att_bias_restart(&v->bias);
    att_consider_reset(&v->consider);

    /* a learned reference settles afresh (att_mag.c, track_reference) */
    v->mag_avg_norm = EKF_C(0);
    v->mag_avg_dip = EKF_C(0);
    v->mag_new_clock = EKF_C(0);
    v->mag_settled = 0u;
    if (s->mag_ref_norm > EKF_C(0)) {
        att_mag_set_reference(v, s->mag_ref_norm, s->mag_ref_dip);
    } else if (use_mag) {
        att_mag_set_reference(v, att_norm3(mag), att_mag_dip(lev));
    } else {
        att_mag_set_reference(v, EKF_C(0), EKF_C(0));
    }
    for (i = 0; i < 3; ++i) {
        v->gated_time[i] = EKF_C(0);
    }
    /* the accelerometer low-pass starts from the alignment's (averaged) specific force */
    for (i = 0; i < 3; ++i) {
        v->accel_lp[i] = accel[i];
        v->accel_lp1[i] = accel[i];
    }
    v->accel_lp_valid = 1u;
    v->tilt_ok = 1u; /* the tilt is the accelerometer's */
    v->flags = ATT_FLAG_ALIGNED;
    v->heading_ref = use_mag ? 1u : 0u;
    if (!use_mag) {
        v->flags |= ATT_FLAG_HEADING_LIMITED;
    }
    att_update_gimbal_flag(v, s);
    return EKF_OK;
}

int att_align_has_gravity(const att_settings_t *s, const ekf_scalar_t accel[3])
{
    return att_norm3(accel) > ekf_mul(EKF_C(0.1), s->gravity);
}

ekf_status_t att_stage_align_sample(att_vars_t *v, const att_settings_t *s, const att_sample_t *sm)
{
    ekf_scalar_t acc[3], mag[3];
    ekf_scalar_t na, nm;
    int i, use_mag;
    if (att_accel_clipped(s, sm->accel)) {
        /* the sensor at its range: no gravity direction to average; the next sample */
        ekf_count(&v->diag.accel_skipped);
        return EKF_SKIPPED;
    }
    if ((sm->valid & ATT_HAS_MAG) != 0u) {
        for (i = 0; i < 3; ++i) {
            v->align_mag[i] = ekf_add(v->align_mag[i], sm->mag[i]);
        }
        ++v->align_mag_count;
    }
    for (i = 0; i < 3; ++i) {
        v->align_acc[i] = ekf_add(v->align_acc[i], sm->accel[i]);
    }
    ++v->align_count;
    if (v->align_count < s->align_samples) {
        return EKF_OK;
    }
    na = ekf_from_int((int32_t)v->align_count);
    nm = ekf_from_int((int32_t)v->align_mag_count);
    use_mag = v->align_mag_count > 0u;
    for (i = 0; i < 3; ++i) {
        acc[i] = ekf_div(v->align_acc[i], na);
        mag[i] = use_mag ? ekf_div(v->align_mag[i], nm) : EKF_C(0);
        v->align_acc[i] = EKF_C(0);
        v->align_mag[i] = EKF_C(0);
    }
    v->align_count = 0u;
    v->align_mag_count = 0u;
    if (!att_align_has_gravity(s, acc)) {
        /* the samples averaged to no usable gravity direction (the sensor was thrown or
         * turned over while aligning): start the average again from the next sample */
        ekf_count(&v->diag.accel_skipped);
        return EKF_SKIPPED;
    }
    return att_stage_align(v, s, acc, use_mag ? mag : NULL);
}
