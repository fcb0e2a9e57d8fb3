/*
 * test_att_mag.c - the magnetometer (firmware/att/att_mag.c; docs/derivation.md,
 * "Magnetometer: tilt-compensated heading", "Gate timeouts"): the reference and tan^2 of its
 * dip, the heading and dip of a levelled field, the heading update (H = e_psi, the
 * innovation wrapped) against the batch update in double with its variance terms (the tilt
 * error under linear acceleration, the norm and dip bands), the gimbal hold, the disturbance
 * tests, the first field after an alignment without one, the HEADING RESET after
 * mag_reset_time of gating an undisturbed field (each of its conditions, and once through
 * att_step), and the learned reference: its settling over the first quarter of mag_new_time
 * and a new place taken after mag_new_time.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "att_mag.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define DT 0.01
#define G 9.81
#define BH 20.0
#define BV 40.0
#define PI 3.141592653589793
#define PHI0 0.2
#define THETA0 (-0.3)
#define PSI0 1.0

static const double k_x[ATT_N] = {0.0, 0.0, 0.0, PHI0, THETA0, PSI0, 0.0, 0.0, 0.0};
static const double k_var[ATT_N] = {0.01, 0.01, 0.01, 1e-3, 1e-3, 1e-2, 0.01, 0.01, 0.01};

static double wrap(double a) { return a - 2.0 * PI * floor((a + PI) / (2.0 * PI)); }
static double ref_norm(void) { return sqrt(BH * BH + BV * BV); }
static double ref_dip(void) { return atan2(BV, BH); }

/* mag_heading_noise 0.01 rad sqrt(s): R = 0.01 rad^2 at 10 ms, the size of the yaw variance;
 * the variance terms, the tracking of the reference off unless a test turns them on. */
static att_settings_t plain(void)
{
    att_settings_t s = att_default_settings;
    s.mag_heading_noise = EKF_C(0.01);
    s.accel_adapt_weight = EKF_C(0);
    s.mag_norm_band = EKF_C(0);
    s.mag_new_time = EKF_C(0);
    return s;
}

/* Variables at (PHI0, THETA0, PSI0) with the reference of the BH, BV field. */
static void vars(att_vars_t *v, const att_settings_t *s, const double var[ATT_N])
{
    af_vars(v, s, k_x, var);
    att_mag_set_reference(v, ekf_from_double(ref_norm()), ekf_from_double(ref_dip()));
    v->tilt_ok = 1u;
}

/* The field of norm n and dip d (rad, down) seen at (PHI0, THETA0) with heading psi. */
static void field(double n, double d, double psi, ekf_scalar_t m[3])
{
    af_field_body(n * cos(d), n * sin(d), 0.0, PHI0, THETA0, psi, m);
}

/* tan^2 of the dip, with |dip| capped at 84 deg (cos at least 0.1). */
static void test_reference_tan2_dip(void)
{
    const double dips[4] = {PI / 3.0, -PI / 6.0, 0.0, 89.0 * PI / 180.0};
    int i;
    for (i = 0; i < 4; ++i) {
        att_vars_t v;
        const double want = (i == 3) ? pow(sin(dips[i]) / 0.1, 2.0) : pow(tan(dips[i]), 2.0);
        memset(&v, 0, sizeof v);
        att_mag_set_reference(&v, EKF_C(48.0), ekf_from_double(dips[i]));
        TEST_ASSERT_TRUE(v.mag_ref_norm == EKF_C(48.0) && v.mag_ref_dip == ekf_from_double(dips[i]));
        AF_NEAR_S(want, v.mag_tan2_dip, 16.0 * af_ulp(want + 1.0));
    }
}

/* A levelled field (B_h sin(psi + D), B_h cos(psi + D), -B_v): heading psi in [-pi, pi), dip
 * atan2(B_v, B_h). */
