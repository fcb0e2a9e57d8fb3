/*
 * att_update.c - the measurement stages: gyroscope (and a saturated gyroscope),
 * accelerometer, magnetometer (docs/derivation.md, "Measurement models", "Innovation
 * gate", "Gate timeouts").
 */
#include "att_gen.h"
#include "att_internal.h"
#include "att_model.h"
#include "ekf_util.h"

/* Trigonometry for the measurement functions: the true (unclamped) pitch. They use only
 * sin and cos, never sec(theta), which is left at zero. */
static void meas_trig(const att_vars_t *v, att_trig_t *t)
{
    if (v->x[ATT_PHI] == v->trig_at[0] && v->x[ATT_THETA] == v->trig_at[1] && v->trig.cth > EKF_C(0)) {
        *t = v->trig; /* the prediction's, of these very angles */
        t->secth = EKF_C(0);
        return;
    }
    ekf_sincos(v->x[ATT_PHI], &t->sphi, &t->cphi);
    ekf_sincos(v->x[ATT_THETA], &t->sth, &t->cth);
    t->secth = EKF_C(0);
}

/* 1 if an innovation would fail the gate of gate sigmas (a bypassed gate still judges the
 * innovations, so that the bypass lasts until they are consistent again). */
static int fails_gate(const ekf_innov_t *info, ekf_scalar_t gate)
{
    return gate > EKF_C(0) && ekf_sq(info->innovation) > ekf_mul(ekf_sq(gate), info->variance);
}

/* Gate of the gyroscope or the accelerometer: its setting, or 0 (off) once it has gated
 * continuously for longer than gate_timeout. A filter that has drifted away from a sensor
 * would otherwise reject it forever. */
static ekf_scalar_t gate_for(att_vars_t *v, const att_settings_t *s, int sensor, ekf_scalar_t gate)
{
    const ekf_scalar_t timeout = s->gate_timeout;
    if (gate > EKF_C(0) && timeout > EKF_C(0) && v->gated_time[sensor] > timeout) {
        v->flags |= ATT_FLAG_GATE_BYPASS;
        /* the innovations say the state is off: not the offset's doing */
        att_bias_hold(&v->bias, s->bias.hold_time);
        return EKF_C(0);
    }
    return gate;
}

/* Records whether a sensor's update gated (starts the gate clock) or passed (stops it). */
static void gate_result(att_vars_t *v, const att_settings_t *s, int sensor, int gated)
{
    if (gated) {
        if (!(v->gated_time[sensor] > EKF_C(0))) {
            v->gated_time[sensor] = EKF_SCALAR_EPS; /* running; the prediction adds dt */
        }
    } else {
        v->gated_time[sensor] = EKF_C(0);
        if (!(v->gated_time[ATT_SENSOR_GYRO] > s->gate_timeout) &&
            !(v->gated_time[ATT_SENSOR_ACCEL] > s->gate_timeout)) {
            v->flags &= ~ATT_FLAG_GATE_BYPASS;
        }
    }
}

/* ---- the reported covariance's considered errors (att_consider.h) ---- */

/* The fraction by which an update reduced a variance (its gain on that state's error). */
static ekf_scalar_t reduction(ekf_scalar_t before, ekf_scalar_t after)
{
    return (before > EKF_C(0)) ? ekf_sub(EKF_C(1), ekf_div(after, before)) : EKF_C(0);
}

/* ---- gyroscope ---- */

/* A clamped gyro reading (ATT_GYRO_SATURATED): the rate is at least its largest component
 * in magnitude, by an unknown amount. Not fused; each body-rate variance is raised to at
 * least that square (P += G diag(extra) G^T, positive semi-definite, so P stays positive
 * definite), docs/derivation.md "Gyroscope saturation". Without this the rates would only
 * random-walk at rate_walk while a tumble beyond full scale turns the vehicle, and the
 * attitude would come out of the tumble wrong with a small covariance: confidently wrong,
 * and gated by the sensors that could correct it. */
