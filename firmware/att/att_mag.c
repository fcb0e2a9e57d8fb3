/*
 * att_mag.c - the magnetometer: the reference field (set, learned, tracked) and the heading
 * stage with its reset (docs/derivation.md, "Magnetometer", "Measurement models").
 */
#include "att_mag.h"

#include "att_gen.h"
#include "att_sensor.h"
#include "att_state.h"
#include "ekf_util.h"

/* The magnetic reference (norm in mag units, dip in rad) and tan^2(dip), which scales the
 * tilt error into the heading ("Magnetometer" in docs/derivation.md): computed here, once
 * per reference, not per sample (|dip| is capped at 84 deg, cos >= 0.1). */
void att_mag_set_reference(att_vars_t *v, ekf_scalar_t norm, ekf_scalar_t dip)
{
    ekf_scalar_t sd, cd;
    v->mag_ref_norm = norm;
    v->mag_ref_dip = dip;
    ekf_sincos(dip, &sd, &cd);
    v->mag_tan2_dip = ekf_sq(ekf_div(sd, ekf_max(cd, EKF_C(0.1))));
}

ekf_scalar_t att_mag_heading(const att_settings_t *s, const ekf_scalar_t lev[3])
{
    return ekf_wrap_pi(ekf_sub(ekf_atan2(lev[0], lev[1]), s->mag_declination));
}

ekf_scalar_t att_mag_dip(const ekf_scalar_t lev[3])
{
    return ekf_atan2(ekf_neg(lev[2]), ekf_sqrt(ekf_add(ekf_sq(lev[0]), ekf_sq(lev[1]))));
}

/* Heading row and column reset: psi <- heading, Var(psi) <- var, no correlation. Keeps P
 * positive semi-definite (a principal block plus a positive diagonal entry). */
static void reset_heading(att_vars_t *v, const att_settings_t *s, ekf_scalar_t heading, ekf_scalar_t var)
{
    att_cov_reset_state(&v->cov, ATT_PSI, ekf_max(var, s->var_floor));
    v->x[ATT_PSI] = heading;
    /* the heading no longer depends on the past offset or the past rate errors */
    att_bias_heading_reset(&v->bias);
    att_consider_heading_reset(&v->consider);
}

/* The learned magnetic reference (mag_ref_norm 0): a reference taken at alignment, perhaps
 * in motion with the tilt still off, settles to the running mean of the field over the first
 * quarter of mag_new_time; afterwards a field off the reference that stays within the
 * tolerances of its own running mean for mag_new_time (a new place, not a passing iron)
 * becomes the reference (docs/derivation.md, "Magnetometer"). */
static void track_reference(att_vars_t *v, const att_settings_t *s, ekf_scalar_t norm, ekf_scalar_t dip,
                            ekf_scalar_t dt)
{
    const ekf_scalar_t T = s->mag_new_time;
    ekf_scalar_t k;
    int settling, off, steady;
    if (s->mag_ref_norm > EKF_C(0) || !(T > EKF_C(0))) {
        return;
    }
    if (!(v->mag_avg_norm > EKF_C(0))) {
        v->mag_avg_norm = norm;
        v->mag_avg_dip = dip;
    }
    /* the dip is levelled with the estimated tilt: only samples whose tilt the accelerometer
     * confirms tell the field's dip */
    if (v->tilt_ok) {
        k = ekf_div(dt, ekf_add(ekf_mul(EKF_C(0.125), T), dt));
        v->mag_avg_norm = ekf_mac(v->mag_avg_norm, k, ekf_sub(norm, v->mag_avg_norm));
        v->mag_avg_dip = ekf_mac(v->mag_avg_dip, k, ekf_sub(dip, v->mag_avg_dip));
    }
    settling = v->mag_new_clock < ekf_mul(EKF_C(0.25), T) && !v->mag_settled;
    if (settling) {
        if (v->tilt_ok) {
            v->mag_new_clock = ekf_add(v->mag_new_clock, dt);
            att_mag_set_reference(v, v->mag_avg_norm, v->mag_avg_dip);
        }
        return;
    }
    if (!v->mag_settled) {
        v->mag_settled = 1u;
        v->mag_new_clock = EKF_C(0);
    }
    off = ekf_abs(ekf_sub(ekf_div(norm, v->mag_ref_norm), EKF_C(1))) > s->mag_norm_tol ||
          ekf_abs(ekf_sub(dip, v->mag_ref_dip)) > s->mag_dip_tol;
    steady = !(ekf_abs(ekf_sub(ekf_div(norm, v->mag_avg_norm), EKF_C(1))) > s->mag_norm_tol) &&
             !(ekf_abs(ekf_sub(dip, v->mag_avg_dip)) > s->mag_dip_tol);
    v->mag_new_clock = (off && steady && v->tilt_ok) ? ekf_add(v->mag_new_clock, dt) : EKF_C(0);
    if (v->mag_new_clock > T) {
        att_mag_set_reference(v, v->mag_avg_norm, v->mag_avg_dip);
        v->mag_new_clock = EKF_C(0);
    }
}

