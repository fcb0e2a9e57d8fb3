/*
 * ekf_scalar.h - the scalar type of the whole filter and every operation on it.
 *
 * Rules for code built on this header (core, attitude model, model library):
 *   - values are ekf_scalar_t; constants are written EKF_C(1.5);
 *   - + - * / go through ekf_add/ekf_sub/ekf_mul/ekf_div/ekf_neg (a fixed-point type
 *     needs rescaling and saturation there);
 *   - comparisons (<, >, ==) and assignment use the native operators: every supported
 *     representation is an arithmetic type with a monotonic encoding;
 *   - trigonometry, square root, floor and finiteness go through the functions below: no other
 *     libm call appears in the library, and nothing is promoted to double by accident
 *     (the project builds with -Wdouble-promotion -Werror); sin and cos of the same angle
 *     through ekf_sincos (one argument reduction for both).
 * Conversion at the API boundary: ekf_from_float / ekf_to_float (ekf_from_double /
 * ekf_to_double for host code and tests; ekf_from_int for counts). Never cast a scalar
 * with (float) or (ekf_scalar_t): in the fixed-point build that reinterprets the number.
 */
#ifndef EKF_SCALAR_H
#define EKF_SCALAR_H

#include <math.h>
#include <stdint.h>

#include "ekf_config.h"

