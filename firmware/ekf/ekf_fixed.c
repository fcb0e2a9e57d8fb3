/*
 * ekf_fixed.c - Q-format multiply, divide, square root, trigonometry and conversions
 * (see ekf_fixed.h; formats, error bounds and their derivation in docs/fixed_point.md).
 *
 * Only integer arithmetic inside the filter's operations: no libm, no floating point
 * (the conversions at the API boundary excepted), so a Cortex-M3 runs them without any
 * soft-float call. Every multiply is a 32 x 32 -> 64 one (UMULL, SMULL, MLA on the M3);
 * the only divide instruction used is the M3's 32 / 32 UDIV (a reciprocal's seed).
 */
#include "ekf_fixed.h"

#include <math.h> /* HUGE_VAL, HUGE_VALF only */

#define FRAC EKF_FX_FRAC
#define ONE_U ((uint64_t)1 << FRAC)

#if defined(EKF_FX_SATURATION_HOOK)
void EKF_FX_SATURATION_HOOK(void);
#endif

ekf_fx_t ekf_fx_saturate(int sign)
{
#if defined(EKF_FX_SATURATION_HOOK)
    EKF_FX_SATURATION_HOOK();
#endif
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

#if !defined(__GNUC__)
int ekf_fx_clz32(uint32_t v)
{
    int n = 0;
    if ((v >> 16) == 0u) { n += 16; v <<= 16; }
    if ((v >> 24) == 0u) { n += 8; v <<= 8; }
    if ((v >> 28) == 0u) { n += 4; v <<= 4; }
    if ((v >> 30) == 0u) { n += 2; v <<= 2; }
    if ((v >> 31) == 0u) { n += 1; }
    return n;
}
#endif

/* Number of leading zero bits of a non-zero 64-bit value. */
static int clz64(uint64_t v)
{
    const uint32_t hi = (uint32_t)(v >> 32);
    return (hi != 0u) ? ekf_fx_clz32(hi) : 32 + ekf_fx_clz32((uint32_t)v);
}

/* ---- add: the cases the inline fast path leaves (large operands, infinities) ---- */
ekf_fx_t ekf_fx_add_slow(ekf_fx_t a, ekf_fx_t b)
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

/* ---- multiply ---- */

/* Both high words in [-2^15, 2^15) (|a|, |b| < 2^47, i.e. below 8192 in Q29.34): the
 * product is below 2^94, the result below 2^60, no infinity among the operands. */
static int mul_fast_ok(ekf_fx_t a, ekf_fx_t b)
{
    return (((uint32_t)ekf_fx_hi(a) + 0x8000u) | ((uint32_t)ekf_fx_hi(b) + 0x8000u)) < 0x10000u;
}

/* The fast path: P = hh 2^64 + mid 2^32 + lo from a = ah 2^32 + al, b = bh 2^32 + bl
 * (ah, bh signed, al, bl unsigned); round(P / 2^F) half up = hh 2^(64-F) +
 * floor((mid + 2^(F-33)) / 2^(F-32)): the low word lo cannot move that floor. */
static ekf_fx_t mul_fast(ekf_fx_t a, ekf_fx_t b)
{
    const int32_t ah = ekf_fx_hi(a), bh = ekf_fx_hi(b);
    const uint32_t al = (uint32_t)a, bl = (uint32_t)b;
    const uint64_t ll = (uint64_t)al * bl;
    const int64_t mid = (int64_t)ah * (int64_t)bl + (int64_t)bh * (int64_t)al + (int64_t)(ll >> 32);
    const int32_t hh = ah * bh; /* |hh| <= 2^30 */
    return (ekf_fx_t)((uint64_t)(int64_t)hh << (64 - FRAC)) + ((mid + ((int64_t)1 << (FRAC - 33))) >> (FRAC - 32));
}

/* Any finite or infinite operands: the exact 128-bit product of the magnitudes. */
static ekf_fx_t mul_slow(ekf_fx_t a, ekf_fx_t b)
{
    uint64_t ua, ub, p00, p01, p10, p11, mid, lo, hi, half;
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
    /* ties toward +inf as in the fast path: half up on a positive magnitude, just below
     * half on a negative one */
    half = (ONE_U >> 1) - (neg ? 1u : 0u);
    lo += half;
    if (lo < half) {
        ++hi;
    }
    if ((hi >> (FRAC - 1)) != 0u) { /* the result needs 64 bits or more */
        return ekf_fx_saturate(neg ? -1 : 1);
    }
    return signed_result((hi << (64 - FRAC)) | (lo >> FRAC), neg);
}

ekf_fx_t ekf_fx_mul(ekf_fx_t a, ekf_fx_t b) { return mul_fast_ok(a, b) ? mul_fast(a, b) : mul_slow(a, b); }

ekf_fx_t ekf_fx_mac(ekf_fx_t c, ekf_fx_t a, ekf_fx_t b)
{
    return ekf_fx_add(c, mul_fast_ok(a, b) ? mul_fast(a, b) : mul_slow(a, b));
}

/* ---- reciprocal, reciprocal square root (32-bit) ---- */

uint32_t ekf_fx_recip32(uint32_t d)
{
    /* seed 2^63 / d from the M3's 32 / 32 divide on d's top 16 bits, rounded up (so the
     * seed is below the target, by at most 2^-15 of it); two Newton steps
     * x += x (2^63 - d x) / 2^63 stay below it and double the correct bits each (at most 1
     * below the target after them, measured) */
    uint64_t x = ((uint64_t)(0xFFFFFFFFu / ((d >> 16) + 1u))) << 15;
    uint64_t e = ((uint64_t)1 << 63) - (uint64_t)d * x; /* >= 0, < 2^49 */
    x += ((uint64_t)(uint32_t)x * (uint32_t)(e >> 17)) >> 46;
    e = ((uint64_t)1 << 63) - (uint64_t)d * x; /* >= 0, < 2^36 */
    x += ((uint64_t)(uint32_t)x * (uint32_t)(e >> 4)) >> 59;
    return (x > 0xFFFFFFFFu) ? 0xFFFFFFFFu : (uint32_t)x;
}

/* Seeds of 2^31 / sqrt(d / 2^32) for the 48 ranges of the top six bits of a d in
 * [2^30, 2^32) (index d >> 26, 16 .. 63), in units of 2^16: each the value at its range's
 * upper end, below the target by at most 3 %. Three Newton steps leave it within -1 .. +2.5
 * (the truncated products can carry it just above). */
static const uint16_t k_rsqrt_seed[48] = {
    63579u, 61787u, 60139u, 58617u, 57204u, 55889u, 54660u, 53509u, 52428u, 51410u, 50449u, 49540u,
    48678u, 47860u, 47082u, 46340u, 45633u, 44957u, 44310u, 43690u, 43096u, 42525u, 41976u, 41448u,
    40940u, 40449u, 39976u, 39519u, 39078u, 38651u, 38237u, 37837u, 37449u, 37072u, 36707u, 36352u,
    36008u, 35673u, 35347u, 35030u, 34721u, 34421u, 34128u, 33842u, 33564u, 33292u, 33027u, 32768u};

uint32_t ekf_fx_rsqrt32(uint32_t d)
{
    /* r = rho 2^31 with rho = 1/sqrt(d / 2^32); Newton rho' = rho (3 - D rho^2) / 2 */
    uint64_t r = (uint64_t)k_rsqrt_seed[(d >> 26) - 16u] << 16;
    int k;
    for (k = 0; k < 3; ++k) {
        const uint32_t sq = (uint32_t)((r * r) >> 32);                   /* rho^2 2^30 */
        const uint32_t t = (uint32_t)(((uint64_t)d * sq) >> 32);          /* D rho^2 2^30, < 2^30 */
        r = (r * (0xC0000000u - t)) >> 31;
    }
    return (r > 0xFFFFFFFFu) ? 0xFFFFFFFFu : (uint32_t)r;
}

/* ---- divide ---- */

/* One 32-bit digit of a long division by D (normalised, >= 2^63, top word d1, reciprocal
 * r1 = recip32(d1)): the dividend part (hi 2^32 + lo) with hi < D. Returns the digit and
 * leaves the remainder (< D) in *hi. The estimate hi r1 / 2^63 is within -6 .. +2 of the
 * digit; two less is never above it, and the remainder steps up to it. */
static uint32_t div_digit(uint64_t *hi, uint32_t lo, uint64_t D, uint32_t r1)
{
    const uint64_t h = *hi;
    const uint64_t t = (uint64_t)(uint32_t)(h >> 32) * r1 + (((uint64_t)(uint32_t)h * r1) >> 32);
    uint64_t q = t >> 31, p_lo, p_mid, low;
    uint32_t top;
    q = (q > 2u) ? q - 2u : 0u;
    if (q > 0xFFFFFFFFu) {
        q = 0xFFFFFFFFu;
    }
    /* remainder (h 2^32 + lo) - q D, as top 2^64 + low */
    p_lo = (uint64_t)(uint32_t)q * (uint32_t)D;
    p_mid = (uint64_t)(uint32_t)q * (uint32_t)(D >> 32) + (p_lo >> 32);
    low = (h << 32) | lo;
    top = (uint32_t)(h >> 32) - (uint32_t)(p_mid >> 32);
    {
        const uint64_t prod_low = (p_mid << 32) | (uint32_t)p_lo;
        if (low < prod_low) {
            --top;
        }
        low -= prod_low;
    }
    while (top != 0u || low >= D) {
        if (low < D) {
            --top;
        }
        low -= D;
        ++q;
    }
    *hi = low;
    return (uint32_t)q;
}

ekf_fx_t ekf_fx_div(ekf_fx_t a, ekf_fx_t b)
{
    uint64_t ua, ub, D, n_hi, n_lo, rem, q;
    uint32_t r1, q1, q0;
    int s, k;
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
    if ((ua >> (63 - FRAC)) >= ub) { /* quotient >= 2^63 */
        return ekf_fx_saturate(neg ? -1 : 1);
    }
    /* q = round(ua 2^F / ub): numerator and divisor shifted by s so that the divisor's
     * top bit is set; the numerator ua 2^(F+s) < 2^128 then (the quotient < 2^64) */
    s = clz64(ub);
    D = ub << s;
    k = FRAC + s;
    if (k >= 64) {
        n_hi = ua << (k - 64);
        n_lo = 0u;
    } else {
        n_hi = ua >> (64 - k);
        n_lo = ua << k;
    }
    r1 = ekf_fx_recip32((uint32_t)(D >> 32));
    rem = n_hi;
    q1 = div_digit(&rem, (uint32_t)(n_lo >> 32), D, r1);
    q0 = div_digit(&rem, (uint32_t)n_lo, D, r1);
    q = ((uint64_t)q1 << 32) | q0;
    if (rem >= D - rem) { /* remainder >= half the divisor: round up */
        ++q;
    }
    return signed_result(q, neg);
}

/* ---- square root ---- */

ekf_fx_t ekf_fx_sqrt(ekf_fx_t a)
{
    uint64_t m, y, y2;
    uint32_t d;
    int s, e;
    if (!ekf_fx_isfinite(a)) {
        return EKF_FX_INF; /* sqrt(inf) = inf, sqrt(-inf) not a number: no new event */
    }
    if (a <= 0) {
        return (a == 0) ? 0 : ekf_fx_saturate(1); /* sqrt(x < 0): not a number, counted */
    }
    /* a 2^FRAC = m 2^e with m = a << s in [2^62, 2^64) and e = FRAC - s even:
     * sqrt = sqrt(m) 2^(e / 2), sqrt(m) a 32-bit integer */
    s = clz64((uint64_t)a);
    if (((FRAC - s) & 1) != 0) {
        --s;
    }
    m = (uint64_t)a << s;
    e = FRAC - s;
    /* estimate from the top word: 2^16 sqrt(d) = d rsqrt(d) / 2^31, within -7 .. +1 of
     * floor(sqrt(m)); then the exact floor by squaring */
    d = (uint32_t)(m >> 32);
    y = ((uint64_t)d * ekf_fx_rsqrt32(d)) >> 31;
    if (y > 0xFFFFFFFFu) {
        y = 0xFFFFFFFFu;
    }
    y2 = y * y;
    while (y2 > m) {
        y2 -= 2u * y - 1u;
        --y;
    }
    while (y < 0xFFFFFFFFu && m - y2 >= 2u * y + 1u) { /* (y + 1)^2 <= m */
        y2 += 2u * y + 1u;
        ++y;
    }
    if (m - y2 > y) { /* remainder above the root: (root + 1/2)^2 < radicand, round up */
        ++y;
    }
    if (e >= 0) {
        return (ekf_fx_t)(y << (e / 2)); /* < 2^(32 + 20): in range for FRAC <= 52 */
    }
    return (ekf_fx_t)((y + ((uint64_t)1 << (-e / 2 - 1))) >> (-e / 2));
}

/* ---- trigonometry ---- */

/* Q0.31 product, rounded. */
static int32_t mulq31(int32_t a, int32_t b) { return (int32_t)(((int64_t)a * b + 0x40000000) >> 31); }

/* pi/2 in Q2.62 (exact to 2^-62): split into the Q format part and the rest. */
#define PIO2_Q62 0x6487ED5110B4611AULL
#define PIO2_HI (PIO2_Q62 >> (62 - FRAC))
#define PIO2_LO (PIO2_Q62 & (((uint64_t)1 << (62 - FRAC)) - 1u))
#define Q31(x) ((int32_t)((x) * 2147483648.0 + (((x) < 0) ? -0.5 : 0.5)))

/* Minimax on |r| <= pi/4 + 2e-3 (scripts/fit_fixed_poly.py, docs/fixed_point.md): sin(r) =
 * r + r u S(u), cos(r) = 1 + u C(u), u = r^2; Horner order, Q0.31. Approximation errors
 * 2.4e-12 and 6.4e-14, below the 32-bit rounding. */
static const int32_t k_sin[4] = {Q31(2.7158128532516944e-06), Q31(-0.00019839021113052878),
                                 Q31(0.008333328160648894), Q31(-0.166666666272065)};
static const int32_t k_cos[5] = {Q31(-2.717818513005281e-07), Q31(2.479901506251693e-05),
                                 Q31(-0.0013888880958799854), Q31(0.04166666655992981),
                                 Q31(-0.49999999999533373)};

void ekf_fx_sincos(ekf_fx_t a, ekf_fx_t *s_out, ekf_fx_t *c_out)
{
    const uint64_t ua = mag(a);
    uint64_t n;
    ekf_fx_t r, s, c, t;
    int32_t r31, u, p;
    int k;
    if (!ekf_fx_isfinite(a)) {
        *s_out = EKF_FX_INF; /* sin(inf): not a number; stays non-finite */
        *c_out = EKF_FX_INF;
        return;
    }
    /* n = round(|a| / (pi/2)); r = |a| - n pi/2 in [-pi/4, pi/4] (+ 2^-27 where n is
     * rounded from a shortened |a|), computed with pi/2 to 62 bits so that the reduction
     * is exact to < 1 LSB for |a| <= 2^20 */
    if (ua < ((uint64_t)1 << (FRAC + 5))) { /* |a| < 32: |a| to 2^-26 is enough for n */
        n = (((ua >> (FRAC - 26)) * 0xA2F9836Eu) + ((uint64_t)1 << 57)) >> 58; /* 2/pi in Q0.32 */
    } else {
        n = ((uint64_t)ekf_fx_mul((ekf_fx_t)ua, EKF_FX_C(0.63661977236758134308)) + (ONE_U >> 1)) >> FRAC;
    }
    r = (ekf_fx_t)(ua - n * PIO2_HI); /* wraps to the small signed difference */
    r = (ekf_fx_t)((uint64_t)r - ((n * PIO2_LO + ((uint64_t)1 << (61 - FRAC))) >> (62 - FRAC)));
    /* |r| < 0.79: Q0.31 */
    r31 = (int32_t)((r + ((ekf_fx_t)1 << (FRAC - 32))) >> (FRAC - 31));
    u = mulq31(r31, r31);
    p = k_sin[0];
    for (k = 1; k < 4; ++k) {
        p = k_sin[k] + mulq31(p, u);
    }
    /* the linear term exact, the correction r u S(u) (|.| < 0.081) in Q0.31 */
    s = r + (ekf_fx_t)mulq31(r31, mulq31(u, p)) * ((ekf_fx_t)1 << (FRAC - 31)); /* a negative value times 2^k: no left shift of it (undefined) */
    p = k_cos[0];
    for (k = 1; k < 5; ++k) {
        p = k_cos[k] + mulq31(p, u);
    }
    c = EKF_FX_ONE + (ekf_fx_t)mulq31(u, p) * ((ekf_fx_t)1 << (FRAC - 31));
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
    ekf_fx_sincos(a, &s, &c);
    return s;
}

ekf_fx_t ekf_fx_cos(ekf_fx_t a)
{
    ekf_fx_t s, c;
    ekf_fx_sincos(a, &s, &c);
    return c;
}

/* atan(t) = t + t u A(u), u = t^2, |t| <= tan(pi/8) + 1e-4: minimax, approximation error
 * 5.2e-12 (scripts/fit_fixed_poly.py). Horner order, Q0.31. */
static const int32_t k_atan[6] = {Q31(0.04632118736540936), Q31(-0.08416507650017625), Q31(0.11032636770587252),
                                  Q31(-0.1428087784151214), Q31(0.19999855889087043), Q31(-0.33333331788177134)};

/* atan(num / den) for 0 <= num <= tan(pi/8) den (+ rounding), den > 0, as Q29.34. */
static ekf_fx_t atan_small(uint64_t num, uint64_t den)
{
    /* t = num / den from the 32 top bits of both (den normalised, num rounded), rounded in
     * Q0.33 (t < 0.415: below 2^32); the reciprocal's estimate is at most 3 below the
     * floor, the remainder steps up to it */
    const int k = clz64(den);
    const uint32_t dh = (uint32_t)((den << k) >> 32), nh = (uint32_t)(((num << k) + 0x80000000u) >> 32);
    uint64_t tq = ((uint64_t)nh * ekf_fx_recip32(dh)) >> 30;
    uint64_t rem = ((uint64_t)nh << 33) - tq * dh; /* nh < 0.42 dh: below 2^64 */
    int32_t t, u, p;
    int i;
    while (rem >= dh) {
        rem -= dh;
        ++tq;
    }
    if (rem >= dh - rem) {
        ++tq;
    }
    /* the linear term in Q0.33, the correction t u A(u) (|.| < 0.023) in Q0.31 */
    t = (int32_t)((tq + 2u) >> 2);
    u = mulq31(t, t);
    p = k_atan[0];
    for (i = 1; i < 6; ++i) {
        p = k_atan[i] + mulq31(p, u);
    }
    return (ekf_fx_t)tq * ((ekf_fx_t)1 << (FRAC - 33)) + (ekf_fx_t)mulq31(t, mulq31(u, p)) * ((ekf_fx_t)1 << (FRAC - 31));
}

ekf_fx_t ekf_fx_atan2(ekf_fx_t y, ekf_fx_t x)
{
    const ekf_fx_t pi_4 = EKF_FX_C(0.78539816339744830962);
    const ekf_fx_t pi_2 = EKF_FX_C(1.57079632679489661923);
    const ekf_fx_t pi = EKF_FX_C(3.14159265358979323846);
    uint64_t ax, ay, lo, hi;
    ekf_fx_t ang;
    int swapped;
    if (!ekf_fx_isfinite(x) || !ekf_fx_isfinite(y)) {
        return EKF_FX_INF; /* no defined direction: stays non-finite */
    }
    if (x == 0 && y == 0) {
        return 0; /* as libm's atan2(+0, +0) */
    }
    ax = mag(x);
    ay = mag(y);
    swapped = ay > ax;
    lo = swapped ? ax : ay;
    hi = swapped ? ay : ax;
    /* lo / hi in [0, 1]: above tan(pi/8), atan(lo / hi) = pi/4 - atan((hi - lo) / (hi + lo))
     * with the argument in [0, tan(pi/8)]: one division either way (hi + lo < 2^64) */
    if (lo > (hi >> 32) * 0x6A09E668u + (((hi & 0xFFFFFFFFu) * 0x6A09E668u) >> 32)) { /* tan(pi/8) hi */
        ang = pi_4 - atan_small(hi - lo, hi + lo);
    } else {
        ang = atan_small(lo, hi);
    }
    if (swapped) {
        ang = pi_2 - ang;
    }
    if (x < 0) {
        ang = pi - ang;
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
