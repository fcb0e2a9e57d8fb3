/*
 * test_ekf_math.c - the float sin, cos, sincos, atan2 and sqrt of ekf_math.h against a
 * double-precision reference, at the error bounds the header states.
 *
 * Host: every 127th float of [-4, 4] (the filter's range, about 17 million arguments) plus
 * every float near the zeros and extrema there, large arguments up to FLT_MAX including the
 * float nearest to a multiple of pi/2 (16367173 * 2^72), 1 million atan2 pairs and every
 * 61st positive float for sqrt. On target (ATTEKF_BARE_METAL) the same checks with fewer
 * points: the reference is soft double there.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ekf_math.h"
#include "testsim.h"
#include "unity.h"

#define SINCOS_MAX_ULP 2.0
#define ATAN2_MAX_ULP 3.0

#if defined(ATTEKF_BARE_METAL)
#define RANGE_STRIDE_DEFAULT 262147u /* about 8,000 arguments of [-4, 4] */
#define NEAR_COUNT 64u
#define RANDOM_COUNT 4000
#define SQRT_STRIDE_DEFAULT 1048573u
#else
#define RANGE_STRIDE_DEFAULT 127u
#define NEAR_COUNT 4096u
#define RANDOM_COUNT 1000000
#define SQRT_STRIDE_DEFAULT 61u
#endif

/* ATTEKF_MATH_EXHAUSTIVE=1 in the environment (host): every float of [-4, 4] and every
 * positive float for sqrt (about 10 minutes; the figures in docs/performance.md). */
static uint32_t range_stride = RANGE_STRIDE_DEFAULT, sqrt_stride = SQRT_STRIDE_DEFAULT;

void setUp(void) {}
void tearDown(void) {}

