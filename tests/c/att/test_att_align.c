/*
 * test_att_align.c - the alignment (firmware/att/att_align.c; docs/derivation.md,
 * "Alignment"): roll and pitch from the gravity direction and the heading from the levelled
 * field of sensor vectors computed from known attitudes, the initial covariance in closed
 * form (the rate uncertainty mapped into the Euler rates by W), the magnetic reference, what
 * the alignment starts afresh, the gravity test, and the averaging phase of att_step before it.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_align.h"
#include "att_fixture.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define G 9.81
#define BH 20.0 /* horizontal field, uT */
#define BV 40.0 /* vertical field (down), uT */
#define TWO_PI 6.283185307179586

/* An angle difference into [-pi, pi). */
static double wrap(double a)
{
    return a - TWO_PI * floor((a + 0.5 * TWO_PI) / TWO_PI);
}

static void zero_vars(att_vars_t *v, const att_settings_t *s)
{
    static const double x0[ATT_N] = {0}, var0[ATT_N] = {1, 1, 1, 1, 1, 1, 1, 1, 1};
    af_vars(v, s, x0, var0);
    v->flags = 0u;
    v->heading_ref = 1u; /* (the alignment sets it either way) */
}

/* Roll and pitch invert h = R^T e_z at any attitude, upside down and near +-90 deg pitch
 * included, whatever the norm; without a field the heading is 0 with variance
 * heading_var_max (ATT_FLAG_HEADING_LIMITED); the rates are zero. */
static void test_tilt_from_gravity(void)
{
    static const double att[][2] = {{0.3, -0.4}, {-2.5, 1.2}, {3.0, 0.1}, {0.0, -1.5}, {-0.7, 0.0}};
    const att_settings_t *s = &att_default_settings;
    size_t k;
    for (k = 0; k < sizeof att / sizeof att[0]; ++k) {
        att_vars_t v;
        ekf_scalar_t a[3];
        int i;
        zero_vars(&v, s);
        af_gravity_body(k == 2 ? 0.5 * G : G, att[k][0], att[k][1], a);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align(&v, s, a, NULL));
        AF_NEAR_S(att[k][0], v.x[ATT_PHI], 8.0 * af_ulp(4.0));
        AF_NEAR_S(att[k][1], v.x[ATT_THETA], 8.0 * af_ulp(4.0));
        TEST_ASSERT_TRUE(v.x[ATT_PSI] == EKF_C(0));
        for (i = 0; i < 3; ++i) {
            TEST_ASSERT_TRUE(v.x[ATT_P + i] == EKF_C(0) && v.x[ATT_PHID + i] == EKF_C(0));
        }
        TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED | ATT_FLAG_HEADING_LIMITED, v.flags);
        TEST_ASSERT_EQUAL_UINT8(0u, v.heading_ref); /* the heading is arbitrary */
        AF_NEAR_S(ekf_to_double(s->heading_var_max), att_cov_var(&v.cov, ATT_PSI), af_ulp(10.0));
        TEST_ASSERT_TRUE(v.mag_ref_norm == EKF_C(0));
    }
}

/* The heading is psi of the field's own attitude, net of the declination, in [-pi, pi); the
 * learned reference is the field's norm and dip (tan^2 of the dip with it). */
static void test_heading_and_reference_from_field(void)
{
    static const double att[][3] = {{0.2, -0.3, 1.0}, {-1.0, 0.6, -3.0}, {2.8, 0.2, 3.1}, {0.1, 1.3, -0.5}};
    att_settings_t s = att_default_settings;
    const double decl = 0.2;
    size_t k;
    s.mag_declination = ekf_from_double(decl);
    for (k = 0; k < sizeof att / sizeof att[0]; ++k) {
        att_vars_t v;
        ekf_scalar_t a[3], m[3];
        zero_vars(&v, &s);
        af_gravity_body(G, att[k][0], att[k][1], a);
        af_field_body(BH, BV, decl, att[k][0], att[k][1], att[k][2], m);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align(&v, &s, a, m));
        AF_NEAR(0.0, wrap(ekf_to_double(v.x[ATT_PSI]) - att[k][2]), 16.0 * af_ulp(4.0));
        TEST_ASSERT_TRUE(v.x[ATT_PSI] >= ekf_neg(EKF_PI) && v.x[ATT_PSI] < EKF_PI);
        TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED, v.flags);
        TEST_ASSERT_EQUAL_UINT8(1u, v.heading_ref);
        AF_NEAR_S(sqrt(BH * BH + BV * BV), v.mag_ref_norm, 4.0 * af_ulp(50.0));
        AF_NEAR_S(atan2(BV, BH), v.mag_ref_dip, 8.0 * af_ulp(2.0));
        AF_NEAR_S((BV / BH) * (BV / BH), v.mag_tan2_dip, 32.0 * af_ulp(4.0));
    }
}

