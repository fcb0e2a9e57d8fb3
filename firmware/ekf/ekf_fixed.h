/*
 * ekf_fixed.h - signed Q-format fixed-point arithmetic: the representation of
 * ekf_scalar_t in the EKF_SCALAR_FIXED build (docs/fixed_point.md).
 *
 * A value v is stored as the int64_t round(v * 2^EKF_FX_FRAC). The default, Q29.34
 * (1 sign bit, 29 integer bits, 34 fraction bits), spans +-5.4e8 with a resolution of
 * 5.8e-11: the range of the settings, states, bounds and innovations the filter's stages
 * compute with, and the resolution its smallest variances need (docs/fixed_point.md,
 * "Measured ranges"). The covariance is not held in this format: att_cov_fx.c stores it in
 * 32-bit words with a power-of-two scale per state.
 *
 * The operations are written for a 32-bit core without an FPU (Cortex-M3): products from
 * 32 x 32 -> 64 multiplies (UMULL, SMULL, MLA), a fast path for the operands the filter
 * uses (|v| < 8192 for mul, |v| < 1.3e8 for add), an exact slow path for the rest;
 * division by long division in 32-bit digits with a reciprocal estimate; trigonometry and
 * square roots in 32-bit arithmetic.
 *
 * Infinity and saturation: INT64_MAX and -INT64_MAX are +inf and -inf. An operation whose
 * exact result lies outside the range returns the infinity of its sign (a saturation, made
 * by ekf_fx_saturate). There is no NaN: what IEEE arithmetic makes NaN (inf - inf, 0 * inf,
 * 0 / 0, inf / inf, sqrt(x < 0), a NaN input) is +inf here, a saturation when it arises from
 * finite operands. An infinite operand gives a non-finite result without a new saturation
 * (x / inf = 0, as in IEEE), so non-finiteness propagates like NaN and Inf do, and
 * ekf_fx_isfinite() is false for it: every finiteness check of the filter refuses a
 * saturated result exactly like an IEEE overflow, and a saturation never passes silently
 * into the state. INT64_MIN is never produced; it reads as -inf. The library keeps no count
 * (no state outside the caller's structs): a build may define EKF_FX_SATURATION_HOOK as the
 * name of a function void f(void), called once per saturation; the tests count them so
 * (tests/c/support/fx_count.h).
 *
 * Operations and their error bounds, checked by tests/c/test_fixed.c against double
 * (LSB = 2^-EKF_FX_FRAC):
 *   add, sub, neg            exact (or saturated)
 *   mul                      correctly rounded, ties toward +inf (mul(-a, b) = -mul(a, b)
 *                            except at an exact tie)
 *   div                      correctly rounded, ties away from zero (long division in two
 *                            32-bit digits; equal to a restoring division)
 *   sqrt                     relative error <= 2^-31, plus 1 LSB (the root of the radicand
 *                            normalised to 64 bits, as a correctly rounded 32-bit integer)
 *   sin, cos                 |x| <= 2^20: abs error <= 2^-30 (exact reduction by pi/2 held to
 *                            62 bits, then minimax polynomials of degree 9 / 10 in r on
 *                            |r| <= pi/4 in 32-bit arithmetic, the linear term exact)
 *   atan2                    abs error <= 2^-30 (octant reduction, the quotient rounded to 33
 *                            bits, an odd minimax polynomial of degree 13 on |t| <= tan(pi/8))
 */
#ifndef EKF_FIXED_H
#define EKF_FIXED_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#ifndef EKF_FX_FRAC
/* The fixed-point code shifts negative values right and needs the arithmetic shift (floor
 * division by a power of two) that GCC, Clang and the Cortex-M compilers implement; C99
 * leaves it implementation-defined (6.5.7), so a compiler that differs is refused here. */
typedef char ekf_fx_needs_arithmetic_right_shift[((-1 >> 1) == -1 && (INT32_MIN >> 31) == -1) ? 1 : -1];

#define EKF_FX_FRAC 34
#endif
#if EKF_FX_FRAC < 33 || EKF_FX_FRAC > 52
#error "EKF_FX_FRAC must be in 33..52"
#endif

typedef int64_t ekf_fx_t;

#define EKF_FX_ONE ((ekf_fx_t)1 << EKF_FX_FRAC)
#define EKF_FX_INF INT64_MAX           /* +inf, also the saturated maximum */
#define EKF_FX_NINF (-INT64_MAX)       /* -inf */
/* 2^EKF_FX_FRAC as a double constant (for compile-time conversion of literals). */
#define EKF_FX_SCALE ((double)EKF_FX_ONE)
/* Constant in Q format, rounded to nearest; a compile-time constant expression for a
 * constant argument. Only for constants: run-time values enter through ekf_fx_from_*. */
#define EKF_FX_C(x) ((ekf_fx_t)((double)(x) * EKF_FX_SCALE + (((double)(x) < 0.0) ? -0.5 : 0.5)))

/* A saturation: the infinity of the given sign (>= 0: +inf); calls EKF_FX_SATURATION_HOOK
 * if the build defines it. */
ekf_fx_t ekf_fx_saturate(int sign);

