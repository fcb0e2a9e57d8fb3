/*
 * test_att_outputs.c - the outputs (firmware/att/att_outputs.c; att.h; docs/derivation.md,
 * "Reported covariance"): what each accessor returns, from variables set by the test. The
 * quaternion is checked through its rotation matrix against R = Rz Ry Rx; the reported
 * attitude covariance is built in double from its parts: P's angle block + V Pb V^T + the
 * considered terms + the reference terms (the magnetic one only while the heading is
 * magnetometer-referenced), roll and heading scaled beyond the gimbal limit, the heading
 * capped; att_get_variances reports those for the angles and P's diagonal for the rates.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const double k_x[ATT_N] = {0.11, -0.22, 0.33, 0.44, -0.55, 0.66, -0.77, 0.88, -0.99};
static const double k_var[ATT_N] = {0.01, 0.02, 0.03, 1e-3, 2e-3, 3e-3, 0.04, 0.05, 0.06};

static att_ekf_t g_f;

static void filter(const att_settings_t *s)
{
    double P[ATT_N * ATT_N];
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&g_f, s));
    af_random_cov(9, k_var, P);
    af_vars_full(&g_f.vars, s, k_x, P);
}

/* Each accessor returns its own part of the state; the pointers are the filter's. */
static void test_state_accessors(void)
{
    ekf_scalar_t e[3], w[3], r[3];
    int i;
    filter(&att_default_settings);
    g_f.vars.flags = ATT_FLAG_ALIGNED | ATT_FLAG_AT_REST;
    g_f.vars.diag.steps = 77u;
    att_get_euler(&g_f, e);
    att_get_body_rates(&g_f, w);
    att_get_euler_rates(&g_f, r);
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(e[i] == ekf_from_double(k_x[ATT_PHI + i]));
        TEST_ASSERT_TRUE(w[i] == ekf_from_double(k_x[ATT_P + i]));
        TEST_ASSERT_TRUE(r[i] == ekf_from_double(k_x[ATT_PHID + i]));
    }
    TEST_ASSERT_TRUE(att_state(&g_f) == g_f.vars.x);
    TEST_ASSERT_TRUE(att_settings(&g_f) == &g_f.settings);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED | ATT_FLAG_AT_REST, att_flags(&g_f));
    TEST_ASSERT_EQUAL_UINT32(77u, att_diag(&g_f)->steps);
}

/* The offset: the rest offset plus the one learned in motion, within +-bias_max per axis;
 * its sigma: the square roots of Pb's variances (in (mrad/s)^2), its covariances unused. */
static void test_gyro_bias_and_sigma(void)
{
    att_settings_t s = att_default_settings;
    ekf_scalar_t b[3], sg[3];
    s.rest.bias_max = EKF_C(0.02);
    filter(&s);
    g_f.vars.rest.bias[0] = EKF_C(0.01);
    g_f.vars.bias.b[0] = EKF_C(0.005);
    g_f.vars.rest.bias[1] = EKF_C(0.015);
    g_f.vars.bias.b[1] = EKF_C(0.01);
    g_f.vars.rest.bias[2] = EKF_C(-0.015);
    g_f.vars.bias.b[2] = EKF_C(-0.01);
    g_f.vars.bias.Pb[0] = EKF_C(4);
    g_f.vars.bias.Pb[1] = EKF_C(9);
    g_f.vars.bias.Pb[2] = EKF_C(16);
    g_f.vars.bias.Pb[3] = g_f.vars.bias.Pb[4] = g_f.vars.bias.Pb[5] = EKF_C(1);
    att_get_gyro_bias(&g_f, b);
    att_get_gyro_bias_sigma(&g_f, sg);
    AF_NEAR_S(0.015, b[0], 2.0 * af_ulp(0.02));
    TEST_ASSERT_TRUE(b[1] == s.rest.bias_max);
    TEST_ASSERT_TRUE(b[2] == ekf_neg(s.rest.bias_max));
    AF_NEAR_S(2e-3, sg[0], 2.0 * af_ulp(4e-3));
    AF_NEAR_S(3e-3, sg[1], 2.0 * af_ulp(4e-3));
    AF_NEAR_S(4e-3, sg[2], 2.0 * af_ulp(4e-3));
}

/* The quaternion's rotation matrix is R = Rz(psi) Ry(theta) Rx(phi), body to ENU, and it is
 * a unit quaternion; at several attitudes, upside down and near +-90 deg pitch included. */