/* The heading measurement's variance, rad^2 per sample of length dt (s). The heading comes
 * from the field levelled with the estimated tilt, and a tilt error e moves it by about
 * tan(dip) e. While linear acceleration disturbs the tilt (its running variance
 * accel_dev_var, m/s^2 squared, is a tilt variance of accel_dev_var / g^2), the heading is
 * trusted that much less (docs/derivation.md, "Magnetometer"). */
static ekf_scalar_t heading_var(const att_vars_t *v, const att_settings_t *s, ekf_scalar_t dt)
{
    ekf_scalar_t r_var = ekf_div(ekf_mac(ekf_sq(s->mag_heading_noise), v->mag_tan2_dip,
                                         ekf_div(ekf_mul(v->accel_dev_var, s->accel_adapt_weight), ekf_sq(s->gravity))),
                                 dt);
    if (s->mag_norm_band > EKF_C(0) && s->mag_dip_band > EKF_C(0)) {
        /* a field off its reference norm or dip is a disturbed one, and its heading errs with
         * it (an iron nearby, a magnet on the sensor): trusted less the further it is off */
        const ekf_scalar_t kn = ekf_div(v->diag.mag_norm_error, s->mag_norm_band);
        const ekf_scalar_t kd = ekf_div(v->diag.mag_dip_error, s->mag_dip_band);
        r_var = ekf_mul(r_var, ekf_add(EKF_C(1), ekf_add(ekf_sq(kn), ekf_sq(kd))));
    }
    return r_var;
}

/* The heading's scalar update with innovation nu (rad) and variance r_var (rad^2), and what
 * follows a fused one: the offset in motion and the considered heading error. No gate bypass
 * for the magnetometer (a magnet that passes the norm and dip tests would drag the heading):
 * recovery is the reset of att_stage_mag, after mag_reset_time. */
static ekf_status_t fuse_heading(att_vars_t *v, const att_settings_t *s, ekf_scalar_t nu, ekf_scalar_t r_var)
{
    static const ekf_scalar_t h3[3] = {EKF_C(0), EKF_C(0), EKF_C(1)};
    const ekf_scalar_t var0 = att_cov_var(&v->cov, ATT_PSI);
    const ekf_scalar_t pht[3] = {att_cov_get(&v->cov, ATT_PHI, ATT_PSI), att_cov_get(&v->cov, ATT_THETA, ATT_PSI), var0};
    ekf_innov_t info;
    const ekf_status_t st = att_cov_update_unit(&v->cov, v->x, ATT_PSI, nu, r_var, s->mag_gate, s->var_floor, &info);
    if (st == EKF_OK) {
        /* the field's errors depend on the orientation and disturbed fields pass the
         * tests: taken at face value they would teach the vertical offset the field's
         * errors (docs/derivation.md, "Gyroscope offset in motion"), hence mag_derate */
        (void)att_bias_update(&v->bias, s->bias.motion >= 2u, h3, pht, nu, info.variance, s->bias.mag_derate, NULL,
                              &v->x[ATT_PHI]);
        att_consider_heading(&v->consider, att_sensor_reduction(var0, att_cov_var(&v->cov, ATT_PSI)));
    }
    v->diag.mag_ratio = info.test_ratio;
    if (st == EKF_GATED) {
        ekf_count(&v->diag.mag_gated);
        att_sensor_gate_result(v, s, ATT_SENSOR_MAG, 1);
        v->flags |= ATT_FLAG_MAG_GATED;
        return EKF_GATED;
    }
    if (st != EKF_OK) {
        return st; /* EKF_ERR_NUMERIC: the caller puts the saved variables back */
    }
    ekf_count(&v->diag.mag_fused);
    v->heading_ref = 1u;
    att_sensor_gate_result(v, s, ATT_SENSOR_MAG, 0);
    if (att_normalise(v)) {
        ekf_count(&v->diag.remaps);
    }
    /* the heading update moves the pitch too, through their correlation */
    att_update_gimbal_flag(v, s);
    return EKF_OK;
}

