/*
 * att_cov_fx_kernels.c - the fixed-point covariance's heavy operations (att_cov.h,
 * ATT_COV_FX): the propagation F P F^T (one transition factor at a time) and the angle
 * increments' variance, the scalar measurement updates (docs/fixed_point.md, "Covariance").
 *
 * With P = S c S (S = diag(2^e_i), c = C 2^-29):
 *   F P F^T = S (F~ c F~^T) S, F~ = S^-1 F S: the scaled transition, one exponent per row;
 *   an update with H: u = S H^T / 2^eta, v = c u, q = u^T c u, Sn = q + R 2^(-2 eta):
 *   c' = c - v v^T / Sn, K = S v / (2^eta Sn).
 * Sums of products are exact in 64 bits, every stored word rounded once and saturated
 * (never wrapped), whatever the words it comes from; the new exponents are chosen from the
 * new variances, so a variance that grows or shrinks by any factor keeps its 29 to 31
 * significant bits.
 */
#include "att_cov_fx_words.h"

#include <stddef.h>

#include "ekf_util.h"

/* round(a b 2^-32) of two words: the product's high word plus the top bit of its low word
 * (the same as (a b + 2^31) >> 32, without the rounding constant in the accumulator). For
 * words within +-INT32_MAX the result is within +-(2^30 - 1). */
ATT_FX_INLINE int32_t mul_hi_round(int32_t a, int32_t b)
{
    const int64_t p = (int64_t)a * b;
    return (int32_t)(p >> 32) + (int32_t)((uint32_t)p >> 31);
}

/* w - 4 round(a b 2^-32), the rank-one update of a word by T_i v_j (Q2.30 x Q2.29 -> Q2.29),
 * saturated to +-INT32_MAX, never wrapped around, for any words: w - 4 t = 4 u + (w mod 4)
 * with u = floor(w / 4) - t, which fits 32 bits (|t| < 2^30). u in (-2^29, 2^29) gives a
 * word; beyond, the result is saturated (exactly where it leaves the word, but for the
 * results -2^31 + 2 and -2^31 + 3, which become -2^31 + 1). */
ATT_FX_INLINE int32_t sub_rank1(int32_t w, int32_t a, int32_t b)
{
    const int32_t u = (w >> 2) - mul_hi_round(a, b);
    if ((uint32_t)u + ((1u << 29) - 1u) < (1u << 30) - 1u) {
        return (int32_t)(((uint32_t)u << 2) | ((uint32_t)w & 3u));
    }
    return (u > 0) ? INT32_MAX : -INT32_MAX;
}

/* Dot product of two 9-vectors of words, exact (nine multiply-accumulates). */
ATT_FX_INLINE int64_t dot9(const int32_t *a, const int32_t *b)
{
    return (int64_t)a[0] * b[0] + (int64_t)a[1] * b[1] + (int64_t)a[2] * b[2] + (int64_t)a[3] * b[3] +
           (int64_t)a[4] * b[4] + (int64_t)a[5] * b[5] + (int64_t)a[6] * b[6] + (int64_t)a[7] * b[7] +
           (int64_t)a[8] * b[8];
}

/* ---- propagation ---- */

/* The prediction applies the transition's two factors in turn, F P F^T = F2 (F1 P F1^T) F2^T:
 * each factor I + D_k changes three rows (D1 the angle rows ATT_PHI .., D2 the Euler-rate rows
 * ATT_PHID ..), so each congruence is a 3-row update of C, rounded once per stored word. */
#define NR 3

/* The rows base .. base+2 of F~ = S^-1 F S (F = I + D, D's values d on the pattern pat, sorted
 * by row, every entry in those rows) as words f[r][j] 2^ph[r] (|f| < 2^28). */