#ifdef __cplusplus
extern "C" {
#endif

#if defined(EKF_SCALAR_DOUBLE)

typedef double ekf_scalar_t;
#define EKF_SCALAR_NAME "double"
/* Constant of the scalar type; the cast happens at compile time. */
#define EKF_C(x) ((ekf_scalar_t)(x))
#define EKF_SCALAR_EPS EKF_C(2.220446049250313e-16)
/* Absolute rounding unit of a product (0: IEEE rounding is relative, EKF_SCALAR_EPS). */
#define EKF_SCALAR_ABS_EPS EKF_C(0)

static inline ekf_scalar_t ekf_sqrt(ekf_scalar_t a) { return sqrt(a); }
static inline ekf_scalar_t ekf_sin(ekf_scalar_t a) { return sin(a); }
static inline ekf_scalar_t ekf_cos(ekf_scalar_t a) { return cos(a); }
static inline void ekf_sincos(ekf_scalar_t a, ekf_scalar_t *s, ekf_scalar_t *c)
{
    *s = sin(a);
    *c = cos(a);
}
static inline ekf_scalar_t ekf_atan2(ekf_scalar_t y, ekf_scalar_t x) { return atan2(y, x); }
static inline ekf_scalar_t ekf_abs(ekf_scalar_t a) { return fabs(a); }
static inline ekf_scalar_t ekf_floor(ekf_scalar_t a) { return floor(a); }
static inline ekf_scalar_t ekf_from_float(float a) { return (ekf_scalar_t)a; }
static inline float ekf_to_float(ekf_scalar_t a) { return (float)a; }

#elif defined(EKF_SCALAR_FLOAT)

#include "ekf_math.h" /* sin, cos, atan2, sqrt with stated bounds, no libm range reduction */
typedef float ekf_scalar_t;
#define EKF_SCALAR_NAME "float"
#define EKF_C(x) ((ekf_scalar_t)(x))
#define EKF_SCALAR_EPS EKF_C(1.1920929e-07)
#define EKF_SCALAR_ABS_EPS EKF_C(0)

static inline ekf_scalar_t ekf_sqrt(ekf_scalar_t a) { return ekf_sqrtf(a); }
static inline void ekf_sincos(ekf_scalar_t a, ekf_scalar_t *s, ekf_scalar_t *c) { ekf_sincosf(a, s, c); }
/* sin and cos alone are ekf_sincosf's outputs (bit-identical to ekf_sinf and ekf_cosf): the
 * filter needs both of most angles, and one function in the image instead of three saves
 * 640 bytes of flash; a lone sin or cos costs about 10 instructions more. */
static inline ekf_scalar_t ekf_sin(ekf_scalar_t a)
{
    float s, c;
    ekf_sincosf(a, &s, &c);
    return s;
}
static inline ekf_scalar_t ekf_cos(ekf_scalar_t a)
{
    float s, c;
    ekf_sincosf(a, &s, &c);
    return c;
}
static inline ekf_scalar_t ekf_atan2(ekf_scalar_t y, ekf_scalar_t x) { return ekf_atan2f(y, x); }
static inline ekf_scalar_t ekf_abs(ekf_scalar_t a) { return fabsf(a); }
static inline ekf_scalar_t ekf_floor(ekf_scalar_t a) { return floorf(a); }
static inline ekf_scalar_t ekf_from_float(float a) { return a; }
static inline float ekf_to_float(ekf_scalar_t a) { return a; }

#elif defined(EKF_SCALAR_FIXED)

/* Signed Q-format fixed point in an int64_t (ekf_fixed.h, docs/fixed_point.md): Q29.34 by
 * default (EKF_FX_FRAC). Comparisons and assignment stay native (a monotonic encoding);
 * everything else goes through the saturating ekf_fx_* operations. The covariance is held
 * apart, in 32-bit words with a scale per state (att_cov_fx.c). */
#include "ekf_fixed.h"

typedef ekf_fx_t ekf_scalar_t;
#define EKF_SCALAR_NAME "fixed"
#define EKF_C(x) EKF_FX_C(x)
/* Relative rounding unit of the covariance arithmetic: its 32-bit words hold each entry
 * normalised to [1, 4) of its state's scale with 29 fraction bits (att_cov_fx.c), so an
 * entry is known to 2^-29 of at most 4: 2^-27 of its scale. */
#define EKF_SCALAR_EPS ((ekf_scalar_t)1 << (EKF_FX_FRAC - 27))
/* Every product of the generic arithmetic is rounded to one LSB, so its error grows with
 * the size of the factors, not with the size of the result. */
#define EKF_SCALAR_ABS_EPS ((ekf_scalar_t)1)

static inline ekf_scalar_t ekf_sqrt(ekf_scalar_t a) { return ekf_fx_sqrt(a); }
static inline ekf_scalar_t ekf_sin(ekf_scalar_t a) { return ekf_fx_sin(a); }
static inline ekf_scalar_t ekf_cos(ekf_scalar_t a) { return ekf_fx_cos(a); }
static inline ekf_scalar_t ekf_atan2(ekf_scalar_t y, ekf_scalar_t x) { return ekf_fx_atan2(y, x); }
static inline ekf_scalar_t ekf_abs(ekf_scalar_t a) { return ekf_fx_abs(a); }
static inline ekf_scalar_t ekf_floor(ekf_scalar_t a) { return ekf_fx_floor(a); }
static inline ekf_scalar_t ekf_from_float(float a) { return ekf_fx_from_float(a); }
static inline float ekf_to_float(ekf_scalar_t a) { return ekf_fx_to_float(a); }
static inline ekf_scalar_t ekf_from_double(double a) { return ekf_fx_from_double(a); }
static inline double ekf_to_double(ekf_scalar_t a) { return ekf_fx_to_double(a); }
static inline ekf_scalar_t ekf_from_int(int32_t a) { return ekf_fx_from_int(a); }

static inline ekf_scalar_t ekf_add(ekf_scalar_t a, ekf_scalar_t b) { return ekf_fx_add(a, b); }
static inline ekf_scalar_t ekf_sub(ekf_scalar_t a, ekf_scalar_t b) { return ekf_fx_sub(a, b); }
static inline ekf_scalar_t ekf_mul(ekf_scalar_t a, ekf_scalar_t b) { return ekf_fx_mul(a, b); }
static inline ekf_scalar_t ekf_div(ekf_scalar_t a, ekf_scalar_t b) { return ekf_fx_div(a, b); }
static inline ekf_scalar_t ekf_neg(ekf_scalar_t a) { return ekf_fx_neg(a); }
static inline ekf_scalar_t ekf_mac(ekf_scalar_t c, ekf_scalar_t a, ekf_scalar_t b) { return ekf_fx_mac(c, a, b); }
/* sin and cos of one angle, one argument reduction. */
static inline void ekf_sincos(ekf_scalar_t a, ekf_scalar_t *s, ekf_scalar_t *c) { ekf_fx_sincos(a, s, c); }
/* Saturated values are the infinities of the format: not finite. */
static inline int ekf_isfinite(ekf_scalar_t a) { return ekf_fx_isfinite(a); }
/* Branch-free finiteness of many values (see the IEEE version): acc stays zero while
 * every value is finite, else it becomes non-zero. */
static inline ekf_scalar_t ekf_finite_acc(ekf_scalar_t acc, ekf_scalar_t a) { return ekf_fx_isfinite(a) ? acc : (ekf_scalar_t)1; }

#else
#error "ekf_scalar.h: no scalar type selected (see ekf_config.h)"
#endif

#if !defined(EKF_SCALAR_FIXED)
/* Arithmetic. For IEEE types these are the plain operators; they exist so that a
 * representation with rescaling or saturation (EKF_SCALAR_FIXED above) replaces them in
 * one place. */
static inline ekf_scalar_t ekf_add(ekf_scalar_t a, ekf_scalar_t b) { return a + b; }
static inline ekf_scalar_t ekf_sub(ekf_scalar_t a, ekf_scalar_t b) { return a - b; }
static inline ekf_scalar_t ekf_mul(ekf_scalar_t a, ekf_scalar_t b) { return a * b; }
static inline ekf_scalar_t ekf_div(ekf_scalar_t a, ekf_scalar_t b) { return a / b; }
static inline ekf_scalar_t ekf_neg(ekf_scalar_t a) { return -a; }
/* a*b + c: one rounding less where the target fuses it. */
static inline ekf_scalar_t ekf_mac(ekf_scalar_t c, ekf_scalar_t a, ekf_scalar_t b)
{
    return c + a * b;
}
static inline int ekf_isfinite(ekf_scalar_t a) { return isfinite(a) ? 1 : 0; }
/* Branch-free finiteness of many values: acc starts at EKF_C(0) and stays exactly zero
 * while every v is finite (v * 0 is +-0); inf * 0 and NaN * 0 make it NaN. One multiply-add
 * per value (the covariance update checks 18 values per scalar measurement). */
static inline ekf_scalar_t ekf_finite_acc(ekf_scalar_t acc, ekf_scalar_t a) { return acc + a * (ekf_scalar_t)0; }
/* Conversions for host code and tests (the casts they replace, so results are unchanged),
 * and of an integer count. */
static inline ekf_scalar_t ekf_from_double(double a) { return (ekf_scalar_t)a; }
static inline double ekf_to_double(ekf_scalar_t a) { return (double)a; }
static inline ekf_scalar_t ekf_from_int(int32_t a) { return (ekf_scalar_t)a; }
#endif

/* v, or exactly 0 if |v| < EKF_SCALAR_TINY (1e-30 in the IEEE builds, far below any
 * physical value in SI; nothing in fixed point, which has no subnormals). For quantities
 * that decay geometrically towards zero, like a low-pass filter whose input is exactly zero:
 * in IEEE arithmetic such a value never reaches zero but settles on a subnormal number
 * (y - k y rounds back to y once k y is below half its spacing), and every later operation on
 * it takes the slow path of an x86 FPU (docs/performance.md, "Subnormal numbers"). */
#if defined(EKF_SCALAR_FIXED)
#define EKF_SCALAR_TINY EKF_C(0)
#else
#define EKF_SCALAR_TINY EKF_C(1e-30)
#endif
static inline ekf_scalar_t ekf_flush_tiny(ekf_scalar_t v) { return (ekf_abs(v) < EKF_SCALAR_TINY) ? EKF_C(0) : v; }

static inline ekf_scalar_t ekf_min(ekf_scalar_t a, ekf_scalar_t b) { return (a < b) ? a : b; }
static inline ekf_scalar_t ekf_max(ekf_scalar_t a, ekf_scalar_t b) { return (a > b) ? a : b; }
static inline ekf_scalar_t ekf_clamp(ekf_scalar_t a, ekf_scalar_t lo, ekf_scalar_t hi)
{
    return ekf_min(ekf_max(a, lo), hi);
}
static inline ekf_scalar_t ekf_sq(ekf_scalar_t a) { return ekf_mul(a, a); }

#define EKF_PI EKF_C(3.14159265358979323846)
#define EKF_TWO_PI EKF_C(6.28318530717958647692)
#define EKF_HALF_PI EKF_C(1.57079632679489661923)

/* Angle wrapped into [-pi, pi) for any finite input. Inline only the test: an angle in
 * range (what the filter nearly always has) costs two comparisons; ekf_wrap_pi_far
 * (ekf_math.c) reduces the others. */
ekf_scalar_t ekf_wrap_pi_far(ekf_scalar_t a);
#if defined(__GNUC__)
__attribute__((always_inline)) /* (GCC at -Os would keep a called copy per file) */
#endif
static inline ekf_scalar_t ekf_wrap_pi(ekf_scalar_t a)
{
    return (a >= EKF_PI || a < ekf_neg(EKF_PI)) ? ekf_wrap_pi_far(a) : a;
}

#ifdef __cplusplus
}
#endif

#endif /* EKF_SCALAR_H */