/* A reference in the settings (mag_ref_norm > 0) is taken whatever the field says. */
static void test_reference_from_settings(void)
{
    att_settings_t s = att_default_settings;
    att_vars_t v;
    ekf_scalar_t a[3], m[3];
    s.mag_ref_norm = EKF_C(48.0);
    s.mag_ref_dip = EKF_C(1.1);
    zero_vars(&v, &s);
    af_gravity_body(G, 0.1, 0.2, a);
    af_field_body(BH, BV, 0.0, 0.1, 0.2, 0.3, m);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align(&v, &s, a, m));
    TEST_ASSERT_TRUE(v.mag_ref_norm == s.mag_ref_norm && v.mag_ref_dip == s.mag_ref_dip);
    AF_NEAR_S(tan(1.1) * tan(1.1), v.mag_tan2_dip, 32.0 * af_ulp(4.0));
}

static void setp(double P[ATT_N * ATT_N], int i, int j, double val)
{
    P[i * ATT_N + j] = val;
    P[j * ATT_N + i] = val;
}

/* P in closed form: tilt init_tilt_sigma^2, heading min(init_heading_sigma^2,
 * heading_var_max), body rates r = init_rate_sigma^2 I, and the Euler rates W r W^T with
 * the relative error on their diagonal. W's rows at (phi, theta): (1, s t, c t),
 * (0, c, -s), (0, s sec, c sec); their squared norms sec^2, 1, sec^2, rows 0 and 2 meet in
 * t sec, row 1 is orthogonal to both. Nothing else is correlated. */
static void test_initial_covariance(void)
{
    const double phi = 0.7, th = 0.5, psi = -1.2;
    int hv;
    for (hv = 0; hv < 2; ++hv) {
        att_settings_t s = att_default_settings;
        att_vars_t v;
        ekf_scalar_t a[3], m[3];
        double P[ATT_N * ATT_N], r, rel, sp = sin(phi), cp = cos(phi), t = tan(th), sec = 1.0 / cos(th), hvar;
        s.heading_var_max = hv ? EKF_C(0.01) : EKF_C(1.0); /* below and above init_heading_sigma^2 */
        r = ekf_to_double(ekf_sq(s.init_rate_sigma));
        rel = ekf_to_double(s.euler_rate_rel);
        hvar = fmin(ekf_to_double(ekf_sq(s.init_heading_sigma)), ekf_to_double(s.heading_var_max));
        zero_vars(&v, &s);
        af_gravity_body(G, phi, th, a);
        af_field_body(BH, BV, 0.0, phi, th, psi, m);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align(&v, &s, a, m));
        memset(P, 0, sizeof P);
        setp(P, ATT_P, ATT_P, r);
        setp(P, ATT_Q, ATT_Q, r);
        setp(P, ATT_R, ATT_R, r);
        setp(P, ATT_PHI, ATT_PHI, ekf_to_double(ekf_sq(s.init_tilt_sigma)));
        setp(P, ATT_THETA, ATT_THETA, ekf_to_double(ekf_sq(s.init_tilt_sigma)));
        setp(P, ATT_PSI, ATT_PSI, hvar);
        setp(P, ATT_PHID, ATT_PHID, r * sec * sec * (1.0 + rel));
        setp(P, ATT_THETAD, ATT_THETAD, r * (1.0 + rel));
        setp(P, ATT_PSID, ATT_PSID, r * sec * sec * (1.0 + rel));
        setp(P, ATT_PHID, ATT_PSID, r * t * sec);
        setp(P, ATT_P, ATT_PHID, r);
        setp(P, ATT_Q, ATT_PHID, r * sp * t);
        setp(P, ATT_R, ATT_PHID, r * cp * t);
        setp(P, ATT_Q, ATT_THETAD, r * cp);
        setp(P, ATT_R, ATT_THETAD, -r * sp);
        setp(P, ATT_Q, ATT_PSID, r * sp * sec);
        setp(P, ATT_R, ATT_PSID, r * cp * sec);
        af_cov_near(&v, P, 16.0 * af_ulp(0.02), __LINE__);
    }
}