static void scaled_rows(const att_cov_t *c, const ekf_nz_t *pat, int nnz, const ekf_scalar_t *d, int base,
                        int32_t f[NR][ATT_N], int ph[NR])
{
    int k = 0, r;
    for (r = 0; r < NR; ++r) {
        const int row = base + r, k0 = k;
        ekf_scalar_t diag = EKF_FX_ONE;
        int top = INT32_MIN, b, j, kend;
        int32_t *fr = f[r];
        for (j = 0; j < ATT_N; ++j) {
            fr[j] = 0;
        }
        /* F~_rj = F_rj 2^(e_j - e_r) 2^-34: the row's largest bit length with the exponents */
        for (; k < nnz && pat[k].row == row; ++k) {
            const int col = pat[k].col;
            if (col == row) {
                diag = ekf_fx_add(diag, d[k]); /* (saturated: an infinite factor overflows the variance) */
            } else if (d[k] != 0) {
                b = att_fx_abslen(d[k]) + c->e[col];
                top = (b > top) ? b : top;
            }
        }
        kend = k;
        b = att_fx_abslen(diag) + c->e[row];
        top = (b > top) ? b : top;
        for (k = k0; k < kend; ++k) {
            const int col = pat[k].col;
            if (col != row && d[k] != 0) {
                fr[col] = att_fx_to_c(d[k], top - 28 - c->e[col]);
            }
        }
        fr[row] = att_fx_to_c(diag, top - 28 - c->e[row]);
        ph[r] = top - 28 - EKF_FX_FRAC - c->e[row];
    }
}

/* C <- F~ C F~^T for the factor F = I + D whose rows base .. base+2 differ from I. */
static void propagate_factor(att_cov_t *c, const ekf_nz_t *pat, int nnz, const ekf_scalar_t *d, int base)
{
    int32_t cf[ATT_N][ATT_N]; /* C unpacked */
    int32_t f[NR][ATT_N], a[NR][ATT_N];
    int ph[NR], al[NR], en[NR];
    int64_t w[ATT_N];
    int r, l, j, k;

    if (c->inf != 0u) {
        c->inf = (uint16_t)(c->inf | (7u << base)); /* the changed rows: not finite either */
        return;
    }
    scaled_rows(c, pat, nnz, d, base, f, ph);
    {
        const int32_t *p = c->c; /* the packed rows (i, j >= i) in order */
        for (j = 0; j < ATT_N; ++j) {
            for (k = j; k < ATT_N; ++k) {
                cf[j][k] = cf[k][j] = *p++;
            }
        }
    }
    /* rows of A = F~ c, each to words with its own scale: A_rk = a[r][k] 2^al[r] */
    for (r = 0; r < NR; ++r) {
        for (k = 0; k < ATT_N; ++k) {
            w[k] = dot9(f[r], cf[k]);
        }
        al[r] = att_fx_block_row(w, a[r]) + ph[r] - ATT_FX_CF;
    }
    /* the new variances c'_rr = sum_m F~_rm A_rm and their exponents */
    for (r = 0; r < NR; ++r) {
        const int i = base + r;
        const int64_t v = dot9(f[r], a[r]);
        const int x = ph[r] + al[r];
        en[r] = (v == 0) ? ATT_FX_E_MIN : att_fx_norm_exp((uint64_t)(v < 0 ? -v : v), x + 2 * c->e[i]);
        if (en[r] < ATT_FX_E_MIN) {
            en[r] = ATT_FX_E_MIN;
        } else if (en[r] > ATT_FX_E_MAX) {
            att_fx_overflow(c, i);
            en[r] = ATT_FX_E_MAX;
        }
        c->c[att_fx_dg[i]] = att_fx_to_c(v, -(x + ATT_FX_CF + 2 * (c->e[i] - en[r])));
    }
    /* the rest of the changed rows, in the new scales: C'_il = c'_il 2^(29 + e_i + e_l - e'_i - e'_l) */
    for (r = 0; r < NR; ++r) {
        const int i = base + r, di = c->e[i] - en[r];
        const int sh = -(al[r] + ATT_FX_CF + di);
        const uint8_t *ix = att_fx_ix[i];
        if (sh == 0) {
            for (l = 0; l < ATT_N; ++l) { /* the rows F leaves: c'_il = A_il */
                if (l < base || l >= base + NR) {
                    c->c[ix[l]] = a[r][l];
                }
            }
        } else if (sh == -1) {
            /* |A_rl| <= 2^30 (att_fx_block_row): doubled within the word but at +-2^30 */
            for (l = 0; l < ATT_N; ++l) {
                if (l < base || l >= base + NR) {
                    const int32_t al1 = a[r][l];
                    c->c[ix[l]] = ((uint32_t)al1 + ((1u << 30) - 1u) < (1u << 31) - 1u) ? (int32_t)((uint32_t)al1 << 1)
                                  : (al1 > 0)                                          ? INT32_MAX
                                                                                       : -INT32_MAX;
                }
            }
        } else if (sh > 0 && sh < 32) {
            for (l = 0; l < ATT_N; ++l) {
                if (l < base || l >= base + NR) {
                    c->c[ix[l]] = (a[r][l] >> sh) + ((a[r][l] >> (sh - 1)) & 1);
                }
            }
        } else {
            for (l = 0; l < ATT_N; ++l) {
                if (l < base || l >= base + NR) {
                    c->c[ix[l]] = att_fx_w(a[r][l], sh);
                }
            }
        }
        for (l = r + 1; l < NR; ++l) {
            const int jl = base + l;
            c->c[att_fx_ix[i][jl]] = att_fx_to_c(dot9(f[l], a[r]), -(ph[l] + al[r] + ATT_FX_CF + di + c->e[jl] - en[l]));
        }
    }
    for (r = 0; r < NR; ++r) {
        c->e[base + r] = (int8_t)en[r];
    }
}