static void test_heading_and_dip_of_levelled_field(void)
{
    const double psis[4] = {0.3, -2.9, 3.0, -PI};
    att_settings_t s = att_default_settings;
    const double decl = 0.2;
    int i, up;
    s.mag_declination = ekf_from_double(decl);
    for (i = 0; i < 4; ++i) {
        for (up = 0; up < 2; ++up) {
            const double bv = up ? -15.0 : BV;
            const ekf_scalar_t lev[3] = {ekf_from_double(BH * sin(psis[i] + decl)),
                                         ekf_from_double(BH * cos(psis[i] + decl)), ekf_from_double(-bv)};
            const ekf_scalar_t h = att_mag_heading(&s, lev);
            AF_NEAR(0.0, wrap(ekf_to_double(h) - psis[i]), 8.0 * af_ulp(4.0));
            TEST_ASSERT_TRUE(h >= ekf_neg(EKF_PI) && h < EKF_PI);
            AF_NEAR_S(atan2(bv, BH), att_mag_dip(lev), 8.0 * af_ulp(2.0));
        }
    }
}

/* The update is the scalar Kalman update of the heading with the innovation wrapped into
 * [-pi, pi) (state 3.0, measured -3.1: +0.18 rad, not -6.1), in the batch form with P's
 * correlations; the rate-proportional considered error shrinks by (1 - K)^2. */
static void test_update_equals_batch(void)
{
    const double truths[2][2] = {{PSI0, PSI0 + 0.1}, {3.0, -3.1}};
    int c;
    for (c = 0; c < 2; ++c) {
        const att_settings_t s = plain();
        double x0[ATT_N], P0[ATT_N * ATT_N], x[ATT_N], P[ATT_N * ATT_N], H[ATT_N] = {0}, nu, r = 0.01, k;
        att_vars_t v;
        ekf_scalar_t m[3];
        int i;
        memcpy(x0, k_x, sizeof x0);
        x0[ATT_PSI] = truths[c][0];
        af_random_cov(4, k_var, P0);
        af_vars_full(&v, &s, x0, P0);
        att_mag_set_reference(&v, ekf_from_double(ref_norm()), ekf_from_double(ref_dip()));
        v.consider.rate[2] = EKF_C(0.02);
        for (i = 0; i < ATT_N; ++i) {
            x[i] = ekf_to_double(v.x[i]);
        }
        af_cov(&v, P);
        H[ATT_PSI] = 1.0;
        nu = wrap(truths[c][1] - x[ATT_PSI]);
        TEST_ASSERT_TRUE(fabs(nu) < 0.2);
        af_batch_update(x, P, H, &nu, &r, 1);
        k = 1.0 - P[ATT_PSI * (ATT_N + 1)] / k_var[ATT_PSI];
        field(ref_norm(), ref_dip(), truths[c][1], m);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_mag(&v, &s, m, EKF_C(DT)));
        for (i = 0; i < ATT_N; ++i) {
            AF_NEAR_S(x[i], v.x[i], 64.0 * af_ulp(4.0));
        }
        af_cov_near(&v, P, 64.0 * af_ulp(0.01), __LINE__);
        AF_NEAR_S((1.0 - k) * (1.0 - k) * 0.02, v.consider.rate[2], 64.0 * af_ulp(0.02));
        TEST_ASSERT_EQUAL_UINT32(1u, v.diag.mag_fused);
        TEST_ASSERT_EQUAL_UINT8(1u, v.heading_ref); /* (af_vars_full: 0 before) */
    }
}

/* R = (noise^2 + tan^2(dip) v accel_adapt_weight / g^2) / dt, times
 * 1 + (e_norm / mag_norm_band)^2 + (e_dip / mag_dip_band)^2 when both bands are on: with a
 * 60 deg reference dip (tan^2 = 3), v = 2 (m/s^2)^2, a field 5 % strong and 0.07 rad steep. */
static void test_variance_terms(void)
{
    int bands;
    for (bands = 0; bands < 2; ++bands) {
        att_settings_t s = plain();
        const double dip0 = PI / 3.0, dev = 2.0, w = 0.0035, P0 = k_var[ATT_PSI];
        const double R = (1e-4 + 3.0 * dev * w / (G * G)) / DT *
                         (bands ? 1.0 + pow(0.05 / 0.08, 2.0) + pow(0.07 / 0.14, 2.0) : 1.0);
        att_vars_t v;
        ekf_scalar_t m[3];
        s.accel_adapt_weight = ekf_from_double(w);
        s.mag_norm_band = EKF_C(0.08);
        s.mag_dip_band = bands ? EKF_C(0.14) : EKF_C(0); /* the factor needs both bands */
        af_vars(&v, &s, k_x, k_var);
        att_mag_set_reference(&v, EKF_C(50), ekf_from_double(dip0));
        v.accel_dev_var = ekf_from_double(dev);
        field(52.5, dip0 + 0.07, PSI0 + 0.05, m);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_mag(&v, &s, m, EKF_C(DT)));
        AF_NEAR_S(0.05, v.diag.mag_norm_error, 16.0 * af_ulp(1.0));
        AF_NEAR_S(0.07, v.diag.mag_dip_error, 16.0 * af_ulp(2.0));
        AF_NEAR_S(P0 * R / (P0 + R), att_cov_var(&v.cov, ATT_PSI), 64.0 * af_ulp(0.01));
        AF_NEAR_S(PSI0 + P0 / (P0 + R) * 0.05, v.x[ATT_PSI], 64.0 * af_ulp(1.0));
    }
}

