/*
 * att.c - the attitude estimator (see att.h; equations in docs/derivation.md).
 */
#include "att.h"

#include <stddef.h>

#include "att_gen.h"
#include "att_model.h"
#include "ekf_util.h"

const att_settings_t att_default_settings = {
    /* process model */
    .rate_walk = EKF_C(2.0),
    .angle_walk = EKF_C(0.001),
    .euler_rate_rel = EKF_C(0.001),
    /* gyroscope */
    .gyro_noise = EKF_C(0.005),
    .gyro_gate = EKF_C(0.0),
    .gyro_range = EKF_C(40.0),
    .rest = {
        .rest_gyro = EKF_C(0.035), /* 2 deg/s */
        .rest_accel = EKF_C(0.5),
        .rest_time = EKF_C(1.5),
        .rest_tau = EKF_C(0.5),
        .bias_tau = EKF_C(10.0),
        .bias_max = EKF_C(0.035),
    },
    /* accelerometer */
    .gravity = EKF_C(9.81),
    .accel_noise = EKF_C(0.5),
    .accel_band = EKF_C(0.0),
    .accel_reject = EKF_C(50.0),
    .accel_adapt_tau = EKF_C(0.5),
    .accel_lpf_tau = EKF_C(1.0),
    .accel_gate = EKF_C(10.0),
    .accel_range = EKF_C(160.0),
    /* magnetometer */
    .mag_heading_noise = EKF_C(0.5),
    .mag_gate = EKF_C(3.0),
    .mag_norm_tol = EKF_C(0.15),
    .mag_dip_tol = EKF_C(0.17),
    .mag_reset_time = EKF_C(3.0),
    .mag_ref_norm = EKF_C(0.0),
    .mag_ref_dip = EKF_C(0.0),
    .mag_declination = EKF_C(0.0),
    .mag_range = EKF_C(5000.0),
    /* robustness */
    .gate_timeout = EKF_C(1.0),
#if defined(EKF_SCALAR_FIXED)
    /* 85 deg: within it the Q29.34 format never saturates (Euler-rate Jacobian ~ sec^2;
     * docs/fixed_point.md, "Operating envelope") */
    .gimbal_limit = EKF_C(1.4835298641951802),
#else
    .gimbal_limit = EKF_C(1.55), /* 88.8 deg */
#endif
    .dt_max = EKF_C(0.5),
    .heading_var_max = EKF_C(9.869604401089358), /* pi^2 */
    .var_floor = EKF_C(1e-10),
    /* initialisation */
    .init_tilt_sigma = EKF_C(0.1),
    .init_heading_sigma = EKF_C(0.2),
    .init_rate_sigma = EKF_C(0.1),
    .align_samples = 10u,
};

enum { SENSOR_GYRO = 0, SENSOR_ACCEL = 1, SENSOR_MAG = 2 };

/* Smallest accepted LDL^T pivot relative to its variance. The factorisation computed in
 * the filter's scalar is the exact one of P + dP with |dP_ij| up to about n^2 eps
 * sqrt(P_ii P_jj): the margin must be well above that, or a float P that is indefinite by
 * 5e-5 of its diagonal passes (seen in the 10^6-step stress test). 10 n^2 eps is 1e-4 in
 * float, far below the Euler-rate pivots (~euler_rate_rel = 1e-3) that the model keeps
 * by design (docs/derivation.md, "Covariance bounds"). */
#define ATT_PD_MARGIN ekf_mul(EKF_C(10 * ATT_N * ATT_N), EKF_SCALAR_EPS)

/* Counts a refused call in the diagnostics and passes the status through. */
static ekf_status_t note(att_ekf_t *f, ekf_status_t st)
{
    if (st == EKF_ERR_NUMERIC) {
        ekf_count(&f->diag.numeric);
    } else if (st != EKF_OK && st != EKF_GATED && st != EKF_SKIPPED) {
        ekf_count(&f->diag.rejected);
    }
    return st;
}

ekf_status_t att_settings_check(const att_settings_t *s)
{
    const ekf_scalar_t big = EKF_C(1e6);
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_in_range(s->rate_walk, EKF_C(1e-6), big) || !ekf_in_range(s->angle_walk, EKF_C(0), big) ||
        !ekf_in_range(s->euler_rate_rel, EKF_C(1e-6), EKF_C(1)) || !ekf_in_range(s->gyro_noise, EKF_C(1e-9), big) ||
        !ekf_in_range(s->gyro_gate, EKF_C(0), big) || !ekf_in_range(s->gyro_range, EKF_C(1e-3), big) ||
        !ekf_in_range(s->gravity, EKF_C(0.1), big) || !ekf_in_range(s->accel_noise, EKF_C(1e-9), big) ||
        !ekf_in_range(s->accel_band, EKF_C(0), big) || !ekf_in_range(s->accel_reject, EKF_C(1e-6), big) ||
        !ekf_in_range(s->accel_adapt_tau, EKF_C(0), big) || !ekf_in_range(s->accel_lpf_tau, EKF_C(0), big) ||
        !ekf_in_range(s->accel_gate, EKF_C(0), big) || !ekf_in_range(s->accel_range, s->gravity, big) ||
        !ekf_in_range(s->mag_heading_noise, EKF_C(1e-9), EKF_PI) || !ekf_in_range(s->mag_gate, EKF_C(0), big) ||
        !ekf_in_range(s->mag_norm_tol, EKF_C(1e-6), big) || !ekf_in_range(s->mag_dip_tol, EKF_C(1e-6), EKF_PI) ||
        !ekf_in_range(s->mag_reset_time, EKF_C(0), big) ||
        !ekf_in_range(s->mag_ref_norm, EKF_C(0), big) ||
        !ekf_in_range(s->mag_ref_dip, ekf_neg(EKF_HALF_PI), EKF_HALF_PI) ||
        !ekf_in_range(s->mag_declination, ekf_neg(EKF_PI), EKF_PI) || !ekf_in_range(s->mag_range, EKF_C(1e-6), big) ||
        !ekf_in_range(s->gate_timeout, EKF_C(0), big) ||
        !ekf_in_range(s->gimbal_limit, EKF_C(0.1), EKF_C(1.5697963267948966)) || /* pi/2 - 1 mrad */
        !ekf_in_range(s->dt_max, EKF_C(1e-6), EKF_C(60)) ||
        !ekf_in_range(s->heading_var_max, ekf_max(EKF_C(1e-6), s->var_floor), big) || /* a cap below the floor */
        !ekf_in_range(s->var_floor, EKF_C(1e-30), EKF_C(1e-2)) ||
        !ekf_in_range(s->init_tilt_sigma, EKF_C(1e-6), EKF_PI) ||
        !ekf_in_range(s->init_heading_sigma, EKF_C(1e-6), EKF_TWO_PI) ||
        !ekf_in_range(s->init_rate_sigma, EKF_C(1e-6), big) || s->align_samples == 0u ||
        !ekf_in_range(s->rest.rest_gyro, EKF_C(1e-6), big) || !ekf_in_range(s->rest.rest_accel, EKF_C(1e-6), big) ||
        !ekf_in_range(s->rest.rest_time, EKF_C(0), big) || !ekf_in_range(s->rest.rest_tau, EKF_C(0), big) ||
        !ekf_in_range(s->rest.bias_tau, EKF_C(0), big) || !ekf_in_range(s->rest.bias_max, EKF_C(0), s->gyro_range)) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

