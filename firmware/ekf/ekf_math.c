/*
 * ekf_math.c - single-precision sin, cos, atan2 and software sqrt with stated error bounds
 * (ekf_math.h says which, and why the C library's are not used in the float build), and the
 * out-of-range part of ekf_wrap_pi for every scalar type (ekf_scalar.h).
 */
#include "ekf_math.h"

#include <stdint.h>
#include <string.h>

#include "ekf_scalar.h"

/* ---- angle wrap (every scalar type; ekf_scalar.h inlines the in-range test) ----------- */

#if defined(EKF_SCALAR_FLOAT)
/* floor(q), exact for every float like floorf, without libm's floorf (148 bytes on the
 * M4F): from 2^23 on every float is an integer; NaN and infinities pass through. */
static float wrap_floor(float q)
{
    float t;
    if (!(ekf_abs(q) < 8388608.0f)) {
        return q;
    }
    t = (float)(int32_t)q; /* toward zero, exact below 2^23 */
    return (t > q) ? t - 1.0f : t;
}
#else
#define wrap_floor ekf_floor
#endif

/* a - 2 pi floor((a + pi) / 2 pi), then one correction step for the rounding of that
 * product, then a clamp (for inputs so large that the reduction is no longer exact in the
 * scalar's precision, the result is still an angle in range, though not the exact residue). */
ekf_scalar_t ekf_wrap_pi_far(ekf_scalar_t a)
{
    const ekf_scalar_t turns = wrap_floor(ekf_div(ekf_add(a, EKF_PI), EKF_TWO_PI));
    a = ekf_sub(a, ekf_mul(turns, EKF_TWO_PI));
    if (a >= EKF_PI) {
        a = ekf_sub(a, EKF_TWO_PI);
    } else if (a < ekf_neg(EKF_PI)) {
        a = ekf_add(a, EKF_TWO_PI);
    }
    a = ekf_clamp(a, ekf_neg(EKF_PI), EKF_PI);
    if (a >= EKF_PI) {
        a = ekf_neg(EKF_PI);
    }
    return a;
}

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

/* The short reduction and the kernels are inlined into each function (about 10 instructions
 * of call overhead saved per call at -Os, 16 calls per filter step); the large reduction,
 * never reached by the filter, stays out of line. */
#if defined(__GNUC__)
#define EKF_MATH_INLINE inline __attribute__((always_inline))
#define EKF_MATH_NOINLINE __attribute__((noinline))
#else
#define EKF_MATH_INLINE inline
#define EKF_MATH_NOINLINE
#endif

/* ---- argument reduction: x = k pi/2 + r, |r| <= pi/4 (plus rounding) ------------------ */

/* |x| below this (8.0f) takes the short reduction; its k is at most 5 (3 bits). */
#define SMALL_LIMIT_BITS 0x41000000u
#define TWO_OVER_PI 6.36619772e-01f
/* 1.5 * 2^23: adding and subtracting it rounds a float of magnitude < 2^22 to an integer. */
#define ROUND_MAGIC 12582912.0f
/* pi/2 = P1 + P2 + P3 + O(2e-21): P1 and P2 have 21 significant bits, so k * P1 and k * P2
 * are exact for |k| <= 7, and x - k P1 is exact (Sterbenz). */
#define PIO2_P1 1.5707960128784180e+00f /* 0x1.921fb0p+0 */
#define PIO2_P2 3.1391641641675960e-07f /* 0x1.5110b0p-22 */
#define PIO2_P3 6.2233719700e-14f       /* 0x1.184698p-44 */

/* Bits of 2/pi after the binary point, 32 per word (bit i of the fraction, i >= 1, is bit
 * 32 - ((i - 1) mod 32) of word (i - 1) / 32). 256 bits: a float's exponent reaches 127,
 * the window below ends at bit 127 - 23 - 1 + 96 + 32. */
