/*
 * test_att_rest.c - the rest detector and the gyroscope offset learned at rest
 * (firmware/att/att_rest.c; docs/derivation.md, "Gyroscope offset"), driven sample by sample
 * with values whose outcome follows from the stated rules: rest after rest_time of still
 * samples (within half a sample), each of the three stillness conditions on its own, the
 * offset as the running mean over the rest and then an exponential average over bias_tau,
 * its clamp at bias_max, no estimation with bias_tau = 0.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "att_rest.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const ekf_scalar_t k_zero[3] = {EKF_C(0), EKF_C(0), EKF_C(0)};

static void vec(double x, double y, double z, ekf_scalar_t out[3])
{
    out[0] = ekf_from_double(x);
    out[1] = ekf_from_double(y);
    out[2] = ekf_from_double(z);
}

/* The sample index (1-based) at which the detector first reports rest for a still sensor,
 * or 0 if not within max samples. */
static int first_rest(att_rest_t *r, const att_rest_settings_t *s, const ekf_scalar_t gyro[3],
                      const ekf_scalar_t acc[3], double dt, int max)
{
    int n;
    for (n = 1; n <= max; ++n) {
        if (att_rest_update(r, s, gyro, acc, ekf_from_double(dt))) {
            return n;
        }
    }
    return 0;
}

/* Rest begins when the still time reaches rest_time, with half a sample of slack against
 * the rounding of the sum: at sample ceil(rest_time / dt - 1/2). dt = 4.5 ms puts
 * rest_time / dt a third of a sample above a whole number, where the slack decides. Nothing
 * is learned before; the first sample at rest is the offset (a mean of one sample). */
static void test_rest_after_rest_time(void)
{
    static const double dts[2] = {0.01, 0.0045};
    const att_rest_settings_t *s = &att_default_settings.rest;
    ekf_scalar_t acc[3], g[3];
    int j, i;
    vec(0.1, -0.2, 9.8, acc);
    vec(0.01, -0.02, 0.005, g);
    for (j = 0; j < 2; ++j) {
        att_rest_t r;
        const double T = ekf_to_double(s->rest_time);
        const int want = (int)ceil(T / dts[j] - 0.5);
        att_rest_reset(&r);
        TEST_ASSERT_EQUAL_INT(0, first_rest(&r, s, g, acc, dts[j], want - 1));
        for (i = 0; i < 3; ++i) {
            TEST_ASSERT_TRUE(r.bias[i] == EKF_C(0));
        }
        TEST_ASSERT_EQUAL_INT(1, att_rest_update(&r, s, g, acc, ekf_from_double(dts[j])));
        TEST_ASSERT_EQUAL_UINT8(1u, r.at_rest);
        for (i = 0; i < 3; ++i) {
            AF_NEAR_S(ekf_to_double(g[i]), r.bias[i], af_ulp(0.02));
        }
    }
}

/* Over the rest seen so far the offset is the plain mean of the raw rates (weight
 * dt / (rest time averaged so far)); once that time reaches bias_tau it is an exponential
 * average with weight dt / bias_tau, so a constant rate c is approached as
 * b - c = (b0 - c) (1 - dt / bias_tau)^n. */
static void test_offset_is_mean_then_exponential_average(void)
{
    att_rest_settings_t s = att_default_settings.rest;
    const double dt = 0.01, tau = 0.1, base[3] = {0.01, -0.005, 0.002}, c[3] = {-0.004, 0.006, 0.001};
    double sum[3] = {0.0, 0.0, 0.0}, mean[3], q;
    ekf_scalar_t acc[3], g[3];
    att_rest_t r;
    int n, i, learned = 0;
    s.rest_time = ekf_from_double(0.05);
    s.bias_tau = ekf_from_double(tau);
    vec(0.0, 0.0, 9.81, acc);
    att_rest_reset(&r);
    /* alternating rates (within rest_gyro of each other): the mean differs from every sample */
    for (n = 0; learned < 10; ++n) {
        const double d = (n % 3 == 0) ? 0.003 : (n % 3 == 1) ? -0.002 : 0.0005;
        for (i = 0; i < 3; ++i) {
            g[i] = ekf_from_double(base[i] + d * (i + 1));
        }
        if (att_rest_update(&r, &s, g, acc, ekf_from_double(dt))) {
            for (i = 0; i < 3; ++i) {
                sum[i] += ekf_to_double(g[i]);
            }
            ++learned;
        }
        TEST_ASSERT_TRUE(n < 100);
    }
    for (i = 0; i < 3; ++i) {
        mean[i] = sum[i] / 10.0;
        AF_NEAR_S(mean[i], r.bias[i], 4.0 * af_ulp(0.02));
    }
    /* bias_time has reached bias_tau: exponential average from here */
    vec(c[0], c[1], c[2], g);
    for (n = 0; n < 20; ++n) {
        TEST_ASSERT_EQUAL_INT(1, att_rest_update(&r, &s, g, acc, ekf_from_double(dt)));
    }
    q = pow(1.0 - dt / tau, 20.0);
    for (i = 0; i < 3; ++i) {
        AF_NEAR_S(c[i] + (mean[i] - c[i]) * q, r.bias[i], 8.0 * af_ulp(0.02));
    }
}

