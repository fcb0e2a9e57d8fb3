/*
 * test_fixed_edges.c - the fixed-point helpers at the edges of their range, as ekf_fixed.h
 * states them: an exact result outside the range is the infinity of its sign and one counted
 * saturation; an infinite operand gives a non-finite result without a new count; the -inf
 * pattern never comes out of a finite input uncounted. Fixed-point build only.
 */
#include <float.h>
#include <math.h>

#include "ekf_fixed.h"
#include "fx_count.h"
#include "unity.h"

void setUp(void) { fx_count_reset(); }
void tearDown(void) {}

#define MAX_FINITE (EKF_FX_INF - 1)
#define MIN_FINITE (EKF_FX_NINF + 1)

/* result, and the number of saturations the call counted */
static void expect(ekf_fx_t got, ekf_fx_t want, uint32_t counted)
{
    TEST_ASSERT_TRUE(got == want);
    TEST_ASSERT_EQUAL_UINT32(counted, fx_count_saturations());
    fx_count_reset();
}

static void test_floor_never_gives_an_uncounted_minus_inf(void)
{
    const ekf_fx_t one = EKF_FX_ONE;
    int k;
    /* the most negative finite values: their floor is below the range */
    for (k = 0; k < 5; ++k) {
        const ekf_fx_t r = ekf_fx_floor(MIN_FINITE + k);
        TEST_ASSERT_TRUE(r == EKF_FX_NINF);
        TEST_ASSERT_EQUAL_UINT32(1u, fx_count_saturations());
        fx_count_reset();
    }
    /* the most negative finite integer is its own floor; one LSB above it floors to it */
    {
        const ekf_fx_t lowest_int = (ekf_fx_t)((uint64_t)(MIN_FINITE + one) & ~((uint64_t)one - 1u));
        expect(ekf_fx_floor(lowest_int), lowest_int, 0u);
        expect(ekf_fx_floor(lowest_int + 1), lowest_int, 0u);
        TEST_ASSERT_TRUE(ekf_fx_isfinite(lowest_int));
    }
    /* ordinary values and the infinities themselves */
    expect(ekf_fx_floor(EKF_FX_C(-1.5)), EKF_FX_C(-2.0), 0u);
    expect(ekf_fx_floor(EKF_FX_C(2.75)), EKF_FX_C(2.0), 0u);
    expect(ekf_fx_floor(MAX_FINITE), (ekf_fx_t)((uint64_t)MAX_FINITE & ~((uint64_t)one - 1u)), 0u);
    expect(ekf_fx_floor(EKF_FX_INF), EKF_FX_INF, 0u);
    expect(ekf_fx_floor(EKF_FX_NINF), EKF_FX_NINF, 0u);
}

static void test_infinite_operands_are_not_counted(void)
{
    const ekf_fx_t two = EKF_FX_C(2.0), zero = 0;
    expect(ekf_fx_add(EKF_FX_INF, two), EKF_FX_INF, 0u);
    expect(ekf_fx_add(EKF_FX_NINF, two), EKF_FX_NINF, 0u);
    expect(ekf_fx_add(EKF_FX_INF, EKF_FX_NINF), EKF_FX_INF, 0u); /* inf - inf: not a number */
    expect(ekf_fx_sub(two, EKF_FX_INF), EKF_FX_NINF, 0u);
    expect(ekf_fx_mul(EKF_FX_INF, two), EKF_FX_INF, 0u);
    expect(ekf_fx_mul(EKF_FX_NINF, two), EKF_FX_NINF, 0u);
    expect(ekf_fx_mul(EKF_FX_INF, zero), EKF_FX_INF, 0u); /* 0 * inf: not a number */
    expect(ekf_fx_div(EKF_FX_INF, two), EKF_FX_INF, 0u);
    expect(ekf_fx_div(EKF_FX_NINF, two), EKF_FX_NINF, 0u);
    expect(ekf_fx_div(EKF_FX_INF, ekf_fx_neg(two)), EKF_FX_NINF, 0u);
    expect(ekf_fx_div(EKF_FX_INF, zero), EKF_FX_INF, 0u);
    expect(ekf_fx_div(EKF_FX_NINF, zero), EKF_FX_NINF, 0u);
    expect(ekf_fx_div(two, EKF_FX_INF), 0, 0u);
    expect(ekf_fx_div(EKF_FX_INF, EKF_FX_INF), EKF_FX_INF, 0u);
    expect(ekf_fx_sqrt(EKF_FX_INF), EKF_FX_INF, 0u);
    expect(ekf_fx_sqrt(EKF_FX_NINF), EKF_FX_INF, 0u);
    expect(ekf_fx_sqrt(INT64_MIN), EKF_FX_INF, 0u); /* reads as -inf */
    expect(ekf_fx_sin(EKF_FX_NINF), EKF_FX_INF, 0u);
    expect(ekf_fx_cos(EKF_FX_INF), EKF_FX_INF, 0u);
    expect(ekf_fx_atan2(EKF_FX_INF, two), EKF_FX_INF, 0u);
    expect(ekf_fx_floor(EKF_FX_NINF), EKF_FX_NINF, 0u);
}

