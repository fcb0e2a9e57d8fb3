/*
 * att_cov_fx.c - the covariance of the fixed-point build (att_cov.h, ATT_COV_FX): 32-bit
 * words with a power-of-two scale per state (docs/fixed_point.md, "Covariance").
 *
 * P_ij = C_ij 2^(e_i + e_j - 29): C is P normalised by s_i = 2^e_i, each C_ii kept in
 * [2^29, 2^31) (1 <= c_ii < 4), so every |C_ij| < 4 (for a positive semi-definite P) in
 * Q2.29, whatever the variances: a tilt variance of 1e-7 and a heading variance of pi^2 both
 * have 29 to 31 significant bits. Every operation works on C with 32 x 32 -> 64 multiplies
 * and changes an exponent when a variance leaves the band (renormalisation: a row and
 * column shifted). The kernels for the propagation and the updates are in
 * att_cov_fx_kernels.c; this file holds the storage, the conversions, the small operations
 * (the rate noise of the alignment too) and the definiteness guard.
 */
#include "att_cov_fx.h"

const uint8_t att_fx_ix[ATT_N][ATT_N] = {
    {0, 1, 2, 3, 4, 5, 6, 7, 8},          {1, 9, 10, 11, 12, 13, 14, 15, 16},
    {2, 10, 17, 18, 19, 20, 21, 22, 23},  {3, 11, 18, 24, 25, 26, 27, 28, 29},
    {4, 12, 19, 25, 30, 31, 32, 33, 34},  {5, 13, 20, 26, 31, 35, 36, 37, 38},
    {6, 14, 21, 27, 32, 36, 39, 40, 41},  {7, 15, 22, 28, 33, 37, 40, 42, 43},
    {8, 16, 23, 29, 34, 38, 41, 43, 44},
};
const uint8_t att_fx_dg[ATT_N] = {0, 9, 17, 24, 30, 35, 39, 42, 44};

/* ---- numeric helpers ---- */

int32_t att_fx_to_c_any(int64_t v, int sh)
{
    int64_t r;
    if (sh > 0) {
        if (sh >= 63) {
            return 0;
        }
        r = (v + ((int64_t)1 << (sh - 1))) >> sh;
    } else {
        const int k = -sh;
        if (v == 0 || k == 0) {
            r = v;
        } else if (k >= 32 || att_fx_abslen(v) + k > 62) {
            return (v > 0) ? INT32_MAX : -INT32_MAX;
        } else {
            r = (int64_t)((uint64_t)v << k);
        }
    }
    return (r > INT32_MAX) ? INT32_MAX : (r < -INT32_MAX) ? -INT32_MAX : (int32_t)r;
}

