/*
 * att_cov_fx_words.c - the words of the fixed-point covariance (att_cov_fx_words.h): the
 * packed index, rounding and saturation, exponents and renormalisation, the variance floor,
 * a row of values in one scale. Every helper is defined for any word and any exponent the
 * format allows, saturated words included: a shift that would leave the int64 range
 * saturates, a rounding never adds before it shifts.
 */
#include "att_cov_fx_words.h"

const uint8_t att_fx_ix[ATT_N][ATT_N] = {
    {0, 1, 2, 3, 4, 5, 6, 7, 8},          {1, 9, 10, 11, 12, 13, 14, 15, 16},
    {2, 10, 17, 18, 19, 20, 21, 22, 23},  {3, 11, 18, 24, 25, 26, 27, 28, 29},
    {4, 12, 19, 25, 30, 31, 32, 33, 34},  {5, 13, 20, 26, 31, 35, 36, 37, 38},
    {6, 14, 21, 27, 32, 36, 39, 40, 41},  {7, 15, 22, 28, 33, 37, 40, 42, 43},
    {8, 16, 23, 29, 34, 38, 41, 43, 44},
};
const uint8_t att_fx_dg[ATT_N] = {0, 9, 17, 24, 30, 35, 39, 42, 44};

int32_t att_fx_to_c_any(int64_t v, int sh)
{
    if (sh > 0) {
        return att_fx_sat(att_fx_round_shr(v, sh));
    }
    if (v == 0 || sh == 0) {
        return att_fx_sat(v);
    }
    if (-sh >= 32 || att_fx_abslen(v) - sh > 31) {
        return (v > 0) ? INT32_MAX : -INT32_MAX;
    }
    return att_fx_sat((int64_t)((uint64_t)v << -sh));
}

ekf_scalar_t att_fx_to_q(int64_t v, int sh)
{
    if (sh > 0) {
        return att_fx_round_shr(v, sh); /* (|v| < 2^63: not an infinity for sh >= 1) */
    }
    if (v == 0 || sh == 0) {
        return v;
    }
    if (-sh >= 63 || att_fx_abslen(v) - sh > 62) {
        return ekf_fx_saturate(v > 0 ? 1 : -1);
    }
    return (ekf_scalar_t)((uint64_t)v << -sh);
}

int att_fx_norm_exp(uint64_t m, int x)
{
    /* the e with m 2^x 2^(29 - 2e) in [2^29, 2^31): floor((bitlen + x + 29 - 30) / 2) */
    const int n = att_fx_bitlen64(m) + x - 1;
    return (n >= 0) ? n / 2 : -((1 - n) / 2);
}

int32_t att_fx_norm_q(ekf_scalar_t v, int *e)
{
    const uint64_t m = (v < 0) ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
    int en = att_fx_norm_exp(m, -EKF_FX_FRAC);
    int32_t cv;
    en = (en < ATT_FX_E_MIN) ? ATT_FX_E_MIN : en;
    cv = att_fx_to_c((int64_t)m, EKF_FX_FRAC - ATT_FX_CF + 2 * en);
    *e = en;
    return (v < 0) ? -cv : cv;
}

void att_fx_set_exp(att_cov_t *c, int i, int en)
{
    const int k = en - c->e[i];
    int j;
    if (k == 0) {
        return;
    }
    if (k > 0 && k < 16) {
        /* a larger scale (the common case): every word a rounded right shift, as below */
        const uint8_t *ix = att_fx_ix[i];
        for (j = 0; j < ATT_N; ++j) {
            int32_t *p = &c->c[ix[j]];
            const int kk = (j == i) ? 2 * k : k;
            *p = (*p >> kk) + ((*p >> (kk - 1)) & 1);
        }
        c->e[i] = (int8_t)en;
        return;
    }
    if (k < 0 && k > -15) {
        /* a smaller scale (a variance back into the band): exact left shifts when every word
         * of the row, the diagonal shifted twice as far, stays within the word */
        const uint8_t *ix = att_fx_ix[i];
        const int32_t d = c->c[ix[i]];
        uint32_t m = 0u;
        for (j = 0; j < ATT_N; ++j) {
            const int32_t w = c->c[ix[j]];
            m |= (uint32_t)(w ^ (w >> 31));
        }
        if ((m >> (31 + k)) == 0u && ((uint32_t)(d ^ (d >> 31)) >> (31 + 2 * k)) == 0u) {
            for (j = 0; j < ATT_N; ++j) {
                c->c[ix[j]] = (int32_t)((uint32_t)c->c[ix[j]] << ((j == i) ? -2 * k : -k));
            }
            c->e[i] = (int8_t)en;
            return;
        }
    }
    for (j = 0; j < ATT_N; ++j) {
        int32_t *p = &c->c[att_fx_ix[i][j]];
        const int kk = (j == i) ? 2 * k : k;
        if (kk > 0 && kk < 32) { /* a larger scale: rounded right shift (att_fx_w) */
            *p = (*p >> kk) + ((*p >> (kk - 1)) & 1);
        } else if (kk < 0 && kk > -31 && ((*p ^ (*p >> 31)) >> (31 + kk)) == 0) { /* exact left shift */
            *p = (int32_t)((uint32_t)*p << -kk);
        } else {
            *p = att_fx_to_c_any(*p, kk);
        }
    }
    c->e[i] = (int8_t)en;
}

