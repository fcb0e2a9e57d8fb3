/*
 * test_att_consider.c - the considered error sources of the reported covariance
 * (firmware/att/att_consider.c; docs/derivation.md, "Reported covariance"). The colored
 * accelerometer error's recursion is checked against a second route: the 2x2 covariance of
 * (e, n) propagated as a linear system, n' = rho n + sqrt(1 - rho^2) w (stationary variance
 * N), e' = (1 - K) e + K n', and against its fixed point in closed form; the rate-proportional
 * term against its sums and products.
 */
#include <math.h>
#include <string.h>

#include "att_consider.h"
#include "att_fixture.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define PI2 9.869604401089358

static att_consider_t zero(void)
{
    att_consider_t c;
    memset(&c, 0xA5, sizeof c);
    att_consider_reset(&c);
    return c;
}

/* Reset: all zero. */
static void test_reset(void)
{
    const att_consider_t c = zero();
    int i;
    for (i = 0; i < 2; ++i) {
        TEST_ASSERT_TRUE(c.tilt[i] == EKF_C(0) && c.cross[i] == EKF_C(0));
    }
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(c.rate[i] == EKF_C(0));
    }
}

/* A prediction adds dt (k |w|)^2 times the squared norm of W's row: sec^2 for roll and yaw, 1
 * for pitch; capped at pi^2 (a uniform angle). */
static void test_prediction_growth_and_cap(void)
{
    att_consider_t c = zero();
    const double k = 0.0015, w2 = 4.0, sec2 = 2.5, dt = 0.01, q = k * k * w2 * dt;
    int n;
    for (n = 0; n < 10; ++n) {
        att_consider_predict(&c, ekf_from_double(w2), ekf_from_double(k), ekf_from_double(sec2), ekf_from_double(dt));
    }
    AF_NEAR_S(10.0 * q * sec2, c.rate[0], 32.0 * af_ulp(1e-6));
    AF_NEAR_S(10.0 * q, c.rate[1], 32.0 * af_ulp(1e-6));
    AF_NEAR_S(10.0 * q * sec2, c.rate[2], 32.0 * af_ulp(1e-6));
    TEST_ASSERT_TRUE(c.tilt[0] == EKF_C(0) && c.tilt[1] == EKF_C(0));
    /* 100 rad/s for 10 s: far beyond a uniform angle */
    att_consider_predict(&c, EKF_C(1e4), EKF_C(0.01), EKF_C(2), EKF_C(10));
    AF_NEAR_S(PI2, c.rate[0], af_ulp(PI2));
    AF_NEAR_S(PI2, c.rate[1], af_ulp(PI2));
    AF_NEAR_S(PI2, c.rate[2], af_ulp(PI2));
}

/* The (e, n) covariance after one update, by the linear-system route. */
static void joint_step(double S[3], double K, double N, double rho)
{
    /* S = {Var e, Cov(e, n), Var n}; x' = M x + b w, M = [[1-K, K rho], [0, rho]],
     * b = sqrt(1 - rho^2) [K, 1], Var w = N */
    const double a = 1.0 - K, m01 = K * rho, q = (1.0 - rho * rho) * N;
    const double ee = a * a * S[0] + 2.0 * a * m01 * S[1] + m01 * m01 * S[2] + K * K * q;
    const double en = a * rho * S[1] + m01 * rho * S[2] + K * q;
    const double nn = rho * rho * S[2] + q;
    S[0] = ee;
    S[1] = en;
    S[2] = nn;
}

/* The colored error's variance and cross-covariance follow the joint covariance of (e, n)
 * update by update, with a different gain on each axis and gains that change; the rate term
 * of roll and pitch shrinks by (1 - K)^2, the yaw's is untouched. */
static void test_colored_error_matches_joint_covariance(void)
{
    static const double gains[6][2] = {{0.1, 0.5}, {0.3, 0.05}, {0.02, 0.9}, {0.5, 0.5}, {0.0, 0.2}, {1.0, 0.01}};
    const double N = 2e-4, rho = 0.98;
    double S[2][3] = {{0.0, 0.0, N}, {0.0, 0.0, N}}, rate[2] = {0.01, 0.02};
    att_consider_t c = zero();
    int n, i;
    c.rate[0] = EKF_C(0.01);
    c.rate[1] = EKF_C(0.02);
    c.rate[2] = EKF_C(0.03);
    for (n = 0; n < 6; ++n) {
        ekf_scalar_t kf[2];
        for (i = 0; i < 2; ++i) {
            kf[i] = ekf_from_double(gains[n][i]);
            joint_step(S[i], gains[n][i], N, rho);
            rate[i] *= (1.0 - gains[n][i]) * (1.0 - gains[n][i]);
        }
        att_consider_accel(&c, kf, ekf_from_double(N), ekf_from_double(rho));
        for (i = 0; i < 2; ++i) {
            AF_NEAR_S(S[i][0], c.tilt[i], 64.0 * af_ulp(N));
            AF_NEAR_S(S[i][1], c.cross[i], 64.0 * af_ulp(N));
            AF_NEAR_S(rate[i], c.rate[i], 64.0 * af_ulp(0.02));
        }
    }
    TEST_ASSERT_TRUE(c.rate[2] == EKF_C(0.03));
}