static uint32_t bits_of(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static float float_of(uint32_t u)
{
    float x;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* Error of got in units of the float spacing at the exact value ref (the ULP of ref's
 * binade, subnormal spacing below FLT_MIN). */
static double ulp_error(float got, double ref)
{
    int e;
    double ulp;
    if (ref == 0.0) {
        return ((double)got == 0.0) ? 0.0 : 1e30;
    }
    (void)frexp(ref, &e);
    ulp = ldexp(1.0, (e - 24 < -149) ? -149 : e - 24);
    return fabs((double)got - ref) / ulp;
}

typedef struct {
    double worst;
    float at;
    const char *what;
} worst_t;

static void track(worst_t *w, double err, float x)
{
    if (err > w->worst || err != err) {
        w->worst = (err != err) ? 1e30 : err;
        w->at = x;
    }
}

static void check_sin_cos(float x, worst_t *ws, worst_t *wc)
{
    track(ws, ulp_error(ekf_sinf(x), sin((double)x)), x);
    track(wc, ulp_error(ekf_cosf(x), cos((double)x)), x);
}

static void report(const worst_t *w, double bound)
{
    char msg[120];
    (void)snprintf(msg, sizeof msg, "%s: %.3f ULP at %.9g (bound %.1f)", w->what, w->worst, (double)w->at, bound);
    printf("%s\n", msg);
    TEST_ASSERT_TRUE_MESSAGE(w->worst <= bound, msg);
}

/* Every range_stride-th float of [-4, 4], both signs. */
static void test_sin_cos_filter_range(void)
{
    worst_t ws = {0.0, 0.0f, "sin on [-4, 4]"}, wc = {0.0, 0.0f, "cos on [-4, 4]"};
    const uint32_t top = bits_of(4.0f);
    uint32_t u;
    for (u = 0u; u <= top; u += range_stride) {
        check_sin_cos(float_of(u), &ws, &wc);
        check_sin_cos(-float_of(u), &ws, &wc);
    }
    report(&ws, SINCOS_MAX_ULP);
    report(&wc, SINCOS_MAX_ULP);
}

/* Every float within NEAR_COUNT of k pi/2 (k = -2..2), where the result is smallest relative
 * to the reduction's rounding, and near 4 and 8 (the ends of the short reduction). */
static void test_sin_cos_near_multiples_of_half_pi(void)
{
    static const float centres[] = {1.57079637f, 3.14159274f, 4.71238899f, 4.0f, 8.0f};
    worst_t ws = {0.0, 0.0f, "sin near k pi/2"}, wc = {0.0, 0.0f, "cos near k pi/2"};
    unsigned i;
    uint32_t d;
    for (i = 0; i < sizeof centres / sizeof centres[0]; ++i) {
        const uint32_t c = bits_of(centres[i]);
        for (d = 0u; d < NEAR_COUNT; ++d) {
            check_sin_cos(float_of(c + d), &ws, &wc);
            check_sin_cos(float_of(c - d), &ws, &wc);
            check_sin_cos(-float_of(c + d), &ws, &wc);
            check_sin_cos(-float_of(c - d), &ws, &wc);
        }
    }
    report(&ws, SINCOS_MAX_ULP);
    report(&wc, SINCOS_MAX_ULP);
}

/* Large arguments (the integer reduction): random magnitudes from 4 to FLT_MAX, and the
 * float nearest to a multiple of pi/2, 16367173 * 2^72 (2^-29.9 of a quadrant away). */
static void test_sin_cos_large_arguments(void)
{
    worst_t ws = {0.0, 0.0f, "sin, |x| >= 4"}, wc = {0.0, 0.0f, "cos, |x| >= 4"};
    ts_rng_t rng;
    int i;
    const float hard = ldexpf(16367173.0f, 72);
    uint32_t d;
    ts_rng_seed(&rng, 20261201u);
    for (i = 0; i < RANDOM_COUNT; ++i) {
        const uint32_t u = bits_of(4.0f) + (uint32_t)(ts_uniform_in(&rng, 0.0, 1.0) * (double)(0x7F7FFFFFu - 0x40800000u));
        check_sin_cos(float_of(u), &ws, &wc);
        check_sin_cos(-float_of(u), &ws, &wc);
    }
    for (d = 0u; d < 64u; ++d) {
        check_sin_cos(float_of(bits_of(hard) + d), &ws, &wc);
        check_sin_cos(float_of(bits_of(hard) - d), &ws, &wc);
        check_sin_cos(float_of(0x7F7FFFFFu - d), &ws, &wc); /* up to FLT_MAX */
    }
    report(&ws, SINCOS_MAX_ULP);
    report(&wc, SINCOS_MAX_ULP);
}

static void test_sin_cos_special_values(void)
{
    static const float tiny[] = {1e-30f, -1e-30f, 1.4e-45f, 3e-6f, -2e-5f};
    unsigned i;
    float s, c;
    TEST_ASSERT_TRUE(isnan(ekf_sinf(INFINITY)));
    TEST_ASSERT_TRUE(isnan(ekf_sinf(-INFINITY)));
    TEST_ASSERT_TRUE(isnan(ekf_cosf(INFINITY)));
    TEST_ASSERT_TRUE(isnan(ekf_sinf(NAN)));
    TEST_ASSERT_TRUE(isnan(ekf_cosf(NAN)));
    ekf_sincosf(NAN, &s, &c);
    TEST_ASSERT_TRUE(isnan(s) && isnan(c));
    TEST_ASSERT_EQUAL_HEX32(bits_of(0.0f), bits_of(ekf_sinf(0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(-0.0f), bits_of(ekf_sinf(-0.0f)));
    TEST_ASSERT_EQUAL_FLOAT(1.0f, ekf_cosf(0.0f));
    TEST_ASSERT_EQUAL_FLOAT(1.0f, ekf_cosf(-0.0f));
    for (i = 0; i < sizeof tiny / sizeof tiny[0]; ++i) {
        TEST_ASSERT_TRUE(ulp_error(ekf_sinf(tiny[i]), sin((double)tiny[i])) <= SINCOS_MAX_ULP);
    }
}

/* ekf_sincosf is ekf_sinf and ekf_cosf, bit for bit, on both reductions. */
static void test_sincos_equals_sin_and_cos(void)
{
    ts_rng_t rng;
    int i;
    ts_rng_seed(&rng, 7u);
    for (i = 0; i < RANDOM_COUNT / 10; ++i) {
        const float x = (float)((i & 1) ? ts_uniform_in(&rng, -4.0, 4.0) : ts_uniform_in(&rng, -1e6, 1e6));
        float s, c;
        ekf_sincosf(x, &s, &c);
        TEST_ASSERT_EQUAL_HEX32(bits_of(ekf_sinf(x)), bits_of(s));
        TEST_ASSERT_EQUAL_HEX32(bits_of(ekf_cosf(x)), bits_of(c));
    }
}

/* Points on circles of radii 2^-40..2^40 at uniform angles, and random finite bit patterns
 * (any ratio, subnormals, huge values). */
static void test_atan2_error_bound(void)
{
    worst_t w = {0.0, 0.0f, "atan2"};
    ts_rng_t rng;
    int i;
    float worst_x = 0.0f;
    ts_rng_seed(&rng, 11u);
    for (i = 0; i < RANDOM_COUNT; ++i) {
        float y, x;
        double before;
        if (i & 1) {
            const double th = ts_uniform_in(&rng, -3.141592653589793, 3.141592653589793);
            const double r = ldexp(1.0, (int)ts_uniform_in(&rng, -40.0, 40.0));
            y = (float)(r * sin(th));
            x = (float)(r * cos(th));
        } else {
            y = float_of((uint32_t)(ts_uniform_in(&rng, 0.0, 1.0) * 4294967295.0));
            x = float_of((uint32_t)(ts_uniform_in(&rng, 0.0, 1.0) * 4294967295.0));
            if (!isfinite(y) || !isfinite(x)) {
                continue;
            }
        }
        before = w.worst;
        track(&w, ulp_error(ekf_atan2f(y, x), atan2((double)y, (double)x)), y);
        if (w.worst > before) {
            worst_x = x;
        }
    }
    printf("atan2: worst at x = %.9g\n", (double)worst_x);
    report(&w, ATAN2_MAX_ULP);
}

/* C99 F.9.1.4 special values, and the range [-pi_f, pi_f] like the C library. */
static void test_atan2_special_values(void)
{
    const float pi_f = 3.14159274f, pio2_f = 1.57079637f, pio4_f = 0.785398185f;
    TEST_ASSERT_EQUAL_HEX32(bits_of(0.0f), bits_of(ekf_atan2f(0.0f, 0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(-0.0f), bits_of(ekf_atan2f(-0.0f, 0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pi_f), bits_of(ekf_atan2f(0.0f, -0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(-pi_f), bits_of(ekf_atan2f(-0.0f, -0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pi_f), bits_of(ekf_atan2f(0.0f, -1.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(-pi_f), bits_of(ekf_atan2f(-0.0f, -1.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pio2_f), bits_of(ekf_atan2f(1.0f, 0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(-pio2_f), bits_of(ekf_atan2f(-1.0f, -0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pio4_f), bits_of(ekf_atan2f(INFINITY, INFINITY)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(-3.0f * pio4_f), bits_of(ekf_atan2f(-INFINITY, -INFINITY)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pi_f), bits_of(ekf_atan2f(1.0f, -INFINITY)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(0.0f), bits_of(ekf_atan2f(1.0f, INFINITY)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pio2_f), bits_of(ekf_atan2f(INFINITY, -5.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pio4_f), bits_of(ekf_atan2f(FLT_MAX, FLT_MAX)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(pi_f), bits_of(ekf_atan2f(FLT_MIN * 1e-7f, -FLT_MAX)));
    TEST_ASSERT_TRUE(isnan(ekf_atan2f(NAN, 1.0f)));
    TEST_ASSERT_TRUE(isnan(ekf_atan2f(1.0f, NAN)));
    TEST_ASSERT_TRUE(ekf_atan2f(-1e-30f, -1.0f) >= -pi_f);
}

/* The software square root is correctly rounded: identical to the C library's sqrtf (IEEE
 * sqrt, correctly rounded everywhere this runs) on every sqrt_stride-th positive float,
 * every subnormal near FLT_MIN and 0, and the special values; ekf_sqrtf too. */
static void test_sqrt_correctly_rounded(void)
{
    uint32_t u, d, mismatches = 0u, first = 0u;
    for (u = 0u; u < 0x7F800000u; u += sqrt_stride) {
        const float a = float_of(u);
        if (bits_of(ekf_sqrtf_soft(a)) != bits_of(sqrtf(a)) || bits_of(ekf_sqrtf(a)) != bits_of(sqrtf(a))) {
            if (mismatches++ == 0u) {
                first = u;
            }
        }
    }
    for (d = 0u; d < 4096u; ++d) {
        const float lo = float_of(d), mid = float_of(0x00800000u - 2048u + d);
        mismatches += (bits_of(ekf_sqrtf_soft(lo)) != bits_of(sqrtf(lo))) ? 1u : 0u;
        mismatches += (bits_of(ekf_sqrtf_soft(mid)) != bits_of(sqrtf(mid))) ? 1u : 0u;
        mismatches += (bits_of(ekf_sqrtf_soft(float_of(0x7F7FFFFFu - d))) != bits_of(sqrtf(float_of(0x7F7FFFFFu - d))))
                          ? 1u : 0u;
    }
    if (mismatches > 0u) {
        printf("sqrt: %lu mismatches, first at 0x%08lx\n", (unsigned long)mismatches, (unsigned long)first);
    }
    TEST_ASSERT_EQUAL_UINT32(0u, mismatches);
    TEST_ASSERT_EQUAL_HEX32(bits_of(-0.0f), bits_of(ekf_sqrtf_soft(-0.0f)));
    TEST_ASSERT_EQUAL_HEX32(bits_of(0.0f), bits_of(ekf_sqrtf_soft(0.0f)));
    TEST_ASSERT_TRUE(isnan(ekf_sqrtf_soft(-1.0f)));
    TEST_ASSERT_TRUE(isnan(ekf_sqrtf_soft(-FLT_MIN)));
    TEST_ASSERT_TRUE(isnan(ekf_sqrtf_soft(NAN)));
    TEST_ASSERT_TRUE(isinf(ekf_sqrtf_soft(INFINITY)));
    TEST_ASSERT_TRUE(isnan(ekf_sqrtf(-1.0f)));
}

int main(void)
{
#if !defined(ATTEKF_BARE_METAL)
    const char *all = getenv("ATTEKF_MATH_EXHAUSTIVE");
    if (all != NULL && strcmp(all, "1") == 0) {
        range_stride = sqrt_stride = 1u;
    }
#endif
    UNITY_BEGIN();
    RUN_TEST(test_sin_cos_filter_range);
    RUN_TEST(test_sin_cos_near_multiples_of_half_pi);
    RUN_TEST(test_sin_cos_large_arguments);
    RUN_TEST(test_sin_cos_special_values);
    RUN_TEST(test_sincos_equals_sin_and_cos);
    RUN_TEST(test_atan2_error_bound);
    RUN_TEST(test_atan2_special_values);
    RUN_TEST(test_sqrt_correctly_rounded);
    return UNITY_END();
}
