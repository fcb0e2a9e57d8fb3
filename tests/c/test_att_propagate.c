/*
 * test_att_propagate.c - the generated covariance propagations att_gen_cov_propagate() and
 * att_gen_cov_propagate_f1/_f2() (host_tools/attekf/codegen/covprop.py) against the generic
 * ekf_cov_propagate() with the same patterns: the same operations in the same order, so the
 * results must be identical bit for bit. Built for float and double.
 */
#include <math.h>
#include <string.h>

#include "att_gen.h"
#include "ekf.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* Random symmetric positive definite P = A A^T + I/10, entries of order 1 .. 10. */
static void random_spd(ts_rng_t *r, ekf_scalar_t P[ATT_N * ATT_N])
{
    double A[ATT_N * ATT_N];
    int i, j, k;
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        A[i] = ts_uniform_in(r, -1.0, 1.0);
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j <= i; ++j) {
            double acc = (i == j) ? 0.1 : 0.0;
            for (k = 0; k < ATT_N; ++k) {
                acc += A[i * ATT_N + k] * A[j * ATT_N + k];
            }
            P[i * ATT_N + j] = P[j * ATT_N + i] = ekf_from_double(acc);
        }
    }
}

/* The generated propagations of the two factors of the transition Jacobian
 * (att_gen_transition_factors), which the reference covariance (att_cov_ref.c) propagates one
 * after the other, equal the generic routine bit for bit. */
static void test_factor_propagations_equal_generic_bit_for_bit(void)
{
    ts_rng_t r;
    int trial, k;
    ts_rng_seed(&r, 37);
    for (trial = 0; trial < 2000; ++trial) {
        ekf_scalar_t P1[ATT_N * ATT_N], P2[ATT_N * ATT_N], d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ];
        ekf_scalar_t work[ATT_N * ATT_N];
        random_spd(&r, P1);
        memcpy(P2, P1, sizeof P1);
        for (k = 0; k < ATT_GEN_F1_NNZ; ++k) {
            d1[k] = ekf_from_double(ts_uniform_in(&r, -1.0, 1.0) * pow(10.0, ts_uniform_in(&r, -4.0, 2.0)));
        }
        for (k = 0; k < ATT_GEN_F2_NNZ; ++k) {
            d2[k] = ekf_from_double(ts_uniform_in(&r, -1.0, 1.0) * pow(10.0, ts_uniform_in(&r, -4.0, 2.0)));
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_cov_propagate(P1, ATT_N, att_gen_f1_pattern, d1, ATT_GEN_F1_NNZ, work,
                                                        (uint16_t)(sizeof work / sizeof work[0])));
        TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_cov_propagate(P1, ATT_N, att_gen_f2_pattern, d2, ATT_GEN_F2_NNZ, work,
                                                        (uint16_t)(sizeof work / sizeof work[0])));
        att_gen_cov_propagate_f1(P2, d1);
        att_gen_cov_propagate_f2(P2, d2);
        TEST_ASSERT_EQUAL_MEMORY(P1, P2, sizeof P1);
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(P2, ATT_N));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_factor_propagations_equal_generic_bit_for_bit);
    return UNITY_END();
}
