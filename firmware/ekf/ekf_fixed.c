/*
 * ekf_fixed.c - Q-format multiply, divide, square root, trigonometry and conversions
 * (see ekf_fixed.h; formats, error bounds and their derivation in docs/fixed_point.md).
 *
 * Only integer arithmetic inside the filter's operations: no libm, no floating point
 * (the conversions at the API boundary excepted), so a Cortex-M3 runs them without any
 * soft-float call.
 */
#include "ekf_fixed.h"

#include <math.h> /* HUGE_VAL, HUGE_VALF only */

#define FRAC EKF_FX_FRAC
#define ONE_U ((uint64_t)1 << FRAC)

static uint32_t g_saturations;

uint32_t ekf_fx_saturations(void) { return g_saturations; }
void ekf_fx_saturations_reset(void) { g_saturations = 0u; }

ekf_fx_t ekf_fx_saturate(int sign)
{
    if (g_saturations != UINT32_MAX) {
        ++g_saturations;
    }
    return (sign >= 0) ? EKF_FX_INF : EKF_FX_NINF;
}

/* |a| as unsigned (a finite, so |a| < 2^63). */
static uint64_t mag(ekf_fx_t a) { return (a < 0) ? (uint64_t)0 - (uint64_t)a : (uint64_t)a; }

/* Magnitude q (< 2^63 required) with a sign; q >= 2^63 - 1 saturates. */
static ekf_fx_t signed_result(uint64_t q, int neg)
{
    if (q >= (uint64_t)EKF_FX_INF) {
        return ekf_fx_saturate(neg ? -1 : 1);
    }
    return neg ? -(ekf_fx_t)q : (ekf_fx_t)q;
}

/* ---- multiply: 64 x 64 -> 128 bits from four 32 x 32 -> 64 products, round, shift ---- */
ekf_fx_t ekf_fx_mul(ekf_fx_t a, ekf_fx_t b)
{
    uint64_t ua, ub, p00, p01, p10, p11, mid, lo, hi;
    const int neg = (a < 0) != (b < 0);
    if (!ekf_fx_isfinite(a) || !ekf_fx_isfinite(b)) {
        if (a == 0 || b == 0) {
            return EKF_FX_INF; /* 0 * inf: not a number */
        }
        return neg ? EKF_FX_NINF : EKF_FX_INF;
    }
    ua = mag(a);
    ub = mag(b);
    p00 = (uint64_t)(uint32_t)ua * (uint32_t)ub;
    p01 = (uint64_t)(uint32_t)ua * (uint32_t)(ub >> 32);
    p10 = (uint64_t)(uint32_t)(ua >> 32) * (uint32_t)ub;
    p11 = (uint64_t)(uint32_t)(ua >> 32) * (uint32_t)(ub >> 32);
    mid = (p00 >> 32) + (uint32_t)p01 + (uint32_t)p10; /* < 3 * 2^32: no overflow */
    lo = (mid << 32) | (uint32_t)p00;
    hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
    /* round half away from zero (on the magnitude): mul(-a, b) == -mul(a, b) exactly */
    lo += ONE_U >> 1;
    if (lo < (ONE_U >> 1)) {
        ++hi;
    }
    if ((hi >> (FRAC - 1)) != 0u) { /* the result needs 64 bits or more */
        return ekf_fx_saturate(neg ? -1 : 1);
    }
    return signed_result((hi << (64 - FRAC)) | (lo >> FRAC), neg);
}