/* A field sample skipped (flag: why), counted. */
static ekf_status_t skip_field(att_vars_t *v, uint32_t flag)
{
    v->flags |= flag;
    ekf_count(&v->diag.mag_skipped);
    return EKF_SKIPPED;
}

ekf_status_t att_stage_mag(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t mag[3], ekf_scalar_t dt)
{
    ekf_scalar_t lev[3], norm, heading, nu;
    att_trig_t t;

    v->flags &= ~(ATT_FLAG_MAG_DISTURBED | ATT_FLAG_HEADING_HELD | ATT_FLAG_MAG_GATED);
    if ((v->flags & ATT_FLAG_GIMBAL_LOCK) != 0u) {
        /* heading is ill-defined next to theta = +-90 deg: hold it */
        return skip_field(v, ATT_FLAG_HEADING_HELD);
    }
    norm = att_norm3(mag);
    att_sensor_trig(v, &t);
    {
        ekf_scalar_t m[3];
        att_sensor_to_interval_end(v, mag, dt, m);
        att_gen_mag_level(&t, m, lev);
    }
    if (!(ekf_sqrt(ekf_add(ekf_sq(lev[0]), ekf_sq(lev[1]))) > ekf_mul(EKF_C(1e-3), norm))) {
        /* no horizontal component (or no field at all): no heading information */
        return skip_field(v, ATT_FLAG_MAG_DISTURBED);
    }
    heading = att_mag_heading(s, lev);
    if (!(v->mag_ref_norm > EKF_C(0))) {
        /* aligned without a magnetometer: the first field sample sets the reference and
         * the heading */
        att_mag_set_reference(v, norm, att_mag_dip(lev));
        reset_heading(v, s, heading, ekf_min(ekf_sq(s->init_heading_sigma), s->heading_var_max));
        v->flags &= ~ATT_FLAG_HEADING_LIMITED;
        ekf_count(&v->diag.mag_fused);
        v->heading_ref = 1u;
        return EKF_OK;
    }
    track_reference(v, s, norm, att_mag_dip(lev), dt);
    v->diag.mag_norm_error = ekf_sub(ekf_div(norm, v->mag_ref_norm), EKF_C(1));
    v->diag.mag_dip_error = ekf_sub(att_mag_dip(lev), v->mag_ref_dip);
    if (ekf_abs(v->diag.mag_norm_error) > s->mag_norm_tol || ekf_abs(v->diag.mag_dip_error) > s->mag_dip_tol) {
        /* the reset below needs mag_reset_time of gating an undisturbed field: a body-fixed
         * offset can pass the tests for a moment in a turn */
        v->gated_time[ATT_SENSOR_MAG] = EKF_C(0);
        return skip_field(v, ATT_FLAG_MAG_DISTURBED);
    }
    nu = ekf_wrap_pi(ekf_sub(heading, v->x[ATT_PSI]));
    if (s->mag_reset_time > EKF_C(0) && v->gated_time[ATT_SENSOR_MAG] > s->mag_reset_time && v->tilt_ok) {
        /* An undisturbed field (norm and dip as referenced) has disagreed with the heading
         * beyond the gate for mag_reset_time: the heading is what is wrong (lost during
         * gyro saturation, or tilted by sustained acceleration). Take the magnetic heading
         * with the initial uncertainty. Only with a tilt the accelerometer confirms: the
         * field is levelled with it, and a tilt still wrong after sustained acceleration
         * gives a heading wrong by up to 180 deg. A magnet fixed to the sensor can pass the
         * norm and dip tests for seconds; with these conditions no reset fires on BROAD's
         * attached-magnet trials (docs/derivation.md, "Magnetometer"). */
        reset_heading(v, s, heading, ekf_min(ekf_sq(s->init_heading_sigma), s->heading_var_max));
        ekf_count(&v->diag.heading_resets);
        ekf_count(&v->diag.mag_fused);
        v->heading_ref = 1u;
        att_sensor_gate_result(v, s, ATT_SENSOR_MAG, 0);
        return EKF_OK;
    }
    return fuse_heading(v, s, nu, heading_var(v, s, dt));
}