/* The offset never leaves +-bias_max, per axis. */
static void test_offset_clamped_at_bias_max(void)
{
    att_rest_settings_t s = att_default_settings.rest;
    ekf_scalar_t acc[3], g[3];
    att_rest_t r;
    s.bias_max = EKF_C(0.01);
    vec(0.0, 0.0, 9.81, acc);
    vec(0.02, -0.02, 0.005, g); /* still: |g| < rest_gyro = 0.035 */
    att_rest_reset(&r);
    TEST_ASSERT_TRUE(first_rest(&r, &s, g, acc, 0.01, 1000) > 0);
    TEST_ASSERT_TRUE(r.bias[0] == s.bias_max);
    TEST_ASSERT_TRUE(r.bias[1] == ekf_neg(s.bias_max));
    AF_NEAR_S(0.005, r.bias[2], af_ulp(0.005));
}

/* Each of the three stillness conditions breaks the rest on its own, just beyond its
 * threshold and not just within it: the low-passed rate below rest_gyro (a constant rate,
 * which the low-pass holds from its first sample), the raw rate within rest_gyro of the
 * low-pass and the specific force within rest_accel of its low-pass (a one-sample spike s
 * moves the low-pass by k s, k = dt / (rest_tau + dt), and leaves (1 - k) s between them). */
static void test_each_condition_breaks_rest(void)
{
    const att_rest_settings_t *s = &att_default_settings.rest;
    const double dt = 0.01, rg = ekf_to_double(s->rest_gyro), ra = ekf_to_double(s->rest_accel);
    const double k = dt / (ekf_to_double(s->rest_tau) + dt);
    const int rest_n = (int)ceil(ekf_to_double(s->rest_time) / dt - 0.5);
    ekf_scalar_t acc[3], g[3];
    att_rest_t r;
    int side;
    vec(0.0, 0.0, 9.81, acc);
    /* a constant rate just above and just below rest_gyro */
    vec(0.0, 0.0, 1.02 * rg, g);
    att_rest_reset(&r);
    TEST_ASSERT_EQUAL_INT(0, first_rest(&r, s, g, acc, dt, 3 * rest_n));
    vec(0.0, 0.0, 0.98 * rg, g);
    att_rest_reset(&r);
    TEST_ASSERT_EQUAL_INT(rest_n, first_rest(&r, s, g, acc, dt, 3 * rest_n));
    /* one-sample spikes of the rate (side 0) and of the specific force (side 1) */
    for (side = 0; side < 2; ++side) {
        const double th = (side == 0) ? rg : ra;
        int big;
        for (big = 0; big < 2; ++big) {
            const double spike = (big ? 1.02 : 0.98) * th / (1.0 - k);
            ekf_scalar_t gs[3], as[3];
            att_rest_reset(&r);
            TEST_ASSERT_EQUAL_INT(rest_n, first_rest(&r, s, k_zero, acc, dt, 3 * rest_n));
            memcpy(gs, k_zero, sizeof gs);
            memcpy(as, acc, sizeof as);
            if (side == 0) {
                gs[1] = ekf_from_double(spike);
            } else {
                as[0] = ekf_from_double(spike);
            }
            TEST_ASSERT_EQUAL_INT(big ? 0 : 1, att_rest_update(&r, s, gs, as, ekf_from_double(dt)));
            if (big) {
                /* a full rest_time again, counted from the next still sample (the low-passes
                 * still hold k s: below both thresholds) */
                TEST_ASSERT_TRUE(r.still_time == EKF_C(0));
                TEST_ASSERT_EQUAL_INT(rest_n, first_rest(&r, s, k_zero, acc, dt, 3 * rest_n));
            }
        }
    }
}