/* (D1 P D1^T)_ii of the angle rows of D1 (pattern att_gen_f1_pattern, sorted by row). */
static void att_cov_increment_var(const att_cov_t *c, const ekf_scalar_t d[ATT_GEN_F1_NNZ], ekf_scalar_t var[3])
{
    int k = 0, i;
    for (i = 0; i < 3; ++i) {
        var[i] = EKF_C(0);
    }
    if (c->inf != 0u) {
        return;
    }
    /* the quadratic form u^T c u of each angle row of D, u_a = d_a 2^(e_col) = fm_a 2^(top - 62) */
    while (k < ATT_GEN_F1_NNZ) {
        const int row = att_gen_f1_pattern[k].row;
        int32_t fm[ATT_N];
        uint8_t col[ATT_N];
        int n = 0, top = INT32_MIN, a, b;
        int64_t s = 0;
        for (; k < ATT_GEN_F1_NNZ && att_gen_f1_pattern[k].row == row; ++k) {
            if (d[k] != 0) {
                const int bl = att_fx_abslen(d[k]) + c->e[att_gen_f1_pattern[k].col];
                top = (bl > top) ? bl : top;
                col[n] = att_gen_f1_pattern[k].col;
                fm[n++] = (int32_t)k; /* the entry, converted below */
            }
        }
        if (n == 0) {
            continue;
        }
        for (a = 0; a < n; ++a) {
            fm[a] = att_fx_to_c(d[fm[a]], top - 28 - c->e[col[a]]);
        }
        for (a = 0; a < n; ++a) {
            const uint8_t *ia = att_fx_ix[col[a]];
            int64_t wa = 0;
            for (b = 0; b < n; ++b) {
                wa += (int64_t)fm[b] * c->c[ia[col[b]]];
            }
            s += (int64_t)fm[a] * att_fx_to_c(wa, 31);
        }
        /* var = s 2^31 2^(2 (top - 62)) 2^-29, in Q29.34 */
        var[row - ATT_PHI] = (s > 0) ? att_fx_to_q(s, 88 - 2 * top) : EKF_C(0);
    }
}

/* ---- the prediction ---- */

ekf_status_t att_cov_predict(att_cov_t *c, const ekf_scalar_t d1[ATT_GEN_F1_NNZ], const ekf_scalar_t d2[ATT_GEN_F2_NNZ],
                             const ekf_scalar_t var[3], ekf_scalar_t inc_var[3])
{
    /* F P F^T + G diag(var) G^T = F2 (F1 P F1^T + diag(var, 0)) F2^T with G = F2 [I; 0; 0]:
     * the rate noise enters between the factors, on the rates' diagonal */
    int j;
    if (!ekf_all_finite(d1, ATT_GEN_F1_NNZ) || !ekf_all_finite(d2, ATT_GEN_F2_NNZ)) {
        return EKF_ERR_NUMERIC;
    }
    att_cov_increment_var(c, d1, inc_var);
    propagate_factor(c, att_gen_f1_pattern, ATT_GEN_F1_NNZ, d1, ATT_PHI);
    for (j = 0; j < 3; ++j) {
        att_cov_add_var(c, ATT_P + j, var[j]);
    }
    propagate_factor(c, att_gen_f2_pattern, ATT_GEN_F2_NNZ, d2, ATT_PHID);
    return EKF_OK;
}

