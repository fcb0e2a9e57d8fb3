/*
 * ekf_fixed.h - signed Q-format fixed-point arithmetic: the representation of
 * ekf_scalar_t in the EKF_SCALAR_FIXED build (docs/fixed_point.md).
 *
 * A value v is stored as the int64_t round(v * 2^EKF_FX_FRAC). The default, Q29.34
 * (1 sign bit, 29 integer bits, 34 fraction bits), spans +-5.4e8 with a resolution of
 * 5.8e-11; docs/fixed_point.md derives it from the measured ranges of the filter's states,
 * covariance and innovations. Products and quotients use exact 128-bit intermediates
 * built from 32x32->64 multiplies (UMULL on Cortex-M3), rounded to nearest.
 *
 * Infinity and saturation: INT64_MAX and -INT64_MAX are +inf and -inf. An operation whose
 * exact result lies outside the range returns the infinity of its sign and counts one
 * saturation event (ekf_fx_saturations()). There is no NaN: what IEEE arithmetic makes NaN
 * (inf - inf, 0 * inf, 0 / 0, inf / inf, sqrt(x < 0), a NaN input) is +inf here, counted
 * when it arises from finite operands. An infinite operand gives a non-finite result
 * without a new count (x / inf = 0, as in IEEE), so non-finiteness propagates like NaN
 * and Inf do, and ekf_fx_isfinite() is false for it: every finiteness check of the
 * filter refuses a saturated result exactly like an IEEE overflow, and a saturation never
 * passes silently into the state. INT64_MIN is never produced; it reads as -inf.
 *
 * Operations and their error bounds, checked by tests/c/test_fixed.c against double
 * (LSB = 2^-EKF_FX_FRAC):
 *   add, sub, neg            exact (or saturated)
 *   mul                      correctly rounded, half away from zero (so mul(-a, b) = -mul(a, b))
 *   div                      correctly rounded (integer division + restoring long division)
 *   sqrt                     relative error <= 2^-31, plus 1 LSB (32-bit digit-by-digit root
 *                            of the normalised radicand)
 *   sin, cos                 |x| <= 2^20: abs error <= 3 LSB (Taylor to degree 13/14 on
 *                            [-pi/4, pi/4] after an exact reduction by pi/2 held to 62 bits)
 *   atan2                    abs error <= 3 LSB (octant reduction with one division, then a
 *                            weighted least-squares odd polynomial of degree 15 on
 *                            |t| <= tan(pi/8), 1.5e-13 in exact arithmetic)
 */
#ifndef EKF_FIXED_H
#define EKF_FIXED_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#ifndef EKF_FX_FRAC
#define EKF_FX_FRAC 34
#endif
#if EKF_FX_FRAC < 24 || EKF_FX_FRAC > 52
#error "EKF_FX_FRAC must be in 24..52"
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

/* Saturation events since start or the last reset (saturates at UINT32_MAX). Global to the
 * program: several filter instances share it. */
uint32_t ekf_fx_saturations(void);
void ekf_fx_saturations_reset(void);
/* Counts one event and returns the infinity of the given sign (>= 0: +inf). */
ekf_fx_t ekf_fx_saturate(int sign);

static inline int ekf_fx_isfinite(ekf_fx_t a) { return (a < EKF_FX_INF && a > EKF_FX_NINF) ? 1 : 0; }

static inline ekf_fx_t ekf_fx_add(ekf_fx_t a, ekf_fx_t b)
{
    /* wrap-around sum in unsigned arithmetic (defined), then the sign test for overflow */
    const ekf_fx_t r = (ekf_fx_t)((uint64_t)a + (uint64_t)b);
    if (!ekf_fx_isfinite(a) || !ekf_fx_isfinite(b)) {
        if (ekf_fx_isfinite(b)) {
            return (a > 0) ? EKF_FX_INF : EKF_FX_NINF;
        }
        if (ekf_fx_isfinite(a) || ((a > 0) == (b > 0))) {
            return (b > 0) ? EKF_FX_INF : EKF_FX_NINF;
        }
        return EKF_FX_INF; /* inf - inf: not a number */
    }
    if (((a ^ b) >= 0) && ((a ^ r) < 0)) {
        return ekf_fx_saturate(a >= 0 ? 1 : -1);
    }
    if (!ekf_fx_isfinite(r)) {
        return ekf_fx_saturate(r > 0 ? 1 : -1);
    }
    return r;
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
ekf_fx_t ekf_fx_div(ekf_fx_t a, ekf_fx_t b);
ekf_fx_t ekf_fx_sqrt(ekf_fx_t a);
ekf_fx_t ekf_fx_sin(ekf_fx_t a);
ekf_fx_t ekf_fx_cos(ekf_fx_t a);
ekf_fx_t ekf_fx_atan2(ekf_fx_t y, ekf_fx_t x);

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