ekf_status_t att_stage_gyro_saturated(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3])
{
    ekf_scalar_t g[9], extra[3], var;
    att_trig_t t;
    int i;

    var = ekf_sq(ekf_max(ekf_max(ekf_abs(gyro[0]), ekf_abs(gyro[1])), ekf_abs(gyro[2])));
    for (i = 0; i < 3; ++i) {
        extra[i] = ekf_max(ekf_sub(var, att_cov_var(&v->cov, ATT_P + i)), EKF_C(0));
    }
    (void)att_trig(v->x[ATT_PHI], v->x[ATT_THETA], s->gimbal_limit, &t);
    att_gen_noise_jacobian(&t, g);
    att_cov_add_rate_noise(&v->cov, g, extra);
    /* the angles' error is now the unmeasured rotation's, not the offset's */
    att_bias_restart(&v->bias);
    att_bias_hold(&v->bias, s->bias.hold_time);
    /* the low-passed force is carried over the step with the body rates, which this sample
     * does not measure: start it again from the next sample whose rates are measured */
    v->accel_lp_valid = 0u;
    v->rate_unmeasured = 1u;
    ekf_count(&v->diag.gyro_saturated);
    return EKF_SKIPPED;
}

ekf_status_t att_stage_gyro(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3], ekf_scalar_t dt)
{
    v->rate_unmeasured = 0u;
    ekf_scalar_t gate, r_var;
    ekf_status_t st;
    ekf_innov_t info;
    int i, gated = 0, bypass_failed = 0;

    gate = gate_for(v, s, ATT_SENSOR_GYRO, s->gyro_gate);
    r_var = ekf_div(ekf_sq(s->gyro_noise), dt); /* a density: the variance of the sample's mean */
    for (i = 0; i < 3; ++i) {
        /* the offset learned in motion stays within bias_max of zero together with the
         * rest offset */
        const ekf_scalar_t m = s->rest.bias_max;
        v->bias.b[i] = ekf_clamp(v->bias.b[i], ekf_sub(ekf_neg(m), v->rest.bias[i]), ekf_sub(m, v->rest.bias[i]));
    }
    for (i = 0; i < 3; ++i) {
        /* the rates net of the offset (att_rest.h, att_bias.h) */
        const ekf_scalar_t nu =
            ekf_sub(ekf_sub(gyro[i], ekf_add(v->rest.bias[i], v->bias.b[i])), v->x[ATT_P + i]);
        st = att_cov_update_unit(&v->cov, v->x, ATT_P + i, nu, r_var, gate, s->var_floor, &info);
        v->diag.gyro_ratio[i] = info.test_ratio;
        if (st == EKF_GATED) {
            gated = 1;
            ekf_count(&v->diag.gyro_gated);
        } else if (st != EKF_OK) {
            return st; /* EKF_ERR_NUMERIC: the call discards its working copy */
        } else {
            ekf_count(&v->diag.gyro_fused);
            bypass_failed |= fails_gate(&info, s->gyro_gate);
        }
    }
    /* the rates correlate with the angles: the update may have moved them too */
    if (att_normalise(v)) {
        ekf_count(&v->diag.remaps);
    }
    att_update_gimbal_flag(v, s);
    gate_result(v, s, ATT_SENSOR_GYRO, gated || bypass_failed);
    if (gated) {
        v->flags |= ATT_FLAG_GYRO_GATED;
        return EKF_GATED;
    }
    v->flags &= ~ATT_FLAG_GYRO_GATED;
    return EKF_OK;
}

/* ---- accelerometer ---- */

/* A vector sample (accelerometer or magnetometer, body frame) is the mean over its own
 * interval, the sample interval (dt, or after a gap the interval without gaps, dt_nom): for a
 * body turning at the rate state it is the vector half an interval before the state's time.
 * out = the same earth-fixed vector in the body axes at the end of the interval, turned by
 * -w dt/2 (second order in th = w dt / 2: v - th x v + th x (th x v) / 2); docs/derivation.md,
 * "Sample timing". */