ekf_status_t att_init(att_ekf_t *f, const att_settings_t *settings)
{
    ekf_status_t st;
    att_ekf_t zero = {0};
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    st = att_settings_check(settings);
    if (st != EKF_OK) {
        return st;
    }
    *f = zero;
    f->settings = *settings;
    att_rest_reset(&f->rest);
    return EKF_OK;
}

/* Finite, every component within +-range. */
static ekf_status_t check_vec(const ekf_scalar_t v[3], ekf_scalar_t range)
{
    int i;
    if (v == NULL) {
        return EKF_ERR_NULL;
    }
    for (i = 0; i < 3; ++i) {
        if (!ekf_isfinite(v[i])) {
            return EKF_ERR_NOT_FINITE;
        }
    }
    for (i = 0; i < 3; ++i) {
        if (ekf_abs(v[i]) > range) {
            return EKF_ERR_RANGE;
        }
    }
    return EKF_OK;
}

static ekf_status_t check_dt(const att_ekf_t *f, ekf_scalar_t dt)
{
    if (!ekf_isfinite(dt)) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(dt > EKF_C(0))) {
        return EKF_ERR_DT_NONPOSITIVE;
    }
    if (dt > f->settings.dt_max) {
        return EKF_ERR_DT_TOO_LARGE;
    }
    return EKF_OK;
}

static ekf_scalar_t norm3(const ekf_scalar_t v[3])
{
    return ekf_sqrt(ekf_add(ekf_add(ekf_sq(v[0]), ekf_sq(v[1])), ekf_sq(v[2])));
}

/* Trigonometry for the measurement functions: the true (unclamped) pitch. They use only
 * sin and cos, never sec(theta), which is left at zero. */
static void meas_trig(const att_ekf_t *f, att_trig_t *t)
{
    t->sphi = ekf_sin(f->x[ATT_PHI]);
    t->cphi = ekf_cos(f->x[ATT_PHI]);
    t->sth = ekf_sin(f->x[ATT_THETA]);
    t->cth = ekf_cos(f->x[ATT_THETA]);
    t->secth = EKF_C(0);
}

/* P += G diag(var) G^T for the body-rate noise input (var per body axis), G = [I; 0; g]
 * with g the 3x3 Euler-rate block (row-major). Symmetric by construction. */
static void add_rate_noise(ekf_scalar_t P[ATT_N * ATT_N], const ekf_scalar_t g[9], const ekf_scalar_t var[3])
{
    int i, j, k;
    for (i = 0; i < 3; ++i) {
        P[(ATT_P + i) * ATT_N + ATT_P + i] = ekf_add(P[(ATT_P + i) * ATT_N + ATT_P + i], var[i]);
        for (j = 0; j < 3; ++j) {
            /* (Euler rate i, body rate j) = var_j * g[i][j], and its mirror */
            const ekf_scalar_t v = ekf_mul(var[j], g[i * 3 + j]);
            P[(ATT_PHID + i) * ATT_N + ATT_P + j] = ekf_add(P[(ATT_PHID + i) * ATT_N + ATT_P + j], v);
            P[(ATT_P + j) * ATT_N + ATT_PHID + i] = ekf_add(P[(ATT_P + j) * ATT_N + ATT_PHID + i], v);
        }
        for (j = i; j < 3; ++j) {
            ekf_scalar_t ggt = EKF_C(0);
            for (k = 0; k < 3; ++k) {
                ggt = ekf_mac(ggt, ekf_mul(g[i * 3 + k], var[k]), g[j * 3 + k]);
            }
            P[(ATT_PHID + i) * ATT_N + ATT_PHID + j] = ekf_add(P[(ATT_PHID + i) * ATT_N + ATT_PHID + j], ggt);
            if (j != i) {
                P[(ATT_PHID + j) * ATT_N + ATT_PHID + i] = P[(ATT_PHID + i) * ATT_N + ATT_PHID + j];
            }
        }
    }
}

static void add_diag(ekf_scalar_t P[ATT_N * ATT_N], int first, int len, ekf_scalar_t var)
{
    int i;
    for (i = first; i < first + len; ++i) {
        P[i * ATT_N + i] = ekf_add(P[i * ATT_N + i], var);
    }
}

/* Heading of a levelled field vector (att_gen_mag_level), rad in [-pi, pi). */
static ekf_scalar_t mag_heading(const att_ekf_t *f, const ekf_scalar_t lev[3])
{
    return ekf_wrap_pi(ekf_sub(ekf_atan2(lev[0], lev[1]), f->settings.mag_declination));
}

/* Dip of a levelled field vector, rad, positive when the field points down. */
static ekf_scalar_t mag_dip(const ekf_scalar_t lev[3])
{
    return ekf_atan2(ekf_neg(lev[2]), ekf_sqrt(ekf_add(ekf_sq(lev[0]), ekf_sq(lev[1]))));
}

static void update_gimbal_flag(att_ekf_t *f)
{
    if (ekf_abs(f->x[ATT_THETA]) > f->settings.gimbal_limit) {
        f->flags |= ATT_FLAG_GIMBAL_LOCK;
    } else {
        f->flags &= ~ATT_FLAG_GIMBAL_LOCK;
    }
}

/* The magnetic reference (norm in mag units, dip in rad) and tan^2(dip), which scales the
 * tilt error into the heading ("Magnetometer" in docs/derivation.md): computed here, once
 * per reference, not per sample (|dip| is capped at 84 deg, cos >= 0.1). */