ekf_scalar_t att_fx_to_q(int64_t v, int sh)
{
    if (sh > 0) {
        /* rounded half up as (v + 2^(sh-1)) >> sh, without the sum that overflows near
         * INT64_MAX */
        return (sh >= 63) ? 0 : (v >> sh) + ((v >> (sh - 1)) & 1);
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

/* The exponent and normalised value of the variance v (Q29.34, v != 0, finite). */
static int32_t norm_q(ekf_scalar_t v, int *e)
{
    const uint64_t m = (uint64_t)((v < 0) ? -v : v);
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
    /* both terms at the exponent y where the larger is below 2^61 */
    const int x1 = 2 * ei - ATT_FX_CF;
    const int l1 = att_fx_abslen(cii) + x1;
    const int l2 = att_fx_bitlen64(m) + x;
    const int y = ((l1 > l2) ? l1 : l2) - 61;
    const int64_t v = (int64_t)att_fx_to_q((int64_t)cii, y - x1) + att_fx_to_q((int64_t)m, y - x);
    const int en = att_fx_norm_exp((uint64_t)(v < 0 ? -v : v), y);
    return (en < ATT_FX_E_MIN) ? ATT_FX_E_MIN : en;
}

/* Marks state i infinite (an overflow: counted like any saturation). */
void att_fx_overflow(att_cov_t *c, int i)
{
    (void)ekf_fx_saturate(1);
    c->inf = (uint16_t)(c->inf | (1u << i));
}

/* ---- set and read ---- */

void att_cov_set_diag(att_cov_t *c, const ekf_scalar_t var[ATT_N])
{
    int i;
    for (i = 0; i < ATT_FX_NP; ++i) {
        c->c[i] = 0;
    }
    c->spare = 0u;
    c->inf = 0u;
    for (i = 0; i < ATT_N; ++i) {
        c->e[i] = ATT_FX_E_MIN;
        att_cov_reset_state(c, i, var[i]);
    }
}

ekf_scalar_t att_cov_get(const att_cov_t *c, int i, int j)
{
    if ((c->inf & ((1u << i) | (1u << j))) != 0u) {
        return EKF_FX_INF;
    }
    /* P_ij raw = C_ij 2^(e_i + e_j - 29 + 34); beyond the scalar's range (only between a
     * propagation and the prediction's variance limits: the guard refuses a covariance that
     * still has such a variance) the largest finite value, not a saturation of an operation */
    {
        const int32_t v = c->c[att_fx_ix[i][j]];
        const int sh = EKF_FX_FRAC - ATT_FX_CF + c->e[i] + c->e[j];
        if (sh > 0 && att_fx_abslen(v) + sh > 62) {
            return (v > 0) ? EKF_FX_INF - 1 : EKF_FX_NINF + 1;
        }
        return att_fx_to_q(v, -sh);
    }
}

ekf_scalar_t att_cov_var(const att_cov_t *c, int i) { return att_cov_get(c, i, i); }

void att_cov_to_full(const att_cov_t *c, ekf_scalar_t P[ATT_N * ATT_N])
{
    int i, j;
    for (i = 0; i < ATT_N; ++i) {
        for (j = i; j < ATT_N; ++j) {
            P[i * ATT_N + j] = P[j * ATT_N + i] = att_cov_get(c, i, j);
        }
    }
}

void att_cov_from_full(att_cov_t *c, const ekf_scalar_t P[ATT_N * ATT_N])
{
    int i, j, e;
    c->spare = 0u;
    c->inf = 0u;
    for (i = 0; i < ATT_N; ++i) { /* the exponents from the variances */
        const ekf_scalar_t v = P[i * ATT_N + i];
        if (v >= EKF_FX_INF) {
            c->inf = (uint16_t)(c->inf | (1u << i));
            e = ATT_FX_E_MAX;
        } else if (v > 0) {
            (void)norm_q(v, &e);
        } else {
            e = ATT_FX_E_MIN;
        }
        c->e[i] = (int8_t)e;
    }
    for (i = 0; i < ATT_N; ++i) { /* C_ij = P_ij 2^-(e_i + e_j - 29) from the lower triangle */
        for (j = 0; j <= i; ++j) {
            c->c[att_fx_ix[i][j]] = att_fx_to_c_any(P[i * ATT_N + j], EKF_FX_FRAC - ATT_FX_CF + c->e[i] + c->e[j]);
        }
    }
}

/* ---- prediction (the small operations and the rate noise; propagate: kernels) ---- */

void att_cov_add_diag(att_cov_t *c, int first, int len, ekf_scalar_t var)
{
    int i;
    for (i = first; i < first + len; ++i) {
        att_cov_add_var(c, i, var);
    }
}

void att_cov_add_var(att_cov_t *c, int i, ekf_scalar_t var)
{
    int32_t *d = &c->c[att_fx_dg[i]];
    int64_t sum;
    if (var <= 0 || (c->inf & (1u << i)) != 0u) {
        return;
    }
    if (!ekf_fx_isfinite(var)) {
        c->inf = (uint16_t)(c->inf | (1u << i));
        return;
    }
    sum = (int64_t)*d + att_fx_to_c(var, EKF_FX_FRAC - ATT_FX_CF + 2 * c->e[i]);
    if (sum < ATT_FX_C_ONE || sum >= INT32_MAX) {
        /* the variance leaves the band: its new exponent first, then the sum in it */
        const int en = att_fx_sum_exp(*d, c->e[i], (uint64_t)var, -EKF_FX_FRAC);
        if (en > ATT_FX_E_MAX) {
            att_fx_overflow(c, i);
            return;
        }
        att_fx_set_exp(c, i, en);
        sum = (int64_t)*d + att_fx_to_c(var, EKF_FX_FRAC - ATT_FX_CF + 2 * en);
    }
    *d = (sum >= INT32_MAX) ? INT32_MAX : (int32_t)sum;
}

void att_cov_scale_diag(att_cov_t *c, int first, int len, ekf_scalar_t rel)
{
    int i;
    if (rel <= 0) {
        return;
    }
    for (i = first; i < first + len; ++i) {
        const int32_t d = c->c[att_fx_dg[i]];
        if (d > 0 && rel < ((ekf_scalar_t)1 << 34)) {
            /* rel < 2^34 raw: d rel in one 32 x 32 product */
            const int64_t sum = (int64_t)d + (int64_t)(((uint64_t)(uint32_t)d * (uint32_t)(rel >> 2)) >> (EKF_FX_FRAC - 2));
            if (sum < INT32_MAX) {
                c->c[att_fx_dg[i]] = (int32_t)sum;
                continue;
            }
        }
        att_cov_add_var(c, i, ekf_mul(att_cov_var(c, i), rel));
    }
}

/* ---- process noise of the body rates ---- */

void att_cov_add_rate_noise(att_cov_t *c, const ekf_scalar_t g[9], const ekf_scalar_t var[3])
{
    /* P += G diag(var) G^T, G = [I; 0; g]: var_j = vm_j 2^xv, g_ij = gm_ij 2^xg (common
     * scales), the increments as exact products, the new exponents from the new variances */
    int64_t v64[ATT_N], g64[ATT_N];
    int32_t vm[3], gm[9], t[9];
    int64_t de[6]; /* the Euler-rate block's increments, (0,0) (0,1) (0,2) (1,1) (1,2) (2,2) */
    int xv, xg, en[ATT_N], i, j, k, n;
    for (i = 0; i < ATT_N; ++i) {
        v64[i] = (i < 3) ? ((var[i] > 0) ? var[i] : 0) : 0;
        g64[i] = g[i];
    }
    if (c->inf != 0u || (v64[0] | v64[1] | v64[2]) == 0) {
        return;
    }
    xv = att_fx_block_row(v64, t) - EKF_FX_FRAC; /* (t: scratch for the 9-wide helper) */
    for (i = 0; i < 3; ++i) {
        vm[i] = t[i];
    }
    xg = att_fx_block_row(g64, gm) - EKF_FX_FRAC;
    /* t_ij = g_ij var_j in Q(xg + xv + 30); the Euler block sum_j t_ij g_kj */
    for (i = 0; i < 9; ++i) {
        t[i] = att_fx_to_c((int64_t)gm[i] * vm[i % 3], 30);
    }
    for (i = 0, n = 0; i < 3; ++i) {
        for (k = i; k < 3; ++k, ++n) {
            de[n] = (int64_t)t[3 * i] * gm[3 * k] + (int64_t)t[3 * i + 1] * gm[3 * k + 1] + (int64_t)t[3 * i + 2] * gm[3 * k + 2];
        }
    }
    /* new exponents of the rates and the Euler rates */
    for (i = 0; i < ATT_N; ++i) {
        en[i] = c->e[i];
    }
    for (j = 0; j < 3; ++j) {
        const int ee = (vm[j] > 0) ? att_fx_sum_exp(c->c[att_fx_ix[j][j]], c->e[j], (uint64_t)vm[j], xv) : c->e[j];
        const int64_t dd = de[(j == 0) ? 0 : (j == 1) ? 3 : 5];
        const int ed = (dd > 0) ? att_fx_sum_exp(c->c[att_fx_ix[6 + j][6 + j]], c->e[6 + j], (uint64_t)dd, 2 * xg + xv + 30)
                                : c->e[6 + j];
        en[j] = (ee > c->e[j]) ? ee : c->e[j];
        en[6 + j] = (ed > c->e[6 + j]) ? ed : c->e[6 + j];
    }
    for (i = 0; i < ATT_N; ++i) {
        if (en[i] > ATT_FX_E_MAX) {
            att_fx_overflow(c, i);
            return;
        }
        att_fx_set_exp(c, i, en[i]);
    }
    /* the increments in the new scales: 2^(29 - e'_i - e'_j) */
    for (j = 0; j < 3; ++j) {
        int32_t *p = &c->c[att_fx_ix[j][j]];
        *p = att_fx_to_c((int64_t)*p + att_fx_to_c(vm[j], -(xv + ATT_FX_CF - 2 * en[j])), 0);
        for (i = 0; i < 3; ++i) {
            p = &c->c[att_fx_ix[6 + i][j]];
            *p = att_fx_to_c((int64_t)*p + att_fx_to_c((int64_t)gm[3 * i + j] * vm[j], -(xg + xv + ATT_FX_CF - en[6 + i] - en[j])), 0);
        }
    }
    for (i = 0, n = 0; i < 3; ++i) {
        for (k = i; k < 3; ++k, ++n) {
            int32_t *p = &c->c[att_fx_ix[6 + i][6 + k]];
            *p = att_fx_to_c((int64_t)*p + att_fx_to_c(de[n], -(2 * xg + xv + 30 + ATT_FX_CF - en[6 + i] - en[6 + k])), 0);
        }
    }
}

/* ---- bounds and remaps ---- */

/* var_floor in the units of state i's C, rounded up (so that the variance it gives back is
 * at least the floor). */
int32_t att_fx_floor_c(const att_cov_t *c, int i, ekf_scalar_t floor)
{
    const int sh = EKF_FX_FRAC - ATT_FX_CF + 2 * c->e[i];
    if (sh > 0 && sh < 63) {
        const int32_t f = att_fx_to_c(floor + (((ekf_scalar_t)1 << (sh - 1)) - 1), sh);
        return (f > 0 || floor <= 0) ? f : 1;
    }
    return att_fx_to_c(floor, sh);
}

/* 1 if P_ii is below floor. att_fx_floor_c saturates to INT32_MAX when the floor does not
 * fit a word of state i's scale; every word is then at most the floor. */
static int below_floor(const att_cov_t *c, int i, ekf_scalar_t floor)
{
    const int32_t f = att_fx_floor_c(c, i, floor);
    return c->c[att_fx_dg[i]] < f || f == INT32_MAX;
}

/* P_ii <- floor, in the floor's own scale (the row and column rescaled with it). */
static void set_to_floor(att_cov_t *c, int i, ekf_scalar_t floor)
{
    int en;
    const int32_t v = norm_q(floor, &en);
    att_fx_set_exp(c, i, en);
    c->c[att_fx_dg[i]] = v;
}

int att_cov_floor_diag(att_cov_t *c, ekf_scalar_t floor)
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        /* a variance beyond the scalar's range: an overflow of the covariance the filter can
         * report (counted, infinite) */
        if (att_fx_abslen(c->c[att_fx_dg[i]]) + 2 * c->e[i] + EKF_FX_FRAC - ATT_FX_CF > 62 && (c->inf & (1u << i)) == 0u) {
            att_fx_overflow(c, i);
        }
    }
    if (c->inf != 0u) {
        return -1;
    }
    for (i = 0; i < ATT_N; ++i) {
        if (c->c[att_fx_dg[i]] < -ATT_FX_TOL) {
            return -1; /* negative beyond rounding */
        }
    }
    for (i = 0; i < ATT_N; ++i) {
        int32_t *d = &c->c[att_fx_dg[i]];
        /* a variance below the band, or in a scale at most the floor's, can be below it */
        if (*d < ATT_FX_C_ONE || (floor > 0 && c->e[i] <= att_fx_norm_exp((uint64_t)floor, -EKF_FX_FRAC))) {
            if (below_floor(c, i, floor)) {
                set_to_floor(c, i, floor);
            } else {
                att_fx_renorm(c, i);
            }
        }
    }
    return 0;
}

