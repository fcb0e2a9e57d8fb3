/*
 * ekf.c - generic EKF primitives (see ekf.h; derivations in docs/derivation.md).
 */
#include "ekf.h"
#include "ekf_util.h"

#include <stddef.h>

const char *ekf_status_str(ekf_status_t status)
{
    switch (status) {
    case EKF_OK: return "EKF_OK";
    case EKF_ERR_NULL: return "EKF_ERR_NULL";
    case EKF_ERR_NOT_FINITE: return "EKF_ERR_NOT_FINITE";
    case EKF_ERR_DT_NONPOSITIVE: return "EKF_ERR_DT_NONPOSITIVE";
    case EKF_ERR_DT_TOO_LARGE: return "EKF_ERR_DT_TOO_LARGE";
    case EKF_ERR_RANGE: return "EKF_ERR_RANGE";
    case EKF_ERR_NOT_INITIALISED: return "EKF_ERR_NOT_INITIALISED";
    case EKF_ERR_SETTINGS: return "EKF_ERR_SETTINGS";
    case EKF_ERR_DIMENSION: return "EKF_ERR_DIMENSION";
    case EKF_ERR_NUMERIC: return "EKF_ERR_NUMERIC";
    case EKF_ERR_SINGULAR: return "EKF_ERR_SINGULAR";
    case EKF_GATED: return "EKF_GATED";
    case EKF_SKIPPED: return "EKF_SKIPPED";
    }
    return "EKF_STATUS_UNKNOWN";
}

int ekf_all_finite(const ekf_scalar_t *v, uint16_t len)
{
    ekf_scalar_t acc = EKF_C(0);
    int i;
    for (i = 0; i < len; ++i) {
        acc = ekf_finite_acc(acc, v[i]);
    }
    return (acc == EKF_C(0)) ? 1 : 0;
}

/* Set of rows of D, one bit per row, in words of 32 bits (any EKF_MAX_STATES). */
#define EKF_MASK_WORDS ((EKF_MAX_STATES + 31) / 32)

/* Start index in pattern of each distinct row (starts[rows] = nnz), validated. Returns the
 * number of distinct rows, or -1 if the pattern is unsorted or out of range. */
static int pattern_rows(const ekf_nz_t *pattern, int nnz, int n, uint16_t *starts)
{
    int rows = 0;
    int k;
    for (k = 0; k < nnz; ++k) {
        if (pattern[k].row >= n || pattern[k].col >= n) {
            return -1;
        }
        if (k == 0 || pattern[k].row != pattern[k - 1].row) {
            if (k > 0 && pattern[k].row < pattern[k - 1].row) {
                return -1;
            }
            starts[rows++] = (uint16_t)k;
        }
    }
    starts[rows] = (uint16_t)nnz;
    return rows;
}