static void cross3(const ekf_scalar_t a[3], const ekf_scalar_t b[3], ekf_scalar_t out[3])
{
    out[0] = ekf_sub(ekf_mul(a[1], b[2]), ekf_mul(a[2], b[1]));
    out[1] = ekf_sub(ekf_mul(a[2], b[0]), ekf_mul(a[0], b[2]));
    out[2] = ekf_sub(ekf_mul(a[0], b[1]), ekf_mul(a[1], b[0]));
}

static void to_interval_end(const att_vars_t *v, const ekf_scalar_t vec[3], ekf_scalar_t dt, ekf_scalar_t out[3])
{
    const ekf_scalar_t own = (v->dt_nom > EKF_C(0)) ? ekf_min(dt, v->dt_nom) : dt;
    /* (a saturated gyro leaves the rate state a guess: the sample is taken as it is) */
    const ekf_scalar_t half = v->rate_unmeasured ? EKF_C(0) : ekf_mul(EKF_C(0.5), own);
    ekf_scalar_t th[3], c1[3], c2[3];
    int i;
    for (i = 0; i < 3; ++i) {
        th[i] = ekf_mul(v->x[ATT_P + i], half);
    }
    cross3(th, vec, c1);
    cross3(th, c1, c2);
    for (i = 0; i < 3; ++i) {
        out[i] = ekf_mac(ekf_sub(vec[i], c1[i]), EKF_C(0.5), c2[i]);
    }
}

/* Blends a sample into the low-passed specific force (see accel_lp_turn, att_predict.c):
 * the first stage follows the sample, the second (accel_lpf_order 2) the first stage; a
 * restarted low-pass takes the sample in every stage. */
static void accel_lp_blend(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt)
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

/* After an accelerometer update (roll and pitch variances var0 before it): the colored
 * error of the low-passed force, whose variance per axis the running linear-acceleration
 * variance estimates and whose correlation time is the low-pass delay (accel_lpf_order
 * stages of accel_lpf_tau), passes into the reported tilt covariance through the gains
 * just applied (att_consider.h). */
static void consider_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t var0[2], ekf_scalar_t dt)
{
    const ekf_scalar_t tau = ekf_mul(ekf_from_int((int32_t)s->accel_lpf_order), s->accel_lpf_tau);
    ekf_scalar_t kf[2];
    kf[0] = reduction(var0[0], att_cov_var(&v->cov, ATT_PHI));
    kf[1] = reduction(var0[1], att_cov_var(&v->cov, ATT_THETA));
    att_consider_accel(&v->consider, kf, ekf_div(v->accel_dev_var, ekf_sq(s->gravity)),
                       ekf_div(tau, ekf_add(tau, dt)));
}

/* The vector the accelerometer stage fuses: at rest the sample itself (no linear
 * acceleration to filter out), else the low-passed force when the low-pass is on (every
 * sample enters it, fused or not, but for those of a saturated gyro: the low-pass turns with
 * the rates, which they do not measure, and starts again after them), else the sample; each
 * turned to the interval's end. The running linear-acceleration variances follow it. Returns
 * its norm. */
static ekf_scalar_t accel_vector(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt,
                                 int rest, ekf_scalar_t a[3])
{
    ekf_scalar_t a_norm;
    int i;
    to_interval_end(v, accel, dt, a);
    if (s->accel_lpf_tau > EKF_C(0) && !v->rate_unmeasured) {
        accel_lp_blend(v, s, a, dt);
        if (s->accel_adapt_tau > EKF_C(0)) {
            const ekf_scalar_t k = ekf_div(dt, ekf_add(s->accel_adapt_tau, dt));
            ekf_scalar_t d2 = EKF_C(0);
            for (i = 0; i < 3; ++i) {
                d2 = ekf_add(d2, ekf_sq(ekf_sub(a[i], v->accel_lp[i])));
            }
            v->accel_hf_var = ekf_mac(v->accel_hf_var, k, ekf_sub(d2, v->accel_hf_var));
        }
        if (!rest) {
            for (i = 0; i < 3; ++i) {
                a[i] = v->accel_lp[i];
            }
        }
    }
    a_norm = att_norm3(a);
    if (s->accel_adapt_tau > EKF_C(0)) {
        /* running mean over accel_adapt_tau of the squared norm error of a: how much linear
         * acceleration is left in it lately, whatever this one sample's norm happens to be */
        const ekf_scalar_t k = ekf_div(dt, ekf_add(s->accel_adapt_tau, dt));
        const ekf_scalar_t e = ekf_sub(a_norm, s->gravity);
        v->accel_dev_var = ekf_mac(v->accel_dev_var, k, ekf_sub(ekf_sq(e), v->accel_dev_var));
    }
    return a_norm;
}