/* ---- divide: integer part by 64-bit division, fraction bits by restoring division ---- */
ekf_fx_t ekf_fx_div(ekf_fx_t a, ekf_fx_t b)
{
    uint64_t ua, ub, q, r;
    int i;
    const int neg = (a < 0) != (b < 0);
    if (!ekf_fx_isfinite(b)) {
        return ekf_fx_isfinite(a) ? 0 : EKF_FX_INF; /* x / inf = 0; inf / inf: not a number */
    }
    if (!ekf_fx_isfinite(a)) {
        return neg ? EKF_FX_NINF : EKF_FX_INF; /* inf / x, inf / 0 too: no new event */
    }
    if (b == 0) {
        return ekf_fx_saturate((a < 0) ? -1 : 1); /* x / 0 = +-inf, 0 / 0 = +inf: counted */
    }
    ua = mag(a);
    ub = mag(b);
    q = ua / ub;
    r = ua % ub;
    if ((q >> (63 - FRAC)) != 0u) {
        return ekf_fx_saturate(neg ? -1 : 1);
    }
    for (i = 0; i < FRAC; ++i) { /* r < ub < 2^63: r << 1 fits */
        q <<= 1;
        r <<= 1;
        if (r >= ub) {
            r -= ub;
            q |= 1u;
        }
    }
    if (r >= ub - r) { /* remainder >= half the divisor: round up */
        ++q;
    }
    return signed_result(q, neg);
}

/* ---- square root ---- */

/* Number of leading zero bits of a non-zero 64-bit value. */
static int clz64(uint64_t v)
{
    int n = 0;
    if ((v >> 32) == 0u) { n += 32; v <<= 32; }
    if ((v >> 48) == 0u) { n += 16; v <<= 16; }
    if ((v >> 56) == 0u) { n += 8; v <<= 8; }
    if ((v >> 60) == 0u) { n += 4; v <<= 4; }
    if ((v >> 62) == 0u) { n += 2; v <<= 2; }
    if ((v >> 63) == 0u) { n += 1; }
    return n;
}

ekf_fx_t ekf_fx_sqrt(ekf_fx_t a)
{
    uint64_t m, res = 0u, bit = (uint64_t)1 << 62;
    int s, e;
    if (!ekf_fx_isfinite(a)) {
        return EKF_FX_INF; /* sqrt(inf) = inf, sqrt(-inf) not a number: no new event */
    }
    if (a <= 0) {
        return (a == 0) ? 0 : ekf_fx_saturate(1); /* sqrt(x < 0): not a number, counted */
    }
    /* a * 2^FRAC = m * 2^e with m = a << s in [2^62, 2^64) and e = FRAC - s even:
     * sqrt = sqrt(m) * 2^(e / 2), sqrt(m) a 32-bit integer (digit-by-digit) */
    s = clz64((uint64_t)a);
    if (((FRAC - s) & 1) != 0) {
        --s;
    }
    m = (uint64_t)a << s;
    e = FRAC - s;
    while (bit != 0u) {
        if (m >= res + bit) {
            m -= res + bit;
            res = (res >> 1) + bit;
        } else {
            res >>= 1;
        }
        bit >>= 2;
    }
    if (m > res) { /* remainder above the root: (root + 1/2)^2 < radicand, round up */
        ++res;
    }
    if (e >= 0) {
        return (ekf_fx_t)(res << (e / 2)); /* < 2^(32 + 20): in range for FRAC <= 52 */
    }
    return (ekf_fx_t)((res + ((uint64_t)1 << (-e / 2 - 1))) >> (-e / 2));
}

/* ---- trigonometry ---- */

/* pi/2 in Q2.62 (exact to 2^-62): split into the Q format part and the rest. */
#define PIO2_Q62 0x6487ED5110B4611AULL
#define PIO2_HI (PIO2_Q62 >> (62 - FRAC))
#define PIO2_LO (PIO2_Q62 & (((uint64_t)1 << (62 - FRAC)) - 1u))

/* Taylor coefficients, Horner order in u = r^2 (docs/fixed_point.md). */
static const ekf_fx_t k_sin[6] = {
    EKF_FX_C(1.0 / 6227020800.0), EKF_FX_C(-1.0 / 39916800.0), EKF_FX_C(1.0 / 362880.0),
    EKF_FX_C(-1.0 / 5040.0), EKF_FX_C(1.0 / 120.0), EKF_FX_C(-1.0 / 6.0)};
static const ekf_fx_t k_cos[7] = {
    EKF_FX_C(-1.0 / 87178291200.0), EKF_FX_C(1.0 / 479001600.0), EKF_FX_C(-1.0 / 3628800.0),
    EKF_FX_C(1.0 / 40320.0), EKF_FX_C(-1.0 / 720.0), EKF_FX_C(1.0 / 24.0), EKF_FX_C(-1.0 / 2.0)};

