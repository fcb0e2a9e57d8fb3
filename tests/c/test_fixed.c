/*
 * test_fixed.c - the Q-format arithmetic of the fixed-point build (firmware/ekf/ekf_fixed.c)
 * against double precision: exactness of multiply and divide, the stated error bounds of
 * sqrt, sin, cos and atan2 (docs/fixed_point.md), saturation (counted, infinite, refused
 * by the finiteness checks) and the filter's generic pieces in fixed point. Built for the
 * FIXED scalar only, on the host and, in the cortex-m3-fixed preset, under QEMU.
 */
#include <math.h>
#include <stdio.h>

#include "ekf.h"
#include "fx_count.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) { fx_count_reset(); }
void tearDown(void) {}

#define LSB (1.0 / (double)EKF_FX_ONE)
/* Random trials per check; a tenth under QEMU (soft double in the reference is slow). */
#if defined(ATTEKF_BARE_METAL)
#define TRIALS 10000
#else
#define TRIALS 100000
#endif

/* Stated bounds (ekf_fixed.h, docs/fixed_point.md). */
#define SIN_COS_ABS 9.313225746154785e-10 /* 2^-30 */
#define ATAN2_ABS 9.313225746154785e-10
#define SQRT_REL 4.7e-10 /* 2^-31 */

static double d(ekf_scalar_t a) { return ekf_to_double(a); }

/* Random value with at most 26 significant bits and magnitude about 2^(e - FRAC) for e in
 * [lo, hi]: products of two such values are exact in double. */
static ekf_scalar_t random_short(ts_rng_t *r, int lo, int hi)
{
    const int e = lo + (int)(ts_uniform(r) * (double)(hi - lo + 1));
    const int64_t m = (int64_t)(ts_uniform(r) * 67108864.0); /* < 2^26 */
    const int64_t v = (e >= 26) ? (m << (e - 26)) : (m >> (26 - e));
    return (ts_uniform(r) < 0.5) ? -v : v;
}

/* Exact round half up (ties toward +inf) of a double holding an integer + fraction. */
static double round_half_up(double v) { return floor(v + 0.5); }

static void test_constants_and_conversions(void)
{
    TEST_ASSERT_TRUE(EKF_C(1.5) == (ekf_scalar_t)3 << (EKF_FX_FRAC - 1));
    TEST_ASSERT_TRUE(EKF_C(-0.25) == -(EKF_FX_ONE / 4));
    TEST_ASSERT_TRUE(EKF_C(1e-30) == 0);
    TEST_ASSERT_TRUE(ekf_from_int(-3) == EKF_C(-3));
    TEST_ASSERT_TRUE(ekf_from_double(2.5) == EKF_C(2.5));
    TEST_ASSERT_TRUE(ekf_from_float(-9.81f) == ekf_from_double((double)-9.81f));
    TEST_ASSERT_TRUE(fabs(d(EKF_C(0.1)) - 0.1) <= 0.5 * LSB);
    TEST_ASSERT_TRUE(ekf_to_float(EKF_C(0.375)) == 0.375f);
    /* non-finite inputs become non-finite values, uncounted */
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_from_double((double)NAN)));
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_from_double(-(double)INFINITY)));
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_from_float(NAN)));
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
    TEST_ASSERT_TRUE(isinf(ekf_to_double(ekf_from_double((double)INFINITY))));
    /* finite but out of range: saturated and counted */
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_from_double(1e12)));
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_from_int(INT32_MIN)));
    TEST_ASSERT_EQUAL_UINT32(2u, fx_count_saturations());
}

