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

/* The bounds of the range table below: lo_bound[] and hi_bound[], by index. */
static const ekf_scalar_t lo_bound[] = {
    EKF_C(0), EKF_C(1e-30), EKF_C(1e-9), EKF_C(1e-6), EKF_C(1e-3), EKF_C(0.1), -EKF_HALF_PI, -EKF_PI,
};
enum { LO_0, LO_1E_30, LO_1E_9, LO_1E_6, LO_1E_3, LO_0_1, LO_M_HALF_PI, LO_M_PI };
static const ekf_scalar_t hi_bound[] = {
    EKF_C(1e6), EKF_C(1e-2), EKF_C(1), EKF_C(60), EKF_C(1.5697963267948966) /* pi/2 - 1 mrad */,
    EKF_HALF_PI, EKF_PI, EKF_TWO_PI,
};
enum { HI_BIG, HI_1E_2, HI_1, HI_60, HI_GIMBAL, HI_HALF_PI, HI_PI, HI_TWO_PI };

/* What the square of a setting must be in the build's scalar (see representable). */
enum { SQ_ANY, SQ_FINITE, SQ_POSITIVE, SQ_ZERO_OR_POSITIVE };

/* One setting in two bytes: its slot (offset in att_settings_t in scalars: every field of
 * the table follows a scalar or a struct of scalars, or a uint16_t padded to a scalar's
 * alignment, which the check below asserts), and lo <= v <= hi (finite) and its square
 * packed as lo | hi << 3 | square << 6. */
typedef struct {
    uint8_t slot, bounds;
} setting_range_t;

#define RANGE(field, lo, hi, sq) \
    {(uint8_t)(offsetof(att_settings_t, field) / sizeof(ekf_scalar_t)), (uint8_t)((lo) | (hi) << 3 | (sq) << 6)}
typedef char att_settings_scalar_slots[(offsetof(att_settings_t, rest) % sizeof(ekf_scalar_t) == 0 &&
                                        offsetof(att_settings_t, bias) % sizeof(ekf_scalar_t) == 0 &&
                                        offsetof(att_settings_t, gravity) % sizeof(ekf_scalar_t) == 0 &&
                                        offsetof(att_settings_t, accel_gate) % sizeof(ekf_scalar_t) == 0)
                                           ? 1
                                           : -1];

/* Every scalar setting with fixed bounds; the bounds that depend on other settings are
 * checked in att_settings_check. A table, not a chain of comparisons: a quarter of the
 * flash. */
static const setting_range_t ranges[] = {
    RANGE(rate_walk, LO_1E_6, HI_BIG, SQ_POSITIVE),
    RANGE(angle_walk, LO_0, HI_BIG, SQ_ZERO_OR_POSITIVE),
    RANGE(euler_rate_rel, LO_1E_6, HI_1, SQ_ANY),
    RANGE(gyro_noise, LO_1E_9, HI_BIG, SQ_POSITIVE),
    RANGE(gyro_gate, LO_0, HI_BIG, SQ_FINITE),
    RANGE(gyro_range, LO_1E_3, HI_BIG, SQ_ANY),
    RANGE(gravity, LO_0_1, HI_BIG, SQ_FINITE),
    RANGE(accel_noise, LO_1E_9, HI_BIG, SQ_POSITIVE),
    RANGE(accel_band, LO_0, HI_BIG, SQ_ANY),
    RANGE(accel_reject, LO_1E_6, HI_BIG, SQ_ANY),
    RANGE(accel_adapt_tau, LO_0, HI_BIG, SQ_ANY),
    RANGE(accel_lpf_tau, LO_0, HI_BIG, SQ_ANY),
    RANGE(accel_gate, LO_0, HI_BIG, SQ_FINITE),
    RANGE(mag_heading_noise, LO_1E_9, HI_PI, SQ_POSITIVE),
    RANGE(mag_gate, LO_0, HI_BIG, SQ_FINITE),
    RANGE(mag_norm_tol, LO_1E_6, HI_BIG, SQ_ANY),
    RANGE(mag_dip_tol, LO_1E_6, HI_PI, SQ_ANY),
    RANGE(mag_reset_time, LO_0, HI_BIG, SQ_ANY),
    RANGE(mag_ref_norm, LO_0, HI_BIG, SQ_ANY),
    RANGE(mag_ref_dip, LO_M_HALF_PI, HI_HALF_PI, SQ_ANY),
    RANGE(mag_declination, LO_M_PI, HI_PI, SQ_ANY),
    RANGE(mag_range, LO_1E_6, HI_BIG, SQ_ANY),
    RANGE(gate_timeout, LO_0, HI_BIG, SQ_ANY),
    RANGE(gimbal_limit, LO_0_1, HI_GIMBAL, SQ_ANY),
    RANGE(dt_max, LO_1E_6, HI_60, SQ_ANY),
    RANGE(var_floor, LO_1E_30, HI_1E_2, SQ_ANY),
    RANGE(init_tilt_sigma, LO_1E_6, HI_PI, SQ_POSITIVE),
    RANGE(init_heading_sigma, LO_1E_6, HI_TWO_PI, SQ_POSITIVE),
    RANGE(init_rate_sigma, LO_1E_6, HI_BIG, SQ_POSITIVE),
    RANGE(rest.rest_gyro, LO_1E_6, HI_BIG, SQ_POSITIVE),
    RANGE(rest.rest_accel, LO_1E_6, HI_BIG, SQ_POSITIVE),
    RANGE(rest.rest_time, LO_0, HI_BIG, SQ_ANY),
    RANGE(rest.rest_tau, LO_0, HI_BIG, SQ_ANY),
    RANGE(rest.bias_tau, LO_0, HI_BIG, SQ_ANY),
    RANGE(angle_walk_rate, LO_0, HI_1, SQ_ANY),
    RANGE(accel_ref_sigma, LO_0, HI_HALF_PI, SQ_ANY),
    RANGE(mag_ref_sigma, LO_0, HI_PI, SQ_ANY),
    RANGE(bias.walk, LO_0, HI_1, SQ_ANY),
};