/* Variance of each component of the fused unit vector: (accel_noise^2 + the recent
 * linear-acceleration variance times accel_adapt_weight) / (g^2 dt), both densities; at
 * rest rest.accel_noise^2 / (g^2 dt); optionally inflated by 1 + (err / accel_band)^2 for
 * this sample (docs/derivation.md, "Linear acceleration"). Sets ATT_FLAG_ACCEL_DEWEIGHTED. */
static ekf_scalar_t accel_variance(att_vars_t *v, const att_settings_t *s, ekf_scalar_t err, ekf_scalar_t dt, int rest)
{
    const ekf_scalar_t g2 = ekf_sq(s->gravity);
    const ekf_scalar_t lin = ekf_mul(v->accel_dev_var, s->accel_adapt_weight);
    ekf_scalar_t r_var = ekf_div(ekf_div(ekf_add(ekf_sq(s->accel_noise), lin), dt), g2);
    if (lin > ekf_sq(s->accel_noise)) {
        v->flags |= ATT_FLAG_ACCEL_DEWEIGHTED; /* the noise variance at least doubled */
    }
    if (rest) {
        r_var = ekf_div(ekf_div(ekf_sq(s->rest.accel_noise), dt), g2);
    }
    if (s->accel_band > EKF_C(0)) {
        const ekf_scalar_t k = ekf_div(err, s->accel_band);
        r_var = ekf_mul(r_var, ekf_add(EKF_C(1), ekf_sq(k)));
        if (k > EKF_C(1)) {
            v->flags |= ATT_FLAG_ACCEL_DEWEIGHTED;
        }
    }
    return r_var;
}

/* How much more than S the offset learned in motion must allow for in an accelerometer
 * innovation: the low-passed force's linear-acceleration residual (variance N = v / g^2)
 * is correlated over the low-pass delay T, so T / dt successive innovations share it and
 * carry the evidence of one; counted as white noise of density 2 N T it adds 2 N T / dt to
 * each innovation's variance (docs/derivation.md, "Gyroscope offset in motion"). */
static ekf_scalar_t learn_excess(const att_vars_t *v, const att_settings_t *s, ekf_scalar_t dt, int rest)
{
    const ekf_scalar_t T = ekf_mul(ekf_from_int((int32_t)s->accel_lpf_order), s->accel_lpf_tau);
    if (rest || !(T > EKF_C(0))) {
        return EKF_C(0);
    }
    return ekf_div(ekf_mul(ekf_mul(EKF_C(2), ekf_div(v->accel_dev_var, ekf_sq(s->gravity))), T), dt);
}

/* The unit vector a / norm, fused as its two components in the tangent plane of the
 * predicted gravity direction h: along u_phi = dh/dphi / |dh/dphi| = (0, c_phi, -s_phi) with
 * H = (c_th, 0, 0) on (phi, theta, psi), and along u_theta = dh/dtheta (a unit vector, at
 * right angles to u_phi) with H = (0, 1, 0). Both are orthogonal to h (u^T h = 0 makes the
 * innovation u^T a / norm), and the component along h (the norm) carries no attitude: for
 * noise isotropic across the components this equals the batch update of the 3-vector
 * (docs/derivation.md, "Accelerometer"). The second is relinearised about the prior. Each
 * fused component also teaches the offset in motion. Returns the first error, else
 * EKF_GATED if a component gated, else EKF_OK; *bypass_failed and *consistent as in
 * att_stage_accel. */
