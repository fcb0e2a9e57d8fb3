/*
 * test_fixed_envelope.c - 10^6 random-input steps inside the fixed-point build's operating
 * envelope (docs/fixed_point.md): not one saturation of the Q format, not one step refused,
 * and after every step P exactly symmetric and positive definite (Cholesky in double), the
 * state finite; the guard's repairs counted and bounded.
 *
 * Envelope: the fixed-point build's default settings (the same as float's, gimbal_limit
 * 88.8 deg: sec(theta) up to 48, the Euler-rate Jacobian up to ~sec^2 |w| dt); sample period
 * 1 .. 5 ms (200 .. 1000 Hz, log-uniform), body rates uniform within +-40 rad/s (the
 * default gyro_range) drawn independently every sample (so the attitude visits every
 * region, the gimbal-lock neighbourhood included), specific force of norm 0 .. 3 g and field
 * of norm 1 .. 100 uT in random directions, every sensor in every sample. Only rotation per
 * sample is bounded (|w| dt <= 0.2 rad); test_att_stress.c covers the rest of the input
 * space, where saturations are counted and refused.
 * A margin study runs other seeds, rates and gimbal limits: ATTEKF_ENVELOPE_SEED,
 * ATTEKF_ENVELOPE_RATE (rad/s), ATTEKF_ENVELOPE_GIMBAL (rad); ctest runs the defaults.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "att.h"
#include "fx_count.h"
#include "testsim.h"
#include "unity.h"

#define STEPS 1000000L
/* Guard repairs allowed in the run: about three times what it measures, none
 * (docs/fixed_point.md, "Operating envelope"). */
#define MAX_REPAIRS 0u

static double env_or(const char *name, double def)
{
    const char *v = getenv(name);
    return (v != NULL) ? strtod(v, NULL) : def;
}

void setUp(void) {}
void tearDown(void) {}

static void test_envelope_never_saturates(void)
{
    att_ekf_t f;
    att_settings_t set = att_default_settings;
    ts_rng_t r;
    long k, fused = 0;
    double min_pivot = HUGE_VAL;
    const double rate = env_or("ATTEKF_ENVELOPE_RATE", 40.0);
    int i;
    ts_rng_seed(&r, getenv("ATTEKF_ENVELOPE_SEED") != NULL ? strtoull(getenv("ATTEKF_ENVELOPE_SEED"), NULL, 10) : 8u);
    if (getenv("ATTEKF_ENVELOPE_GIMBAL") != NULL) {
        set.gimbal_limit = ekf_from_double(env_or("ATTEKF_ENVELOPE_GIMBAL", 0.0));
    }
    fx_count_reset();
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &set));
    for (k = 0; k < STEPS; ++k) {
        att_sample_t smp;
        ekf_scalar_t P[ATT_N * ATT_N];
        double pivot;
        ekf_status_t st;
        smp.dt = ekf_from_double(exp(ts_uniform_in(&r, log(1e-3), log(5e-3))));
        for (i = 0; i < 3; ++i) {
            smp.gyro[i] = ekf_from_double(ts_uniform_in(&r, -rate, rate));
        }
        ts_random_direction(&r, ts_uniform_in(&r, 0.0, 3.0 * 9.81), smp.accel);
        ts_random_direction(&r, ts_uniform_in(&r, 1.0, 100.0), smp.mag);
        smp.valid = ATT_HAS_GYRO | ATT_HAS_ACCEL | ATT_HAS_MAG;
        st = att_step(&f, &smp, NULL);
        if (st == EKF_OK) {
            ++fused;
        }
        if (ekf_status_is_error(st)) {
            printf("step %ld: refused (%s)\n", k, ekf_status_str(st));
            TEST_FAIL();
        }
        if (fx_count_saturations() != 0u) {
            printf("step %ld: %lu saturation events\n", k, (unsigned long)fx_count_saturations());
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
    printf("%ld steps in the envelope (%s, %.1f rad/s, gimbal limit %.2f deg): saturations %lu, all fused %ld, "
           "covariance repairs %lu, numeric refusals %lu, smallest Cholesky pivot %.3e\n",
           STEPS, EKF_SCALAR_NAME, rate, ekf_to_double(set.gimbal_limit) * 57.29577951308232,
           (unsigned long)fx_count_saturations(), fused, (unsigned long)att_diag(&f)->cov_repairs,
           (unsigned long)att_diag(&f)->numeric, min_pivot);
    TEST_ASSERT_TRUE(fused > 0);
    TEST_ASSERT_TRUE_MESSAGE(att_diag(&f)->cov_repairs <= MAX_REPAIRS, "the guard repaired P too often");
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_envelope_never_saturates);
    return UNITY_END();
}