ekf_status_t ekf_cov_propagate(ekf_scalar_t *P, uint8_t n, const ekf_nz_t *pattern,
                               const ekf_scalar_t *d, uint16_t nnz, ekf_scalar_t *work,
                               uint16_t work_len)
{
    uint16_t starts[EKF_MAX_STATES + 1]; /* first pattern entry of each row of D */
    uint32_t in_m[EKF_MASK_WORDS] = {0}; /* bit i set: row i of F differs from the identity */
    const int nn = n;
    int rows, a, b, j, k;

    if (P == NULL || (nnz > 0 && (pattern == NULL || d == NULL || work == NULL))) {
        return EKF_ERR_NULL;
    }
    if (nn == 0 || nn > EKF_MAX_STATES) {
        return EKF_ERR_DIMENSION;
    }
    rows = pattern_rows(pattern, nnz, nn, starts);
    if (rows < 0 || (uint32_t)rows * (uint32_t)nn > work_len) {
        return EKF_ERR_DIMENSION;
    }
    if (!ekf_all_finite(d, nnz)) {
        return EKF_ERR_NOT_FINITE;
    }

    /* Step 1: the rows of A = F P = P + D P that differ from P, into work (one row of
     * work per distinct row of D, in pattern order). P itself is not touched yet, so
     * every D P term reads the old P. Row i of D P is a combination of rows of P (the
     * columns of D's row i): A_i = P_i + d_k1 P_c1 + d_k2 P_c2 + ..., summed in pattern
     * order, two terms per pass over the row. */
    for (a = 0; a < rows; ++a) {
        ekf_scalar_t *w = &work[a * nn];
        const ekf_scalar_t *pr = &P[pattern[starts[a]].row * nn];
        const int kend = starts[a + 1];
        k = starts[a];
        if (kend - k >= 2) {
            const ekf_scalar_t *p0 = &P[pattern[k].col * nn], *p1 = &P[pattern[k + 1].col * nn];
            const ekf_scalar_t d0 = d[k], d1 = d[k + 1];
            for (j = 0; j < nn; ++j) {
                w[j] = ekf_mac(ekf_mac(pr[j], d0, p0[j]), d1, p1[j]);
            }
            k += 2;
        } else {
            const ekf_scalar_t *p0 = &P[pattern[k].col * nn];
            const ekf_scalar_t d0 = d[k];
            for (j = 0; j < nn; ++j) {
                w[j] = ekf_mac(pr[j], d0, p0[j]);
            }
            k += 1;
        }
        for (; k + 1 < kend; k += 2) {
            const ekf_scalar_t *p0 = &P[pattern[k].col * nn], *p1 = &P[pattern[k + 1].col * nn];
            const ekf_scalar_t d0 = d[k], d1 = d[k + 1];
            for (j = 0; j < nn; ++j) {
                w[j] = ekf_mac(ekf_mac(w[j], d0, p0[j]), d1, p1[j]);
            }
        }
        if (k < kend) {
            const ekf_scalar_t *p0 = &P[pattern[k].col * nn];
            const ekf_scalar_t d0 = d[k];
            for (j = 0; j < nn; ++j) {
                w[j] = ekf_mac(w[j], d0, p0[j]);
            }
        }
    }

    /* Step 2: P+ = A F^T = A + A D^T. A column j of D^T only exists for the rows of D,
     * so P+ differs from A only in those columns, and A differs from P only in those
     * rows. With M the set of rows of D:
     *   i in M, j not in M: P+_ij = A_ij                      (work row of i)
     *   i in M, j in M:     P+_ij = A_ij + sum_l D_jl A_il
     *   i, j not in M:      P+_ij = P_ij                      (untouched)
     * Each (i, j) pair with both in M is computed once (j's group not before i's) and
     * written to both triangles, so P stays exactly symmetric. Only work is read here. */
    for (k = 0; k < nnz; ++k) {
        in_m[pattern[k].row >> 5] |= (uint32_t)1u << (pattern[k].row & 31u);
    }
    for (a = 0; a < rows; ++a) {
        const int ri = pattern[starts[a]].row;
        const ekf_scalar_t *arow = &work[a * nn];
        ekf_scalar_t *prow = &P[ri * nn];
        ekf_scalar_t *pcol = &P[ri];
        for (j = 0; j < nn; ++j, pcol += nn) {
            if ((in_m[j >> 5] & ((uint32_t)1u << (j & 31))) == 0u) {
                prow[j] = arow[j];
                *pcol = arow[j];
            }
        }
        for (b = a; b < rows; ++b) {
            const int rj = pattern[starts[b]].row;
            const int kend = starts[b + 1];
            ekf_scalar_t v = arow[rj];
            for (k = starts[b]; k < kend; ++k) {
                v = ekf_mac(v, d[k], arow[pattern[k].col]);
            }
            prow[rj] = v;
            P[rj * nn + ri] = v;
        }
    }
    return EKF_OK;
}

/* Rounding allowance of an updated variance v = P_ii - K_i b_i (docs/derivation.md,
 * "Covariance update"): below -tol the covariance is indefinite beyond rounding and the
 * update is refused; between -tol and var_floor v is floored. In exact arithmetic v >= 0
 * for a positive semi-definite P. The relative part covers IEEE rounding of the n-term sums
 * behind b and S (about n eps of |P_ii| + K_i b_i, with a margin for cancellation); the
 * absolute part covers fixed point, where every product is rounded to one LSB and the
 * error grows with the factors K_i and b_i. */