static void test_finite_operands_out_of_range_are_counted(void)
{
    const ekf_fx_t two = EKF_FX_C(2.0);
    expect(ekf_fx_add(MAX_FINITE, two), EKF_FX_INF, 1u);
    expect(ekf_fx_sub(MIN_FINITE, two), EKF_FX_NINF, 1u);
    expect(ekf_fx_mul(MAX_FINITE, two), EKF_FX_INF, 1u);
    expect(ekf_fx_div(two, 0), EKF_FX_INF, 1u);
    expect(ekf_fx_div(ekf_fx_neg(two), 0), EKF_FX_NINF, 1u);
    expect(ekf_fx_sqrt(ekf_fx_neg(two)), EKF_FX_INF, 1u);
}

static void test_conversions_of_large_finite_values_are_counted(void)
{
    /* 3.402e38f is finite (FLT_MAX is 3.4028235e38): a counted saturation, not an
     * uncounted infinity */
    expect(ekf_fx_from_float(3.402e38f), EKF_FX_INF, 1u);
    expect(ekf_fx_from_float(-3.402e38f), EKF_FX_NINF, 1u);
    expect(ekf_fx_from_float(FLT_MAX), EKF_FX_INF, 1u);
    expect(ekf_fx_from_float(1e30f), EKF_FX_INF, 1u);
    expect(ekf_fx_from_double(1.5e308), EKF_FX_INF, 1u);
    expect(ekf_fx_from_double(-DBL_MAX), EKF_FX_NINF, 1u);
    expect(ekf_fx_from_double(1e20), EKF_FX_INF, 1u);
    /* infinities and NaN: non-finite, not counted */
    expect(ekf_fx_from_float(HUGE_VALF), EKF_FX_INF, 0u);
    expect(ekf_fx_from_float(-HUGE_VALF), EKF_FX_NINF, 0u);
    expect(ekf_fx_from_float(NAN), EKF_FX_INF, 0u);
    expect(ekf_fx_from_double(HUGE_VAL), EKF_FX_INF, 0u);
    expect(ekf_fx_from_double(-HUGE_VAL), EKF_FX_NINF, 0u);
    expect(ekf_fx_from_double((double)NAN), EKF_FX_INF, 0u);
    /* in range: exact */
    expect(ekf_fx_from_double(-2.5), EKF_FX_C(-2.5), 0u);
    expect(ekf_fx_from_float(0.25f), EKF_FX_C(0.25), 0u);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_floor_never_gives_an_uncounted_minus_inf);
    RUN_TEST(test_infinite_operands_are_not_counted);
    RUN_TEST(test_finite_operands_out_of_range_are_counted);
    RUN_TEST(test_conversions_of_large_finite_values_are_counted);
    return UNITY_END();
}