static const uint32_t two_over_pi_bits[8] = {
    0xA2F9836Eu, 0x4E441529u, 0xFC2757D1u, 0xF534DDC0u,
    0xDB629599u, 0x3C439041u, 0xFE5163ABu, 0xDEBBC561u,
};

/* The 32 bits of 2/pi's fraction starting at bit pos (bits at pos <= 0 are zero). */
static uint32_t two_over_pi_word(int pos)
{
    const int off = pos - 1;
    if (off <= -32) {
        return 0u;
    }
    if (off < 0) {
        return two_over_pi_bits[0] >> (unsigned)(-off);
    }
    {
        const int j = off / 32, sh = off % 32;
        if (sh == 0) {
            return two_over_pi_bits[j];
        }
        return (two_over_pi_bits[j] << (unsigned)sh) | (two_over_pi_bits[j + 1] >> (unsigned)(32 - sh));
    }
}

/* Reduction of a finite x with |x| >= 8 (Payne-Hanek, in integers). x = m 2^e with a 24-bit
 * integer m; x (2/pi) mod 4 = m 2^e (2/pi) mod 4 needs only the bits of 2/pi from e - 1 on
 * (earlier ones contribute multiples of 4). With 96 of them, the product m * window mod 2^96
 * is x (2/pi) mod 4 in units of 2^-94: the top two bits are the quadrant, the remaining 94
 * the fraction, truncated by less than 2^-70 of a quadrant; the 64 fraction bits kept leave
 * at least 32 significant bits for any float argument, whose distance from a multiple of
 * pi/2 is never below 2^-30 of one (tests/c/test_ekf_math.c checks the nearest cases).
 * Returns r in rad and the quadrant in *q. */
static EKF_MATH_NOINLINE float reduce_large(uint32_t ux, int32_t *q)
{
    const int e = (int)((ux >> 23) & 0xFFu) - 150;
    const uint32_t m = (ux & 0x007FFFFFu) | 0x00800000u;
    const uint32_t w0 = two_over_pi_word(e - 1), w1 = two_over_pi_word(e + 31), w2 = two_over_pi_word(e + 63);
    const uint64_t p2 = (uint64_t)m * w2;
    const uint64_t p1 = (uint64_t)m * w1 + (p2 >> 32);
    const uint32_t p0 = (uint32_t)((uint64_t)m * w0 + (p1 >> 32));
    /* 64 bits of fraction below the two quadrant bits; round the quadrant to nearest so that
     * the fraction is in [-1/2, 1/2) (read as signed) */
    uint64_t f = ((uint64_t)p0 << 34) | ((uint64_t)(uint32_t)p1 << 2) | ((uint64_t)(uint32_t)p2 >> 30);
    int32_t quad = (int32_t)(p0 >> 30) + (int32_t)(f >> 63);
    uint32_t neg = (uint32_t)(f >> 63), hi;
    int shift = 0;
    float r;
    if (neg) {
        f = ~f + 1u;
    }
    if (f == 0u) {
        r = 0.0f;
    } else {
        while ((f >> 63) == 0u) {
            f <<= 1;
            ++shift;
        }
        /* r = fraction * pi/2 in integers (pi/4 in Q32 times 2), top 32 bits kept with a sticky
         * bit, so that the conversion to float is the only rounding */
        hi = (uint32_t)(f >> 32) | (((uint32_t)f != 0u) ? 1u : 0u);
        {
            const uint64_t p = (uint64_t)hi * 0xC90FDAA2u; /* pi/4 * 2^32 */
            const uint32_t ph = (uint32_t)(p >> 32) | (((uint32_t)p != 0u) ? 1u : 0u);
            r = (float)ph * float_of((uint32_t)(127 - 31 - shift) << 23);
        }
    }
    if (neg) {
        r = -r;
    }
    if (ux >> 31) { /* x = -|x| = (-quad) pi/2 + (-r) */
        quad = -quad;
        r = -r;
    }
    *q = quad;
    return r;
}

/* Below 2^-12, sin(x) rounds to x (|x^3/6| < 2^-26 |x|) and cos(x) to 1; this also keeps
 * the sign of -0. */