void att_cov_reset_state(att_cov_t *c, int i, ekf_scalar_t var)
{
    int j, en = ATT_FX_E_MIN;
    for (j = 0; j < ATT_N; ++j) {
        c->c[att_fx_ix[i][j]] = 0;
    }
    c->inf = (uint16_t)(c->inf & ~(1u << i));
    if (!ekf_fx_isfinite(var)) {
        c->inf = (uint16_t)(c->inf | (1u << i));
    } else if (var != 0) {
        c->c[att_fx_dg[i]] = norm_q(var, &en);
        if (en > ATT_FX_E_MAX) {
            att_fx_overflow(c, i);
            en = ATT_FX_E_MAX;
        }
    }
    c->e[i] = (int8_t)en;
}

/* P_ii > v (v > 0, Q29.34), from C_ii 2^(2 e_i + 5) against v's raw value: no conversion
 * (P_ii may be beyond the scalar's range there, between a propagation and its limits). */
static int var_above(const att_cov_t *c, int i, ekf_scalar_t v)
{
    const int32_t d = c->c[att_fx_dg[i]];
    const int sh = 2 * c->e[i] + EKF_FX_FRAC - ATT_FX_CF;
    const int ld = ekf_fx_bitlen64((uint64_t)(d > 0 ? d : 0)) + sh, lv = ekf_fx_bitlen64((uint64_t)v);
    if (d <= 0 || ld != lv) {
        return d > 0 && ld > lv;
    }
    /* the same bit length (at most 31 + sh, or 31 for sh < 0): the exact comparison */
    return (sh >= 0) ? ((int64_t)d << sh) > v : (int64_t)d > (v << -sh);
}