static ekf_scalar_t variance_tolerance(int n, ekf_scalar_t pii, ekf_scalar_t ki, ekf_scalar_t bi)
{
    const ekf_scalar_t c = ekf_from_int((int32_t)(32 * n));
    const ekf_scalar_t k = ekf_abs(ki);
    ekf_scalar_t tol = ekf_mul(ekf_mul(c, EKF_SCALAR_EPS), ekf_add(ekf_abs(pii), ekf_mul(k, ekf_abs(bi))));
    if (EKF_SCALAR_ABS_EPS > EKF_C(0)) { /* a compile-time constant: fixed point only */
        const ekf_scalar_t fac = ekf_mul(ekf_add(EKF_C(1), k), ekf_add(ekf_add(EKF_C(1), k), ekf_abs(bi)));
        tol = ekf_mac(tol, ekf_mul(c, EKF_SCALAR_ABS_EPS), fac);
    }
    return tol;
}

ekf_status_t ekf_update_scalar(ekf_scalar_t *x, ekf_scalar_t *P, uint8_t n, const ekf_hrow_t *h,
                               ekf_scalar_t innovation, ekf_scalar_t r_var,
                               ekf_scalar_t gate_sigma, ekf_scalar_t var_floor,
                               ekf_innov_t *info)
{
    ekf_scalar_t b[EKF_MAX_STATES]; /* P H^T */
    ekf_scalar_t K[EKF_MAX_STATES]; /* gain */
    ekf_scalar_t s, inv_s, hb, bad;
    const uint8_t *hidx;
    const ekf_scalar_t *hval;
    const int nn = n;
    int i, j, k, nh, indefinite;

    if (info != NULL) {
        /* every field defined on every path (overwritten below once S is formed) */
        info->innovation = EKF_C(0);
        info->variance = EKF_C(0);
        info->test_ratio = EKF_C(0);
    }
    if (x == NULL || P == NULL || h == NULL || (h->nnz > 0 && (h->idx == NULL || h->value == NULL))) {
        return EKF_ERR_NULL;
    }
    nh = h->nnz;
    hidx = h->idx;
    hval = h->value;
    if (nn == 0 || nn > EKF_MAX_STATES || nh == 0 || nh > nn) {
        return EKF_ERR_DIMENSION;
    }
    for (k = 0; k < nh; ++k) {
        if (hidx[k] >= nn) {
            return EKF_ERR_DIMENSION;
        }
    }
    if (!ekf_isfinite(innovation) || !ekf_isfinite(r_var) || !ekf_all_finite(hval, h->nnz)) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(r_var > EKF_C(0))) {
        return EKF_ERR_RANGE;
    }

    /* b = P H^T = sum_k h_k (column idx_k of P); P is exactly symmetric, so that column is
     * row idx_k, contiguous in memory. H has one or two non-zeros in the attitude model. */
    {
        const ekf_scalar_t *row = &P[hidx[0] * nn];
        const ekf_scalar_t h0 = hval[0];
        for (i = 0; i < nn; ++i) {
            b[i] = ekf_mul(row[i], h0);
        }
        for (k = 1; k < nh; ++k) {
            const ekf_scalar_t hk = hval[k];
            row = &P[hidx[k] * nn];
            for (i = 0; i < nn; ++i) {
                b[i] = ekf_mac(b[i], row[i], hk);
            }
        }
    }
    hb = EKF_C(0);
    for (k = 0; k < nh; ++k) {
        hb = ekf_mac(hb, hval[k], b[hidx[k]]);
    }
    s = ekf_add(hb, r_var);
    if (info != NULL) {
        info->innovation = innovation;
        info->variance = s;
    }
    if (!ekf_isfinite(s) || !(s >= r_var) || !(s > EKF_C(0))) {
        /* H P H^T < 0 means P is not positive semi-definite along H: refuse */
        return EKF_ERR_NUMERIC;
    }
    if (ekf_gate_test(innovation, s, gate_sigma, info) == EKF_GATED) {
        return EKF_GATED;
    }

    /* Gain, and a check that the gain, the new state and the new variances are finite and
     * the new variances not negative beyond rounding, before anything is written, so that
     * a refused update leaves x and P as they were. */
    inv_s = ekf_div(EKF_C(1), s);
    bad = EKF_C(0);
    indefinite = 0;
    for (i = 0; i < nn; ++i) {
        const ekf_scalar_t ki = ekf_mul(b[i], inv_s);
        const ekf_scalar_t vi = ekf_mac(P[i * nn + i], ekf_neg(ki), b[i]);
        K[i] = ki;
        bad = ekf_finite_acc(bad, ekf_mac(x[i], ki, innovation));
        bad = ekf_finite_acc(bad, vi);
        if (vi < EKF_C(0) && vi < ekf_neg(variance_tolerance(nn, P[i * nn + i], ki, b[i]))) {
            indefinite = 1; /* (the allowance is only needed for the rare negative values) */
        }
    }
    if (!(bad == EKF_C(0)) || indefinite) {
        return EKF_ERR_NUMERIC;
    }
    /* P+ = P - K b^T (= P - b b^T / S), docs/derivation.md "Covariance update". Computed
     * on the upper triangle and mirrored, so P stays exactly symmetric; the diagonal is
     * floored (the values below the floor are rounding-size or small positive ones: the
     * loop above refused anything more negative). This is the Joseph form
     * (I - K H) P (I - K H)^T + K R K^T evaluated at the gain K = b / S the routine itself
     * computes: the Joseph form's extra terms, -b K^T + S K K^T = (S K - b) K^T, vanish for
     * that gain and would only add the rounding of K (below the rounding of P itself). */
    for (i = 0; i < nn; ++i) {
        ekf_scalar_t *pi = &P[i * nn];
        ekf_scalar_t *pc = &P[(i + 1) * nn + i];
        const ekf_scalar_t nki = ekf_neg(K[i]);
        ekf_scalar_t v = ekf_mac(pi[i], nki, b[i]);
        pi[i] = (v < var_floor) ? var_floor : v;
        for (j = i + 1; j < nn; ++j, pc += nn) {
            v = ekf_mac(pi[j], nki, b[j]);
            pi[j] = v;
            *pc = v;
        }
        x[i] = ekf_mac(x[i], K[i], innovation);
    }
    return EKF_OK;
}