#define TINY_LIMIT_BITS 0x39800000u

/* x = k pi/2 + r for finite x; k mod 4 in *q. */
static EKF_MATH_INLINE float reduce(float x, int32_t *q)
{
    const uint32_t ux = bits_of(x);
    if ((ux & 0x7FFFFFFFu) < SMALL_LIMIT_BITS) {
        const float t = x * TWO_OVER_PI + ROUND_MAGIC;
        const float k = t - ROUND_MAGIC;
        *q = (int32_t)(bits_of(t) - bits_of(ROUND_MAGIC));
        return ((x - k * PIO2_P1) - k * PIO2_P2) - k * PIO2_P3;
    }
    return reduce_large(ux, q);
}

/* ---- kernels on |r| <= pi/4 (scripts/fit_ekf_math.py) -------------------------------- */

static EKF_MATH_INLINE float kernel_sin(float r)
{
    const float z = r * r;
    return r + r * z * (-1.666665524e-01f + z * (8.332160302e-03f + z * -1.951528393e-04f));
}

static EKF_MATH_INLINE float kernel_cos(float r)
{
    const float z = r * r;
    return (1.0f - 0.5f * z) + z * z * (4.166664556e-02f + z * (-1.388731645e-03f + z * 2.443315498e-05f));
}

float ekf_sinf(float x)
{
    int32_t q;
    float r;
    if ((bits_of(x) & 0x7F800000u) == 0x7F800000u) {
        return x - x; /* inf or NaN: NaN */
    }
    if ((bits_of(x) & 0x7FFFFFFFu) < TINY_LIMIT_BITS) {
        return x;
    }
    r = reduce(x, &q);
    switch ((uint32_t)q & 3u) {
    case 0u: return kernel_sin(r);
    case 1u: return kernel_cos(r);
    case 2u: return -kernel_sin(r);
    default: return -kernel_cos(r);
    }
}

float ekf_cosf(float x)
{
    int32_t q;
    float r;
    if ((bits_of(x) & 0x7F800000u) == 0x7F800000u) {
        return x - x;
    }
    r = reduce(x, &q);
    switch ((uint32_t)q & 3u) {
    case 0u: return kernel_cos(r);
    case 1u: return -kernel_sin(r);
    case 2u: return -kernel_cos(r);
    default: return kernel_sin(r);
    }
}

void ekf_sincosf(float x, float *s, float *c)
{
    int32_t q;
    float r, ks, kc;
    if ((bits_of(x) & 0x7F800000u) == 0x7F800000u) {
        *s = *c = x - x;
        return;
    }
    if ((bits_of(x) & 0x7FFFFFFFu) < TINY_LIMIT_BITS) {
        *s = x;
        *c = kernel_cos(x);
        return;
    }
    r = reduce(x, &q);
    ks = kernel_sin(r);
    kc = kernel_cos(r);
    switch ((uint32_t)q & 3u) {
    case 0u: *s = ks; *c = kc; break;
    case 1u: *s = kc; *c = -ks; break;
    case 2u: *s = -ks; *c = -kc; break;
    default: *s = -kc; *c = ks; break;
    }
}

/* ---- atan2 ---------------------------------------------------------------------------- */

#define PI_HI 3.141592741e+00f     /* float(pi) */
#define PI_LO (-8.742277657e-08f) /* pi - PI_HI */
#define PIO2_HI 1.570796371e+00f
#define PIO2_LO (-4.371138829e-08f)
#define PIO4_HI 7.853981853e-01f
#define PIO4_LO (-2.185569414e-08f)
#define TAN_PI_8 4.142135680e-01f

/* atan(t) - t for |t| <= tan(pi/8) */
static float kernel_atan_tail(float t)
{
    const float z = t * t;
    return t * z * (-3.333294988e-01f + z * (1.997770965e-01f + z * (-1.387767345e-01f + z * 8.053703606e-02f)));
}

