/*
 * test_att_state.c - keeping the filter's variables consistent (firmware/att/att_state.c;
 * docs/derivation.md, "Gimbal lock", "Covariance bounds"): the finiteness check of the state,
 * the saved copy, the angles' remap over +-90 deg (the same rotation, by the rotation
 * matrices; P and the offset's sensitivity transformed by its Jacobian
 * diag(1, 1, 1, 1, -1, 1, 1, -1, 1)), the gimbal flag, and the guard: the floor, one repair
 * round of rounding-sized loading accepted and reported, more refused (ATT_REPAIR_ROUNDS),
 * a P that is not finite or negative refused.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "att_state.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define PI 3.141592653589793

static const double k_var[ATT_N] = {0.01, 0.02, 0.03, 1e-3, 2e-3, 3e-3, 0.04, 0.05, 0.06};

static ekf_scalar_t bad_value(int k)
{
#if defined(EKF_SCALAR_FIXED)
    return (k == 0) ? EKF_FX_INF : EKF_FX_NINF;
#else
    return ekf_from_double((k == 0) ? (double)NAN : (k == 1) ? (double)INFINITY : -(double)INFINITY);
#endif
}

/* Finite: every state finite; one non-finite value (NaN, +-inf; in fixed point the saturated
 * values) anywhere makes it not. Large finite values are finite. */
static void test_state_finite(void)
{
    ekf_scalar_t x[ATT_N];
    int i, k;
    for (i = 0; i < ATT_N; ++i) {
        x[i] = ekf_from_double(1e8 * (i - 4));
    }
    TEST_ASSERT_EQUAL_INT(1, att_state_finite(x));
    for (i = 0; i < ATT_N; ++i) {
#if defined(EKF_SCALAR_FIXED)
        const int kinds = 2;
#else
        const int kinds = 3;
#endif
        for (k = 0; k < kinds; ++k) {
            const ekf_scalar_t keep = x[i];
            x[i] = bad_value(k);
            TEST_ASSERT_EQUAL_INT(0, att_state_finite(x));
            x[i] = keep;
        }
    }
}

/* |(3, 4, 12)| = 13; the saved copy is byte for byte. */
static void test_norm_and_copy(void)
{
    static att_vars_t a, b;
    const ekf_scalar_t v[3] = {EKF_C(3), EKF_C(-4), EKF_C(12)};
    size_t i;
    AF_NEAR_S(13.0, att_norm3(v), 2.0 * af_ulp(13.0));
    for (i = 0; i < sizeof a; ++i) {
        ((unsigned char *)&a)[i] = (unsigned char)(i * 37u + 11u);
    }
    memset(&b, 0, sizeof b);
    att_vars_copy(&b, &a);
    TEST_ASSERT_EQUAL_MEMORY(&a, &b, sizeof a);
}

/* The flag follows |theta| > gimbal_limit, strictly, both signs. */
static void test_gimbal_flag(void)
{
    const att_settings_t *s = &att_default_settings;
    const double lim = ekf_to_double(s->gimbal_limit);
    static const double x0[ATT_N] = {0};
    att_vars_t v;
    af_vars(&v, s, x0, k_var);
    v.x[ATT_THETA] = ekf_from_double(lim + 1e-5);
    att_update_gimbal_flag(&v, s);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED | ATT_FLAG_GIMBAL_LOCK, v.flags);
    v.x[ATT_THETA] = s->gimbal_limit;
    att_update_gimbal_flag(&v, s);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED, v.flags);
    v.x[ATT_THETA] = ekf_from_double(-lim - 1e-5);
    att_update_gimbal_flag(&v, s);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED | ATT_FLAG_GIMBAL_LOCK, v.flags);
    v.x[ATT_THETA] = ekf_from_double(-lim + 1e-5);
    att_update_gimbal_flag(&v, s);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED, v.flags);
}

/* A pitch beyond +-90 deg: the triple replaced by (phi + pi, +-pi - theta, psi + pi) in range,
 * the same rotation; thetad negated, the rates kept; P's pitch and pitch-rate rows and
 * columns negated (the diagonal kept); the offset's pitch sensitivity negated. */