/* ---- measurement updates ---- */

/* a / b (a >= 0, b > 0, Q29.34) to 2^-31 of the quotient, from the reciprocal of b's top word:
 * the gate's test ratio (a diagnostic and a comparison with 1). */
static ekf_scalar_t ratio_q(ekf_scalar_t a, ekf_scalar_t b)
{
    const int la = ekf_fx_bitlen64((uint64_t)a), lb = ekf_fx_bitlen64((uint64_t)b);
    /* bh: b's top 32 bits (b < 2^63: the shift by 63 - lb loses none, and is defined for b = 0) */
    const uint32_t ah = (uint32_t)att_fx_to_c(a, la - 31), bh = (uint32_t)((uint64_t)b << (63 - lb) >> 31);
    /* a / b = ah 2^(la - 31) / (bh 2^(lb - 32)); ah / bh = ah recip(bh) 2^-63 */
    return att_fx_to_q((int64_t)(((uint64_t)ah * ekf_fx_recip32(bh)) >> 32), -(la - 31 - (lb - 32) - 31 + EKF_FX_FRAC));
}

/* The gate of ekf_update_scalar (ekf.h) on the innovation nu and its variance s. */
static ekf_status_t gate_test(ekf_scalar_t nu, ekf_scalar_t s, ekf_scalar_t gate, ekf_innov_t *info)
{
    if (gate > EKF_C(0)) {
        const ekf_scalar_t nu2 = ekf_sq(nu);
        const ekf_scalar_t lim = ekf_mul(ekf_sq(gate), s);
        const ekf_scalar_t ratio = !ekf_isfinite(nu2) || !ekf_isfinite(lim) ? EKF_FX_INF
                                   : (lim > EKF_C(0))                      ? ((nu2 > 0) ? ratio_q(nu2, lim) : EKF_C(0))
                                   : ((nu2 > EKF_C(0)) ? EKF_C(1e6) : EKF_C(0));
        if (info != NULL) {
            info->test_ratio = ratio;
        }
        if (!ekf_isfinite(ratio) || ratio > EKF_C(1)) {
            return EKF_GATED;
        }
    }
    return EKF_OK;
}

/* round(v 2^-s) for a non-negative 64-bit v and any s, saturated at 2^62. */
static int64_t shift_pos(int64_t v, int s)
{
    if (s > 0) {
        return att_fx_round_shr(v, s);
    }
    if (v == 0 || s == 0) {
        return v;
    }
    return (-s >= 62 || ekf_fx_bitlen64((uint64_t)v) - s > 62) ? ((int64_t)1 << 62) : (int64_t)((uint64_t)v << -s);
}

/* The update with v = c u (Q2.29), q = u^T c u (Q2.29, in [1, 4), or 0 with v = 0), the
 * measurement's scale 2^eta, and k the measured state of a unit row (its row and column in
 * closed form, row k of c taken in the scale 2^eta) or -1. The checks of ekf_update_scalar,
 * in its order, before anything is written. */