void att_fx_renorm(att_cov_t *c, int i)
{
    const int32_t v = c->c[att_fx_dg[i]];
    int en;
    if (v >= ATT_FX_C_ONE || v <= 0) {
        return;
    }
    en = att_fx_norm_exp((uint64_t)v, 2 * c->e[i] - ATT_FX_CF);
    att_fx_set_exp(c, i, (en < ATT_FX_E_MIN) ? ATT_FX_E_MIN : en);
}

int att_fx_sum_exp(int32_t cii, int ei, uint64_t m, int x)
{
    /* both terms at the exponent y where the larger is below 2^61 (each rounded term at
     * most 2^61, their sum below 2^62) */
    const int x1 = 2 * ei - ATT_FX_CF;
    const int l1 = att_fx_abslen(cii) + x1;
    const int l2 = att_fx_bitlen64(m) + x;
    const int y = ((l1 > l2) ? l1 : l2) - 61;
    const int64_t v = (int64_t)att_fx_to_q((int64_t)cii, y - x1) + att_fx_to_q((int64_t)m, y - x);
    const int en = att_fx_norm_exp((uint64_t)(v < 0 ? -v : v), y);
    return (en < ATT_FX_E_MIN) ? ATT_FX_E_MIN : en;
}

void att_fx_overflow(att_cov_t *c, int i)
{
    (void)ekf_fx_saturate(1);
    c->inf = (uint16_t)(c->inf | (1u << i));
}

int32_t att_fx_floor_c(const att_cov_t *c, int i, ekf_scalar_t floor)
{
    /* floor 2^(29 - 2 e_i) in Q29.34 units: a right shift by sh, rounded up (so that the
     * variance it gives back is at least the floor) */
    const int sh = EKF_FX_FRAC - ATT_FX_CF + 2 * c->e[i];
    if (floor <= 0) {
        return 0;
    }
    if (sh > 0 && sh < 62 && floor < ((ekf_scalar_t)1 << 61)) {
        /* ceil(floor 2^-sh) as the rounding of floor + 2^(sh-1) - 1 (no overflow below 2^62) */
        return att_fx_to_c(floor + (((ekf_scalar_t)1 << (sh - 1)) - 1), sh);
    }
    if (sh > 0) {
        const int64_t q = (sh >= 63) ? 0 : (floor >> sh);
        const int64_t f = q + (((sh >= 63) ? floor : (floor - (q << sh))) != 0);
        return (f >= INT32_MAX) ? INT32_MAX : (int32_t)f;
    }
    return att_fx_to_c(floor, sh);
}

void att_fx_floor_var(att_cov_t *c, int i, ekf_scalar_t floor)
{
    const int32_t f = att_fx_floor_c(c, i, floor);
    int32_t *d = &c->c[att_fx_dg[i]];
    if (f == INT32_MAX) {
        /* the floor does not fit a word of this scale, so every word is below it: the
         * variance becomes the floor in the floor's own scale */
        int en;
        const int32_t v = att_fx_norm_q(floor, &en);
        att_fx_set_exp(c, i, en);
        *d = v;
        return;
    }
    if (*d < f) {
        *d = f;
    }
    att_fx_renorm(c, i);
}

int att_fx_block_row(const int64_t *v, int32_t *w)
{
    const int bits = 30;
    uint64_t m = 0u;
    int j, sh;
    for (j = 0; j < ATT_N; ++j) {
        m |= (v[j] < 0) ? (uint64_t)0 - (uint64_t)v[j] : (uint64_t)v[j];
    }
    sh = ekf_fx_bitlen64(m) - bits;
    /* every |v_j| < 2^(sh + bits): the rounded words stay within 2^30, so
     * att_fx_to_c's range checks are not needed (the same rounding: floor plus the last
     * bit shifted out) */
    if (sh >= 32) {
        const int k = sh - 32;
        for (j = 0; j < ATT_N; ++j) {
            const int32_t hi = (int32_t)(v[j] >> 32);
            w[j] = (hi >> k) + (int32_t)((k > 0) ? ((uint32_t)hi >> (k - 1)) & 1u : (uint32_t)v[j] >> 31);
        }
    } else if (sh > 0) {
        for (j = 0; j < ATT_N; ++j) {
            const int32_t hi = (int32_t)(v[j] >> 32);
            const uint32_t lo = (uint32_t)v[j];
            w[j] = (int32_t)((lo >> sh) | ((uint32_t)hi << (32 - sh))) + (int32_t)((lo >> (sh - 1)) & 1u);
        }
    } else {
        for (j = 0; j < ATT_N; ++j) {
            w[j] = (int32_t)((uint32_t)v[j] << -sh);
        }
    }
    return sh;
}