static void test_saturation_counted_and_propagated(void)
{
    const ekf_scalar_t big = (ekf_scalar_t)1 << 62; /* half the range */
    const ekf_scalar_t root = ekf_sqrt(big);          /* root * root * 4: out of range */
    ekf_scalar_t s;
    s = ekf_add(big, big);
    TEST_ASSERT_FALSE(ekf_isfinite(s));
    TEST_ASSERT_TRUE(s > 0);
    TEST_ASSERT_EQUAL_UINT32(1u, fx_count_saturations());
    /* an infinite operand: non-finite result, no new count */
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_sub(s, big)));
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_mul(s, EKF_C(1e-6))));
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_mul(s, EKF_C(0))));   /* 0 * inf: not a number */
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_add(s, ekf_neg(s)))); /* inf - inf */
    TEST_ASSERT_TRUE(ekf_div(EKF_C(3), s) == 0);              /* x / inf = 0 */
    TEST_ASSERT_EQUAL_UINT32(1u, fx_count_saturations());
    /* products, quotients, negative overflow, division by zero, sqrt of a negative */
    TEST_ASSERT_TRUE(ekf_mul(ekf_mul(root, EKF_C(-2)), ekf_mul(root, EKF_C(2))) == EKF_FX_NINF);
    TEST_ASSERT_TRUE(ekf_div(big, EKF_C(0.25)) == EKF_FX_INF);
    TEST_ASSERT_TRUE(ekf_div(EKF_C(-1.0), EKF_C(0)) == EKF_FX_NINF);
    TEST_ASSERT_TRUE(ekf_add(ekf_neg(big), ekf_neg(big)) == EKF_FX_NINF);
    TEST_ASSERT_FALSE(ekf_isfinite(ekf_sqrt(EKF_C(-1.0))));
    TEST_ASSERT_EQUAL_UINT32(6u, fx_count_saturations());
    /* the core's finiteness checks refuse saturated values */
    {
        ekf_scalar_t v[3] = {EKF_C(1), EKF_C(2), EKF_C(3)};
        TEST_ASSERT_EQUAL_INT(1, ekf_all_finite(v, 3));
        v[1] = s;
        TEST_ASSERT_EQUAL_INT(0, ekf_all_finite(v, 3));
    }
    /* in range: nothing counted, exact */
    fx_count_reset();
    TEST_ASSERT_TRUE(ekf_add(EKF_C(8000000.0), EKF_C(388607.0)) == EKF_C(8388607.0));
    TEST_ASSERT_TRUE(ekf_mul(EKF_C(2896.0), EKF_C(2896.0)) == EKF_C(8386816.0));
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
}

/* mul is the correctly rounded product, ties toward +inf; exact check on operands whose
 * product double holds exactly (the fast path for |a|, |b| < 2^47 and the slow one beyond),
 * bounded check on full-width operands. */
static void test_mul_correctly_rounded(void)
{
    ts_rng_t r;
    int k;
    ts_rng_seed(&r, 1);
    for (k = 0; k < TRIALS; ++k) {
        const ekf_scalar_t a = random_short(&r, 0, 60), b = random_short(&r, 0, 60);
        const double exact = (double)a * (double)b / (double)EKF_FX_ONE; /* exact */
        if (fabs(exact) >= 9.2e18) {
            continue;
        }
        if (!(ekf_mul(a, b) == (ekf_scalar_t)round_half_up(exact))) {
            printf("mul %lld * %lld: got %lld, want %.1f\n", (long long)a, (long long)b, (long long)ekf_mul(a, b), exact);
            TEST_FAIL();
        }
        /* odd, except at an exact tie (rounded up either way) */
        TEST_ASSERT_TRUE(ekf_mul(ekf_neg(a), b) == ekf_neg(ekf_mul(a, b)) || exact - floor(exact) == 0.5);
        /* the multiply-add rounds its product the same way */
        TEST_ASSERT_TRUE(ekf_mac(EKF_C(1), a, b) == ekf_add(EKF_C(1), ekf_mul(a, b)));
    }
    for (k = 0; k < TRIALS; ++k) {
        const ekf_scalar_t a = ekf_from_double(ts_uniform_in(&r, -2896.0, 2896.0));
        const ekf_scalar_t b = ekf_from_double(ts_uniform_in(&r, -2896.0, 2896.0));
        const double want = d(a) * d(b);
        TEST_ASSERT_TRUE(fabs(d(ekf_mul(a, b)) - want) <= 0.5 * LSB + fabs(want) * 3e-16);
    }
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
}