static void test_remap_over_the_top(void)
{
    static const double cases[3][3] = {{0.4, PI / 2.0 + 0.1, -0.5}, {-2.9, -PI / 2.0 - 0.2, 3.0}, {1.0, 2.5, 2.0}};
    const att_settings_t *s = &att_default_settings;
    int c, i, j;
    for (c = 0; c < 3; ++c) {
        double x0[ATT_N] = {0.1, -0.2, 0.3, 0, 0, 0, 0.4, -0.5, 0.6}, P0[ATT_N * ATT_N], P[ATT_N * ATT_N];
        double R0[9], R1[9], e[3];
        att_vars_t v;
        x0[ATT_PHI] = cases[c][0];
        x0[ATT_THETA] = cases[c][1];
        x0[ATT_PSI] = cases[c][2];
        af_random_cov(7, k_var, P0);
        af_vars_full(&v, s, x0, P0);
        for (i = 0; i < 9; ++i) {
            v.bias.V[i] = ekf_from_double(0.1 * (i + 1));
        }
        af_cov(&v, P);
        for (i = 0; i < ATT_N; ++i) {
            for (j = 0; j < ATT_N; ++j) {
                if ((i == ATT_THETA || i == ATT_THETAD) != (j == ATT_THETA || j == ATT_THETAD)) {
                    P[i * ATT_N + j] = -P[i * ATT_N + j];
                }
            }
        }
        TEST_ASSERT_EQUAL_INT(1, att_normalise(&v));
        for (i = 0; i < 3; ++i) {
            e[i] = ekf_to_double(v.x[ATT_PHI + i]);
        }
        TEST_ASSERT_TRUE(e[0] >= -PI && e[0] < PI && e[1] >= -PI / 2.0 && e[1] <= PI / 2.0 && e[2] >= -PI &&
                         e[2] < PI);
        ts_euler_to_R(x0[ATT_PHI], x0[ATT_THETA], x0[ATT_PSI], R0);
        ts_euler_to_R(e[0], e[1], e[2], R1);
        for (i = 0; i < 9; ++i) {
            AF_NEAR(R0[i], R1[i], 16.0 * af_ulp(4.0));
        }
        TEST_ASSERT_TRUE(v.x[ATT_THETAD] == ekf_neg(ekf_from_double(x0[ATT_THETAD])));
        TEST_ASSERT_TRUE(v.x[ATT_PHID] == ekf_from_double(x0[ATT_PHID]));
        TEST_ASSERT_TRUE(v.x[ATT_Q] == ekf_from_double(x0[ATT_Q]));
        af_cov_near(&v, P, 0.0, __LINE__);
        for (j = 0; j < 3; ++j) {
            AF_NEAR_S(-0.1 * (3 + j + 1), v.bias.V[3 + j], af_ulp(1.0));
            AF_NEAR_S(0.1 * (j + 1), v.bias.V[j], af_ulp(1.0));
        }
    }
}

/* In range (the pitch at +-90 deg itself included): nothing changes; a roll or heading out of
 * range is wrapped, with no remap of P. */
static void test_no_remap_in_range(void)
{
    const att_settings_t *s = &att_default_settings;
    static const double x0[ATT_N] = {0.1, -0.2, 0.3, 0.4, PI / 2.0, -0.5, 0.4, -0.5, 0.6};
    double x1[ATT_N], P0[ATT_N * ATT_N];
    att_vars_t v, before;
    af_random_cov(8, k_var, P0);
    af_vars_full(&v, s, x0, P0);
    v.x[ATT_THETA] = EKF_HALF_PI;
    before = v;
    TEST_ASSERT_EQUAL_INT(0, att_normalise(&v));
    TEST_ASSERT_EQUAL_MEMORY(&before, &v, sizeof v);
    memcpy(x1, x0, sizeof x1);
    x1[ATT_PHI] = 3.5;
    x1[ATT_THETA] = 0.3;
    af_vars_full(&v, s, x1, P0);
    before = v;
    TEST_ASSERT_EQUAL_INT(0, att_normalise(&v));
    AF_NEAR_S(3.5 - 2.0 * PI, v.x[ATT_PHI], 4.0 * af_ulp(4.0));
    TEST_ASSERT_EQUAL_MEMORY(&before.cov, &v.cov, sizeof v.cov);
}

/* Variables with P = I but for a correlation c between roll and pitch. */
static void corr_vars(att_vars_t *v, const att_settings_t *s, double c)
{
    static const double x0[ATT_N] = {0};
    double P[ATT_N * ATT_N];
    int i;
    memset(P, 0, sizeof P);
    for (i = 0; i < ATT_N; ++i) {
        P[i * (ATT_N + 1)] = 1.0;
    }
    P[ATT_PHI * ATT_N + ATT_THETA] = P[ATT_THETA * ATT_N + ATT_PHI] = c;
    af_vars_full(v, s, x0, P);
}