int ekf_cov_limit_variance(ekf_scalar_t *P, uint8_t n, uint8_t i, ekf_scalar_t max_var)
{
    ekf_scalar_t pii, scale;
    uint8_t j;
    if (P == NULL || i >= n || !(max_var > EKF_C(0))) {
        return 0;
    }
    pii = P[(uint32_t)i * n + i];
    if (!(pii > max_var) || !ekf_isfinite(pii)) {
        /* (an overflowed variance has no scale: left for the caller's finiteness check to
         * refuse, not reset to a bound that would hide the overflow) */
        return 0;
    }
    scale = ekf_sqrt(ekf_div(max_var, pii));
    for (j = 0; j < n; ++j) {
        P[(uint32_t)i * n + j] = ekf_mul(P[(uint32_t)i * n + j], scale);
        P[(uint32_t)j * n + i] = ekf_mul(P[(uint32_t)j * n + i], scale);
    }
    /* the diagonal was scaled twice (scale^2), as a congruence requires */
    return 1;
}

int ekf_cov_is_pd(const ekf_scalar_t *P, uint8_t n, ekf_scalar_t rel_margin, ekf_scalar_t *work)
{
    /* LDL^T, row by row. work holds the packed lower triangle: row j starts at j(j+1)/2;
     * its off-diagonal entries are L_jk and its diagonal entry is the pivot d_j. While
     * row j is formed its entries hold w_jk = L_jk d_k:
     *   w_jk = P_jk - sum_{m<k} w_jm L_km,  L_jk = w_jk / d_k,  d_j = P_jj - sum_k w_jk L_jk,
     * n^3/6 multiply-adds, no product of three factors. */
    const int nn = n;
    int j, k, m;
    ekf_scalar_t *lj;
    if (P == NULL || work == NULL || nn == 0 || nn > EKF_MAX_STATES) {
        return 0;
    }
    for (j = 0, lj = work; j < nn; lj += j + 1, ++j) {
        const ekf_scalar_t *pj = &P[j * nn];
        const ekf_scalar_t *lk;
        ekf_scalar_t dj = pj[j];
        for (k = 0, lk = work; k < j; lk += k + 1, ++k) {
            ekf_scalar_t v = pj[k];
            for (m = 0; m < k; ++m) {
                v = ekf_mac(v, ekf_neg(lj[m]), lk[m]);
            }
            lj[k] = v;
        }
        for (k = 0, lk = work; k < j; lk += k + 1, ++k) {
            const ekf_scalar_t l = ekf_div(lj[k], lk[k]); /* lk[k] is d_k */
            dj = ekf_mac(dj, ekf_neg(l), lj[k]);
            lj[k] = l;
        }
        if (!ekf_isfinite(dj) || !(dj > EKF_C(0)) || !(dj >= ekf_mul(rel_margin, pj[j]))) {
            return 0;
        }
        lj[j] = dj;
    }
    return 1;
}