static void test_div_correctly_rounded(void)
{
    ts_rng_t r;
    int k, n = 0;
    ts_rng_seed(&r, 2);
    for (k = 0; k < TRIALS; ++k) {
        const ekf_scalar_t a = random_short(&r, 0, 62), b = random_short(&r, 1, 62);
        double want;
        ekf_scalar_t q;
        if (b == 0) {
            continue;
        }
        want = (double)a / (double)b * (double)EKF_FX_ONE;
        if (fabs(want) >= 9.2e18) {
            continue;
        }
        q = ekf_div(a, b);
        /* |q - a 2^F / b| <= 1/2 LSB, up to double's own rounding of want */
        if (!(fabs((double)q - want) <= 0.5 + fabs(want) * 3e-16)) {
            printf("div %lld / %lld: got %lld, want %.3f\n", (long long)a, (long long)b, (long long)q, want);
            TEST_FAIL();
        }
        ++n;
    }
    TEST_ASSERT_TRUE(n > TRIALS / 2);
    TEST_ASSERT_TRUE(ekf_div(EKF_C(1), EKF_C(3)) == (EKF_FX_ONE + 1) / 3);
    TEST_ASSERT_TRUE(ekf_div(EKF_C(-7), EKF_C(2)) == EKF_C(-3.5));
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
}

/* The restoring long division the library used before its reciprocal-based one, as the
 * reference: q = round(|a| 2^F / |b|) half away from zero, the sign applied after. */
static ekf_scalar_t div_reference(ekf_scalar_t a, ekf_scalar_t b)
{
    uint64_t ua = (a < 0) ? (uint64_t)0 - (uint64_t)a : (uint64_t)a, ub = (b < 0) ? (uint64_t)0 - (uint64_t)b : (uint64_t)b;
    uint64_t q = ua / ub, r = ua % ub;
    int i;
    if ((q >> (63 - EKF_FX_FRAC)) != 0u) {
        return ((a < 0) != (b < 0)) ? EKF_FX_NINF : EKF_FX_INF;
    }
    for (i = 0; i < EKF_FX_FRAC; ++i) {
        q <<= 1;
        r <<= 1;
        if (r >= ub) {
            r -= ub;
            q |= 1u;
        }
    }
    if (r >= ub - r) {
        ++q;
    }
    if (q >= (uint64_t)EKF_FX_INF) {
        return ((a < 0) != (b < 0)) ? EKF_FX_NINF : EKF_FX_INF;
    }
    return ((a < 0) != (b < 0)) ? -(ekf_scalar_t)q : (ekf_scalar_t)q;
}

/* Random raw value with a random bit length 1 .. 63 and a random sign. */
static ekf_scalar_t random_raw(ts_rng_t *r)
{
    const int bits = 1 + (int)(ts_uniform(r) * 62.0);
    uint64_t v = ((uint64_t)(ts_uniform(r) * 4294967296.0) << 32) | (uint64_t)(ts_uniform(r) * 4294967296.0);
    v = (v >> (64 - bits)) | ((uint64_t)1 << (bits - 1));
    return (ts_uniform(r) < 0.5) ? -(ekf_scalar_t)v : (ekf_scalar_t)v;
}

/* The division equals the reference bit for bit over operands of every size (the
 * quotient's two 32-bit digits, their corrections, the rounding, the saturation). */
static void test_div_equals_long_division(void)
{
    ts_rng_t r;
    int k;
    ts_rng_seed(&r, 12);
    for (k = 0; k < TRIALS; ++k) {
        const ekf_scalar_t a = random_raw(&r), b = random_raw(&r);
        const ekf_scalar_t want = div_reference(a, b);
        ekf_scalar_t got;
        fx_count_reset();
        got = ekf_div(a, b);
        if (got != want) {
            printf("div raw %lld / %lld: got %lld, want %lld\n", (long long)a, (long long)b, (long long)got, (long long)want);
            TEST_FAIL();
        }
        TEST_ASSERT_EQUAL_UINT32(ekf_isfinite(want) ? 0u : 1u, fx_count_saturations());
    }
    /* the divisor's top word all ones (the reciprocal at its clamp) and at its smallest */
    TEST_ASSERT_TRUE(ekf_div(EKF_C(1), (ekf_scalar_t)0x7FFFFFFFFFFFFFFELL) == div_reference(EKF_C(1), (ekf_scalar_t)0x7FFFFFFFFFFFFFFELL));
    TEST_ASSERT_TRUE(ekf_div(EKF_C(3), (ekf_scalar_t)0x4000000000000000LL) == div_reference(EKF_C(3), (ekf_scalar_t)0x4000000000000000LL));
}