/* Initial sigmas below the floor: the variances start at var_floor. */
static void test_floor_holds_from_the_start(void)
{
    att_settings_t s = att_default_settings;
    att_vars_t v;
    ekf_scalar_t a[3];
    s.var_floor = EKF_C(1e-6);
    s.init_tilt_sigma = EKF_C(1e-4);
    zero_vars(&v, &s);
    af_gravity_body(G, 0.1, -0.1, a);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align(&v, &s, a, NULL));
    TEST_ASSERT_TRUE(att_cov_var(&v.cov, ATT_PHI) == s.var_floor);
    TEST_ASSERT_TRUE(att_cov_var(&v.cov, ATT_THETA) == s.var_floor);
}

/* Upside down, atan2 gives +pi for the roll: it comes back as -pi, in [-pi, pi). */
static void test_upside_down_roll_in_range(void)
{
    const att_settings_t *s = &att_default_settings;
    const ekf_scalar_t a[3] = {EKF_C(0), EKF_C(0), EKF_C(-9.81)};
    att_vars_t v;
    zero_vars(&v, s);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align(&v, s, a, NULL));
    TEST_ASSERT_TRUE(v.x[ATT_PHI] >= ekf_neg(EKF_PI) && v.x[ATT_PHI] < EKF_PI);
    AF_NEAR(-3.141592653589793, ekf_to_double(v.x[ATT_PHI]), 4.0 * af_ulp(4.0));
}

/* What the alignment starts afresh: the low-pass from the (averaged) sample, the gate clocks,
 * the offset's sensitivity, the considered errors, the learned reference's settling; the
 * tilt counts as confirmed. */
static void test_starts_afresh(void)
{
    const att_settings_t *s = &att_default_settings;
    att_vars_t v;
    ekf_scalar_t a[3], m[3];
    int i;
    zero_vars(&v, s);
    for (i = 0; i < 3; ++i) {
        v.gated_time[i] = EKF_C(2);
        v.accel_lp[i] = v.accel_lp1[i] = EKF_C(1);
        v.consider.rate[i] = EKF_C(0.1);
    }
    for (i = 0; i < 9; ++i) {
        v.bias.V[i] = EKF_C(0.5);
    }
    v.consider.tilt[0] = v.consider.cross[1] = EKF_C(0.2);
    v.mag_avg_norm = v.mag_avg_dip = v.mag_new_clock = EKF_C(3);
    v.mag_settled = 1u;
    v.tilt_ok = 0u;
    af_gravity_body(G, 0.4, -0.2, a);
    af_field_body(BH, BV, 0.0, 0.4, -0.2, 0.9, m);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align(&v, s, a, m));
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(v.accel_lp[i] == a[i] && v.accel_lp1[i] == a[i]);
        TEST_ASSERT_TRUE(v.gated_time[i] == EKF_C(0) && v.consider.rate[i] == EKF_C(0));
    }
    for (i = 0; i < 9; ++i) {
        TEST_ASSERT_TRUE(v.bias.V[i] == EKF_C(0));
    }
    TEST_ASSERT_TRUE(v.consider.tilt[0] == EKF_C(0) && v.consider.cross[1] == EKF_C(0));
    TEST_ASSERT_TRUE(v.mag_avg_norm == EKF_C(0) && v.mag_avg_dip == EKF_C(0) && v.mag_new_clock == EKF_C(0));
    TEST_ASSERT_EQUAL_UINT8(0u, v.mag_settled);
    TEST_ASSERT_EQUAL_UINT8(1u, v.accel_lp_valid);
    TEST_ASSERT_EQUAL_UINT8(1u, v.tilt_ok);
}

/* Gravity is usable above a tenth of g, strictly. */
static void test_gravity_threshold(void)
{
    const att_settings_t *s = &att_default_settings;
    ekf_scalar_t a[3];
    af_gravity_body(0.1 * G * 1.001, 0.3, 0.2, a);
    TEST_ASSERT_EQUAL_INT(1, att_align_has_gravity(s, a));
    af_gravity_body(0.1 * G * 0.999, 0.3, 0.2, a);
    TEST_ASSERT_EQUAL_INT(0, att_align_has_gravity(s, a));
}

/* The levelled field's heading, in double: l = Ry(theta) Rx(phi) m, psi = atan2(l_x, l_y). */
static double heading_of(const double a[3], const double m[3])
{
    const double phi = atan2(a[1], a[2]), th = atan2(-a[0], sqrt(a[1] * a[1] + a[2] * a[2]));
    const double my = cos(phi) * m[1] - sin(phi) * m[2], mz = sin(phi) * m[1] + cos(phi) * m[2];
    const double lx = cos(th) * m[0] + sin(th) * mz;
    return atan2(lx, my);
}