static ekf_status_t accel_fuse(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t a[3], ekf_scalar_t norm,
                               ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t excess, int *bypass_failed,
                               int *consistent)
{
    /* beyond the gimbal limit the kinematics are clamped: the innovations then carry the
     * clamp's error, not the offset's */
    const int learn = s->bias.motion >= 1u && (v->flags & ATT_FLAG_GIMBAL_LOCK) == 0u &&
                      !(v->accel_hf_var > ekf_sq(s->bias.quiet_accel));
    const ekf_scalar_t theta0 = v->x[ATT_THETA];
    ekf_scalar_t u[2][3];
    att_trig_t t;
    ekf_innov_t info;
    ekf_status_t st, out = EKF_OK;
    int i;
    meas_trig(v, &t);
    u[0][0] = EKF_C(0);
    u[0][1] = t.cphi;
    u[0][2] = ekf_neg(t.sphi);
    u[1][0] = ekf_neg(t.cth);
    u[1][1] = ekf_neg(ekf_mul(t.sphi, t.sth));
    u[1][2] = ekf_neg(ekf_mul(t.cphi, t.sth));
    for (i = 0; i < 2; ++i) {
        const ekf_scalar_t h3[3] = {(i == 0) ? t.cth : EKF_C(0), (i == 0) ? EKF_C(0) : EKF_C(1), EKF_C(0)};
        const int ang = (i == 0) ? ATT_PHI : ATT_THETA;
        ekf_scalar_t pht[3], nu;
        nu = ekf_div(ekf_mac(ekf_mac(ekf_mul(u[i][0], a[0]), u[i][1], a[1]), u[i][2], a[2]), norm);
        if (i == 1) {
            nu = ekf_sub(nu, ekf_sub(v->x[ATT_THETA], theta0)); /* relinearised about the prior */
        }
        /* the angle rows of P h^T before the update: its gain times S */
        pht[0] = ekf_mul(att_cov_get(&v->cov, ATT_PHI, ang), h3[i]);
        pht[1] = ekf_mul(att_cov_get(&v->cov, ATT_THETA, ang), h3[i]);
        pht[2] = ekf_mul(att_cov_get(&v->cov, ATT_PSI, ang), h3[i]);
        st = att_cov_update_angles(&v->cov, v->x, h3, nu, r_var, gate, s->var_floor, &info);
        if (st == EKF_OK) {
            (void)att_bias_update(&v->bias, learn, h3, pht, nu, info.variance,
                                  ekf_add(EKF_C(1), ekf_div(excess, info.variance)), &v->x[ATT_PHI]);
        }
        v->diag.accel_ratio[i] = info.test_ratio;
        *bypass_failed |= (st == EKF_OK) && fails_gate(&info, s->accel_gate);
        *consistent = *consistent && (st == EKF_OK) && !fails_gate(&info, EKF_C(3));
        if (st == EKF_GATED) {
            out = EKF_GATED;
            ekf_count(&v->diag.accel_gated);
        } else if (st != EKF_OK) {
            return st; /* EKF_ERR_NUMERIC: the call puts its saved copy back */
        } else {
            ekf_count(&v->diag.accel_fused);
        }
    }
    return out;
}