/* The 32-bit reciprocal and reciprocal square root the division, the square root and the
 * covariance use, against their stated bounds (ekf_fixed.h): 2^63 / d from below within 2
 * (measured 1), 2^47 / sqrt(d) within -2 .. +3 (measured -1.01 .. +2.46). */
static void test_recip32_rsqrt32_bounds(void)
{
    ts_rng_t r;
    int k;
    ts_rng_seed(&r, 13);
    for (k = 0; k < 2 * TRIALS; ++k) {
        const uint32_t d = 0x80000000u | (uint32_t)(ts_uniform(&r) * 2147483648.0);
        const uint32_t e = 0x40000000u + (uint32_t)(ts_uniform(&r) * 3221225472.0); /* [2^30, 2^32) */
        const double want_r = 9223372036854775808.0 / (double)d;
        const double want_s = 140737488355328.0 / sqrt((double)e);
        const double gr = (double)ekf_fx_recip32(d), gs = (double)ekf_fx_rsqrt32(e);
        if (!((gr <= want_r && gr >= want_r - 2.0) || (want_r >= 4294967295.0 && gr == 4294967295.0))) {
            printf("recip32(%lu) = %.1f, want %.3f\n", (unsigned long)d, gr, want_r);
            TEST_FAIL();
        }
        if (!((gs <= want_s + 3.0 && gs >= want_s - 2.0) || (want_s >= 4294967295.0 && gs == 4294967295.0))) {
            printf("rsqrt32(%lu) = %.1f, want %.3f\n", (unsigned long)e, gs, want_s);
            TEST_FAIL();
        }
    }
    TEST_ASSERT_TRUE(ekf_fx_recip32(0x80000000u) == 0xFFFFFFFFu);
    TEST_ASSERT_TRUE(ekf_fx_recip32(0xFFFFFFFFu) <= 0x80000000u && ekf_fx_recip32(0xFFFFFFFFu) >= 0x80000000u - 2u);
    TEST_ASSERT_TRUE(ekf_fx_rsqrt32(0x40000000u) >= 0xFFFFFFFDu); /* 2^32, clamped */
}