static void test_quaternion_is_the_rotation(void)
{
    static const double att[5][3] = {{0.44, -0.55, 0.66}, {3.0, 0.1, -3.0}, {-1.0, 1.5, 2.0}, {0.0, 0.0, 0.0},
                                     {-2.5, -1.2, -0.4}};
    int k, i;
    filter(&att_default_settings);
    for (k = 0; k < 5; ++k) {
        ekf_scalar_t q[4];
        double w, x, y, z, Rq[9], R[9];
        for (i = 0; i < 3; ++i) {
            g_f.vars.x[ATT_PHI + i] = ekf_from_double(att[k][i]);
        }
        att_get_quaternion(&g_f, q);
        w = ekf_to_double(q[0]);
        x = ekf_to_double(q[1]);
        y = ekf_to_double(q[2]);
        z = ekf_to_double(q[3]);
        AF_NEAR(1.0, w * w + x * x + y * y + z * z, 16.0 * af_ulp(1.0));
        Rq[0] = 1 - 2 * (y * y + z * z);
        Rq[1] = 2 * (x * y - w * z);
        Rq[2] = 2 * (x * z + w * y);
        Rq[3] = 2 * (x * y + w * z);
        Rq[4] = 1 - 2 * (x * x + z * z);
        Rq[5] = 2 * (y * z - w * x);
        Rq[6] = 2 * (x * z - w * y);
        Rq[7] = 2 * (y * z + w * x);
        Rq[8] = 1 - 2 * (x * x + y * y);
        ts_euler_to_R(ekf_to_double(g_f.vars.x[ATT_PHI]), ekf_to_double(g_f.vars.x[ATT_THETA]),
                      ekf_to_double(g_f.vars.x[ATT_PSI]), R);
        for (i = 0; i < 9; ++i) {
            AF_NEAR(R[i], Rq[i], 32.0 * af_ulp(1.0));
        }
    }
}

/* All of P, row-major, as it is held. */
static void test_full_covariance(void)
{
    double P[ATT_N * ATT_N];
    ekf_scalar_t Ps[ATT_N * ATT_N];
    int i;
    filter(&att_default_settings);
    af_cov(&g_f.vars, P);
    att_get_covariance(&g_f, Ps);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        TEST_ASSERT_TRUE(Ps[i] == ekf_from_double(P[i]));
    }
}

/* The reported attitude covariance in double: P's angle block, V Pb V^T (Pb in
 * ATT_BIAS_UNIT^2), the considered variances, accel_ref_sigma^2 on roll and pitch,
 * mag_ref_sigma^2 on yaw when referenced; beyond the gimbal limit (the flag set) the roll and
 * yaw rows and columns scaled by k = cos(gimbal_limit) / |cos(theta)|, each factor capped
 * where its variance would exceed heading_var_max but never below 1 (docs/derivation.md,
 * "Gimbal lock"); yaw capped at heading_var_max. */
static double gimbal_factor(const att_settings_t *s, double k, double var)
{
    const double floor_var = fmax(var, ekf_to_double(s->var_floor));
    return fmax(1.0, fmin(k, sqrt(ekf_to_double(s->heading_var_max) / floor_var)));
}

static void expect_angle_cov(const att_settings_t *s, int referenced, double c[6])
{
    static const int row[6] = {0, 1, 2, 0, 0, 1}, col[6] = {0, 1, 2, 1, 2, 2};
    static const int pb_at[9] = {0, 3, 4, 3, 1, 5, 4, 5, 2};
    double P[ATT_N * ATT_N], V[9], Pb[9];
    int i, k, m;
    af_cov(&g_f.vars, P);
    for (i = 0; i < 9; ++i) {
        V[i] = ekf_to_double(g_f.vars.bias.V[i]);
        Pb[i] = ekf_to_double(g_f.vars.bias.Pb[pb_at[i]]) * 1e-6;
    }
    for (i = 0; i < 6; ++i) {
        const int r = row[i], q = col[i];
        double vpv = 0.0;
        for (k = 0; k < 3; ++k) {
            for (m = 0; m < 3; ++m) {
                vpv += V[3 * r + k] * Pb[3 * k + m] * V[3 * q + m];
            }
        }
        c[i] = P[(ATT_PHI + r) * ATT_N + ATT_PHI + q] + vpv;
    }
    for (i = 0; i < 2; ++i) {
        c[i] += ekf_to_double(g_f.vars.consider.tilt[i]) + ekf_to_double(g_f.vars.consider.rate[i]) +
                pow(ekf_to_double(s->accel_ref_sigma), 2.0);
    }
    c[2] += ekf_to_double(g_f.vars.consider.rate[2]) + (referenced ? pow(ekf_to_double(s->mag_ref_sigma), 2.0) : 0.0);
    if ((g_f.vars.flags & ATT_FLAG_GIMBAL_LOCK) != 0u) {
        const double kg = cos(ekf_to_double(s->gimbal_limit)) / fabs(cos(ekf_to_double(g_f.vars.x[ATT_THETA])));
        const double k_phi = gimbal_factor(s, kg, c[0]), k_psi = gimbal_factor(s, kg, c[2]);
        c[0] *= k_phi * k_phi;
        c[2] *= k_psi * k_psi;
        c[3] *= k_phi;
        c[4] *= k_phi * k_psi;
        c[5] *= k_psi;
    }
    c[2] = fmin(c[2], ekf_to_double(s->heading_var_max));
}

