/*
 * ekf.c - generic EKF primitives (see ekf.h; derivations in docs/derivation.md).
 */
#include "ekf.h"

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
    uint16_t i;
    for (i = 0; i < len; ++i) {
        if (!ekf_isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

/* Index of the first pattern entry of each distinct row, validated. Returns the number
 * of distinct rows, or -1 if the pattern is unsorted or out of range. */
static int pattern_rows(const ekf_nz_t *pattern, uint16_t nnz, uint8_t n)
{
    int rows = 0;
    uint16_t k;
    for (k = 0; k < nnz; ++k) {
        if (pattern[k].row >= n || pattern[k].col >= n) {
            return -1;
        }
        if (k == 0 || pattern[k].row != pattern[k - 1u].row) {
            if (k > 0 && pattern[k].row < pattern[k - 1u].row) {
                return -1;
            }
            ++rows;
        }
    }
    return rows;
}

ekf_status_t ekf_cov_propagate(ekf_scalar_t *P, uint8_t n, const ekf_nz_t *pattern,
                               const ekf_scalar_t *d, uint16_t nnz, ekf_scalar_t *work,
                               uint16_t work_len)
{
    int rows;
    uint16_t k, k0, a;
    uint8_t j;
    uint32_t in_m = 0u; /* bit i set: row i of F differs from the identity */

    if (P == NULL || (nnz > 0 && (pattern == NULL || d == NULL || work == NULL))) {
        return EKF_ERR_NULL;
    }
    if (n == 0 || n > EKF_MAX_STATES) {
        return EKF_ERR_DIMENSION;
    }
    rows = pattern_rows(pattern, nnz, n);
    if (rows < 0 || (uint32_t)rows * n > work_len) {
        return EKF_ERR_DIMENSION;
    }
    if (!ekf_all_finite(d, nnz)) {
        return EKF_ERR_NOT_FINITE;
    }

    /* Step 1: the rows of A = F P = P + D P that differ from P, into work (one row of
     * work per distinct row of D, in pattern order). P itself is not touched yet, so
     * every D P term reads the old P. */
    for (k = 0, a = 0; k < nnz; ++a) {
        ekf_scalar_t *wrow = &work[(uint32_t)a * n];
        const uint8_t row = pattern[k].row;
        for (j = 0; j < n; ++j) {
            wrow[j] = P[(uint32_t)row * n + j];
        }
        for (; k < nnz && pattern[k].row == row; ++k) {
            const ekf_scalar_t *prow = &P[(uint32_t)pattern[k].col * n];
            for (j = 0; j < n; ++j) {
                wrow[j] = ekf_mac(wrow[j], d[k], prow[j]);
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
        in_m |= (uint32_t)1u << pattern[k].row;
    }
    for (k0 = 0, a = 0; k0 < nnz; ++a) {
        const uint8_t ri = pattern[k0].row;
        const ekf_scalar_t *arow = &work[(uint32_t)a * n];
        uint16_t kj = k0;
        for (j = 0; j < n; ++j) {
            if ((in_m & ((uint32_t)1u << j)) == 0u) {
                P[(uint32_t)ri * n + j] = arow[j];
                P[(uint32_t)j * n + ri] = arow[j];
            }
        }
        while (kj < nnz) {
            const uint8_t rj = pattern[kj].row;
            ekf_scalar_t v = arow[rj];
            for (; kj < nnz && pattern[kj].row == rj; ++kj) {
                v = ekf_mac(v, d[kj], arow[pattern[kj].col]);
            }
            P[(uint32_t)ri * n + rj] = v;
            P[(uint32_t)rj * n + ri] = v;
        }
        while (k0 < nnz && pattern[k0].row == ri) {
            ++k0;
        }
    }
    return EKF_OK;
}

ekf_status_t ekf_update_scalar(ekf_scalar_t *x, ekf_scalar_t *P, uint8_t n, const ekf_hrow_t *h,
                               ekf_scalar_t innovation, ekf_scalar_t r_var,
                               ekf_scalar_t gate_sigma, ekf_scalar_t var_floor,
                               ekf_innov_t *info)
{
    ekf_scalar_t b[EKF_MAX_STATES]; /* P H^T */
    ekf_scalar_t K[EKF_MAX_STATES]; /* gain */
    ekf_scalar_t s, inv_s, hb;
    uint8_t i, j, k;

    if (x == NULL || P == NULL || h == NULL || (h->nnz > 0 && (h->idx == NULL || h->value == NULL))) {
        return EKF_ERR_NULL;
    }
    if (n == 0 || n > EKF_MAX_STATES || h->nnz == 0 || h->nnz > n) {
        return EKF_ERR_DIMENSION;
    }
    for (k = 0; k < h->nnz; ++k) {
        if (h->idx[k] >= n) {
            return EKF_ERR_DIMENSION;
        }
    }
    if (!ekf_isfinite(innovation) || !ekf_isfinite(r_var) || !ekf_all_finite(h->value, h->nnz)) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(r_var > EKF_C(0))) {
        return EKF_ERR_RANGE;
    }

    /* b = P H^T (H sparse) and S = H b + R */
    for (i = 0; i < n; ++i) {
        ekf_scalar_t acc = EKF_C(0);
        for (k = 0; k < h->nnz; ++k) {
            acc = ekf_mac(acc, P[(uint32_t)i * n + h->idx[k]], h->value[k]);
        }
        b[i] = acc;
    }
    hb = EKF_C(0);
    for (k = 0; k < h->nnz; ++k) {
        hb = ekf_mac(hb, h->value[k], b[h->idx[k]]);
    }
    s = ekf_add(hb, r_var);
    if (!ekf_isfinite(s) || !(s >= r_var) || !(s > EKF_C(0))) {
        /* H P H^T < 0 means P is not positive semi-definite along H: refuse */
        return EKF_ERR_NUMERIC;
    }
    if (info != NULL) {
        info->innovation = innovation;
        info->variance = s;
        info->test_ratio = EKF_C(0);
    }
    if (gate_sigma > EKF_C(0)) {
        const ekf_scalar_t ratio = ekf_div(ekf_sq(innovation), ekf_mul(ekf_sq(gate_sigma), s));
        if (info != NULL) {
            info->test_ratio = ratio;
        }
        if (!ekf_isfinite(ratio) || ratio > EKF_C(1)) {
            return EKF_GATED;
        }
    }

    inv_s = ekf_div(EKF_C(1), s);
    for (i = 0; i < n; ++i) {
        K[i] = ekf_mul(b[i], inv_s);
        if (!ekf_isfinite(K[i]) || !ekf_isfinite(ekf_mac(x[i], K[i], innovation))) {
            return EKF_ERR_NUMERIC;
        }
    }
    /* Joseph form (I - K H) P (I - K H)^T + K R K^T expanded for a scalar measurement:
     *   P+_ij = P_ij - K_i b_j - b_i K_j + S K_i K_j = P_ij - K_i b_j + c_i K_j,
     * exact for any gain K, and first-order insensitive to rounding in K (the property
     * that makes the Joseph form robust); docs/derivation.md. Check the diagonal before
     * writing anything, so that a refused update leaves P as it was.
     * c_i = S K_i - b_i is zero in exact arithmetic; it carries the rounding of K. */
    for (i = 0; i < n; ++i) {
        const ekf_scalar_t ci = ekf_sub(ekf_mul(s, K[i]), b[i]);
        const ekf_scalar_t pii = ekf_mac(ekf_sub(P[(uint32_t)i * n + i], ekf_mul(K[i], b[i])), ci, K[i]);
        if (!ekf_isfinite(pii)) {
            return EKF_ERR_NUMERIC;
        }
    }
    for (i = 0; i < n; ++i) {
        const ekf_scalar_t ci = ekf_sub(ekf_mul(s, K[i]), b[i]);
        for (j = i; j < n; ++j) {
            ekf_scalar_t v = P[(uint32_t)i * n + j];
            v = ekf_sub(v, ekf_mul(K[i], b[j]));
            v = ekf_mac(v, ci, K[j]);
            if (i == j && v < var_floor) {
                v = var_floor;
            }
            P[(uint32_t)i * n + j] = v;
            P[(uint32_t)j * n + i] = v;
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
    if (!(pii > max_var)) {
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
     * its off-diagonal entries are L_jk and its diagonal entry is the pivot d_j. */
    uint16_t j, k, m;
    if (P == NULL || work == NULL || n == 0 || n > EKF_MAX_STATES) {
        return 0;
    }
    for (j = 0; j < n; ++j) {
        ekf_scalar_t *lj = &work[(uint32_t)j * (j + 1u) / 2u];
        ekf_scalar_t dj = P[(uint32_t)j * n + j];
        for (k = 0; k < j; ++k) {
            const ekf_scalar_t *lk = &work[(uint32_t)k * (k + 1u) / 2u];
            ekf_scalar_t v = P[(uint32_t)j * n + k];
            for (m = 0; m < k; ++m) {
                /* lk[k] is d_k, lk[m] is L_km, lj[m] is L_jm, work row m's diagonal is d_m */
                v = ekf_sub(v, ekf_mul(ekf_mul(lj[m], lk[m]), work[(uint32_t)m * (m + 1u) / 2u + m]));
            }
            lj[k] = ekf_div(v, lk[k]);
            dj = ekf_sub(dj, ekf_mul(ekf_mul(lj[k], lj[k]), lk[k]));
        }
        if (!ekf_isfinite(dj) || !(dj > EKF_C(0)) || !(dj >= ekf_mul(rel_margin, P[(uint32_t)j * n + j]))) {
            return 0;
        }
        lj[j] = dj;
    }
    return 1;
}

int ekf_cov_ensure_pd(ekf_scalar_t *P, uint8_t n, ekf_scalar_t rel_margin, ekf_scalar_t floor,
                      ekf_scalar_t *work)
{
    ekf_scalar_t lambda = ekf_mul(EKF_C(10), rel_margin);
    int rounds = 0;
    uint8_t i, j;
    if (P == NULL || work == NULL || n == 0 || n > EKF_MAX_STATES) {
        return 0;
    }
    while (!ekf_cov_is_pd(P, n, rel_margin, work)) {
        ++rounds;
        if (lambda > EKF_C(1)) {
            /* the correlations themselves are broken: keep the variances only */
            for (i = 0; i < n; ++i) {
                for (j = 0; j < n; ++j) {
                    if (i != j) {
                        P[(uint32_t)i * n + j] = EKF_C(0);
                    }
                }
                P[(uint32_t)i * n + i] = ekf_max(P[(uint32_t)i * n + i], floor);
            }
            break;
        }
        for (i = 0; i < n; ++i) {
            const ekf_scalar_t pii = ekf_max(P[(uint32_t)i * n + i], floor);
            P[(uint32_t)i * n + i] = ekf_mac(pii, pii, lambda);
        }
        lambda = ekf_mul(lambda, EKF_C(10));
    }
    return rounds;
}