/* Gimbal lock: the heading is held, nothing else changes. */
static void test_gimbal_hold(void)
{
    const att_settings_t s = plain();
    att_vars_t v, before;
    ekf_scalar_t m[3];
    vars(&v, &s, k_var);
    v.flags |= ATT_FLAG_GIMBAL_LOCK | ATT_FLAG_MAG_DISTURBED | ATT_FLAG_MAG_GATED;
    before = v;
    field(ref_norm(), ref_dip(), PSI0 + 0.1, m);
    TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_stage_mag(&v, &s, m, EKF_C(DT)));
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED | ATT_FLAG_GIMBAL_LOCK | ATT_FLAG_HEADING_HELD, v.flags);
    TEST_ASSERT_EQUAL_UINT32(1u, v.diag.mag_skipped);
    TEST_ASSERT_EQUAL_MEMORY(before.x, v.x, sizeof v.x);
    TEST_ASSERT_EQUAL_MEMORY(&before.cov, &v.cov, sizeof v.cov);
}

/* The heading update moves the pitch through their correlation: the gimbal flag follows the
 * updated pitch. From 5 mrad inside gimbal_limit, with a pitch-heading correlation of 0.9, a
 * heading innovation of 0.1 rad moves the pitch beyond the limit (flag set), one of 0.02 rad
 * not (flag clear); the pitch after the update from the batch update in double. */
static void test_gimbal_flag_after_update(void)
{
    const att_settings_t s = plain();
    const double lim = ekf_to_double(s.gimbal_limit), nus[2] = {0.1, 0.02}, r = 0.01;
    int c, i;
    for (c = 0; c < 2; ++c) {
        double x[ATT_N], P[ATT_N * ATT_N], H[ATT_N] = {0};
        att_vars_t v;
        ekf_scalar_t m[3];
        memcpy(x, k_x, sizeof x);
        x[ATT_THETA] = lim - 0.005;
        memset(P, 0, sizeof P);
        for (i = 0; i < ATT_N; ++i) {
            P[i * (ATT_N + 1)] = k_var[i];
        }
        P[ATT_THETA * ATT_N + ATT_PSI] = P[ATT_PSI * ATT_N + ATT_THETA] = 0.9 * sqrt(k_var[ATT_THETA] * k_var[ATT_PSI]);
        af_vars_full(&v, &s, x, P);
        att_mag_set_reference(&v, ekf_from_double(ref_norm()), ekf_from_double(ref_dip()));
        v.tilt_ok = 1u;
        TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GIMBAL_LOCK);
        for (i = 0; i < ATT_N; ++i) {
            x[i] = ekf_to_double(v.x[i]);
        }
        af_cov(&v, P);
        H[ATT_PSI] = 1.0;
        af_batch_update(x, P, H, &nus[c], &r, 1);
        /* the field at the state's own tilt: the levelled heading is the measured one */
        af_field_body(BH, BV, 0.0, x[ATT_PHI], ekf_to_double(v.x[ATT_THETA]), ekf_to_double(v.x[ATT_PSI]) + nus[c], m);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_mag(&v, &s, m, EKF_C(DT)));
        /* within a thousandth of its distance from the limit: on the same side, by the update */
        AF_NEAR_S(x[ATT_THETA], v.x[ATT_THETA], 1e-3 * fabs(x[ATT_THETA] - lim));
        TEST_ASSERT_TRUE((c == 0) ? x[ATT_THETA] > lim : x[ATT_THETA] < lim);
        TEST_ASSERT_EQUAL_UINT32((c == 0) ? ATT_FLAG_GIMBAL_LOCK : 0u, v.flags & ATT_FLAG_GIMBAL_LOCK);
    }
}