/* With a constant gain the recursion settles to its fixed point,
 * B* = K N / (1 - (1 - K) rho),  A* = (2 (1 - K) K rho B* + K^2 N) / (1 - (1 - K)^2),
 * which for a white error (rho = 0) is the K N / (2 - K) the filter itself claims. */
static void test_fixed_point(void)
{
    static const double rhos[3] = {0.0, 0.5, 0.99};
    const double K = 0.05, N = 1e-3;
    int r, n;
    for (r = 0; r < 3; ++r) {
        const double rho = rhos[r], B = K * N / (1.0 - (1.0 - K) * rho);
        const double A = (2.0 * (1.0 - K) * K * rho * B + K * K * N) / (1.0 - (1.0 - K) * (1.0 - K));
        const ekf_scalar_t kf[2] = {ekf_from_double(K), ekf_from_double(K)};
        att_consider_t c = zero();
        for (n = 0; n < 3000; ++n) {
            att_consider_accel(&c, kf, ekf_from_double(N), ekf_from_double(rho));
        }
        AF_NEAR_S(B, c.cross[0], 1e-4 * B);
        AF_NEAR_S(A, c.tilt[1], 1e-4 * A);
        if (r == 0) {
            AF_NEAR(K * N / (2.0 - K), A, 1e-12 * A);
        }
    }
}

/* Gains outside [0, 1] are taken as their nearest end: K = 1 replaces the error by the
 * colored one (A = B = N, no rate term), K = 0 keeps it (and B decays by rho). */
static void test_gain_clamped(void)
{
    const double N = 1e-3, rho = 0.5;
    const ekf_scalar_t kf[2] = {EKF_C(1.5), EKF_C(-0.2)};
    att_consider_t c = zero();
    c.tilt[1] = EKF_C(2e-3);
    c.cross[1] = EKF_C(1e-3);
    c.rate[0] = c.rate[1] = EKF_C(0.01);
    att_consider_accel(&c, kf, ekf_from_double(N), ekf_from_double(rho));
    AF_NEAR_S(N, c.tilt[0], 4.0 * af_ulp(N));
    AF_NEAR_S(N, c.cross[0], 4.0 * af_ulp(N));
    TEST_ASSERT_TRUE(c.rate[0] == EKF_C(0));
    AF_NEAR_S(2e-3, c.tilt[1], 4.0 * af_ulp(N));
    AF_NEAR_S(rho * 1e-3, c.cross[1], 4.0 * af_ulp(N));
    AF_NEAR_S(0.01, c.rate[1], 4.0 * af_ulp(0.01));
}

/* The heading: an update shrinks its rate term by (1 - k)^2 (k clamped likewise), a reset
 * clears it; the tilt terms are not the heading's. */
static void test_heading(void)
{
    att_consider_t c = zero();
    c.rate[0] = EKF_C(0.01);
    c.rate[2] = EKF_C(0.04);
    c.tilt[0] = EKF_C(0.002);
    att_consider_heading(&c, EKF_C(0.25));
    AF_NEAR_S(0.04 * 0.75 * 0.75, c.rate[2], 4.0 * af_ulp(0.04));
    att_consider_heading(&c, EKF_C(-1));
    AF_NEAR_S(0.04 * 0.75 * 0.75, c.rate[2], 4.0 * af_ulp(0.04));
    att_consider_heading_reset(&c);
    TEST_ASSERT_TRUE(c.rate[2] == EKF_C(0));
    TEST_ASSERT_TRUE(c.rate[0] == EKF_C(0.01) && c.tilt[0] == EKF_C(0.002));
}

/* What the reported covariance adds: tilt + rate for roll and pitch, the rate term for yaw. */
static void test_add(void)
{
    att_consider_t c = zero();
    ekf_scalar_t var[3] = {EKF_C(1e-3), EKF_C(2e-3), EKF_C(3e-3)};
    c.tilt[0] = EKF_C(1e-4);
    c.tilt[1] = EKF_C(2e-4);
    c.cross[0] = c.cross[1] = EKF_C(5e-2); /* a covariance with the error source: not a variance */
    c.rate[0] = EKF_C(1e-5);
    c.rate[1] = EKF_C(2e-5);
    c.rate[2] = EKF_C(3e-5);
    att_consider_add(&c, var);
    AF_NEAR_S(1e-3 + 1e-4 + 1e-5, var[0], 4.0 * af_ulp(1e-3));
    AF_NEAR_S(2e-3 + 2e-4 + 2e-5, var[1], 4.0 * af_ulp(2e-3));
    AF_NEAR_S(3e-3 + 3e-5, var[2], 4.0 * af_ulp(3e-3));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_reset);
    RUN_TEST(test_prediction_growth_and_cap);
    RUN_TEST(test_colored_error_matches_joint_covariance);
    RUN_TEST(test_fixed_point);
    RUN_TEST(test_gain_clamped);
    RUN_TEST(test_heading);
    RUN_TEST(test_add);
    af_print_worst();
    return UNITY_END();
}