static void set_mag_reference(att_ekf_t *f, ekf_scalar_t norm, ekf_scalar_t dip)
{
    f->mag_ref_norm = norm;
    f->mag_ref_dip = dip;
    f->mag_tan2_dip = ekf_sq(ekf_div(ekf_sin(dip), ekf_max(ekf_cos(dip), EKF_C(0.1))));
}

ekf_status_t att_align(att_ekf_t *f, const ekf_scalar_t accel[3], const ekf_scalar_t mag[3])
{
    const att_settings_t *s;
    ekf_scalar_t x[ATT_N] = {0};
    att_trig_t t;
    ekf_scalar_t g[9];
    ekf_scalar_t lev[3];
    ekf_scalar_t heading_var;
    ekf_status_t st;
    int i, use_mag = 0;

    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    s = &f->settings;
    st = check_vec(accel, s->accel_range);
    if (st != EKF_OK) {
        return note(f, st);
    }
    if (!(norm3(accel) > ekf_mul(EKF_C(0.1), s->gravity))) {
        return note(f, EKF_ERR_RANGE); /* no usable gravity direction (free fall) */
    }
    if (mag != NULL) {
        st = check_vec(mag, s->mag_range);
        if (st != EKF_OK) {
            return note(f, st);
        }
    }

    /* roll and pitch from the gravity direction: a = g (-sin th, sin ph cos th, cos ph cos th) */
    x[ATT_PHI] = ekf_atan2(accel[1], accel[2]);
    x[ATT_THETA] = ekf_atan2(ekf_neg(accel[0]), ekf_sqrt(ekf_add(ekf_sq(accel[1]), ekf_sq(accel[2]))));
    (void)att_trig(x[ATT_PHI], x[ATT_THETA], s->gimbal_limit, &t);
    heading_var = s->heading_var_max;
    if (mag != NULL && norm3(mag) > EKF_C(0)) {
        att_gen_mag_level(&t, mag, lev);
        if (ekf_add(ekf_sq(lev[0]), ekf_sq(lev[1])) > EKF_C(0)) {
            use_mag = 1;
            x[ATT_PSI] = mag_heading(f, lev);
            heading_var = ekf_min(ekf_sq(s->init_heading_sigma), s->heading_var_max);
        }
    }

    for (i = 0; i < ATT_N; ++i) {
        f->x[i] = x[i];
    }
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        f->P[i] = EKF_C(0);
    }
    f->P[ATT_PHI * ATT_N + ATT_PHI] = ekf_sq(s->init_tilt_sigma);
    f->P[ATT_THETA * ATT_N + ATT_THETA] = ekf_sq(s->init_tilt_sigma);
    f->P[ATT_PSI * ATT_N + ATT_PSI] = heading_var;
    /* rates: zero with the rate uncertainty mapped into the Euler rates, plus their own
     * relative error, so that P starts positive definite */
    att_gen_noise_jacobian(&t, g);
    {
        const ekf_scalar_t v = ekf_sq(s->init_rate_sigma), var[3] = {v, v, v};
        add_rate_noise(f->P, g, var);
    }
    for (i = ATT_PHID; i <= ATT_PSID; ++i) {
        f->P[i * ATT_N + i] = ekf_mac(f->P[i * ATT_N + i], f->P[i * ATT_N + i], s->euler_rate_rel);
    }
    /* the initial sigmas may be set below the variance floor (found by fuzzing): the floor
     * holds from the first step, like after every update */
    for (i = 0; i < ATT_N; ++i) {
        f->P[i * ATT_N + i] = ekf_max(f->P[i * ATT_N + i], s->var_floor);
    }
    /* atan2 can return +pi itself (a = (0, +0, -g), upside down): into [-pi, pi) like after
     * every other stage (found by fuzzing) */
    (void)att_model_normalise(f->x, f->P);

    if (s->mag_ref_norm > EKF_C(0)) {
        set_mag_reference(f, s->mag_ref_norm, s->mag_ref_dip);
    } else if (use_mag) {
        set_mag_reference(f, norm3(mag), mag_dip(lev));
    } else {
        set_mag_reference(f, EKF_C(0), EKF_C(0));
    }
    for (i = 0; i < 3; ++i) {
        f->gated_time[i] = EKF_C(0);
    }
    /* the accelerometer low-pass starts from the alignment's (averaged) specific force */
    for (i = 0; i < 3; ++i) {
        f->accel_lp[i] = accel[i];
    }
    f->accel_lp_valid = 1u;
    f->tilt_ok = 1u; /* the tilt is the accelerometer's */
    f->flags = ATT_FLAG_ALIGNED;
    if (!use_mag) {
        f->flags |= ATT_FLAG_HEADING_LIMITED;
    }
    update_gimbal_flag(f);
    return EKF_OK;
}

/* Keeps every variance below a physical bound (docs/derivation.md, "Covariance bounds"):
 * body rates within the gyro range, roll and pitch within half a turn, Euler rates within
 * what W can produce from in-range body rates at the gimbal limit. Only reached under
 * inputs far outside normal use (very long steps at extreme rates), where it keeps P
 * finite; a congruence, so P stays positive definite. */
/* ekf_cov_limit_variance, called only when it has something to do (9 calls per predict). */
static void cap_variance(ekf_scalar_t P[ATT_N * ATT_N], int i, ekf_scalar_t max_var)
{
    if (P[i * ATT_N + i] > max_var) {
        (void)ekf_cov_limit_variance(P, ATT_N, (uint8_t)i, max_var);
    }
}

static void limit_variances(att_ekf_t *f)
{
    const att_settings_t *s = &f->settings;
    const ekf_scalar_t rate_max = ekf_sq(s->gyro_range);
    /* The Euler-rate bound is at least (3 gyro_range)^2 (sec >= 1): its cosine is evaluated
     * only when a variance exceeds that, never in normal use. Capping a body rate does not
     * change the Euler-rate variances, so the test before the loop holds in it. */
    ekf_scalar_t euler_rate_max = ekf_sq(ekf_mul(s->gyro_range, EKF_C(3)));
    int i;
    for (i = ATT_PHID; i <= ATT_PSID; ++i) {
        if (f->P[i * ATT_N + i] > euler_rate_max) {
            const ekf_scalar_t sec_lim = ekf_div(EKF_C(1), ekf_cos(s->gimbal_limit));
            euler_rate_max = ekf_sq(ekf_mul(s->gyro_range, ekf_add(EKF_C(1), ekf_mul(EKF_C(2), sec_lim))));
            break;
        }
    }
    for (i = 0; i < 3; ++i) {
        cap_variance(f->P, ATT_P + i, rate_max);
        cap_variance(f->P, ATT_PHID + i, euler_rate_max);
    }
    cap_variance(f->P, ATT_PHI, ekf_sq(EKF_PI));
    cap_variance(f->P, ATT_THETA, ekf_sq(EKF_HALF_PI));
}