/* A field with no horizontal component (vertical in the levelled frame), or none at all:
 * no heading information. */
static void test_no_horizontal_component(void)
{
    const att_settings_t s = plain();
    int c;
    for (c = 0; c < 2; ++c) {
        att_vars_t v, before;
        ekf_scalar_t m[3];
        vars(&v, &s, k_var);
        before = v;
        af_field_body(0.0, c ? 0.0 : BV, 0.0, PHI0, THETA0, PSI0, m);
        TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_stage_mag(&v, &s, m, EKF_C(DT)));
        TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_MAG_DISTURBED, v.flags & ATT_FLAG_MAG_DISTURBED);
        TEST_ASSERT_EQUAL_MEMORY(before.x, v.x, sizeof v.x);
    }
}

/* The norm and dip tests: just beyond mag_norm_tol (0.15) or mag_dip_tol (0.17 rad) the field
 * is disturbed (not fused, and the reset's gating clock restarts), just within it is fused. */
static void test_disturbance_tolerances(void)
{
    static const double cases[8][3] = {
        /* norm factor, dip offset, disturbed */
        {1.16, 0.0, 1}, {1.14, 0.0, 0}, {0.84, 0.0, 1}, {0.86, 0.0, 0},
        {1.0, 0.18, 1}, {1.0, 0.16, 0}, {1.0, -0.18, 1}, {1.0, -0.16, 0},
    };
    const att_settings_t s = plain();
    int c;
    for (c = 0; c < 8; ++c) {
        att_vars_t v;
        ekf_scalar_t m[3];
        const int dist = cases[c][2] > 0.5;
        vars(&v, &s, k_var);
        v.gated_time[2] = EKF_C(2.0);
        field(ref_norm() * cases[c][0], ref_dip() + cases[c][1], PSI0, m);
        TEST_ASSERT_EQUAL_INT(dist ? EKF_SKIPPED : EKF_OK, att_stage_mag(&v, &s, m, EKF_C(DT)));
        TEST_ASSERT_EQUAL_UINT32(dist ? ATT_FLAG_MAG_DISTURBED : 0u, v.flags & ATT_FLAG_MAG_DISTURBED);
        TEST_ASSERT_TRUE(v.gated_time[2] == EKF_C(0));
        AF_NEAR_S(cases[c][0] - 1.0, v.diag.mag_norm_error, 16.0 * af_ulp(1.0));
        AF_NEAR_S(cases[c][1], v.diag.mag_dip_error, 16.0 * af_ulp(2.0));
    }
}

/* Aligned without a magnetometer: the first field sets the reference and the heading, the
 * heading's row and column of P cleared and its variance min(init_heading_sigma^2,
 * heading_var_max); the heading no longer limited. */
static void test_first_field_sets_reference_and_heading(void)
{
    const att_settings_t s = plain();
    const double psi = -2.0, hv = pow(ekf_to_double(s.init_heading_sigma), 2.0);
    double P0[ATT_N * ATT_N], P[ATT_N * ATT_N];
    att_vars_t v;
    ekf_scalar_t m[3];
    int i;
    af_random_cov(5, k_var, P0);
    af_vars_full(&v, &s, k_x, P0);
    v.flags |= ATT_FLAG_HEADING_LIMITED;
    for (i = 0; i < 9; ++i) {
        v.bias.V[i] = EKF_C(0.2);
    }
    v.consider.rate[2] = EKF_C(0.05);
    af_cov(&v, P);
    for (i = 0; i < ATT_N; ++i) {
        P[i * ATT_N + ATT_PSI] = P[ATT_PSI * ATT_N + i] = 0.0;
    }
    P[ATT_PSI * (ATT_N + 1)] = hv;
    field(ref_norm(), ref_dip(), psi, m);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_mag(&v, &s, m, EKF_C(DT)));
    AF_NEAR_S(psi, v.x[ATT_PSI], 16.0 * af_ulp(4.0));
    af_cov_near(&v, P, 4.0 * af_ulp(0.05), __LINE__);
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_HEADING_LIMITED);
    TEST_ASSERT_EQUAL_UINT8(1u, v.heading_ref);
    AF_NEAR_S(ref_norm(), v.mag_ref_norm, 16.0 * af_ulp(50.0));
    AF_NEAR_S(ref_dip(), v.mag_ref_dip, 16.0 * af_ulp(2.0));
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(v.bias.V[6 + i] == EKF_C(0) && v.bias.V[i] == EKF_C(0.2));
    }
    TEST_ASSERT_TRUE(v.consider.rate[2] == EKF_C(0));
}