ekf_status_t att_stage_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt)
{
    const int rest = (v->flags & ATT_FLAG_AT_REST) != 0u && s->rest.accel_noise > EKF_C(0);
    ekf_scalar_t norm, a_norm, err, r_var, var0[2], a[3];
    ekf_status_t st;
    int bypass_failed = 0, consistent = 1;

    v->tilt_ok = 0u; /* until this update shows otherwise */
    norm = att_norm3(accel);
    err = ekf_abs(ekf_sub(norm, s->gravity));
    v->diag.accel_norm_error = err;
    v->flags &= ~(ATT_FLAG_ACCEL_DEWEIGHTED | ATT_FLAG_ACCEL_REJECTED | ATT_FLAG_ACCEL_GATED);
    a_norm = accel_vector(v, s, accel, dt, rest, a);
    /* far from 1 g (the direction is dominated by linear acceleration), or no force at all
     * (free fall, or shaking that averaged to none): no direction to fuse */
    if (err > s->accel_reject || !(norm > EKF_C(0)) || !(a_norm > EKF_C(0))) {
        v->flags |= ATT_FLAG_ACCEL_REJECTED;
        ekf_count(&v->diag.accel_skipped);
        return EKF_SKIPPED;
    }
    r_var = accel_variance(v, s, err, dt, rest);
    var0[0] = att_cov_var(&v->cov, ATT_PHI);
    var0[1] = att_cov_var(&v->cov, ATT_THETA);
    st = accel_fuse(v, s, a, a_norm, r_var, gate_for(v, s, ATT_SENSOR_ACCEL, s->accel_gate),
                    learn_excess(v, s, dt, rest), &bypass_failed, &consistent);
    if (ekf_status_is_error(st)) {
        return st;
    }
    if (att_normalise(v)) {
        ekf_count(&v->diag.remaps);
    }
    consider_accel(v, s, var0, dt);
    att_update_gimbal_flag(v, s);
    gate_result(v, s, ATT_SENSOR_ACCEL, st == EKF_GATED || bypass_failed);
    v->tilt_ok = (uint8_t)(consistent && (v->flags & ATT_FLAG_ACCEL_DEWEIGHTED) == 0u);
    if (st == EKF_GATED) {
        v->flags |= ATT_FLAG_ACCEL_GATED;
    }
    return st;
}

/* ---- magnetometer ---- */

/* The magnetic reference (norm in mag units, dip in rad) and tan^2(dip), which scales the
 * tilt error into the heading ("Magnetometer" in docs/derivation.md): computed here, once
 * per reference, not per sample (|dip| is capped at 84 deg, cos >= 0.1). */
void att_set_mag_reference(att_vars_t *v, ekf_scalar_t norm, ekf_scalar_t dip)
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
            att_set_mag_reference(v, v->mag_avg_norm, v->mag_avg_dip);
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
        att_set_mag_reference(v, v->mag_avg_norm, v->mag_avg_dip);
        v->mag_new_clock = EKF_C(0);
    }
}