static inline int ekf_fx_isfinite(ekf_fx_t a) { return (a < EKF_FX_INF && a > EKF_FX_NINF) ? 1 : 0; }

/* a + b for any operands, infinities included (the fast path below covers the rest). */
ekf_fx_t ekf_fx_add_slow(ekf_fx_t a, ekf_fx_t b);

/* High word of a value. */
static inline int32_t ekf_fx_hi(ekf_fx_t a) { return (int32_t)(a >> 32); }

static inline ekf_fx_t ekf_fx_add(ekf_fx_t a, ekf_fx_t b)
{
    /* |a|, |b| < 2^61 (high words in [-2^29, 2^29)): the sum is in range and neither
     * operand is an infinity; the wrap-around sum in unsigned arithmetic is exact */
    if ((((uint32_t)ekf_fx_hi(a) + 0x20000000u) | ((uint32_t)ekf_fx_hi(b) + 0x20000000u)) < 0x40000000u) {
        return (ekf_fx_t)((uint64_t)a + (uint64_t)b);
    }
    return ekf_fx_add_slow(a, b);
}

static inline ekf_fx_t ekf_fx_neg(ekf_fx_t a)
{
    /* -inf and +inf are exact negatives; INT64_MIN (read as -inf) becomes +inf */
    return (a == INT64_MIN) ? EKF_FX_INF : -a;
}

static inline ekf_fx_t ekf_fx_sub(ekf_fx_t a, ekf_fx_t b) { return ekf_fx_add(a, ekf_fx_neg(b)); }

static inline ekf_fx_t ekf_fx_abs(ekf_fx_t a) { return (a < 0) ? ekf_fx_neg(a) : a; }

/* Largest integer <= a (fraction bits cleared; two's complement rounds toward -inf). The
 * floor of a finite value just above -inf (within one unit of it) lies outside the range:
 * -inf, counted like every other saturation. */
static inline ekf_fx_t ekf_fx_floor(ekf_fx_t a)
{
    ekf_fx_t r;
    if (!ekf_fx_isfinite(a)) {
        return a;
    }
    r = (ekf_fx_t)((uint64_t)a & ~((uint64_t)EKF_FX_ONE - 1u));
    return ekf_fx_isfinite(r) ? r : ekf_fx_saturate(-1);
}

ekf_fx_t ekf_fx_mul(ekf_fx_t a, ekf_fx_t b);
/* c + a * b, the product rounded as by ekf_fx_mul (one call instead of two). */
ekf_fx_t ekf_fx_mac(ekf_fx_t c, ekf_fx_t a, ekf_fx_t b);
ekf_fx_t ekf_fx_div(ekf_fx_t a, ekf_fx_t b);
ekf_fx_t ekf_fx_sqrt(ekf_fx_t a);
ekf_fx_t ekf_fx_sin(ekf_fx_t a);
ekf_fx_t ekf_fx_cos(ekf_fx_t a);
/* sin and cos of one angle (one reduction). */
void ekf_fx_sincos(ekf_fx_t a, ekf_fx_t *s, ekf_fx_t *c);
ekf_fx_t ekf_fx_atan2(ekf_fx_t y, ekf_fx_t x);

/* 32-bit helpers shared with the covariance (att_cov_fx.c): for d in [2^31, 2^32), 2^63 / d
 * from below within 2 (clamped to 2^32 - 1); for d in [2^30, 2^32), 2^47 / sqrt(d) within
 * -2 .. +3 (clamped likewise). tests/c/test_fixed.c checks both. */
uint32_t ekf_fx_recip32(uint32_t d);
uint32_t ekf_fx_rsqrt32(uint32_t d);
/* Number of leading zero bits of a non-zero 32-bit value: one CLZ instruction on the
 * Cortex-M3 (and x86) through the compiler's builtin, else a portable search. */
#if defined(__GNUC__)
static inline __attribute__((always_inline)) int ekf_fx_clz32(uint32_t v) { return __builtin_clz(v); }
#define EKF_FX_INLINE static inline __attribute__((always_inline))
#else
int ekf_fx_clz32(uint32_t v);
#define EKF_FX_INLINE static inline
#endif
/* Bit length of v (0 for 0). */
EKF_FX_INLINE int ekf_fx_bitlen64(uint64_t v)
{
    const uint32_t hi = (uint32_t)(v >> 32);
    return (hi != 0u) ? 64 - ekf_fx_clz32(hi) : ((uint32_t)v != 0u) ? 32 - ekf_fx_clz32((uint32_t)v) : 0;
}

/* Boundary conversions (not used inside the filter). Out-of-range finite values saturate
 * (counted); NaN becomes +inf and infinities stay infinite (not counted), so that the
 * filter's input checks refuse them as non-finite. */
ekf_fx_t ekf_fx_from_float(float a);
ekf_fx_t ekf_fx_from_double(double a);
ekf_fx_t ekf_fx_from_int(int32_t a);
float ekf_fx_to_float(ekf_fx_t a);
double ekf_fx_to_double(ekf_fx_t a);

#ifdef __cplusplus
}
#endif

#endif /* EKF_FIXED_H */