/* The HEADING RESET: an undisturbed field gated for longer than mag_reset_time, with a tilt
 * the accelerometer confirms, resets the heading to the field's with variance
 * min(init_heading_sigma^2, heading_var_max), uncorrelated; counted, the clock stopped, the
 * offset's heading sensitivity and the considered heading error forgotten. Without any one
 * condition (the clock at or below mag_reset_time, the tilt unconfirmed, mag_reset_time 0)
 * the sample is gated; a disturbed field restarts the clock. */
static void test_heading_reset_conditions(void)
{
    enum { RESET, RESET_CAPPED, SHORT, NO_TILT, NEVER, DISTURBED };
    int c;
    for (c = RESET; c <= DISTURBED; ++c) {
        att_settings_t s = plain();
        const double psi_true = PSI0 + 2.0;
        double hv;
        att_vars_t v;
        ekf_scalar_t m[3];
        ekf_status_t st;
        int i;
        if (c == RESET_CAPPED) {
            s.heading_var_max = EKF_C(0.01);
        }
        if (c == NEVER) {
            s.mag_reset_time = EKF_C(0);
        }
        hv = fmin(pow(ekf_to_double(s.init_heading_sigma), 2.0), ekf_to_double(s.heading_var_max));
        {
            double P0[ATT_N * ATT_N], var[ATT_N];
            memcpy(var, k_var, sizeof var);
            var[ATT_PSI] = 1e-3; /* 3 sigma of the innovation: 0.31 rad, far below 2 */
            af_random_cov(6, var, P0);
            af_vars_full(&v, &s, k_x, P0);
        }
        att_mag_set_reference(&v, ekf_from_double(ref_norm()), ekf_from_double(ref_dip()));
        v.tilt_ok = (uint8_t)((c == NO_TILT) ? 0u : 1u);
        v.gated_time[2] = ekf_add(EKF_C(3.0), (c == SHORT) ? EKF_C(-0.01) : EKF_C(0.01));
        for (i = 0; i < 9; ++i) {
            v.bias.V[i] = EKF_C(0.2);
        }
        v.consider.rate[2] = EKF_C(0.05);
        field(ref_norm() * ((c == DISTURBED) ? 1.3 : 1.0), ref_dip(), psi_true, m);
        st = att_stage_mag(&v, &s, m, EKF_C(DT));
        if (c == RESET || c == RESET_CAPPED) {
            TEST_ASSERT_EQUAL_INT(EKF_OK, st);
            AF_NEAR_S(psi_true, v.x[ATT_PSI], 16.0 * af_ulp(4.0));
            for (i = 0; i < ATT_N; ++i) {
                if (i != ATT_PSI) {
                    TEST_ASSERT_TRUE(att_cov_get(&v.cov, i, ATT_PSI) == EKF_C(0));
                }
            }
            AF_NEAR_S(hv, att_cov_var(&v.cov, ATT_PSI), 2.0 * af_ulp(hv));
            TEST_ASSERT_EQUAL_UINT32(1u, v.diag.heading_resets);
            TEST_ASSERT_EQUAL_UINT32(1u, v.diag.mag_fused);
            TEST_ASSERT_EQUAL_UINT8(1u, v.heading_ref);
            TEST_ASSERT_TRUE(v.gated_time[2] == EKF_C(0));
            TEST_ASSERT_TRUE(v.bias.V[6] == EKF_C(0) && v.bias.V[8] == EKF_C(0) && v.bias.V[0] == EKF_C(0.2));
            TEST_ASSERT_TRUE(v.consider.rate[2] == EKF_C(0));
        } else {
            TEST_ASSERT_EQUAL_INT((c == DISTURBED) ? EKF_SKIPPED : EKF_GATED, st);
            TEST_ASSERT_EQUAL_UINT32(0u, v.diag.heading_resets);
            TEST_ASSERT_EQUAL_UINT8(0u, v.heading_ref);
            AF_NEAR_S(PSI0, v.x[ATT_PSI], af_ulp(4.0));
            TEST_ASSERT_TRUE((c == DISTURBED) ? v.gated_time[2] == EKF_C(0) : v.gated_time[2] > EKF_C(2.9));
        }
    }
}