static ekf_status_t update(att_cov_t *c, ekf_scalar_t x[ATT_N], const int32_t v[ATT_N], int32_t q, int eta, int k,
                           ekf_scalar_t nu, ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor,
                           ekf_innov_t *info)
{
    int32_t T[ATT_N], dg[ATT_N];
    ekf_scalar_t xn[ATT_N], s_q;
    const int ef = (var_floor > 0) ? att_fx_norm_exp((uint64_t)var_floor, -EKF_FX_FRAC) : ATT_FX_E_MIN;
    /* Sn = q 2^-29 + r 2^(-34 - 2 eta) = (qu + ru) 2^y, y putting the larger term below 2^61
     * (R can exceed H P H^T by any factor: a row H nearly orthogonal to gravity) */
    const int lq = ekf_fx_bitlen64((uint64_t)(uint32_t)q) - ATT_FX_CF, lr = ekf_fx_bitlen64((uint64_t)r_var) - EKF_FX_FRAC - 2 * eta;
    const int y = ((lq > lr) ? lq : lr) - 61;
    const int64_t ru = shift_pos(r_var, EKF_FX_FRAC + 2 * eta + y);
    const uint64_t sn = (uint64_t)shift_pos(q, ATT_FX_CF + y) + (uint64_t)ru;
    const int bs = ekf_fx_bitlen64(sn);
    /* Sn = sm 2^xs (sm the top 32 bits), gamma = 1 / Sn = gm 2^(-63 - xs) */
    const uint32_t sm = (uint32_t)((bs >= 32) ? sn >> (bs - 32) : sn << (32 - bs));
    const int xs = y + bs - 32;
    const uint32_t gm = ekf_fx_recip32(sm);
    /* gamma in Q1.30 (gamma <= 1 while Sn >= q >= 1; 0 for q = 0, where v = 0) */
    const int g30 = 33 + xs;
    const int32_t gamma30 = (q > 0 && g30 >= 1 && g30 < 32) ? (int32_t)(gm >> g30) : 0;
    ekf_status_t st;
    int i, j;

    /* S in the scalar: H P H^T rounded to it, plus R (exactly: S >= R whenever q >= 0) */
    s_q = ekf_fx_add(att_fx_to_q(q, ATT_FX_CF - EKF_FX_FRAC - 2 * eta), r_var);
    if (info != NULL) {
        info->innovation = nu;
        info->variance = s_q;
    }
    if (!ekf_isfinite(s_q) || !(s_q >= r_var) || !(s_q > EKF_C(0))) {
        return EKF_ERR_NUMERIC;
    }
    st = gate_test(nu, s_q, gate, info);
    if (st != EKF_OK) {
        return st;
    }
    if (c->inf != 0u) {
        return EKF_ERR_NUMERIC; /* a new variance would not be finite */
    }
    /* T = gamma v in Q2.30, the new variances c_ii - T_i v_i, the new state */
    for (i = 0; i < ATT_N; ++i) {
        /* (|T_i| < 2 for a positive semi-definite c: saturated, like every word, beyond) */
        T[i] = att_fx_sat(((int64_t)v[i] * gamma30 + (1 << 28)) >> 29);
        dg[i] = sub_rank1(c->c[att_fx_dg[i]], T[i], v[i]);
        if (i != k && dg[i] < -ATT_FX_TOL) {
            return EKF_ERR_NUMERIC; /* indefinite beyond rounding: no floor hides it */
        }
    }
    {
        /* K_i nu = 2^(e_i - eta) v_i gamma nu, gamma nu = wv 2^xw: the product v_i wv in
         * Q29.34 after a shift of xw - 29 + e_i - eta + 34 */
        const int nb = ekf_fx_bitlen64((nu < 0) ? (uint64_t)0 - (uint64_t)nu : (uint64_t)nu);
        const int32_t nm = att_fx_to_c(nu, nb - 31);
        const int32_t wv = (int32_t)(((int64_t)nm * gm) >> 32);
        const int base = (-63 - xs + (nb - 31 - EKF_FX_FRAC) + 32) - ATT_FX_CF - eta + EKF_FX_FRAC;
        ekf_scalar_t bad = EKF_C(0);
        for (i = 0; i < ATT_N; ++i) {
            const int sh = -(base + ((i == k) ? eta : c->e[i]));
            const int64_t p = (int64_t)v[i] * wv;
            const int32_t ph = (int32_t)(p >> 32);
            if (sh > 32 && sh < 63 && (uint32_t)ekf_fx_hi(x[i]) + 0x20000000u < 0x40000000u) {
                /* the common case: the correction from the product's high word (|dx| < 2^31)
                 * and |x_i| < 2^61, so the sum is finite and exact (att_fx_shr's rounding) */
                const int32_t dx = (ph >> (sh - 32)) + ((ph >> (sh - 33)) & 1);
                xn[i] = (ekf_scalar_t)((uint64_t)x[i] + (uint64_t)(int64_t)dx);
            } else {
                const ekf_scalar_t dx = (sh > 0 && sh < 63) ? att_fx_shr(p, sh) : att_fx_to_q(p, sh);
                xn[i] = ekf_fx_add(x[i], dx);
                bad = ekf_finite_acc(bad, xn[i]);
            }
        }
        if (!(bad == EKF_C(0))) {
            return EKF_ERR_NUMERIC;
        }
    }
    /* write: c - T v^T on the upper triangle (the diagonal as checked), in Q2.29 from the high
     * word of the Q4.59 product, rounded to nearest: two bits coarser than C's last one (2^-27
     * of the scale per update, unbiased; a rounding toward -inf would add a positive rank-one
     * bias that correlates every pair of states, an unobserved heading with the tilt too) */
    {
        int32_t *p = c->c; /* the packed rows (i, j >= i) in order */
        for (i = 0; i < ATT_N; ++i) {
            const int32_t ti = T[i];
            const int32_t *vj = &v[i + 1];
            x[i] = xn[i];
            *p++ = dg[i];
            for (j = i + 1; j < ATT_N; ++j) {
                *p = sub_rank1(*p, ti, *vj++);
                ++p;
            }
        }
    }
    if (k >= 0) {
        /* row and column k: c'_ik = c_ik rho, rho = r 2^(-2 eta) / Sn (no cancellation), from r's
         * top 32 bits rm = r 2^(32 - bq) and gamma = gm 2^(-63 - xs); in the
         * scale where c'_kk is in the band, or the floor's if the floor is larger */
        const int bq = ekf_fx_bitlen64((uint64_t)r_var);
        const uint32_t rm = (uint32_t)((bq >= 32) ? (uint64_t)r_var >> (bq - 32) : (uint64_t)r_var << (32 - bq));
        const int32_t rho = (int32_t)((uint32_t)(((uint64_t)rm * gm) >> 32) >> 1); /* < 2^31 */
        const int xr = bq - 96 - 2 * eta - xs;                   /* rho (real) = rho 2^xr */
        const int64_t pk = (int64_t)v[k] * rho;                     /* c'_kk = pk 2^(xr - 29) */
        int ek = (pk <= 0) ? ATT_FX_E_MIN : att_fx_norm_exp((uint64_t)pk, xr - ATT_FX_CF + 2 * eta);
        ek = (ef > ek) ? ef : ek;
        ek = (ek < ATT_FX_E_MIN) ? ATT_FX_E_MIN : ek;
        const int s1 = -(xr + eta - ek); /* the shift of c'_ik, i != k */
        const uint8_t *ix = att_fx_ix[k];
        if (s1 > 32 && s1 < 63) {
            /* from the product's high word (att_fx_to_c's rounding; |result| < 2^30) */
            for (i = 0; i < ATT_N; ++i) {
                const int32_t h = (int32_t)(((int64_t)v[i] * rho) >> 32);
                c->c[ix[i]] = (h >> (s1 - 32)) + ((h >> (s1 - 33)) & 1);
            }
        } else {
            for (i = 0; i < ATT_N; ++i) {
                c->c[ix[i]] = att_fx_to_c((int64_t)v[i] * rho, s1);
            }
        }
        c->c[ix[k]] = att_fx_to_c(pk, -(xr + 2 * (eta - ek)));
        c->e[k] = (int8_t)ek;
    }
    /* the floor (a variance that can be below it: below the band, or in a scale at most the
     * floor's) and the band */
    for (i = 0; i < ATT_N; ++i) {
        int32_t *d = &c->c[att_fx_dg[i]];
        if (*d < ATT_FX_C_ONE || c->e[i] <= ef) {
            const int32_t fl = att_fx_floor_c(c, i, var_floor);
            if (fl == INT32_MAX) {
                att_fx_floor_var(c, i, var_floor); /* rare: a floor this scale cannot hold */
            } else {
                *d = (*d < fl) ? fl : *d;
                att_fx_renorm(c, i);
            }
        }
    }
    return EKF_OK;
}