/* The guard. A positive definite P passes untouched (and clears the repair flag); a variance
 * below var_floor is raised to it, which is not a repair; a P indefinite by the size of
 * rounding (correlation 1 + 0.3 lambda, lambda = 10 ATT_PD_MARGIN, at least 16 eps) is
 * repaired by one round of loading, P_ii (1 + lambda), reported and counted; a P that needs a
 * second round (correlation 1 + 3 lambda: the second round loads by 10 lambda more) is
 * refused, like one with a variance negative beyond rounding or overflowed (one negative by
 * rounding is floored); a filter not aligned has nothing to guard. */
static void test_guard(void)
{
    const att_settings_t *s = &att_default_settings;
    const double margin = ekf_to_double(ATT_PD_MARGIN), eps = ekf_to_double(EKF_SCALAR_EPS);
    const double lambda = fmax(10.0 * margin, 16.0 * eps);
    att_vars_t v, before;
    int i;
    /* positive definite */
    corr_vars(&v, s, 0.5);
    v.flags |= ATT_FLAG_COV_REPAIRED;
    before = v;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_guard_covariance(&v, s));
    TEST_ASSERT_EQUAL_MEMORY(&before.cov, &v.cov, sizeof v.cov);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ALIGNED, v.flags);
    TEST_ASSERT_EQUAL_UINT32(0u, v.diag.cov_repairs);
    /* below the floor */
    {
        static const double x0[ATT_N] = {0};
        double var[ATT_N];
        memcpy(var, k_var, sizeof var);
        var[ATT_THETAD] = 0.25 * ekf_to_double(s->var_floor);
        af_vars(&v, s, x0, var);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_guard_covariance(&v, s));
        AF_NEAR_S(ekf_to_double(s->var_floor), att_cov_var(&v.cov, ATT_THETAD), af_ulp(1e-9));
        TEST_ASSERT_EQUAL_UINT32(0u, v.diag.cov_repairs);
        TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_COV_REPAIRED);
    }
    /* one round */
    corr_vars(&v, s, 1.0 + 0.3 * lambda);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_guard_covariance(&v, s));
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_COV_REPAIRED, v.flags & ATT_FLAG_COV_REPAIRED);
    TEST_ASSERT_EQUAL_UINT32(1u, v.diag.cov_repairs);
    for (i = 0; i < ATT_N; ++i) {
        AF_NEAR_S(1.0 + lambda, att_cov_var(&v.cov, i), 4.0 * af_ulp(1.0));
    }
    AF_NEAR_S(1.0 + 0.3 * lambda, att_cov_get(&v.cov, ATT_PHI, ATT_THETA), 4.0 * af_ulp(1.0));
    /* two rounds, a correlation of 1.05, a negative variance: refused */
    corr_vars(&v, s, 1.0 + 3.0 * lambda);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, att_guard_covariance(&v, s));
    corr_vars(&v, s, 1.05);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, att_guard_covariance(&v, s));
    {
        static const double x0[ATT_N] = {0};
        const double bad[2] = {-1e-3, (double)INFINITY}; /* negative beyond rounding; overflowed */
        double var[ATT_N];
        int k;
        for (k = 0; k < 2; ++k) {
            memcpy(var, k_var, sizeof var);
            var[ATT_PSI] = bad[k];
            af_vars(&v, s, x0, var);
            TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, att_guard_covariance(&v, s));
        }
#if !defined(EKF_SCALAR_FIXED)
        /* negative by a few units of rounding of the largest variance (0.06): floored (the
         * fixed-point words hold a negative variance only in the scale of the arithmetic that
         * produced it, not from a full matrix) */
        var[ATT_PSI] = -10.0 * af_ulp(0.06);
        af_vars(&v, s, x0, var);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_guard_covariance(&v, s));
        AF_NEAR_S(ekf_to_double(s->var_floor), att_cov_var(&v.cov, ATT_PSI), af_ulp(1e-9));
#endif
    }
    TEST_ASSERT_EQUAL_UINT32(0u, v.diag.cov_repairs);
    /* not aligned: nothing to guard */
    corr_vars(&v, s, 1.05);
    v.flags = 0u;
    before = v;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_guard_covariance(&v, s));
    TEST_ASSERT_EQUAL_MEMORY(&before, &v, sizeof v);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_state_finite);
    RUN_TEST(test_norm_and_copy);
    RUN_TEST(test_gimbal_flag);
    RUN_TEST(test_remap_over_the_top);
    RUN_TEST(test_no_remap_in_range);
    RUN_TEST(test_guard);
    af_print_worst();
    return UNITY_END();
}