static void cross(const ekf_scalar_t a[3], const ekf_scalar_t b[3], ekf_scalar_t out[3])
{
    out[0] = ekf_sub(ekf_mul(a[1], b[2]), ekf_mul(a[2], b[1]));
    out[1] = ekf_sub(ekf_mul(a[2], b[0]), ekf_mul(a[0], b[2]));
    out[2] = ekf_sub(ekf_mul(a[0], b[1]), ekf_mul(a[1], b[0]));
}

/* The accelerometer low-pass (accel_lpf_tau) lives in a frame that turns with the body:
 * every prediction carries the filtered specific force into the new body frame with the
 * body rates (dv/dt = -w x v for a vector fixed in the earth frame), every accelerometer
 * sample is blended in. Gravity is earth-fixed, so it passes without lag; linear
 * acceleration that averages to zero in the earth frame (shaking, vibration) is filtered
 * out (docs/derivation.md, "Linear acceleration"). */
static void accel_lp_turn(att_ekf_t *f, ekf_scalar_t dt)
{
    ekf_scalar_t th[3], c1[3], c2[3];
    int i;
    if (!f->accel_lp_valid) {
        return;
    }
    for (i = 0; i < 3; ++i) {
        th[i] = ekf_mul(f->x[ATT_P + i], dt);
    }
    if (ekf_add(ekf_add(ekf_sq(th[0]), ekf_sq(th[1])), ekf_sq(th[2])) > EKF_C(0.04)) {
        /* more than 0.2 rad in one step (a gap, or beyond any IMU's rate): the series
         * below would be wrong; start again from the next sample */
        f->accel_lp_valid = 0u;
        return;
    }
    /* second order in th = w dt: v - th x v + (th x (th x v)) / 2; first order loses
     * gravity at fast rotation (|th| ~ 0.05 rad per sample) */
    cross(th, f->accel_lp, c1);
    cross(th, c1, c2);
    for (i = 0; i < 3; ++i) {
        f->accel_lp[i] = ekf_mac(ekf_sub(f->accel_lp[i], c1[i]), EKF_C(0.5), c2[i]);
    }
}

static void accel_lp_blend(att_ekf_t *f, const ekf_scalar_t accel[3])
{
    const ekf_scalar_t k = ekf_div(f->last_dt, ekf_add(f->settings.accel_lpf_tau, f->last_dt));
    int i;
    for (i = 0; i < 3; ++i) {
        f->accel_lp[i] = f->accel_lp_valid ? ekf_mac(f->accel_lp[i], k, ekf_sub(accel[i], f->accel_lp[i])) : accel[i];
    }
    f->accel_lp_valid = 1u;
}