ekf_status_t att_cov_update_unit(att_cov_t *c, ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu, ekf_scalar_t r_var,
                                 ekf_scalar_t gate, ekf_scalar_t var_floor, ekf_innov_t *info)
{
    int32_t v[ATT_N];
    int i;
    if (info != NULL) {
        info->innovation = EKF_C(0);
        info->variance = EKF_C(0);
        info->test_ratio = EKF_C(0);
    }
    if (x == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_isfinite(nu) || !ekf_isfinite(r_var)) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(r_var > EKF_C(0))) {
        return EKF_ERR_RANGE;
    }
    if ((c->inf & (1u << idx)) != 0u || c->c[att_fx_ix[idx][idx]] < 0) {
        if (info != NULL) {
            info->innovation = nu;
            info->variance = ((c->inf & (1u << idx)) != 0u) ? EKF_FX_INF : r_var;
        }
        return EKF_ERR_NUMERIC; /* S not finite, or H P H^T < 0 */
    }
    {
        /* q = c_kk in the band: row k taken in the scale 2^eta (a left shift, exact) */
        const int32_t ckk = c->c[att_fx_ix[idx][idx]];
        int m = 0;
        if (ckk > 0 && ckk < ATT_FX_C_ONE) {
            m = c->e[idx] - att_fx_norm_exp((uint64_t)ckk, 2 * c->e[idx] - ATT_FX_CF);
        }
        const uint8_t *col = att_fx_ix[idx];
        if (m == 0) {
            for (i = 0; i < ATT_N; ++i) {
                v[i] = c->c[col[i]];
            }
        } else {
            for (i = 0; i < ATT_N; ++i) {
                v[i] = att_fx_to_c(c->c[col[i]], (i == idx) ? -2 * m : -m);
            }
        }
        return update(c, x, v, v[idx], c->e[idx] - m, idx, nu, r_var, gate, var_floor, info);
    }
}

