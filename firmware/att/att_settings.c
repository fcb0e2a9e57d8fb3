/*
 * att_settings.c - the default settings and the settings check (att.h).
 */
#include "att.h"

#include <stddef.h>

#include "ekf_util.h"

const att_settings_t att_default_settings = {
    /* process model */
    .rate_walk = EKF_C(2.0),
    .angle_walk = EKF_C(0.001),
    .angle_walk_rate = EKF_C(0.0015), /* reported only (att_consider.h); attekf cv */
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
    .bias = {
        .sigma_init = EKF_C(0.0087), /* 0.5 deg/s */
        .walk = EKF_C(6.7e-5),       /* 0.038 deg/s after 100 s; attekf cv */
        .mag_derate = EKF_C(30.0),
        .motion = 2u,
    },
    /* accelerometer */
    .gravity = EKF_C(9.81),
    .accel_noise = EKF_C(0.7), /* attekf cv */
    .accel_band = EKF_C(0.0),
    .accel_reject = EKF_C(50.0),
    .accel_adapt_tau = EKF_C(0.5),
    .accel_lpf_tau = EKF_C(1.0), /* attekf cv */
    .accel_lpf_order = 2u,
    .accel_gate = EKF_C(10.0),
    .accel_range = EKF_C(160.0),
    .accel_ref_sigma = EKF_C(0.005), /* 0.29 deg; reported only; attekf cv */
    /* magnetometer */
    .mag_heading_noise = EKF_C(0.5), /* attekf cv */
    .mag_gate = EKF_C(3.0),
    .mag_norm_tol = EKF_C(0.15),
    .mag_dip_tol = EKF_C(0.17),
    .mag_reset_time = EKF_C(3.0),
    .mag_ref_norm = EKF_C(0.0),
    .mag_ref_dip = EKF_C(0.0),
    .mag_declination = EKF_C(0.0),
    .mag_ref_sigma = EKF_C(0.05), /* 2.9 deg; reported only; attekf cv */
    .mag_range = EKF_C(5000.0),
    /* robustness */
    .gate_timeout = EKF_C(1.0),
    .gimbal_limit = EKF_C(1.55), /* 88.8 deg */
    .dt_max = EKF_C(0.5),
    .heading_var_max = EKF_C(9.869604401089358), /* pi^2 */
#if defined(EKF_SCALAR_FIXED)
    /* above the covariance guard's absolute margin (ATT_COV_FX_TAU, 8 LSB = 4.7e-10 rad^2),
     * three decades below the smallest variance measured on BROAD, the stress and the
     * envelope (9.9e-7; docs/fixed_point.md, "Measured ranges") */
    .var_floor = EKF_C(1e-9),
#else
    .var_floor = EKF_C(1e-10),
#endif
    /* initialisation */
    .init_tilt_sigma = EKF_C(0.1),
    .init_heading_sigma = EKF_C(0.2),
    .init_rate_sigma = EKF_C(0.1),
    .align_samples = 10u,
};

/* v^2 is finite and not zero in the build's scalar. */
static int positive_square(ekf_scalar_t v)
{
    const ekf_scalar_t q = ekf_sq(v);
    return ekf_isfinite(q) && q > EKF_C(0);
}

static int finite_square(ekf_scalar_t v) { return ekf_isfinite(ekf_sq(v)); }

/* The variances and sums derived from the settings are representable in the build's
 * scalar: no noise variance that rounds to zero (nothing would be fused, or a variance
 * would be exact where it must not be), no bound or sum that saturates. Every setting in
 * range passes in float and double; the fixed-point build refuses, for example, a
 * gyro_noise of 1e-6 in Q29.34 (its square is below one LSB), or a var_floor that rounds to
 * zero or is not above twice the covariance guard's absolute margin, which the guard could
 * then not hold (docs/fixed_point.md). */
static int representable(const att_settings_t *s)
{
#if defined(ATT_COV_FX)
    if (!(s->var_floor >= 2 * ATT_COV_FX_TAU)) {
        return 0;
    }
#endif
    const ekf_scalar_t sec_lim = ekf_div(EKF_C(1), ekf_cos(s->gimbal_limit));
    const ekf_scalar_t n = ekf_from_int((int32_t)s->align_samples);
    const ekf_scalar_t r_accel = ekf_div(ekf_sq(s->accel_noise), ekf_sq(s->gravity));
    return s->var_floor > EKF_C(0) && positive_square(s->rate_walk) && positive_square(s->gyro_noise) &&
           positive_square(s->accel_noise) && positive_square(s->mag_heading_noise) &&
           ekf_isfinite(r_accel) && r_accel > EKF_C(0) &&
           (s->angle_walk == EKF_C(0) || positive_square(s->angle_walk)) &&
           positive_square(s->init_tilt_sigma) && positive_square(s->init_heading_sigma) &&
           positive_square(s->init_rate_sigma) && positive_square(s->rest.rest_gyro) &&
           positive_square(s->rest.rest_accel) && finite_square(s->gravity) &&
           finite_square(s->gyro_gate) && finite_square(s->accel_gate) && finite_square(s->mag_gate) &&
           /* the Euler-rate variance bound (att_predict.c) and the norms of the sensor vectors */
           finite_square(ekf_mul(s->gyro_range, ekf_add(EKF_C(1), ekf_mul(EKF_C(2), sec_lim)))) &&
           ekf_isfinite(ekf_mul(EKF_C(3), ekf_sq(s->accel_range))) &&
           ekf_isfinite(ekf_mul(EKF_C(3), ekf_sq(s->mag_range))) &&
           /* the sums of the alignment average */
           ekf_isfinite(ekf_mul(n, s->accel_range)) && ekf_isfinite(ekf_mul(n, s->mag_range));
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
        !ekf_in_range(s->rest.bias_tau, EKF_C(0), big) || !ekf_in_range(s->rest.bias_max, EKF_C(0), s->gyro_range) ||
        s->accel_lpf_order < 1u || s->accel_lpf_order > 2u ||
        !ekf_in_range(s->angle_walk_rate, EKF_C(0), EKF_C(1)) ||
        !ekf_in_range(s->accel_ref_sigma, EKF_C(0), EKF_HALF_PI) || !ekf_in_range(s->mag_ref_sigma, EKF_C(0), EKF_PI) ||
        !ekf_in_range(s->bias.sigma_init, EKF_C(0), s->gyro_range) || !ekf_in_range(s->bias.walk, EKF_C(0), EKF_C(1)) ||
        !ekf_in_range(s->bias.mag_derate, EKF_C(1), EKF_C(1e4)) || s->bias.motion > 2u ||
        !representable(s)) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}