int att_cov_limit_variance(att_cov_t *c, int i, ekf_scalar_t max_var)
{
    int32_t *d = &c->c[att_fx_dg[i]];
    int32_t dn, g;
    int en, j;
    if ((c->inf & (1u << i)) != 0u || !(max_var > 0) || !var_above(c, i, max_var)) {
        return 0;
    }
    /* the diagonal becomes max_var, row and column scale by g = sqrt(dn / d) (in (1/2, 2)
     * when both are normalised): g in Q1.30 from two reciprocal square roots */
    att_fx_renorm(c, i);
    dn = norm_q(max_var, &en);
    {
        const uint32_t rn = ekf_fx_rsqrt32((uint32_t)dn << 1), ro = ekf_fx_rsqrt32((uint32_t)*d << 1);
        const uint64_t t = ((uint64_t)(uint32_t)dn * rn) >> 32; /* 2^15 sqrt(dn / 2) */
        g = (int32_t)((t * ro) >> 31);
    }
    for (j = 0; j < ATT_N; ++j) {
        if (j != i) {
            int32_t *p = &c->c[att_fx_ix[i][j]];
            *p = att_fx_to_c((int64_t)*p * g, 30);
        }
    }
    *d = dn;
    c->e[i] = (int8_t)en;
    return 1;
}