/* sin and cos of a finite angle. */
static void sincos_fx(ekf_fx_t a, ekf_fx_t *s_out, ekf_fx_t *c_out)
{
    const uint64_t ua = mag(a);
    uint64_t n;
    ekf_fx_t r, u, ps, pc, s, c, t;
    int k;
    /* n = round(|a| / (pi/2)); r = |a| - n pi/2 in [-pi/4, pi/4] (+ rounding), computed
     * with pi/2 to 62 bits so that the reduction is exact to < 1 LSB for |a| <= 2^20 */
    n = (uint64_t)ekf_fx_mul((ekf_fx_t)ua, EKF_FX_C(0.63661977236758134308)) + (ONE_U >> 1);
    n >>= FRAC;
    r = (ekf_fx_t)(ua - n * PIO2_HI); /* wraps to the small signed difference */
    r = (ekf_fx_t)((uint64_t)r - ((n * PIO2_LO + ((uint64_t)1 << (61 - FRAC))) >> (62 - FRAC)));
    u = ekf_fx_mul(r, r);
    ps = k_sin[0];
    for (k = 1; k < 6; ++k) {
        ps = ekf_fx_add(ekf_fx_mul(ps, u), k_sin[k]);
    }
    s = ekf_fx_add(r, ekf_fx_mul(ekf_fx_mul(ps, u), r));
    pc = k_cos[0];
    for (k = 1; k < 7; ++k) {
        pc = ekf_fx_add(ekf_fx_mul(pc, u), k_cos[k]);
    }
    c = ekf_fx_add(EKF_FX_ONE, ekf_fx_mul(pc, u));
    switch (n & 3u) {
    case 1u: t = s; s = c; c = -t; break;
    case 2u: s = -s; c = -c; break;
    case 3u: t = s; s = -c; c = t; break;
    default: break;
    }
    *s_out = (a < 0) ? -s : s;
    *c_out = c;
}

ekf_fx_t ekf_fx_sin(ekf_fx_t a)
{
    ekf_fx_t s, c;
    if (!ekf_fx_isfinite(a)) {
        return EKF_FX_INF; /* sin(inf): not a number; stays non-finite */
    }
    sincos_fx(a, &s, &c);
    return s;
}

ekf_fx_t ekf_fx_cos(ekf_fx_t a)
{
    ekf_fx_t s, c;
    if (!ekf_fx_isfinite(a)) {
        return EKF_FX_INF;
    }
    sincos_fx(a, &s, &c);
    return c;
}

/* atan(t) = t P(t^2) for |t| <= tan(pi/8): weighted least squares, degree 15 in t,
 * max abs error 1.5e-13 in exact arithmetic (docs/fixed_point.md). Horner order. */
static const ekf_fx_t k_atan[8] = {
    EKF_FX_C(-0.03642757107335588), EKF_FX_C(0.06895041801554433), EKF_FX_C(-0.0897212775857512),
    EKF_FX_C(0.11100771517914702),  EKF_FX_C(-0.14285197350280235), EKF_FX_C(0.199999862043882),
    EKF_FX_C(-0.3333333316746715),  EKF_FX_C(0.9999999999941789)};

static ekf_fx_t atan_small(ekf_fx_t t)
{
    const ekf_fx_t u = ekf_fx_mul(t, t);
    ekf_fx_t p = k_atan[0];
    int k;
    for (k = 1; k < 8; ++k) {
        p = ekf_fx_add(ekf_fx_mul(p, u), k_atan[k]);
    }
    return ekf_fx_mul(p, t);
}