/* 1 if the table's setting is in its range and its square is what the table says. The
 * variances derived from the settings must be representable in the build's scalar: no
 * noise variance that rounds to zero (nothing would be fused, or a variance would be exact
 * where it must not be), no square that saturates. Every setting in range passes in float
 * and double; the fixed-point build refuses, for example, a gyro_noise of 1e-6 in Q29.34
 * (its square is below one LSB). */
static int setting_ok(const att_settings_t *s, const setting_range_t *r)
{
    const ekf_scalar_t v =
        *(const ekf_scalar_t *)(const void *)((const char *)s + (size_t)r->slot * sizeof(ekf_scalar_t));
    const ekf_scalar_t q = ekf_sq(v);
    if (!ekf_in_range(v, lo_bound[r->bounds & 7u], hi_bound[(r->bounds >> 3) & 7u])) {
        return 0;
    }
    switch (r->bounds >> 6) {
    case SQ_FINITE: return ekf_isfinite(q);
    case SQ_POSITIVE: return ekf_isfinite(q) && q > EKF_C(0);
    case SQ_ZERO_OR_POSITIVE: return v == EKF_C(0) || (ekf_isfinite(q) && q > EKF_C(0));
    default: return 1;
    }
}

/* The bounds and sums derived from several settings are representable in the build's
 * scalar (see setting_ok); the fixed-point build also refuses a var_floor that is not above
 * twice the covariance guard's absolute margin, which the guard could then not hold
 * (docs/fixed_point.md). */
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
    return s->var_floor > EKF_C(0) && ekf_isfinite(r_accel) && r_accel > EKF_C(0) &&
           /* the Euler-rate variance bound (att_predict.c) and the norms of the sensor vectors */
           ekf_isfinite(ekf_sq(ekf_mul(s->gyro_range, ekf_add(EKF_C(1), ekf_mul(EKF_C(2), sec_lim))))) &&
           ekf_isfinite(ekf_mul(EKF_C(3), ekf_sq(s->accel_range))) &&
           ekf_isfinite(ekf_mul(EKF_C(3), ekf_sq(s->mag_range))) &&
           /* the sums of the alignment average */
           ekf_isfinite(ekf_mul(n, s->accel_range)) && ekf_isfinite(ekf_mul(n, s->mag_range));
}

ekf_status_t att_settings_check(const att_settings_t *s)
{
    const ekf_scalar_t big = hi_bound[HI_BIG];
    size_t i;
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    for (i = 0; i < sizeof ranges / sizeof ranges[0]; ++i) {
        if (!setting_ok(s, &ranges[i])) {
            return EKF_ERR_SETTINGS;
        }
    }
    if (!ekf_in_range(s->accel_range, s->gravity, big) ||
        !ekf_in_range(s->heading_var_max, ekf_max(EKF_C(1e-6), s->var_floor), big) || /* a cap below the floor */
        !ekf_in_range(s->rest.bias_max, EKF_C(0), s->gyro_range) || s->align_samples == 0u ||
        s->accel_lpf_order < 1u || s->accel_lpf_order > 2u ||
        !ekf_in_range(s->bias.sigma_init, EKF_C(0), s->gyro_range) ||
        !ekf_in_range(s->bias.mag_derate, EKF_C(1), EKF_C(1e4)) || s->bias.motion > 2u || !representable(s)) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}
