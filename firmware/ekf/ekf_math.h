/*
 * ekf_math.h - sine, cosine, arctangent and square root in single precision, with stated
 * error bounds, for the float build of the filter (ekf_scalar.h maps ekf_sin, ekf_cos,
 * ekf_atan2 and ekf_sqrt to these). The double build keeps the C library; the fixed-point
 * build has its own functions (ekf_fixed.h).
 *
 * Why not the C library: newlib's sinf/cosf carry a reduction for arguments of any size
 * (3.2 KB of flash on the Cortex-M4F) while the filter's angles stay in [-pi, pi), plus
 * half-step midpoints: |x| < 4. Here an argument with |x| < 8 is reduced by pi/2 in a few
 * float operations (pi/2 in three parts, the products exact), and a larger one by the same
 * method as the C library's, but small: the argument's 24-bit significand times 96 bits of
 * 2/pi in 32-bit integer arithmetic. Every finite argument thus gets a correct result; the
 * large path is only slower, never less accurate than stated.
 *
 * Error bounds, in units in the last place of the float result (ULP), measured against a
 * double-precision reference (tests/c/test_ekf_math.c checks them on every run; the
 * exhaustive figures over every float in [-4, 4] are in docs/performance.md):
 *   ekf_sinf, ekf_cosf, ekf_sincosf   <= 2 ULP for every finite x (sin and cos identical to
 *                                     ekf_sinf and ekf_cosf); +-inf and NaN give NaN.
 *   ekf_atan2f                        <= 3 ULP for all finite y, x; C99's special values:
 *                                     atan2(+-0, +0) = +-0, atan2(+-0, -0) = +-pi,
 *                                     infinities as in C99 F.9.1.4; NaN in, NaN out.
 *                                     Result in [-pi_f, pi_f], pi_f = float(pi) (like atan2f).
 *   ekf_sqrtf                         correctly rounded (0 ULP, bit-identical to IEEE sqrt):
 *                                     the FPU's VSQRT on cores with a single-precision FPU,
 *                                     the C library's sqrtf on other hosts, and on
 *                                     soft-float Arm (Cortex-M0/M3) ekf_sqrtf_soft below, so no
 *                                     libm wrapper (with errno and its reentrancy struct) is
 *                                     linked. sqrt(-0) = -0; negative or NaN give NaN.
 * Polynomials: minimax fits of relative error on |r| <= pi/4 (sin, cos) and
 * |t| <= tan(pi/8) (atan), coefficients from scripts/fit_ekf_math.py.
 *
 * Requirements: IEEE single precision evaluated in single precision (FLT_EVAL_METHOD 0:
 * Arm, x86-64 SSE); the reduction adds and subtracts 1.5 * 2^23 to round, so the file must
 * not be compiled with -ffast-math or -fassociative-math (contraction into FMA is harmless).
 */
#ifndef EKF_MATH_H
#define EKF_MATH_H

#include <math.h>

#ifdef __cplusplus
extern "C" {
#endif

/* sin(x) and cos(x), x in rad. */
float ekf_sinf(float x);
float ekf_cosf(float x);
/* Both at once (one reduction): *s = ekf_sinf(x), *c = ekf_cosf(x), bit for bit. */
void ekf_sincosf(float x, float *s, float *c);
/* Angle of the point (x, y) from the +x axis, rad, in [-pi, pi]. */
float ekf_atan2f(float y, float x);
/* Square root by integer digit recurrence, correctly rounded: the soft-float path of
 * ekf_sqrtf, available on every target (so that it can be tested on the host). */
float ekf_sqrtf_soft(float a);

static inline float ekf_sqrtf(float a)
{
#if defined(__arm__) && defined(__ARM_FP) && ((__ARM_FP & 4) != 0)
    float r;
    __asm__("vsqrt.f32 %0, %1" : "=t"(r) : "t"(a));
    return r;
#elif defined(__arm__)
    return ekf_sqrtf_soft(a);
#else
    return sqrtf(a);
#endif
}

#ifdef __cplusplus
}
#endif

#endif /* EKF_MATH_H */