ekf_fx_t ekf_fx_atan2(ekf_fx_t y, ekf_fx_t x)
{
    const ekf_fx_t pi_4 = EKF_FX_C(0.78539816339744830962);
    const ekf_fx_t pi_2 = EKF_FX_C(1.57079632679489661923);
    const ekf_fx_t pi = EKF_FX_C(3.14159265358979323846);
    ekf_fx_t ax, ay, lo, hi, ang;
    int swapped;
    if (!ekf_fx_isfinite(x) || !ekf_fx_isfinite(y)) {
        return EKF_FX_INF; /* no defined direction: stays non-finite */
    }
    if (x == 0 && y == 0) {
        return 0; /* as libm's atan2(+0, +0) */
    }
    ax = ekf_fx_abs(x);
    ay = ekf_fx_abs(y);
    if (ax > (EKF_FX_INF >> 2) || ay > (EKF_FX_INF >> 2)) { /* keep lo + hi in range */
        ax >>= 2;
        ay >>= 2;
    }
    swapped = ay > ax;
    lo = swapped ? ax : ay;
    hi = swapped ? ay : ax;
    /* lo / hi in [0, 1]: above tan(pi/8), atan(lo / hi) = pi/4 + atan((lo - hi) / (lo + hi))
     * with the argument in [-tan(pi/8), 0]: one division either way */
    if (lo > ekf_fx_mul(hi, EKF_FX_C(0.41421356237309504880))) {
        ang = ekf_fx_add(pi_4, atan_small(ekf_fx_div(ekf_fx_sub(lo, hi), ekf_fx_add(lo, hi))));
    } else {
        ang = atan_small(ekf_fx_div(lo, hi));
    }
    if (swapped) {
        ang = ekf_fx_sub(pi_2, ang);
    }
    if (x < 0) {
        ang = ekf_fx_sub(pi, ang);
    }
    return (y < 0) ? -ang : ang;
}

/* ---- conversions at the API boundary ---- */

ekf_fx_t ekf_fx_from_double(double a)
{
    const double limit = (double)((uint64_t)1 << (63 - FRAC)); /* first value out of range */
    double v;
    ekf_fx_t i;
    if (a != a) {
        return EKF_FX_INF; /* NaN */
    }
    if (a >= limit || a <= -limit) {
        if (a == HUGE_VAL || a == -HUGE_VAL) {
            return (a > 0.0) ? EKF_FX_INF : EKF_FX_NINF; /* infinity: not counted */
        }
        return ekf_fx_saturate(a > 0.0 ? 1 : -1); /* finite, beyond the range: counted */
    }
    v = a * EKF_FX_SCALE;
    i = (ekf_fx_t)v; /* toward zero */
    if (v - (double)i >= 0.5) {
        ++i;
    } else if (v - (double)i <= -0.5) {
        --i;
    }
    return i;
}

ekf_fx_t ekf_fx_from_float(float a)
{
    /* in float arithmetic: a * 2^FRAC is exact (a power of two), so only the final
     * conversion rounds; no double arithmetic on an FPU-less or single-precision target */
    const float limit = (float)((uint64_t)1 << (63 - FRAC));
    const float scale = (float)EKF_FX_ONE;
    float v;
    ekf_fx_t i;
    if (a != a) {
        return EKF_FX_INF;
    }
    if (a >= limit || a <= -limit) {
        if (a == HUGE_VALF || a == -HUGE_VALF) {
            return (a > 0.0f) ? EKF_FX_INF : EKF_FX_NINF; /* infinity: not counted */
        }
        return ekf_fx_saturate(a > 0.0f ? 1 : -1); /* finite (3.4e38 too), beyond the range */
    }
    v = a * scale;
    i = (ekf_fx_t)v;
    if (v - (float)i >= 0.5f) {
        ++i;
    } else if (v - (float)i <= -0.5f) {
        --i;
    }
    return i;
}

ekf_fx_t ekf_fx_from_int(int32_t a)
{
    const int64_t limit = (int64_t)1 << (63 - FRAC);
    if (a >= limit || a <= -limit) {
        return ekf_fx_saturate(a > 0 ? 1 : -1);
    }
    return (ekf_fx_t)((uint64_t)(int64_t)a << FRAC);
}

double ekf_fx_to_double(ekf_fx_t a)
{
    if (!ekf_fx_isfinite(a)) {
        return (a > 0) ? HUGE_VAL : -HUGE_VAL;
    }
    return (double)a / EKF_FX_SCALE;
}

float ekf_fx_to_float(ekf_fx_t a)
{
    if (!ekf_fx_isfinite(a)) {
        return (a > 0) ? HUGE_VALF : -HUGE_VALF;
    }
    return (float)a * (1.0f / (float)EKF_FX_ONE);
}