static void test_sqrt_error_bound(void)
{
    ts_rng_t r;
    double worst = 0.0;
    int k;
    ts_rng_seed(&r, 3);
    TEST_ASSERT_TRUE(ekf_sqrt(0) == 0);
    TEST_ASSERT_TRUE(ekf_sqrt(EKF_C(4)) == EKF_C(2));
    TEST_ASSERT_TRUE(ekf_sqrt(EKF_C(96.28515625)) == EKF_C(9.8125)); /* 9.8125^2, exact in Q format */
    /* 9.81 from its square: EKF_C rounds 96.2361 by <= 1/2 LSB, which moves the root by
     * 1/2 LSB / (2 x 9.81); then the stated bound */
    TEST_ASSERT_TRUE(fabs(d(ekf_sqrt(EKF_C(96.2361))) - 9.81) <= SQRT_REL * 9.81 + LSB + 0.5 * LSB / 19.62);
#if (EKF_FX_FRAC % 2) == 0
    /* Perfect squares at every scale are exact, an integer reference: the raw value q^2 is
     * the number q^2 2^-F, whose root q 2^-F/2 is the raw value q 2^(F/2). */
    for (k = 0; k < TRIALS; ++k) {
        const int64_t q = 1 + (int64_t)(ts_uniform(&r) * 3037000498.0); /* q^2 < 2^63 */
        const ekf_scalar_t want = (ekf_scalar_t)(q << (EKF_FX_FRAC / 2));
        if (ekf_sqrt((ekf_scalar_t)(q * q)) != want) {
            printf("sqrt(raw %lld^2) = raw %lld, want %lld\n", (long long)q,
                   (long long)ekf_sqrt((ekf_scalar_t)(q * q)), (long long)want);
            TEST_FAIL();
        }
    }
#endif
    for (k = 0; k < 2 * TRIALS; ++k) {
        /* log-uniform over the whole positive range, 1 LSB .. 8e6 */
        const ekf_scalar_t a = ekf_from_double(exp(ts_uniform_in(&r, log(LSB), log(8.3e6))));
        const double want = sqrt(d(a));
        const double err = fabs(d(ekf_sqrt(a)) - want);
        const double rel = (err - LSB) / want;
        if (a <= 0) {
            continue;
        }
        if (rel > worst) {
            worst = rel;
        }
        if (!(err <= SQRT_REL * want + LSB)) {
            printf("sqrt(%.17g) = %.17g, want %.17g\n", d(a), d(ekf_sqrt(a)), want);
            TEST_FAIL();
        }
    }
    /* the correctly rounded 32-bit root of the normalised radicand: equal to the
     * digit-by-digit root the library used before, over values of every size */
    for (k = 0; k < TRIALS; ++k) {
        const ekf_scalar_t a = random_raw(&r);
        const ekf_scalar_t v = (a < 0) ? -a : a;
        uint64_t m, res = 0u, bit = (uint64_t)1 << 62;
        int sh = 0, e;
        while ((((uint64_t)v << sh) >> 63) == 0u) { /* leading zeros: v << sh in [2^63, 2^64) */
            ++sh;
        }
        if (((EKF_FX_FRAC - sh) & 1) != 0) {
            --sh;
        }
        m = (uint64_t)v << sh;
        e = EKF_FX_FRAC - sh;
        while (bit != 0u) {
            if (m >= res + bit) {
                m -= res + bit;
                res = (res >> 1) + bit;
            } else {
                res >>= 1;
            }
            bit >>= 2;
        }
        if (m > res) {
            ++res;
        }
        res = (e >= 0) ? res << (e / 2) : (res + ((uint64_t)1 << (-e / 2 - 1))) >> (-e / 2);
        TEST_ASSERT_TRUE(ekf_sqrt(v) == (ekf_scalar_t)res);
    }
    printf("sqrt: worst relative error beyond 1 LSB %.3e (bound %.1e)\n", worst, SQRT_REL);
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
}

static void check_sincos(double x, double *worst)
{
    const ekf_scalar_t a = ekf_from_double(x);
    const double xa = d(a); /* the angle the fixed-point value holds */
    const double es = fabs(d(ekf_sin(a)) - sin(xa)), ec = fabs(d(ekf_cos(a)) - cos(xa));
    const double e = (es > ec) ? es : ec;
    if (e > *worst) {
        *worst = e;
    }
    if (!(e <= SIN_COS_ABS)) {
        printf("sin/cos(%.17g): error %.3e\n", xa, e);
        TEST_FAIL();
    }
}

static void test_sin_cos_error_bound(void)
{
    ts_rng_t r;
    double worst = 0.0, x;
    int k;
    ts_rng_seed(&r, 4);
    /* the filter's range (|angle| <= 2 pi after one step) densely, every quadrant edge */
    for (x = -4.0 * 3.141592653589793; x <= 4.0 * 3.141592653589793; x += 100.0 / (double)TRIALS) {
        check_sincos(x, &worst);
    }
    for (k = -16; k <= 16; ++k) {
        const double edge = (double)k * 0.78539816339744831;
        check_sincos(edge, &worst);
        check_sincos(edge + LSB, &worst);
        check_sincos(edge - LSB, &worst);
    }
    /* far arguments, up to 2^20 rad */
    for (k = 0; k < TRIALS / 5; ++k) {
        check_sincos(ts_uniform_in(&r, -1048576.0, 1048576.0), &worst);
    }
    TEST_ASSERT_TRUE(ekf_sin(0) == 0);
    TEST_ASSERT_TRUE(ekf_cos(0) == EKF_C(1));
    /* sincos: the same two values as sin and cos */
    for (k = 0; k < TRIALS / 10; ++k) {
        const ekf_scalar_t a = ekf_from_double(ts_uniform_in(&r, -20.0, 20.0));
        ekf_scalar_t s, c;
        ekf_sincos(a, &s, &c);
        TEST_ASSERT_TRUE(s == ekf_sin(a) && c == ekf_cos(a));
    }
    printf("sin/cos: worst absolute error %.3e (bound %.1e)\n", worst, SIN_COS_ABS);
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
}