float ekf_atan2f(float y, float x)
{
    const uint32_t uy = bits_of(y), ux = bits_of(x);
    const float ay = float_of(uy & 0x7FFFFFFFu), ax = float_of(ux & 0x7FFFFFFFu);
    float n, d, z;
    int swapped, left;
    if (!(ay == ay) || !(ax == ax)) {
        return x + y; /* NaN */
    }
    swapped = ay > ax;
    n = swapped ? ax : ay; /* n <= d: z = atan(n / d) in [0, pi/4] */
    d = swapped ? ay : ax;
    if (d == 0.0f) {
        z = 0.0f; /* both zero: the signs below give +-0 or +-pi */
    } else if (d > 3.402823466e+38f) {
        z = (n > 3.402823466e+38f) ? PIO4_HI : 0.0f; /* inf/inf: pi/4; finite/inf: 0 */
    } else if (n > TAN_PI_8 * d) {
        /* atan(n/d) = pi/4 + atan(t), t = (n - d)/(n + d) in (-0.4143, 0]; n + d must not
         * overflow (exact scaling by 1/4: n is far from the subnormals there) */
        float t;
        if (d > 1.0e38f) {
            n *= 0.25f;
            d *= 0.25f;
        }
        t = (n - d) / (n + d);
        z = PIO4_HI + (t + (kernel_atan_tail(t) + PIO4_LO));
    } else {
        const float t = n / d;
        z = t + kernel_atan_tail(t);
    }
    /* the angle from z = atan(n/d): z, pi/2 -+ z or pi - z, with the constants in two parts;
     * the left half-plane is x < 0, or x = -0 with y = 0 */
    left = (ux >> 31) != 0u && (ax != 0.0f || ay == 0.0f);
    if (swapped) {
        z = left ? PIO2_HI + (z + PIO2_LO) : PIO2_HI - (z - PIO2_LO);
    } else if (left) {
        z = PI_HI - (z - PI_LO);
    }
    return (uy >> 31) ? -z : z;
}

/* ---- square root ---------------------------------------------------------------------- */

float ekf_sqrtf_soft(float a)
{
    uint32_t u = bits_of(a), m, rem, root, bit, trial;
    int32_t e;
    if (u >= 0x80000000u) {
        return (u == 0x80000000u) ? a : float_of(0x7FC00000u); /* -0, or negative/-NaN: NaN */
    }
    if (u >= 0x7F800000u || u == 0u) {
        return a + a; /* +inf, NaN (quieted), +0 */
    }
    e = (int32_t)(u >> 23);
    m = u & 0x007FFFFFu;
    if (e == 0) { /* subnormal: normalise so that bit 23 is the leading one */
        e = 1;
        while ((m & 0x00800000u) == 0u) {
            m <<= 1;
            --e;
        }
    } else {
        m |= 0x00800000u;
    }
    e -= 127;
    if (e & 1) { /* make the exponent even: a = m 2^(e - 23), m in [2^23, 2^25) */
        m <<= 1;
        --e;
    }
    /* Digit recurrence for sqrt(m 2^-23) in [1, 2), 25 bits (24 + a rounding bit), each
     * step testing one bit of the root: rem holds (m 2^-23 - root^2) scaled by 2^(24 + i)
     * at step i, 2 root + bit in the same scale is trial. */
    rem = m << 1;
    root = 0u;
    bit = 0x01000000u;
    {
        uint32_t s = 0u;
        while (bit != 0u) {
            trial = s + bit;
            if (trial <= rem) {
                s = trial + bit;
                rem -= trial;
                root += bit;
            }
            rem <<= 1;
            bit >>= 1;
        }
    }
    /* root = floor(sqrt * 2^24). An exact tie between two floats is impossible for a square
     * root, so the rounding bit alone decides (round half up = to nearest). The increment may
     * carry into the exponent, which the addition of the bit fields handles. */
    return float_of(((uint32_t)(e / 2 + 126) << 23) + ((root + 1u) >> 1));
}
