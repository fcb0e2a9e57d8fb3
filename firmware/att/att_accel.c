/*
 * att_accel.c - the accelerometer stage: the vector it fuses, its variance, the two
 * tangent-plane updates, the offset learned from them, the considered error of the low-pass
 * (docs/derivation.md, "Measurement models", "Linear acceleration", "Innovation gate").
 */
#include "att_accel.h"

#include "att_gen.h"
#include "att_lowpass.h"
#include "att_sensor.h"
#include "att_state.h"
#include "ekf_util.h"

/* After an accelerometer update (roll and pitch variances var0 before it): the colored
 * error of the low-passed force, whose variance per axis the running linear-acceleration
 * variance estimates and whose correlation time is the low-pass delay (accel_lpf_order
 * stages of accel_lpf_tau), passes into the reported tilt covariance through the gains
 * just applied (att_consider.h). */
static void consider_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t var0[2], ekf_scalar_t dt)
{
    const ekf_scalar_t tau = ekf_mul(ekf_from_int((int32_t)s->accel_lpf_order), s->accel_lpf_tau);
    ekf_scalar_t kf[2];
    kf[0] = att_sensor_reduction(var0[0], att_cov_var(&v->cov, ATT_PHI));
    kf[1] = att_sensor_reduction(var0[1], att_cov_var(&v->cov, ATT_THETA));
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
    att_sensor_to_interval_end(v, accel, dt, a);
    if (s->accel_lpf_tau > EKF_C(0) && !v->rate_unmeasured) {
        att_lowpass_blend(v, s, a, dt);
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

/* Without a heading reference (att_vars_t.heading_ref): the accelerometer sees the tilt, never a turn about the vertical, so its
 * update must not turn the body about the vertical. In the state's angles a roll change at
 * pitch theta is itself such a turn, -sin(theta) dphi, and the Kalman gain on psi follows
 * correlations that nothing has measured; the gain on psi becomes sin(theta) times the one on
 * phi (a Schmidt update of the turn about the vertical), P the Joseph form for that gain,
 * which is the Kalman update's P plus delta^2 / S on psi's variance, with
 * delta = sin(theta) (P h^T)_phi - (P h^T)_psi (docs/derivation.md, "Accelerometer: no turn
 * about the vertical"). pht: the angle rows of P h^T before the update; sth: sin of the
 * pitch both components are linearised about (the prior's); nu, s_var: the component's
 * innovation and innovation variance. */
static void hold_vertical(att_vars_t *v, const ekf_scalar_t pht[3], ekf_scalar_t sth, ekf_scalar_t nu,
                          ekf_scalar_t s_var)
{
    const ekf_scalar_t delta = ekf_sub(ekf_mul(sth, pht[0]), pht[2]);
    if (v->heading_ref != 0u || !(s_var > EKF_C(0))) {
        return;
    }
    v->x[ATT_PSI] = ekf_add(v->x[ATT_PSI], ekf_div(ekf_mul(delta, nu), s_var));
    att_cov_add_diag(&v->cov, ATT_PSI, 1, ekf_mul(ekf_div(delta, s_var), delta));
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
    ekf_scalar_t u[2][3], up[3];
    att_trig_t t;
    ekf_innov_t info;
    ekf_status_t st, out = EKF_OK;
    int i;
    att_sensor_trig(v, &t);
    u[0][0] = EKF_C(0);
    u[0][1] = t.cphi;
    u[0][2] = ekf_neg(t.sphi);
    u[1][0] = ekf_neg(t.cth);
    u[1][1] = ekf_neg(ekf_mul(t.sphi, t.sth));
    u[1][2] = ekf_neg(ekf_mul(t.cphi, t.sth));
    /* the predicted gravity direction (up, body frame) */
    up[0] = ekf_neg(t.sth);
    up[1] = ekf_mul(t.sphi, t.cth);
    up[2] = ekf_mul(t.cphi, t.cth);
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
            hold_vertical(v, pht, t.sth, nu, info.variance);
            (void)att_bias_update(&v->bias, learn, h3, pht, nu, info.variance,
                                  ekf_add(EKF_C(1), ekf_div(excess, info.variance)), up, &v->x[ATT_PHI]);
        }
        v->diag.accel_ratio[i] = info.test_ratio;
        *bypass_failed |= (st == EKF_OK) && att_sensor_fails_gate(&info, s->accel_gate);
        *consistent = *consistent && (st == EKF_OK) && !att_sensor_fails_gate(&info, EKF_C(3));
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

int att_accel_clipped(const att_settings_t *s, const ekf_scalar_t accel[3])
{
    const ekf_scalar_t at = ekf_mul(s->accel_range, EKF_C(1.0 - ATT_ACCEL_CLIP_MARGIN));
    return !(ekf_abs(accel[0]) < at) || !(ekf_abs(accel[1]) < at) || !(ekf_abs(accel[2]) < at);
}

ekf_status_t att_stage_accel(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t accel[3], ekf_scalar_t dt)
{
    const int rest = (v->flags & ATT_FLAG_AT_REST) != 0u && s->rest.accel_noise > EKF_C(0);
    const int clipped = att_accel_clipped(s, accel);
    ekf_scalar_t norm, a_norm, err, r_var, var0[2], a[3], clamped[3];
    ekf_status_t st;
    int bypass_failed = 0, consistent = 1;

    v->tilt_ok = 0u; /* until this update shows otherwise */
    if (clipped) {
        /* what the sensor would have read at its full scale: beyond it only a wrong range
         * setting gives, and the value is still the best lower bound of the force (dropping
         * clipped samples biases the low-passed force by their whole impact) */
        int i;
        for (i = 0; i < 3; ++i) {
            clamped[i] = ekf_max(ekf_neg(s->accel_range), ekf_min(accel[i], s->accel_range));
        }
        accel = clamped;
        att_bias_hold(&v->bias, s->bias.hold_time); /* the innovation is the clip's, not the offset's */
    }
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
    if (clipped) {
        r_var = ekf_mul(EKF_C(2), r_var); /* (the flag's meaning: the variance at least doubled) */
        v->flags |= ATT_FLAG_ACCEL_DEWEIGHTED;
    }
    var0[0] = att_cov_var(&v->cov, ATT_PHI);
    var0[1] = att_cov_var(&v->cov, ATT_THETA);
    st = accel_fuse(v, s, a, a_norm, r_var, att_sensor_gate(v, s, ATT_SENSOR_ACCEL, s->accel_gate),
                    learn_excess(v, s, dt, rest), &bypass_failed, &consistent);
    if (ekf_status_is_error(st)) {
        return st;
    }
    if (att_normalise(v)) {
        ekf_count(&v->diag.remaps);
    }
    consider_accel(v, s, var0, dt);
    att_update_gimbal_flag(v, s);
    att_sensor_gate_result(v, s, ATT_SENSOR_ACCEL, st == EKF_GATED || bypass_failed);
    v->tilt_ok = (uint8_t)(consistent && (v->flags & ATT_FLAG_ACCEL_DEWEIGHTED) == 0u);
    if (st == EKF_GATED) {
        v->flags |= ATT_FLAG_ACCEL_GATED;
    }
    return st;
}