static void test_atan2_error_bound(void)
{
    ts_rng_t r;
    double worst = 0.0;
    int k;
    ts_rng_seed(&r, 5);
    for (k = 0; k < 2 * TRIALS; ++k) {
        /* directions all round, magnitudes 1e-6 .. 1e6 (components of unit vectors, uT) */
        const double ang = ts_uniform_in(&r, -3.141592653589793, 3.141592653589793);
        const double m = exp(ts_uniform_in(&r, log(1e-6), log(1e6)));
        const ekf_scalar_t y = ekf_from_double(m * sin(ang)), x = ekf_from_double(m * cos(ang));
        const double want = atan2(d(y), d(x));
        double e = fabs(d(ekf_atan2(y, x)) - want);
        if (e > 3.0) {
            e = fabs(e - 6.283185307179586); /* +-pi on the negative x axis */
        }
        if (e > worst) {
            worst = e;
        }
        if (!(e <= ATAN2_ABS)) {
            printf("atan2(%.17g, %.17g): error %.3e\n", d(y), d(x), e);
            TEST_FAIL();
        }
    }
    TEST_ASSERT_TRUE(ekf_atan2(0, 0) == 0);
    TEST_ASSERT_TRUE(ekf_atan2(EKF_C(1), 0) == EKF_HALF_PI);
    TEST_ASSERT_TRUE(ekf_atan2(0, EKF_C(-2)) == EKF_PI);
    TEST_ASSERT_TRUE(ekf_atan2(EKF_C(-1), 0) == ekf_neg(EKF_HALF_PI));
    TEST_ASSERT_TRUE(ekf_atan2(EKF_C(2), EKF_C(2)) == EKF_C(0.78539816339744830962));
    printf("atan2: worst absolute error %.3e (bound %.1e)\n", worst, ATAN2_ABS);
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
}

static void test_floor_and_wrap(void)
{
    ts_rng_t r;
    int k;
    ts_rng_seed(&r, 6);
    TEST_ASSERT_TRUE(ekf_floor(EKF_C(-0.5)) == EKF_C(-1));
    TEST_ASSERT_TRUE(ekf_floor(EKF_C(2.75)) == EKF_C(2));
    TEST_ASSERT_TRUE(ekf_floor(EKF_C(-3)) == EKF_C(-3));
    for (k = 0; k < TRIALS / 5; ++k) {
        const ekf_scalar_t a = ekf_from_double(ts_uniform_in(&r, -1000.0, 1000.0));
        const ekf_scalar_t w = ekf_wrap_pi(a);
        const double want = remainder(d(a), 6.283185307179586);
        TEST_ASSERT_TRUE(w >= ekf_neg(EKF_PI) && w < EKF_PI);
        /* 2 pi is held to 1/2 LSB: the error grows with the number of turns removed */
        TEST_ASSERT_TRUE(fabs(remainder(d(w) - want, 6.283185307179586)) <= LSB * (4.0 + fabs(d(a)) / 6.28));
    }
}

/* One scalar update and a propagation in fixed point against the same in double
 * (computed here): the core's arithmetic keeps P symmetric and positive definite and
 * matches double to a few LSB, amplified by 1 / S where the gain divides by S. */