/* bias_tau = 0: no estimation, never at rest, nothing learned. */
static void test_no_estimation_without_bias_tau(void)
{
    att_rest_settings_t s = att_default_settings.rest;
    ekf_scalar_t acc[3], g[3];
    att_rest_t r;
    int i;
    s.bias_tau = EKF_C(0);
    vec(0.0, 0.0, 9.81, acc);
    vec(0.01, 0.0, -0.01, g);
    att_rest_reset(&r);
    TEST_ASSERT_EQUAL_INT(0, first_rest(&r, &s, g, acc, 0.01, 1000));
    TEST_ASSERT_EQUAL_UINT8(0u, r.at_rest);
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(r.bias[i] == EKF_C(0));
    }
}

/* att_rest_reset clears the detector and the offset. */
static void test_reset_clears(void)
{
    ekf_scalar_t acc[3], g[3];
    att_rest_t r;
    int i;
    vec(0.3, 0.0, 9.7, acc);
    vec(0.01, 0.02, -0.01, g);
    att_rest_reset(&r);
    TEST_ASSERT_TRUE(first_rest(&r, &att_default_settings.rest, g, acc, 0.01, 1000) > 0);
    att_rest_reset(&r);
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(r.gyro_lp[i] == EKF_C(0) && r.acc_lp[i] == EKF_C(0) && r.bias[i] == EKF_C(0));
    }
    TEST_ASSERT_TRUE(r.still_time == EKF_C(0) && r.bias_time == EKF_C(0));
    TEST_ASSERT_EQUAL_UINT8(0u, r.primed);
    TEST_ASSERT_EQUAL_UINT8(0u, r.at_rest);
}

/* A low-pass whose input is exactly zero reaches exactly zero in IEEE arithmetic (not a
 * subnormal number, which would slow every later operation on an x86 FPU): after a spike of
 * 0.01 rad/s it falls below 1e-30 within ln(1e-30 / (k 0.01)) / ln(1 - k), about 3,100
 * samples. Fixed point has no subnormals: there it stops where k y rounds to zero, within
 * 1 / (2 k) LSB of zero. */
static void test_zero_input_decays_to_exact_zero(void)
{
    const att_rest_settings_t *s = &att_default_settings.rest;
    ekf_scalar_t acc[3], g[3];
    att_rest_t r;
    int n;
    vec(0.0, 0.0, 9.81, acc);
    vec(0.0, 0.0, 0.0, g);
    att_rest_reset(&r);
    (void)att_rest_update(&r, s, g, acc, EKF_C(0.01));
    g[0] = EKF_C(0.01);
    (void)att_rest_update(&r, s, g, acc, EKF_C(0.01));
    g[0] = EKF_C(0);
    for (n = 0; n < 5000; ++n) {
        (void)att_rest_update(&r, s, g, acc, EKF_C(0.01));
    }
#if defined(EKF_SCALAR_FIXED)
    {
        const double k = 0.01 / (ekf_to_double(s->rest_tau) + 0.01);
        TEST_ASSERT_TRUE(ekf_abs(r.gyro_lp[0]) <= (ekf_scalar_t)(0.5 / k + 1.0));
    }
#else
    TEST_ASSERT_TRUE(r.gyro_lp[0] == EKF_C(0));
#endif
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_rest_after_rest_time);
    RUN_TEST(test_offset_is_mean_then_exponential_average);
    RUN_TEST(test_offset_clamped_at_bias_max);
    RUN_TEST(test_each_condition_breaks_rest);
    RUN_TEST(test_no_estimation_without_bias_tau);
    RUN_TEST(test_reset_clears);
    RUN_TEST(test_zero_input_decays_to_exact_zero);
    af_print_worst();
    return UNITY_END();
}