int ekf_cov_ensure_pd(ekf_scalar_t *P, uint8_t n, ekf_scalar_t rel_margin, ekf_scalar_t floor,
                      ekf_scalar_t *work)
{
    /* the first load is 10 rel_margin, at least 16 eps (so that a zero margin terminates
     * too), growing tenfold per round up to 1 */
    ekf_scalar_t lambda = ekf_max(ekf_mul(EKF_C(10), rel_margin), ekf_mul(EKF_C(16), EKF_SCALAR_EPS));
    int rounds = 0, passed = 0;
    uint8_t i, j;
    if (P == NULL || work == NULL || n == 0 || n > EKF_MAX_STATES || !ekf_isfinite(floor) ||
        !(floor > EKF_C(0)) || !ekf_isfinite(rel_margin) || rel_margin < EKF_C(0) || !(rel_margin < EKF_C(1))) {
        return -1;
    }
    if (ekf_cov_is_pd(P, n, rel_margin, work)) {
        return 0; /* (the check also shows that P is finite) */
    }
    if (!ekf_all_finite(P, (uint16_t)((uint16_t)n * n))) {
        return -1; /* nothing to repair from: an overflow upstream, the caller refuses */
    }
    while (!passed) {
        int finite = 1;
        ++rounds;
        if (lambda > EKF_C(1)) {
            break;
        }
        for (i = 0; i < n && finite; ++i) {
            const ekf_scalar_t pii = ekf_max(P[(uint32_t)i * n + i], floor);
            finite = ekf_isfinite(ekf_mac(pii, pii, lambda));
        }
        if (!finite) {
            break; /* loading would overflow: keep the variances only (below) */
        }
        for (i = 0; i < n; ++i) {
            const ekf_scalar_t pii = ekf_max(P[(uint32_t)i * n + i], floor);
            P[(uint32_t)i * n + i] = ekf_mac(pii, pii, lambda);
        }
        lambda = ekf_mul(lambda, EKF_C(10));
        passed = ekf_cov_is_pd(P, n, rel_margin, work);
    }
    if (!passed) {
        /* the correlations themselves are broken: keep the variances only, a positive
         * diagonal matrix (every pivot equals its variance: passes any margin < 1) */
        for (i = 0; i < n; ++i) {
            for (j = 0; j < n; ++j) {
                if (i != j) {
                    P[(uint32_t)i * n + j] = EKF_C(0);
                }
            }
            P[(uint32_t)i * n + i] = ekf_max(P[(uint32_t)i * n + i], floor);
        }
    }
    return rounds;
}