static ekf_status_t predict_stage(att_ekf_t *f, ekf_scalar_t dt)
{
    const att_settings_t *s;
    ekf_scalar_t xn[ATT_N];
    ekf_scalar_t d[ATT_GEN_F_NNZ];
    ekf_scalar_t g[9];
    att_trig_t tm, tn;
    ekf_status_t st;
    int i;

    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    if ((f->flags & ATT_FLAG_ALIGNED) == 0u) {
        return note(f, EKF_ERR_NOT_INITIALISED);
    }
    s = &f->settings;
    st = check_dt(f, dt);
    if (st != EKF_OK) {
        return note(f, st);
    }

    att_model_transition(f->x, NULL, dt, s->gimbal_limit, xn, &tm, &tn);
    if (!ekf_all_finite(xn, ATT_N)) {
        return note(f, EKF_ERR_NUMERIC);
    }
    att_gen_transition_jacobian(&tm, &tn, f->x, dt, d);
    /* P <- F P F^T, generated for F's fixed pattern (bit-identical to ekf_cov_propagate) */
    if (!ekf_all_finite(d, ATT_GEN_F_NNZ)) {
        return note(f, EKF_ERR_NUMERIC);
    }
    att_gen_cov_propagate(f->P, d);

    /* Q = G diag(rate_walk^2 dt) G^T + angle random walk + the Euler rates' own error */
    att_gen_noise_jacobian(&tn, g);
    {
        const ekf_scalar_t v = ekf_mul(ekf_sq(s->rate_walk), dt), var[3] = {v, v, v};
        add_rate_noise(f->P, g, var);
    }
    add_diag(f->P, ATT_PHI, 3, ekf_mul(ekf_sq(s->angle_walk), dt));
    for (i = ATT_PHID; i <= ATT_PSID; ++i) {
        f->P[i * ATT_N + i] = ekf_mac(f->P[i * ATT_N + i], f->P[i * ATT_N + i], s->euler_rate_rel);
    }

    for (i = 0; i < ATT_N; ++i) {
        f->x[i] = xn[i];
    }
    f->last_dt = dt;
    if (s->accel_lpf_tau > EKF_C(0)) {
        accel_lp_turn(f, dt);
    }
    f->flags &= ~ATT_FLAG_REMAPPED;
    if (att_model_normalise(f->x, f->P)) {
        f->flags |= ATT_FLAG_REMAPPED;
        ekf_count(&f->diag.remaps);
    }
    update_gimbal_flag(f);
    limit_variances(f);
    if (ekf_cov_limit_variance(f->P, ATT_N, ATT_PSI, s->heading_var_max) ||
        !(f->P[ATT_PSI * ATT_N + ATT_PSI] < s->heading_var_max)) {
        f->flags |= ATT_FLAG_HEADING_LIMITED;
    } else {
        f->flags &= ~ATT_FLAG_HEADING_LIMITED;
    }
    /* time bookkeeping for the gate timeouts */
    for (i = 0; i < 3; ++i) {
        if (f->gated_time[i] > EKF_C(0)) {
            f->gated_time[i] = ekf_add(f->gated_time[i], dt);
        }
    }
    return EKF_OK;
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
static ekf_scalar_t gate_for(att_ekf_t *f, int sensor, ekf_scalar_t gate)
{
    const ekf_scalar_t timeout = f->settings.gate_timeout;
    if (gate > EKF_C(0) && timeout > EKF_C(0) && f->gated_time[sensor] > timeout) {
        f->flags |= ATT_FLAG_GATE_BYPASS;
        return EKF_C(0);
    }
    return gate;
}

/* Records whether a sensor's update gated (starts the gate clock) or passed (stops it). */
static void gate_result(att_ekf_t *f, int sensor, int gated)
{
    if (gated) {
        if (!(f->gated_time[sensor] > EKF_C(0))) {
            f->gated_time[sensor] = EKF_SCALAR_EPS; /* running; att_predict adds dt */
        }
    } else {
        f->gated_time[sensor] = EKF_C(0);
        if (!(f->gated_time[SENSOR_GYRO] > f->settings.gate_timeout) &&
            !(f->gated_time[SENSOR_ACCEL] > f->settings.gate_timeout)) {
            f->flags &= ~ATT_FLAG_GATE_BYPASS;
        }
    }
}

/* A clamped gyro reading (ATT_GYRO_SATURATED): the rate is at least its largest component
 * in magnitude, by an unknown amount. Not fused; each body-rate variance is raised to at
 * least that square (P += G diag(extra) G^T, positive semi-definite, so P stays positive
 * definite), docs/derivation.md "Gyroscope saturation". Without this the rates would only
 * random-walk at rate_walk while a tumble beyond full scale turns the vehicle, and the
 * attitude would come out of the tumble wrong with a small covariance: confidently wrong,
 * and gated by the sensors that could correct it. */
static ekf_status_t stage_gyro_saturated(att_ekf_t *f, const ekf_scalar_t gyro[3])
{
    ekf_scalar_t g[9], extra[3], var;
    att_trig_t t;
    ekf_status_t st;
    int i;

    st = check_vec(gyro, f->settings.gyro_range);
    if (st != EKF_OK) {
        return note(f, st);
    }
    var = ekf_sq(ekf_max(ekf_max(ekf_abs(gyro[0]), ekf_abs(gyro[1])), ekf_abs(gyro[2])));
    for (i = 0; i < 3; ++i) {
        extra[i] = ekf_max(ekf_sub(var, f->P[(ATT_P + i) * ATT_N + ATT_P + i]), EKF_C(0));
    }
    (void)att_trig(f->x[ATT_PHI], f->x[ATT_THETA], f->settings.gimbal_limit, &t);
    att_gen_noise_jacobian(&t, g);
    add_rate_noise(f->P, g, extra);
    ekf_count(&f->diag.gyro_saturated);
    return EKF_SKIPPED;
}

static ekf_status_t stage_gyro(att_ekf_t *f, const ekf_scalar_t gyro[3])
{
    static const ekf_scalar_t one = EKF_C(1);
    ekf_scalar_t gate, r_var;
    ekf_status_t st;
    ekf_innov_t info;
    int i, gated = 0, bypass_failed = 0;

    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    if ((f->flags & ATT_FLAG_ALIGNED) == 0u) {
        return note(f, EKF_ERR_NOT_INITIALISED);
    }
    st = check_vec(gyro, f->settings.gyro_range);
    if (st != EKF_OK) {
        return note(f, st);
    }
    gate = gate_for(f, SENSOR_GYRO, f->settings.gyro_gate);
    r_var = ekf_sq(f->settings.gyro_noise);
    for (i = 0; i < 3; ++i) {
        const uint8_t idx = (uint8_t)(ATT_P + i);
        const ekf_hrow_t h = {&idx, &one, 1u};
        /* the rates net of the learned offset (att_rest.h) */
        const ekf_scalar_t nu = ekf_sub(ekf_sub(gyro[i], f->rest.bias[i]), f->x[ATT_P + i]);
        st = ekf_update_scalar(f->x, f->P, ATT_N, &h, nu, r_var, gate,
                               f->settings.var_floor, &info);
        f->diag.gyro_ratio[i] = info.test_ratio;
        if (st == EKF_GATED) {
            gated = 1;
            ekf_count(&f->diag.gyro_gated);
        } else if (st != EKF_OK) {
            return note(f, st);
        } else {
            ekf_count(&f->diag.gyro_fused);
            bypass_failed |= fails_gate(&info, f->settings.gyro_gate);
        }
    }
    /* the rates correlate with the angles: the update may have moved them too */
    if (att_model_normalise(f->x, f->P)) {
        ekf_count(&f->diag.remaps);
    }
    update_gimbal_flag(f);
    gate_result(f, SENSOR_GYRO, gated || bypass_failed);
    if (gated) {
        f->flags |= ATT_FLAG_GYRO_GATED;
        return EKF_GATED;
    }
    f->flags &= ~ATT_FLAG_GYRO_GATED;
    return EKF_OK;
}

static ekf_status_t stage_accel(att_ekf_t *f, const ekf_scalar_t accel[3])
{
    const att_settings_t *s;
    ekf_scalar_t norm, a_norm, err, r_var, gate, phi0, theta0;
    ekf_scalar_t a[3], h[3], hj[6];
    att_trig_t t;
    ekf_status_t st;
    ekf_innov_t info;
    static const uint8_t idx[2] = {ATT_PHI, ATT_THETA};
    int i, gated = 0, bypass_failed = 0, consistent = 1;

    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    if ((f->flags & ATT_FLAG_ALIGNED) == 0u) {
        return note(f, EKF_ERR_NOT_INITIALISED);
    }
    s = &f->settings;
    st = check_vec(accel, s->accel_range);
    if (st != EKF_OK) {
        return note(f, st);
    }
    f->tilt_ok = 0u; /* until this update shows otherwise */
    norm = norm3(accel);
    err = ekf_abs(ekf_sub(norm, s->gravity));
    f->diag.accel_norm_error = err;
    f->flags &= ~(ATT_FLAG_ACCEL_DEWEIGHTED | ATT_FLAG_ACCEL_REJECTED | ATT_FLAG_ACCEL_GATED);
    /* a: what is fused, the low-passed force when the low-pass is on (every sample enters
     * it, fused or not), else the sample */
    if (s->accel_lpf_tau > EKF_C(0)) {
        accel_lp_blend(f, accel);
        for (i = 0; i < 3; ++i) {
            a[i] = f->accel_lp[i];
        }
        a_norm = norm3(a);
    } else {
        for (i = 0; i < 3; ++i) {
            a[i] = accel[i];
        }
        a_norm = norm;
    }
    if (s->accel_adapt_tau > EKF_C(0)) {
        /* running mean over accel_adapt_tau of the squared norm error of a: how much linear
         * acceleration is left in it lately, whatever this one sample's norm happens to be */
        const ekf_scalar_t k = ekf_div(f->last_dt, ekf_add(s->accel_adapt_tau, f->last_dt));
        const ekf_scalar_t e = ekf_sub(a_norm, s->gravity);
        f->accel_dev_var = ekf_mac(f->accel_dev_var, k, ekf_sub(ekf_sq(e), f->accel_dev_var));
    }
    if (err > s->accel_reject || !(norm > EKF_C(0))) {
        /* far from 1 g: the direction is dominated by linear acceleration */
        f->flags |= ATT_FLAG_ACCEL_REJECTED;
        ekf_count(&f->diag.accel_skipped);
        return EKF_SKIPPED;
    }
    /* unit-vector measurement; variance (accel_noise^2 + recent linear-acceleration
     * variance) / g^2, optionally inflated by 1 + (err / accel_band)^2 for this sample
     * (docs/derivation.md, "Linear acceleration") */
    r_var = ekf_div(ekf_add(ekf_sq(s->accel_noise), f->accel_dev_var), ekf_sq(s->gravity));
    if (f->accel_dev_var > ekf_sq(s->accel_noise)) {
        f->flags |= ATT_FLAG_ACCEL_DEWEIGHTED; /* the noise variance at least doubled */
    }
    if (s->accel_band > EKF_C(0)) {
        const ekf_scalar_t k = ekf_div(err, s->accel_band);
        r_var = ekf_mul(r_var, ekf_add(EKF_C(1), ekf_sq(k)));
        if (k > EKF_C(1)) {
            f->flags |= ATT_FLAG_ACCEL_DEWEIGHTED;
        }
    }
    gate = gate_for(f, SENSOR_ACCEL, s->accel_gate);
    if (!(a_norm > EKF_C(0))) {
        /* the shaking averaged to no force at all: no direction to fuse (the raw sample's
         * zero norm was rejected above) */
        f->flags |= ATT_FLAG_ACCEL_REJECTED;
        ekf_count(&f->diag.accel_skipped);
        return EKF_SKIPPED;
    }
    norm = a_norm;

    /* h and H at the prior; the three components are fused sequentially with innovations
     * relinearised about the prior, which equals the batch update of the 3-vector
     * (docs/derivation.md, "Sequential vector updates") */
    meas_trig(f, &t);
    att_gen_accel_h(&t, h);
    att_gen_accel_jacobian(&t, hj);
    phi0 = f->x[ATT_PHI];
    theta0 = f->x[ATT_THETA];
    for (i = 0; i < 3; ++i) {
        const ekf_hrow_t hr = {idx, &hj[2 * i], 2u};
        ekf_scalar_t nu = ekf_sub(ekf_div(a[i], norm), h[i]);
        nu = ekf_sub(nu, ekf_mul(hj[2 * i], ekf_sub(f->x[ATT_PHI], phi0)));
        nu = ekf_sub(nu, ekf_mul(hj[2 * i + 1], ekf_sub(f->x[ATT_THETA], theta0)));
        st = ekf_update_scalar(f->x, f->P, ATT_N, &hr, nu, r_var, gate, s->var_floor, &info);
        f->diag.accel_ratio[i] = info.test_ratio;
        bypass_failed |= (st == EKF_OK) && fails_gate(&info, s->accel_gate);
        consistent = consistent && (st == EKF_OK) && !fails_gate(&info, EKF_C(3));
        if (st == EKF_GATED) {
            gated = 1;
            ekf_count(&f->diag.accel_gated);
        } else if (st != EKF_OK) {
            if (att_model_normalise(f->x, f->P)) {
                ekf_count(&f->diag.remaps);
            }
            return note(f, st);
        } else {
            ekf_count(&f->diag.accel_fused);
        }
    }
    if (att_model_normalise(f->x, f->P)) {
        ekf_count(&f->diag.remaps);
    }
    update_gimbal_flag(f);
    gate_result(f, SENSOR_ACCEL, gated || bypass_failed);
    f->tilt_ok = (uint8_t)(consistent && (f->flags & ATT_FLAG_ACCEL_DEWEIGHTED) == 0u);
    if (gated) {
        f->flags |= ATT_FLAG_ACCEL_GATED;
        return EKF_GATED;
    }
    return EKF_OK;
}

/* Heading row and column reset: psi <- heading, Var(psi) <- var, no correlation. Keeps P
 * positive semi-definite (a principal block plus a positive diagonal entry). */
static void reset_heading(att_ekf_t *f, ekf_scalar_t heading, ekf_scalar_t var)
{
    int j;
    for (j = 0; j < ATT_N; ++j) {
        f->P[ATT_PSI * ATT_N + j] = EKF_C(0);
        f->P[j * ATT_N + ATT_PSI] = EKF_C(0);
    }
    f->P[ATT_PSI * ATT_N + ATT_PSI] = ekf_max(var, f->settings.var_floor);
    f->x[ATT_PSI] = heading;
}

static ekf_status_t stage_mag(att_ekf_t *f, const ekf_scalar_t mag[3])
{
    static const uint8_t idx = ATT_PSI;
    static const ekf_scalar_t one = EKF_C(1);
    const ekf_hrow_t hr = {&idx, &one, 1u};
    const att_settings_t *s;
    ekf_scalar_t lev[3], norm, heading, nu, r_var;
    att_trig_t t;
    ekf_status_t st;
    ekf_innov_t info;

    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    if ((f->flags & ATT_FLAG_ALIGNED) == 0u) {
        return note(f, EKF_ERR_NOT_INITIALISED);
    }
    s = &f->settings;
    st = check_vec(mag, s->mag_range);
    if (st != EKF_OK) {
        return note(f, st);
    }
    f->flags &= ~(ATT_FLAG_MAG_DISTURBED | ATT_FLAG_HEADING_HELD | ATT_FLAG_MAG_GATED);
    if ((f->flags & ATT_FLAG_GIMBAL_LOCK) != 0u) {
        /* heading is ill-defined next to theta = +-90 deg: hold it */
        f->flags |= ATT_FLAG_HEADING_HELD;
        ekf_count(&f->diag.mag_skipped);
        return EKF_SKIPPED;
    }
    norm = norm3(mag);
    meas_trig(f, &t);
    att_gen_mag_level(&t, mag, lev);
    if (!(ekf_sqrt(ekf_add(ekf_sq(lev[0]), ekf_sq(lev[1]))) > ekf_mul(EKF_C(1e-3), norm))) {
        /* no horizontal component (or no field at all): no heading information */
        f->flags |= ATT_FLAG_MAG_DISTURBED;
        ekf_count(&f->diag.mag_skipped);
        return EKF_SKIPPED;
    }
    heading = mag_heading(f, lev);
    if (!(f->mag_ref_norm > EKF_C(0))) {
        /* aligned without a magnetometer: the first field sample sets the reference and
         * the heading */
        set_mag_reference(f, norm, mag_dip(lev));
        reset_heading(f, heading, ekf_min(ekf_sq(s->init_heading_sigma), s->heading_var_max));
        f->flags &= ~ATT_FLAG_HEADING_LIMITED;
        ekf_count(&f->diag.mag_fused);
        return EKF_OK;
    }
    f->diag.mag_norm_error = ekf_sub(ekf_div(norm, f->mag_ref_norm), EKF_C(1));
    f->diag.mag_dip_error = ekf_sub(mag_dip(lev), f->mag_ref_dip);
    if (ekf_abs(f->diag.mag_norm_error) > s->mag_norm_tol || ekf_abs(f->diag.mag_dip_error) > s->mag_dip_tol) {
        f->flags |= ATT_FLAG_MAG_DISTURBED;
        ekf_count(&f->diag.mag_skipped);
        /* the reset below needs mag_reset_time of gating an undisturbed field: a body-fixed
         * offset can pass the tests for a moment in a turn (the soak found a reset to
         * such a sample) */
        f->gated_time[SENSOR_MAG] = EKF_C(0);
        return EKF_SKIPPED;
    }
    nu = ekf_wrap_pi(ekf_sub(heading, f->x[ATT_PSI]));
    if (s->mag_reset_time > EKF_C(0) && f->gated_time[SENSOR_MAG] > s->mag_reset_time && f->tilt_ok) {
        /* An undisturbed field (norm and dip as referenced) has disagreed with the heading
         * beyond the gate for mag_reset_time: the heading is what is wrong (lost during
         * gyro saturation, or tilted by sustained acceleration). Take the magnetic heading
         * with the initial uncertainty. Only with a tilt the accelerometer confirms: the
         * field is levelled with it, and a tilt still wrong after sustained acceleration
         * gives a heading wrong by up to 180 deg (the soak found it). A magnet fixed to the
         * sensor can pass the norm and dip tests for seconds; with these conditions no
         * reset fires on BROAD's attached-magnet trials (docs/derivation.md, "Magnetometer"). */
        reset_heading(f, heading, ekf_min(ekf_sq(s->init_heading_sigma), s->heading_var_max));
        ekf_count(&f->diag.heading_resets);
        ekf_count(&f->diag.mag_fused);
        gate_result(f, SENSOR_MAG, 0);
        return EKF_OK;
    }
    /* The heading comes from the field levelled with the estimated tilt, and a tilt error
     * e moves it by about tan(dip) e. While linear acceleration disturbs the tilt (its
     * running variance accel_dev_var, m/s^2 squared, is a tilt variance of
     * accel_dev_var / g^2), the heading is trusted that much less (docs/derivation.md,
     * "Magnetometer"). */
    r_var = ekf_mac(ekf_sq(s->mag_heading_noise), f->mag_tan2_dip, ekf_div(f->accel_dev_var, ekf_sq(s->gravity)));
    /* no gate bypass for the magnetometer (a magnet that passes the norm and dip tests would
     * drag the heading): recovery is the reset above, after mag_reset_time */
    st = ekf_update_scalar(f->x, f->P, ATT_N, &hr, nu, r_var, s->mag_gate, s->var_floor, &info);
    f->diag.mag_ratio = info.test_ratio;
    if (st == EKF_GATED) {
        ekf_count(&f->diag.mag_gated);
        gate_result(f, SENSOR_MAG, 1);
        f->flags |= ATT_FLAG_MAG_GATED;
        return EKF_GATED;
    }
    if (st != EKF_OK) {
        return note(f, st);
    }
    ekf_count(&f->diag.mag_fused);
    gate_result(f, SENSOR_MAG, 0);
    if (att_model_normalise(f->x, f->P)) {
        ekf_count(&f->diag.remaps);
    }
    return EKF_OK;
}

/* Rounding in F P F^T and in the updates can make P indefinite when it is ill-conditioned
 * (Euler rates near gimbal lock at high rates, very long steps, float); repair it once
 * per public call, and say so (docs/derivation.md, "Covariance bounds"). */
static void guard_covariance(att_ekf_t *f)
{
    ekf_scalar_t ldl[ATT_N * (ATT_N + 1) / 2];
    int i;
    if ((f->flags & ATT_FLAG_ALIGNED) == 0u) {
        return;
    }
    /* The updates floor the variances they reduce, but the prediction can reduce one too
     * (F P F^T with a negative correlation, and no process noise on it if angle_walk = 0:
     * found by fuzzing). Raising a diagonal entry keeps P positive (semi-)definite. */
    for (i = 0; i < ATT_N; ++i) {
        f->P[i * ATT_N + i] = ekf_max(f->P[i * ATT_N + i], f->settings.var_floor);
    }
    if (ekf_cov_ensure_pd(f->P, ATT_N, ATT_PD_MARGIN, f->settings.var_floor, ldl) > 0) {
        f->flags |= ATT_FLAG_COV_REPAIRED;
        ekf_count(&f->diag.cov_repairs);
    } else {
        f->flags &= ~ATT_FLAG_COV_REPAIRED;
    }
}

/* The public stages: each one leaves P positive definite. */
static ekf_status_t guarded(att_ekf_t *f, ekf_status_t st)
{
    if (f != NULL) {
        guard_covariance(f);
    }
    return st;
}

ekf_status_t att_predict(att_ekf_t *f, ekf_scalar_t dt) { return guarded(f, predict_stage(f, dt)); }
ekf_status_t att_update_gyro(att_ekf_t *f, const ekf_scalar_t gyro[3]) { return guarded(f, stage_gyro(f, gyro)); }
ekf_status_t att_update_accel(att_ekf_t *f, const ekf_scalar_t accel[3]) { return guarded(f, stage_accel(f, accel)); }
ekf_status_t att_update_mag(att_ekf_t *f, const ekf_scalar_t mag[3]) { return guarded(f, stage_mag(f, mag)); }

/* Alignment phase of att_step: average accelerometer (and magnetometer) samples. */
static ekf_status_t align_step(att_ekf_t *f, const att_sample_t *sm, att_step_report_t *rep)
{
    const att_settings_t *s = &f->settings;
    ekf_status_t st;
    int i;
    if ((sm->valid & ATT_HAS_ACCEL) == 0u) {
        rep->accel = note(f, EKF_ERR_NOT_INITIALISED);
        return rep->accel;
    }
    st = check_vec(sm->accel, s->accel_range);
    if (st != EKF_OK) {
        rep->accel = note(f, st);
        return st;
    }
    if ((sm->valid & ATT_HAS_MAG) != 0u) {
        rep->mag = check_vec(sm->mag, s->mag_range);
        if (rep->mag == EKF_OK) {
            for (i = 0; i < 3; ++i) {
                f->align_mag[i] = ekf_add(f->align_mag[i], sm->mag[i]);
            }
            ++f->align_mag_count;
        } else {
            (void)note(f, rep->mag);
        }
    }
    for (i = 0; i < 3; ++i) {
        f->align_acc[i] = ekf_add(f->align_acc[i], sm->accel[i]);
    }
    ++f->align_count;
    if (f->align_count < s->align_samples) {
        return EKF_OK;
    }
    {
        ekf_scalar_t acc[3], mag[3];
        const ekf_scalar_t na = ekf_from_int((int32_t)f->align_count);
        const ekf_scalar_t nm = ekf_from_int((int32_t)f->align_mag_count);
        for (i = 0; i < 3; ++i) {
            acc[i] = ekf_div(f->align_acc[i], na);
            mag[i] = (f->align_mag_count > 0u) ? ekf_div(f->align_mag[i], nm) : EKF_C(0);
            f->align_acc[i] = EKF_C(0);
            f->align_mag[i] = EKF_C(0);
        }
        f->align_count = 0u;
        st = att_align(f, acc, (f->align_mag_count > 0u) ? mag : NULL);
        f->align_mag_count = 0u;
        rep->accel = st;
        if (st == EKF_OK && (sm->valid & ATT_HAS_GYRO) != 0u && check_vec(sm->gyro, s->gyro_range) == EKF_OK) {
            rep->gyro = att_update_gyro(f, sm->gyro);
        }
    }
    return st;
}

ekf_status_t att_step(att_ekf_t *f, const att_sample_t *sample, att_step_report_t *report)
{
    att_step_report_t local = {EKF_OK, EKF_OK, EKF_OK, EKF_OK}; /* set below; initialised for the analysers */
    att_step_report_t *rep = (report != NULL) ? report : &local;
    ekf_status_t st;

    rep->predict = EKF_OK;
    rep->gyro = EKF_OK;
    rep->accel = EKF_OK;
    rep->mag = EKF_OK;
    if (f == NULL || sample == NULL) {
        return EKF_ERR_NULL;
    }
    /* rest detection sees every complete sample, from the first one on, so that the
     * initial rest already yields the gyroscope offset */
    f->flags &= ~ATT_FLAG_AT_REST;
    if ((sample->valid & (ATT_HAS_GYRO | ATT_HAS_ACCEL | ATT_GYRO_SATURATED)) == (ATT_HAS_GYRO | ATT_HAS_ACCEL) &&
        check_dt(f, sample->dt) == EKF_OK && check_vec(sample->gyro, f->settings.gyro_range) == EKF_OK &&
        check_vec(sample->accel, f->settings.accel_range) == EKF_OK &&
        att_rest_update(&f->rest, &f->settings.rest, sample->gyro, sample->accel, sample->dt)) {
        f->flags |= ATT_FLAG_AT_REST;
    }
    if ((f->flags & ATT_FLAG_ALIGNED) == 0u) {
        return align_step(f, sample, rep);
    }
    st = check_dt(f, sample->dt);
    if (st != EKF_OK) {
        rep->predict = note(f, st);
        return st;
    }
    /* The gyro sample describes the rotation over the interval ending now: fuse it
     * before propagating, so the angles integrate it (docs/derivation.md, "Step order"). */
    if ((sample->valid & ATT_GYRO_SATURATED) != 0u) {
        rep->gyro = stage_gyro_saturated(f, sample->gyro);
    } else if ((sample->valid & ATT_HAS_GYRO) != 0u) {
        rep->gyro = stage_gyro(f, sample->gyro);
    }
    rep->predict = predict_stage(f, sample->dt);
    if (rep->predict == EKF_OK) {
        ekf_count(&f->diag.steps);
    }
    if ((sample->valid & ATT_HAS_ACCEL) != 0u) {
        rep->accel = stage_accel(f, sample->accel);
    }
    if ((sample->valid & ATT_HAS_MAG) != 0u) {
        rep->mag = stage_mag(f, sample->mag);
    }
    guard_covariance(f);
    if (rep->predict != EKF_OK) {
        return rep->predict;
    }
    if (rep->gyro != EKF_OK) {
        return rep->gyro;
    }
    if (rep->accel != EKF_OK) {
        return rep->accel;
    }
    return rep->mag;
}

void att_get_euler(const att_ekf_t *f, ekf_scalar_t euler[3])
{
    euler[0] = f->x[ATT_PHI];
    euler[1] = f->x[ATT_THETA];
    euler[2] = f->x[ATT_PSI];
}

void att_get_body_rates(const att_ekf_t *f, ekf_scalar_t w[3])
{
    w[0] = f->x[ATT_P];
    w[1] = f->x[ATT_Q];
    w[2] = f->x[ATT_R];
}

void att_get_gyro_bias(const att_ekf_t *f, ekf_scalar_t b[3])
{
    b[0] = f->rest.bias[0];
    b[1] = f->rest.bias[1];
    b[2] = f->rest.bias[2];
}

void att_get_euler_rates(const att_ekf_t *f, ekf_scalar_t e[3])
{
    e[0] = f->x[ATT_PHID];
    e[1] = f->x[ATT_THETAD];
    e[2] = f->x[ATT_PSID];
}

void att_get_quaternion(const att_ekf_t *f, ekf_scalar_t q[4])
{
    att_model_euler_to_quat(f->x[ATT_PHI], f->x[ATT_THETA], f->x[ATT_PSI], q);
}

void att_get_variances(const att_ekf_t *f, ekf_scalar_t var[ATT_N])
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        var[i] = f->P[i * ATT_N + i];
    }
}

const ekf_scalar_t *att_state(const att_ekf_t *f) { return f->x; }
const ekf_scalar_t *att_covariance(const att_ekf_t *f) { return f->P; }
uint32_t att_flags(const att_ekf_t *f) { return f->flags; }
const att_diag_t *att_diag(const att_ekf_t *f) { return &f->diag; }