void att_cov_negate_state(att_cov_t *c, int i)
{
    int j;
    for (j = 0; j < ATT_N; ++j) {
        if (j != i) {
            c->c[att_fx_ix[i][j]] = -c->c[att_fx_ix[i][j]];
        }
    }
}

/* ---- definiteness ---- */

/* floor(a b / 2^32) for a signed 64-bit a and an unsigned 32-bit b. */
static int64_t mul_hi(int64_t a, uint32_t b)
{
    return (int64_t)ekf_fx_hi(a) * (int64_t)b + (int64_t)(((uint64_t)(uint32_t)a * b) >> 32);
}

/* Cholesky factorisation of C - diag(tau / s_i^2) (tau = ATT_COV_FX_TAU) in Q2.29 with
 * 64-bit sums: G_jk = (C_jk - sum_m G_jm G_km) / G_kk, each product bounded by
 * sqrt(C_jj C_kk) < 4, the division a multiplication by the pivot's reciprocal square
 * root. 1 if every pivot p_j >= rel_margin C_jj and > 0, else 0. */
static int chol_pd(const att_cov_t *c, ekf_scalar_t rel_margin)
{
    int32_t G[ATT_N][ATT_N]; /* G_jk (k < j) at G[j][k] */
    uint32_t rs[ATT_N];       /* 1 / sqrt(p_k) = rs_k 2^(-18 - t_k / 2), p_k = acc_k 2^-58 */
    int sh[ATT_N];            /* 15 + t_k / 2: G_jk = (acc rs_k / 2^32) >> sh_k */
    /* rel_margin in Q0.32 (< 1 by the callers) */
    const uint32_t rel = (rel_margin >= EKF_C(1)) ? 0xFFFFFFFFu : (uint32_t)(rel_margin >> (EKF_FX_FRAC - 32));
    int j, k, m;
    for (j = 0; j < ATT_N; ++j) {
        int32_t *gj = G[j];
        int64_t acc, sum;
        int t;
        for (k = 0; k < j; ++k) {
            const int32_t *gk = G[k];
            /* the products summed first (one multiply-accumulate each), subtracted once */
            for (m = 0, sum = 0; m < k; ++m) {
                sum += (int64_t)gj[m] * gk[m];
            }
            acc = (int64_t)c->c[att_fx_ix[j][k]] * ((int64_t)1 << ATT_FX_CF) - sum; /* Q4.58 (times 2^CF: a left shift of a negative value is undefined) */
            gj[k] = att_fx_to_c(mul_hi(acc, rs[k]), sh[k]);
        }
        for (m = 0, sum = 0; m < j; ++m) {
            sum += (int64_t)gj[m] * gj[m];
        }
        acc = ((int64_t)c->c[att_fx_dg[j]] - att_fx_floor_c(c, j, ATT_COV_FX_TAU)) * ((int64_t)1 << ATT_FX_CF) - sum;
        /* p_j 2^26 against rel C_jj 2^26 (the product Q0.32 x Q2.29 >> 35) */
        if (acc <= 0 || (acc >> 32) < (int64_t)(((uint64_t)rel * (uint32_t)c->c[att_fx_dg[j]]) >> 35)) {
            return 0;
        }
        /* acc = d 2^t, d in [2^30, 2^32), t even: 1/sqrt(p) = rsqrt(d) 2^-47 2^(29 - t/2) */
        t = att_fx_bitlen64((uint64_t)acc) - 32;
        t += t & 1;
        rs[j] = ekf_fx_rsqrt32((uint32_t)(t >= 0 ? acc >> t : acc << -t));
        sh[j] = 15 + t / 2;
    }
    return 1;
}