static void test_core_update_matches_double(void)
{
    ts_rng_t r;
    int trial;
    ts_rng_seed(&r, 7);
    for (trial = 0; trial < 200; ++trial) {
        enum { N = 6 };
        double A[N * N], Pd[N * N], xd[N], b[N], s, hv = 0.0, nu, rv;
        ekf_scalar_t P[N * N], x[N], hval;
        uint8_t idx;
        ekf_hrow_t h;
        int i, j, k;
        double pivot;
        /* random SPD P = A A^T + 1e-6 I, variances from 1e-6 to ~1 */
        for (i = 0; i < N * N; ++i) {
            A[i] = ts_uniform_in(&r, -1.0, 1.0) * ((i / N) % 2 == 0 ? 1.0 : 1e-2);
        }
        for (i = 0; i < N; ++i) {
            for (j = 0; j < N; ++j) {
                double acc = (i == j) ? 1e-6 : 0.0;
                for (k = 0; k < N; ++k) {
                    acc += A[i * N + k] * A[j * N + k];
                }
                P[i * N + j] = ekf_from_double(acc);
            }
            x[i] = ekf_from_double(ts_uniform_in(&r, -1.0, 1.0));
        }
        for (i = 0; i < N * N; ++i) {
            Pd[i] = d(P[i]);
        }
        for (i = 0; i < N; ++i) {
            xd[i] = d(x[i]);
        }
        idx = (uint8_t)(trial % N);
        hval = ekf_from_double(ts_uniform_in(&r, 0.5, 2.0));
        hv = d(hval);
        h.idx = &idx;
        h.value = &hval;
        h.nnz = 1u;
        nu = d(ekf_from_double(ts_uniform_in(&r, -0.1, 0.1)));
        rv = d(ekf_from_double(1e-4));
        TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_update_scalar(x, P, N, &h, ekf_from_double(nu), ekf_from_double(rv), 0,
                                                        EKF_C(1e-10), NULL));
        /* double reference: P - b b^T / S */
        for (i = 0; i < N; ++i) {
            b[i] = Pd[i * N + idx] * hv;
        }
        s = hv * b[idx] + rv;
        for (i = 0; i < N; ++i) {
            xd[i] += b[i] / s * nu;
            /* b and S carry about 1 LSB of rounding each, which K = b / S scales by 1 / S
             * and |b| / S^2: absolute resolution, relative to a small S */
            if (!(fabs(d(x[i]) - xd[i]) <= 4.0 * LSB * (1.0 + (1.0 + fabs(b[i]) / s) * fabs(nu) / s))) {
                printf("trial %d x[%d]: fixed %.15g double %.15g s %.6g b %.6g nu %.6g\n", trial, i, d(x[i]), xd[i], s, b[i], nu);
                TEST_FAIL();
            }
            for (j = 0; j < N; ++j) {
                const double want = Pd[i * N + j] - b[i] * b[j] / s;
                /* rounding of b, 1/S and K (each <= 1/2 LSB) carried through K b^T */
                const double g = (1.0 + fabs(b[i]) + fabs(b[j])) * (1.0 + 1.0 / s);
                const double tol = 4.0 * LSB * g * g;
                if (!(fabs(d(P[i * N + j]) - want) <= tol)) {
                    printf("trial %d P[%d][%d]: fixed %.15g double %.15g tolerance %.3g\n", trial, i, j,
                           d(P[i * N + j]), want, tol);
                    TEST_FAIL();
                }
            }
        }
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(P, N));
        TEST_ASSERT_TRUE(ts_is_positive_definite(P, N, &pivot));
    }
    TEST_ASSERT_EQUAL_UINT32(0u, fx_count_saturations());
}

int main(void)
{
    UNITY_BEGIN();
    printf("Q format: Q%d.%d in int64 (resolution %.3e, range +-%.3e)\n", 63 - EKF_FX_FRAC, EKF_FX_FRAC, LSB,
           9.223372036854775807e18 * LSB);
    RUN_TEST(test_constants_and_conversions);
    RUN_TEST(test_saturation_counted_and_propagated);
    RUN_TEST(test_mul_correctly_rounded);
    RUN_TEST(test_div_correctly_rounded);
    RUN_TEST(test_div_equals_long_division);
    RUN_TEST(test_recip32_rsqrt32_bounds);
    RUN_TEST(test_sqrt_error_bound);
    RUN_TEST(test_sin_cos_error_bound);
    RUN_TEST(test_atan2_error_bound);
    RUN_TEST(test_floor_and_wrap);
    RUN_TEST(test_core_update_matches_double);
    return UNITY_END();
}