/* The reset through att_step, at rest with a simulated sensor: a heading knocked 2 rad off
 * (beyond the gate) is gated sample after sample, and reset once the gating has lasted
 * mag_reset_time; afterwards the heading is the magnetic one. */
static void test_heading_reset_through_step(void)
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    att_ekf_t f;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_sample_t smp;
    att_step_report_t rep;
    double e[3];
    int k, first_gated = -1, reset_at = -1;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 7, 0.1, -0.2, 0.5);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    for (k = 0; k < 300; ++k) {
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    TEST_ASSERT_EQUAL_UINT32(0u, att_diag(&f)->mag_gated);
    f.vars.x[ATT_PSI] = ekf_from_double(wrap(ekf_to_double(f.vars.x[ATT_PSI]) + 2.0));
    for (k = 0; k < 500; ++k) {
        ts_sim_step(&sim, zero, NULL, &smp);
        TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, &rep)));
        if (first_gated < 0 && rep.mag == EKF_GATED) {
            first_gated = k;
        }
        if (reset_at < 0 && att_diag(&f)->heading_resets > 0u) {
            reset_at = k;
        }
    }
    TEST_ASSERT_EQUAL_INT(0, first_gated);
    TEST_ASSERT_EQUAL_UINT32(1u, att_diag(&f)->heading_resets);
    /* the clock starts at the first gated sample and each prediction adds dt: the reset comes
     * 300 samples later, or 301 if the rounded sum of the steps falls short of 3 s */
    TEST_ASSERT_TRUE(reset_at - first_gated == 300 || reset_at - first_gated == 301);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(reset_at - first_gated), att_diag(&f)->mag_gated);
    ts_sim_euler(&sim, e);
    /* about 200 samples fused since, each with a heading noise of mag_noise / B_h rad: their
     * mean is off by that / sqrt(200) (1 sigma); allowed: 3 sigma, far below the 2 rad the
     * heading was off */
    AF_NEAR(0.0, wrap(ekf_to_double(att_state(&f)[ATT_PSI]) - e[2]), 3.0 * cfg.mag_noise / cfg.mag_h / sqrt(200.0));
}

/* Feeds n samples of the field of norm `norm` and the reference dip; returns the 1-based
 * index of the first that was fused (0 if none). */
static int feed(att_vars_t *v, const att_settings_t *s, double norm, int n)
{
    int k, fused = 0;
    for (k = 1; k <= n; ++k) {
        ekf_scalar_t m[3];
        field(norm, ref_dip(), PSI0, m);
        if (att_stage_mag(v, s, m, EKF_C(DT)) == EKF_OK && fused == 0) {
            fused = k;
        }
    }
    return fused;
}

/* The learned reference settles: the first field after the alignment becomes the running
 * mean (and the reference), which then follows the field with k = dt / (mag_new_time / 8 +
 * dt) while its clock, advanced by the samples whose tilt is confirmed, is below a quarter of
 * mag_new_time; after that it is settled and stays. T = 0.855 s: 22 samples settle. */
static void test_learned_reference_settles(void)
{
    att_settings_t s = plain();
    const double T = 0.855, k = DT / (T / 8.0 + DT);
    att_vars_t v;
    int tilt;
    s.mag_new_time = ekf_from_double(T);
    for (tilt = 0; tilt < 2; ++tilt) {
        vars(&v, &s, k_var);
        att_mag_set_reference(&v, EKF_C(50.0), ekf_from_double(ref_dip()));
        v.tilt_ok = (uint8_t)tilt;
        TEST_ASSERT_EQUAL_INT(1, feed(&v, &s, 52.0, 1));
        TEST_ASSERT_TRUE(feed(&v, &s, 54.0, 29) > 0);
        if (tilt) {
            AF_NEAR_S(54.0 - 2.0 * pow(1.0 - k, 21.0), v.mag_ref_norm, 64.0 * af_ulp(60.0));
            TEST_ASSERT_EQUAL_UINT8(1u, v.mag_settled);
        } else {
            TEST_ASSERT_TRUE(v.mag_ref_norm == EKF_C(50.0)); /* unconfirmed tilt: nothing taken */
            TEST_ASSERT_EQUAL_UINT8(0u, v.mag_settled);
        }
    }
}

