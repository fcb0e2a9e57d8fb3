/*
 * test_fixed_envelope.c - 10^6 random-input steps inside the fixed-point build's operating
 * envelope (docs/fixed_point.md): not one saturation of the Q format, and after every step
 * P exactly symmetric and positive definite (Cholesky in double), the state finite.
 *
 * Envelope: the fixed-point build's default settings (gimbal_limit 85 deg there, not the
 * 88.8 deg of float and double: the Euler-rate Jacobian grows as sec(theta)^2,
 * docs/fixed_point.md);
 * sample period 1 .. 5 ms (200 .. 1000 Hz, log-uniform), body rates uniform within
 * +-40 rad/s (the default gyro_range) drawn independently every sample (so the attitude
 * visits every region, the gimbal-lock neighbourhood included), specific force of norm
 * 0 .. 3 g and field of norm 1 .. 100 uT in random directions, every sensor in every sample.
 * Only rotation per sample is bounded (|w| dt <= 0.2 rad); test_att_stress.c covers the
 * rest of the input space, where saturations are counted and harmless.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "att.h"
#include "testsim.h"
#include "unity.h"

#define STEPS 1000000L

void setUp(void) {}
void tearDown(void) {}

static void test_envelope_never_saturates(void)
{
    att_ekf_t f;
    att_settings_t set = att_default_settings;
    ts_rng_t r;
    long k, fused = 0;
    double min_pivot = HUGE_VAL;
    int i;
    /* ATTEKF_ENVELOPE_SEED: other seeds for a margin study (docs/fixed_point.md); ctest uses 8 */
    ts_rng_seed(&r, getenv("ATTEKF_ENVELOPE_SEED") != NULL ? strtoull(getenv("ATTEKF_ENVELOPE_SEED"), NULL, 10) : 8u);
    ekf_scalar_saturations_reset();
    /* the default gimbal limit of this build, 85 deg: sec(theta) <= 11.5 bounds the
     * Euler-rate Jacobian */
    TEST_ASSERT_TRUE(set.gimbal_limit <= EKF_C(1.4835298641951802));
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &set));
    for (k = 0; k < STEPS; ++k) {
        att_sample_t smp;
        ekf_scalar_t P[ATT_N * ATT_N];
        double pivot;
        ekf_status_t st;
        smp.dt = ekf_from_double(exp(ts_uniform_in(&r, log(1e-3), log(5e-3))));
        for (i = 0; i < 3; ++i) {
            smp.gyro[i] = ekf_from_double(ts_uniform_in(&r, -40.0, 40.0));
        }
        ts_random_direction(&r, ts_uniform_in(&r, 0.0, 3.0 * 9.81), smp.accel);
        ts_random_direction(&r, ts_uniform_in(&r, 1.0, 100.0), smp.mag);
        smp.valid = ATT_HAS_GYRO | ATT_HAS_ACCEL | ATT_HAS_MAG;
        st = att_step(&f, &smp, NULL);
        if (st == EKF_OK) {
            ++fused;
        }
        if (ekf_scalar_saturations() != 0u) {
            printf("step %ld: %lu saturation events\n", k, (unsigned long)ekf_scalar_saturations());
            TEST_FAIL();
        }
        if (!ekf_all_finite(att_state(&f), ATT_N)) {
            printf("step %ld: non-finite state\n", k);
            TEST_FAIL();
        }
        if ((att_flags(&f) & ATT_FLAG_ALIGNED) == 0u) {
            continue;
        }
        att_get_covariance(&f, P);
        if (!ts_is_symmetric_exact(P, ATT_N) || !ts_is_positive_definite(P, ATT_N, &pivot)) {
            printf("step %ld: P not symmetric positive definite\n", k);
            TEST_FAIL();
        }
        if (pivot < min_pivot) {
            min_pivot = pivot;
        }
    }
    printf("%ld steps in the envelope (%s): saturations %lu, all fused %ld, covariance repairs %lu, "
           "numeric refusals %lu, smallest Cholesky pivot %.3e\n",
           STEPS, EKF_SCALAR_NAME, (unsigned long)ekf_scalar_saturations(), fused,
           (unsigned long)att_diag(&f)->cov_repairs, (unsigned long)att_diag(&f)->numeric, min_pivot);
    TEST_ASSERT_TRUE(fused > 0);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_envelope_never_saturates);
    return UNITY_END();
}