/* The averaging phase: align_samples accelerometer samples, then the alignment on their
 * mean; the field averaged over the samples that had one. */
static void test_averaging_phase(void)
{
    att_settings_t s = att_default_settings;
    att_vars_t v;
    att_sample_t sm;
    double sum_a[3] = {0, 0, 0}, sum_m[3] = {0, 0, 0}, mean_a[3], mean_m[3];
    int k, i;
    s.align_samples = 4u;
    zero_vars(&v, &s);
    memset(&sm, 0, sizeof sm);
    for (k = 0; k < 4; ++k) {
        af_gravity_body(G, 0.1 * (k + 1), -0.05 * k, sm.accel);
        sm.valid = ATT_HAS_GYRO | ATT_HAS_ACCEL;
        if (k == 1 || k == 3) {
            /* the same field direction, scaled: its mean has the norm of the unscaled one */
            af_field_body(BH * (k == 1 ? 0.8 : 1.2), BV * (k == 1 ? 0.8 : 1.2), 0.0, 0.25, -0.075, 0.6, sm.mag);
            sm.valid |= ATT_HAS_MAG;
            for (i = 0; i < 3; ++i) {
                sum_m[i] += ekf_to_double(sm.mag[i]);
            }
        }
        for (i = 0; i < 3; ++i) {
            sum_a[i] += ekf_to_double(sm.accel[i]);
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align_sample(&v, &s, &sm));
        TEST_ASSERT_EQUAL_UINT32(k < 3 ? 0u : ATT_FLAG_ALIGNED, v.flags & ATT_FLAG_ALIGNED);
    }
    for (i = 0; i < 3; ++i) {
        mean_a[i] = sum_a[i] / 4.0;
        mean_m[i] = sum_m[i] / 2.0;
    }
    AF_NEAR_S(atan2(mean_a[1], mean_a[2]), v.x[ATT_PHI], 8.0 * af_ulp(4.0));
    AF_NEAR_S(atan2(-mean_a[0], sqrt(mean_a[1] * mean_a[1] + mean_a[2] * mean_a[2])), v.x[ATT_THETA],
              8.0 * af_ulp(4.0));
    AF_NEAR(0.0, wrap(ekf_to_double(v.x[ATT_PSI]) - heading_of(mean_a, mean_m)), 32.0 * af_ulp(4.0));
    AF_NEAR_S(sqrt(BH * BH + BV * BV), v.mag_ref_norm, 8.0 * af_ulp(50.0));
    TEST_ASSERT_EQUAL_UINT16(0u, v.align_count);
    TEST_ASSERT_EQUAL_UINT16(0u, v.align_mag_count);
}

/* A mean without a gravity direction restarts the averaging (EKF_SKIPPED, counted), and the
 * next align_samples samples align on their own mean only. */
static void test_averaging_restarts_without_gravity(void)
{
    att_settings_t s = att_default_settings;
    att_vars_t v;
    att_sample_t sm;
    int k;
    s.align_samples = 2u;
    zero_vars(&v, &s);
    memset(&sm, 0, sizeof sm);
    sm.valid = ATT_HAS_ACCEL;
    af_gravity_body(G, 0.0, 0.0, sm.accel);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align_sample(&v, &s, &sm));
    af_gravity_body(-1.05 * G, 0.0, 0.0, sm.accel); /* the mean: 0.025 g */
    TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_stage_align_sample(&v, &s, &sm));
    TEST_ASSERT_EQUAL_UINT32(1u, v.diag.accel_skipped);
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_ALIGNED);
    for (k = 0; k < 2; ++k) {
        af_gravity_body(G, 0.3, 0.0, sm.accel);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_align_sample(&v, &s, &sm));
    }
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED, v.flags & ATT_FLAG_ALIGNED);
    AF_NEAR_S(0.3, v.x[ATT_PHI], 8.0 * af_ulp(4.0));
    AF_NEAR_S(0.0, v.x[ATT_THETA], 8.0 * af_ulp(4.0));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_tilt_from_gravity);
    RUN_TEST(test_heading_and_reference_from_field);
    RUN_TEST(test_reference_from_settings);
    RUN_TEST(test_initial_covariance);
    RUN_TEST(test_floor_holds_from_the_start);
    RUN_TEST(test_upside_down_roll_in_range);
    RUN_TEST(test_starts_afresh);
    RUN_TEST(test_gravity_threshold);
    RUN_TEST(test_averaging_phase);
    RUN_TEST(test_averaging_restarts_without_gravity);
    af_print_worst();
    return UNITY_END();
}