/* After settling, a field off the reference (20 % strong, beyond mag_norm_tol) is disturbed
 * until it has stayed within the tolerances of its own running mean for mag_new_time; it then
 * becomes the reference (the running mean) and is fused. The running mean is within
 * tolerance of the new field from a sample n0 on (below), the clock counts from there, and
 * the switch comes at n0 + floor(T / dt). A field off for half that
 * time and back leaves the reference. */
static void test_new_place_becomes_reference(void)
{
    att_settings_t s = plain();
    const double T = 0.855, k = DT / (T / 8.0 + DT), n1 = 60.0, n0_ref = 50.0;
    /* avg_n = n1 - (n1 - n0_ref) (1 - k)^n is within tol when n1 / avg_n - 1 <= 0.15 */
    const int n0 = (int)ceil(log((n1 - n1 / 1.15) / (n1 - n0_ref)) / log(1.0 - k));
    const int n_switch = n0 + (int)floor(T / DT);
    att_vars_t v;
    s.mag_new_time = ekf_from_double(T);
    vars(&v, &s, k_var);
    att_mag_set_reference(&v, EKF_C(50.0), ekf_from_double(ref_dip()));
    v.mag_avg_norm = EKF_C(50.0);
    v.mag_avg_dip = ekf_from_double(ref_dip());
    v.mag_settled = 1u;
    TEST_ASSERT_EQUAL_INT(n_switch, feed(&v, &s, n1, n_switch + 5));
    AF_NEAR_S(n1 - (n1 - n0_ref) * pow(1.0 - k, (double)n_switch), v.mag_ref_norm, 64.0 * af_ulp(60.0));
    /* a passing iron: off for half of mag_new_time, then back */
    att_mag_set_reference(&v, EKF_C(50.0), ekf_from_double(ref_dip()));
    v.mag_avg_norm = EKF_C(50.0);
    TEST_ASSERT_EQUAL_INT(0, feed(&v, &s, n1, n_switch / 2));
    TEST_ASSERT_EQUAL_INT(1, feed(&v, &s, 50.0, 5));
    TEST_ASSERT_TRUE(v.mag_ref_norm == EKF_C(50.0));
    TEST_ASSERT_TRUE(v.mag_new_clock == EKF_C(0));
}

/* A reference from the settings (mag_ref_norm > 0), or mag_new_time 0, is never tracked. */
static void test_fixed_reference_kept(void)
{
    int c;
    for (c = 0; c < 2; ++c) {
        att_settings_t s = plain();
        att_vars_t v;
        if (c == 0) {
            s.mag_new_time = EKF_C(0.855);
            s.mag_ref_norm = EKF_C(50.0);
            s.mag_ref_dip = ekf_from_double(ref_dip());
        }
        vars(&v, &s, k_var);
        att_mag_set_reference(&v, EKF_C(50.0), ekf_from_double(ref_dip()));
        TEST_ASSERT_EQUAL_INT(1, feed(&v, &s, 53.0, 100));
        TEST_ASSERT_TRUE(v.mag_ref_norm == EKF_C(50.0));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_reference_tan2_dip);
    RUN_TEST(test_heading_and_dip_of_levelled_field);
    RUN_TEST(test_update_equals_batch);
    RUN_TEST(test_variance_terms);
    RUN_TEST(test_gimbal_hold);
    RUN_TEST(test_gimbal_flag_after_update);
    RUN_TEST(test_no_horizontal_component);
    RUN_TEST(test_disturbance_tolerances);
    RUN_TEST(test_first_field_sets_reference_and_heading);
    RUN_TEST(test_heading_reset_conditions);
    RUN_TEST(test_heading_reset_through_step);
    RUN_TEST(test_learned_reference_settles);
    RUN_TEST(test_new_place_becomes_reference);
    RUN_TEST(test_fixed_reference_kept);
    af_print_worst();
    return UNITY_END();
}