ekf_status_t att_stage_mag(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t mag[3], ekf_scalar_t dt)
{
    ekf_scalar_t lev[3], norm, heading, nu, r_var;
    att_trig_t t;
    ekf_status_t st;
    ekf_innov_t info;

    v->flags &= ~(ATT_FLAG_MAG_DISTURBED | ATT_FLAG_HEADING_HELD | ATT_FLAG_MAG_GATED);
    if ((v->flags & ATT_FLAG_GIMBAL_LOCK) != 0u) {
        /* heading is ill-defined next to theta = +-90 deg: hold it */
        v->flags |= ATT_FLAG_HEADING_HELD;
        ekf_count(&v->diag.mag_skipped);
        return EKF_SKIPPED;
    }
    norm = att_norm3(mag);
    meas_trig(v, &t);
    {
        ekf_scalar_t m[3];
        to_interval_end(v, mag, dt, m);
        att_gen_mag_level(&t, m, lev);
    }
    if (!(ekf_sqrt(ekf_add(ekf_sq(lev[0]), ekf_sq(lev[1]))) > ekf_mul(EKF_C(1e-3), norm))) {
        /* no horizontal component (or no field at all): no heading information */
        v->flags |= ATT_FLAG_MAG_DISTURBED;
        ekf_count(&v->diag.mag_skipped);
        return EKF_SKIPPED;
    }
    heading = att_mag_heading(s, lev);
    if (!(v->mag_ref_norm > EKF_C(0))) {
        /* aligned without a magnetometer: the first field sample sets the reference and
         * the heading */
        att_set_mag_reference(v, norm, att_mag_dip(lev));
        reset_heading(v, s, heading, ekf_min(ekf_sq(s->init_heading_sigma), s->heading_var_max));
        v->flags &= ~ATT_FLAG_HEADING_LIMITED;
        ekf_count(&v->diag.mag_fused);
        return EKF_OK;
    }
    track_reference(v, s, norm, att_mag_dip(lev), dt);
    v->diag.mag_norm_error = ekf_sub(ekf_div(norm, v->mag_ref_norm), EKF_C(1));
    v->diag.mag_dip_error = ekf_sub(att_mag_dip(lev), v->mag_ref_dip);
    if (ekf_abs(v->diag.mag_norm_error) > s->mag_norm_tol || ekf_abs(v->diag.mag_dip_error) > s->mag_dip_tol) {
        v->flags |= ATT_FLAG_MAG_DISTURBED;
        ekf_count(&v->diag.mag_skipped);
        /* the reset below needs mag_reset_time of gating an undisturbed field: a body-fixed
         * offset can pass the tests for a moment in a turn */
        v->gated_time[ATT_SENSOR_MAG] = EKF_C(0);
        return EKF_SKIPPED;
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
        gate_result(v, s, ATT_SENSOR_MAG, 0);
        return EKF_OK;
    }
    /* The heading comes from the field levelled with the estimated tilt, and a tilt error
     * e moves it by about tan(dip) e. While linear acceleration disturbs the tilt (its
     * running variance accel_dev_var, m/s^2 squared, is a tilt variance of
     * accel_dev_var / g^2), the heading is trusted that much less (docs/derivation.md,
     * "Magnetometer"). */
    r_var = ekf_div(ekf_mac(ekf_sq(s->mag_heading_noise), v->mag_tan2_dip,
                            ekf_div(ekf_mul(v->accel_dev_var, s->accel_adapt_weight), ekf_sq(s->gravity))),
                    dt);
    if (s->mag_norm_band > EKF_C(0) && s->mag_dip_band > EKF_C(0)) {
        /* a field off its reference norm or dip is a disturbed one, and its heading errs with
         * it (an iron nearby, a magnet on the sensor): trusted less the further it is off */
        const ekf_scalar_t kn = ekf_div(v->diag.mag_norm_error, s->mag_norm_band);
        const ekf_scalar_t kd = ekf_div(v->diag.mag_dip_error, s->mag_dip_band);
        r_var = ekf_mul(r_var, ekf_add(EKF_C(1), ekf_add(ekf_sq(kn), ekf_sq(kd))));
    }
    /* no gate bypass for the magnetometer (a magnet that passes the norm and dip tests would
     * drag the heading): recovery is the reset above, after mag_reset_time */
    {
        static const ekf_scalar_t h3[3] = {EKF_C(0), EKF_C(0), EKF_C(1)};
        const ekf_scalar_t var0 = att_cov_var(&v->cov, ATT_PSI);
        const ekf_scalar_t pht[3] = {att_cov_get(&v->cov, ATT_PHI, ATT_PSI), att_cov_get(&v->cov, ATT_THETA, ATT_PSI),
                                     var0};
        st = att_cov_update_unit(&v->cov, v->x, ATT_PSI, nu, r_var, s->mag_gate, s->var_floor, &info);
        if (st == EKF_OK) {
            /* the field's errors depend on the orientation and disturbed fields pass the
             * tests: taken at face value they would teach the vertical offset the field's
             * errors (docs/derivation.md, "Gyroscope offset in motion"), hence mag_derate */
            (void)att_bias_update(&v->bias, s->bias.motion >= 2u, h3, pht, nu, info.variance, s->bias.mag_derate,
                                  &v->x[ATT_PHI]);
            att_consider_heading(&v->consider, reduction(var0, att_cov_var(&v->cov, ATT_PSI)));
        }
    }
    v->diag.mag_ratio = info.test_ratio;
    if (st == EKF_GATED) {
        ekf_count(&v->diag.mag_gated);
        gate_result(v, s, ATT_SENSOR_MAG, 1);
        v->flags |= ATT_FLAG_MAG_GATED;
        return EKF_GATED;
    }
    if (st != EKF_OK) {
        return st; /* EKF_ERR_NUMERIC: the call discards its working copy */
    }
    ekf_count(&v->diag.mag_fused);
    gate_result(v, s, ATT_SENSOR_MAG, 0);
    if (att_normalise(v)) {
        ekf_count(&v->diag.remaps);
    }
    return EKF_OK;
}