/* att_get_angle_covariance and att_get_variances, in every case of the reference terms, with
 * the heading cap, beyond the gimbal limit (roll and heading scaled by k, about 2 here; with
 * heading_var_max 0.004 the roll factor capped below k, where roll reaches the cap, and the
 * heading's 1, its variance 0.0055 already above the cap); not aligned: P alone. */
static void test_reported_covariance(void)
{
    enum { REFERENCED, LIMITED, NO_REFERENCE, CAPPED, GIMBAL, GIMBAL_CAPPED, NOT_ALIGNED };
    static const double Pb[6] = {4.0, 9.0, 16.0, 1.0, -2.0, 3.0};
    int c;
    for (c = REFERENCED; c <= NOT_ALIGNED; ++c) {
        att_settings_t s = att_default_settings;
        double want[6];
        ekf_scalar_t got[6], var[ATT_N];
        int i;
        s.accel_ref_sigma = EKF_C(0.01);
        s.mag_ref_sigma = EKF_C(0.05);
        if (c == CAPPED) {
            s.heading_var_max = EKF_C(0.004);
        }
        if (c == GIMBAL_CAPPED) {
            s.heading_var_max = EKF_C(0.004);
        }
        filter(&s);
        if (c == GIMBAL || c == GIMBAL_CAPPED) {
            /* halfway between the limit and 90 deg: |cos(theta)| about half cos(gimbal_limit) */
            g_f.vars.x[ATT_THETA] = ekf_from_double(-0.5 * (ekf_to_double(s.gimbal_limit) + acos(0.0)));
            g_f.vars.flags |= ATT_FLAG_GIMBAL_LOCK;
        }
        for (i = 0; i < 9; ++i) {
            g_f.vars.bias.V[i] = ekf_from_double(0.5 * (i % 4) - 0.7);
        }
        for (i = 0; i < 6; ++i) {
            g_f.vars.bias.Pb[i] = ekf_from_double(Pb[i]);
        }
        g_f.vars.consider.tilt[0] = EKF_C(1e-4);
        g_f.vars.consider.tilt[1] = EKF_C(2e-4);
        g_f.vars.consider.cross[0] = g_f.vars.consider.cross[1] = EKF_C(0.5);
        g_f.vars.consider.rate[0] = EKF_C(1e-5);
        g_f.vars.consider.rate[1] = EKF_C(2e-5);
        g_f.vars.consider.rate[2] = EKF_C(3e-5);
        g_f.vars.mag_ref_norm = (c == NO_REFERENCE) ? EKF_C(0) : EKF_C(50);
        if (c == LIMITED) {
            g_f.vars.flags |= ATT_FLAG_HEADING_LIMITED;
        }
        if (c == NOT_ALIGNED) {
            double P[ATT_N * ATT_N];
            g_f.vars.flags = 0u;
            af_cov(&g_f.vars, P);
            want[0] = P[ATT_PHI * (ATT_N + 1)];
            want[1] = P[ATT_THETA * (ATT_N + 1)];
            want[2] = P[ATT_PSI * (ATT_N + 1)];
            want[3] = P[ATT_PHI * ATT_N + ATT_THETA];
            want[4] = P[ATT_PHI * ATT_N + ATT_PSI];
            want[5] = P[ATT_THETA * ATT_N + ATT_PSI];
        } else {
            expect_angle_cov(&s, c != LIMITED && c != NO_REFERENCE, want);
        }
        att_get_angle_covariance(&g_f, got);
        for (i = 0; i < 6; ++i) {
            AF_NEAR_S(want[i], got[i], 16.0 * af_ulp(0.01));
        }
        if (c == CAPPED || c == GIMBAL_CAPPED) {
            AF_NEAR_S(0.004, got[2], af_ulp(0.004));
        }
        if (c == GIMBAL_CAPPED) {
            AF_NEAR_S(0.004, got[0], 16.0 * af_ulp(0.01));
        }
        att_get_variances(&g_f, var);
        for (i = 0; i < ATT_N; ++i) {
            if (i >= ATT_PHI && i <= ATT_PSI) {
                TEST_ASSERT_TRUE(var[i] == got[i - ATT_PHI]);
            } else {
                TEST_ASSERT_TRUE(var[i] == att_cov_var(&g_f.vars.cov, i));
            }
        }
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_state_accessors);
    RUN_TEST(test_gyro_bias_and_sigma);
    RUN_TEST(test_quaternion_is_the_rotation);
    RUN_TEST(test_full_covariance);
    RUN_TEST(test_reported_covariance);
    af_print_worst();
    return UNITY_END();
}