int att_cov_is_pd(const att_cov_t *c, ekf_scalar_t rel_margin) { return (c->inf == 0u) && chol_pd(c, rel_margin); }

int att_cov_ensure_pd(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor)
{
    ekf_scalar_t lambda = ekf_max(ekf_mul(EKF_C(10), rel_margin), ekf_mul(EKF_C(16), EKF_SCALAR_EPS));
    int rounds = 0, i, j;
    if (c->inf != 0u || !(var_floor > 0) || rel_margin < 0 || !(rel_margin < EKF_C(1))) {
        return -1;
    }
    if (chol_pd(c, rel_margin)) {
        return 0;
    }
    while (lambda <= EKF_C(1)) {
        /* P_ii <- max(P_ii, floor) (1 + lambda): lambda in Q0.31 on the normalised C_ii */
        ++rounds;
        for (i = 0; i < ATT_N; ++i) {
            const int32_t f = att_fx_floor_c(c, i, var_floor);
            int32_t *d = &c->c[att_fx_dg[i]];
            if (f == INT32_MAX) { /* the floor does not fit this scale's word */
                set_to_floor(c, i, var_floor);
            } else if (*d < f) {
                *d = f;
            }
            att_fx_renorm(c, i);
            att_cov_add_var(c, i, ekf_mul(att_cov_var(c, i), lambda));
        }
        if (c->inf != 0u) {
            return -1;
        }
        lambda = ekf_mul(lambda, EKF_C(10));
        if (chol_pd(c, rel_margin)) {
            return rounds;
        }
    }
    /* the correlations themselves are broken: keep the variances only */
    ++rounds;
    for (i = 0; i < ATT_N; ++i) {
        for (j = i + 1; j < ATT_N; ++j) {
            c->c[att_fx_ix[i][j]] = 0;
        }
        if (below_floor(c, i, var_floor)) {
            att_cov_reset_state(c, i, var_floor);
        }
        att_fx_renorm(c, i);
    }
    return rounds;
}

int att_cov_guard(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor)
{
    if (att_cov_floor_diag(c, var_floor) != 0) {
        return -1;
    }
    return att_cov_ensure_pd(c, rel_margin, var_floor);
}