ekf_status_t att_cov_update_angles(att_cov_t *c, ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3], ekf_scalar_t nu,
                                   ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor, ekf_innov_t *info)
{
    int64_t v64[ATT_N], q64 = 0;
    int32_t v[ATT_N], u[3];
    int eta, i, a, top = INT32_MIN, m;
    if (info != NULL) {
        info->innovation = EKF_C(0);
        info->variance = EKF_C(0);
        info->test_ratio = EKF_C(0);
    }
    if (x == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_isfinite(nu) || !ekf_isfinite(r_var) || !ekf_isfinite(h[0]) || !ekf_isfinite(h[1]) ||
        !ekf_isfinite(h[2])) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(r_var > EKF_C(0))) {
        return EKF_ERR_RANGE;
    }
    for (a = 0; a < 3; ++a) {
        if (h[a] != 0 && (c->inf & (1u << (ATT_PHI + a))) != 0u) {
            if (info != NULL) {
                info->innovation = nu;
                info->variance = EKF_FX_INF;
            }
            return EKF_ERR_NUMERIC;
        }
    }
    /* u = S H^T / 2^eta in Q0.31 with |u| < 1/4 */
    for (a = 0; a < 3; ++a) {
        if (h[a] != 0) {
            const int b = att_fx_abslen(h[a]) + c->e[ATT_PHI + a];
            top = (b > top) ? b : top;
        }
    }
    if (top == INT32_MIN) {
        return update(c, x, (const int32_t[ATT_N]){0}, 0, 0, -1, nu, r_var, gate, var_floor, info);
    }
    eta = top - EKF_FX_FRAC + 2;
    for (a = 0; a < 3; ++a) {
        u[a] = (h[a] != 0) ? att_fx_to_c(h[a], EKF_FX_FRAC + eta - 31 - c->e[ATT_PHI + a]) : 0;
    }
    for (i = 0; i < ATT_N; ++i) {
        v64[i] = (int64_t)c->c[att_fx_ix[i][ATT_PHI]] * u[0] + (int64_t)c->c[att_fx_ix[i][ATT_THETA]] * u[1] +
                 (int64_t)c->c[att_fx_ix[i][ATT_PSI]] * u[2]; /* Q2.60 */
    }
    /* q = u^T c u, then u (and v) scaled by 2^m so that q is in [1, 4) */
    for (a = 0; a < 3; ++a) {
        q64 += (int64_t)u[a] * att_fx_to_c(v64[ATT_PHI + a], 31); /* Q2.60 */
    }
    if (q64 < 0) {
        if (info != NULL) {
            info->innovation = nu;
            info->variance = r_var;
        }
        return EKF_ERR_NUMERIC; /* H P H^T < 0 */
    }
    m = (q64 > 0) ? (62 - att_fx_bitlen64((uint64_t)q64)) / 2 : 0;
    for (i = 0; i < ATT_N; ++i) {
        v[i] = att_fx_to_c(v64[i], 31 - m);
    }
    return update(c, x, v, att_fx_to_c(q64, 31 - 2 * m), eta - m, -1, nu, r_var, gate, var_floor, info);
}

