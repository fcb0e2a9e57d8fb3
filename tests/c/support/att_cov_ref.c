/*
 * att_cov_ref.c - reference implementation of att_cov.h for the tests: P full row-major 9x9,
 * on the generic routines of ekf.h (ekf_update_scalar, ekf_cov_limit_variance, ekf_cov_is_pd,
 * ekf_cov_ensure_pd) and the generated att_gen_cov_propagate_f1/_f2 (ekf_cov_propagate
 * unrolled, bit for bit). The same filter without any storage optimisation, compiled with
 * ATT_COV_REFERENCE in place of the build's own covariance (tests/c/CMakeLists.txt).
 */
#include "att_cov.h"

#if !defined(ATT_COV_REFERENCE)
#error "att_cov_ref.c is the tests' reference covariance: compile it with ATT_COV_REFERENCE"
#endif

#include <stddef.h>

#define PIJ(c, i, j) ((c)->P[(i) * ATT_N + (j)])

void att_cov_set_diag(att_cov_t *c, const ekf_scalar_t var[ATT_N])
{
    int i;
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        c->P[i] = EKF_C(0);
    }
    for (i = 0; i < ATT_N; ++i) {
        PIJ(c, i, i) = var[i];
    }
}

ekf_scalar_t att_cov_get(const att_cov_t *c, int i, int j) { return PIJ(c, i, j); }

ekf_scalar_t att_cov_var(const att_cov_t *c, int i) { return PIJ(c, i, i); }

void att_cov_to_full(const att_cov_t *c, ekf_scalar_t P[ATT_N * ATT_N])
{
    int i;
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        P[i] = c->P[i];
    }
}

void att_cov_from_full(att_cov_t *c, const ekf_scalar_t P[ATT_N * ATT_N])
{
    int i, j;
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j <= i; ++j) {
            PIJ(c, i, j) = PIJ(c, j, i) = P[i * ATT_N + j];
        }
    }
}

ekf_status_t att_cov_predict(att_cov_t *c, const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                             const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const ekf_scalar_t var[3],
                             ekf_scalar_t inc_var[3])
{
    int k = 0, i;
    if (!ekf_all_finite(d1, ATT_GEN_F1_NNZ) || !ekf_all_finite(d2, ATT_GEN_F2_NNZ)) {
        return EKF_ERR_NUMERIC;
    }
    for (i = 0; i < 3; ++i) {
        inc_var[i] = EKF_C(0);
    }
    /* the increment variances: the quadratic form of each row of D1 (sorted by row) over
     * the entries of P its columns select (7, 4 and 6 entries) */
    while (k < ATT_GEN_F1_NNZ) {
        const int row = att_gen_f1_pattern[k].row;
        int end = k, a, b;
        ekf_scalar_t v = EKF_C(0);
        while (end < ATT_GEN_F1_NNZ && att_gen_f1_pattern[end].row == row) {
            ++end;
        }
        for (a = k; a < end; ++a) {
            const ekf_scalar_t *pa = &c->P[att_gen_f1_pattern[a].col * ATT_N];
            ekf_scalar_t acc = EKF_C(0);
            for (b = k; b < end; ++b) {
                acc = ekf_mac(acc, d1[b], pa[att_gen_f1_pattern[b].col]);
            }
            v = ekf_mac(v, d1[a], acc);
        }
        if (row >= ATT_PHI && row <= ATT_PSI) {
            inc_var[row - ATT_PHI] = ekf_max(v, EKF_C(0));
        }
        k = end;
    }
    /* F2 (F1 P F1^T + diag(var, 0)) F2^T: G diag(var) G^T = F2 diag(var, 0) F2^T. Each factor
     * generated for its pattern, bit-identical to ekf_cov_propagate (test_att_propagate.c). */
    att_gen_cov_propagate_f1(c->P, d1);
    for (i = 0; i < 3; ++i) {
        PIJ(c, ATT_P + i, ATT_P + i) = ekf_add(PIJ(c, ATT_P + i, ATT_P + i), var[i]);
    }
    att_gen_cov_propagate_f2(c->P, d2);
    return EKF_OK;
}

void att_cov_add_rate_noise(att_cov_t *c, const ekf_scalar_t g[9], const ekf_scalar_t var[3])
{
    int i, j, k;
    for (i = 0; i < 3; ++i) {
        PIJ(c, ATT_P + i, ATT_P + i) = ekf_add(PIJ(c, ATT_P + i, ATT_P + i), var[i]);
        for (j = 0; j < 3; ++j) {
            /* (Euler rate i, body rate j) = var_j * g[i][j], and its mirror */
            const ekf_scalar_t v = ekf_mul(var[j], g[i * 3 + j]);
            PIJ(c, ATT_PHID + i, ATT_P + j) = ekf_add(PIJ(c, ATT_PHID + i, ATT_P + j), v);
            PIJ(c, ATT_P + j, ATT_PHID + i) = ekf_add(PIJ(c, ATT_P + j, ATT_PHID + i), v);
        }
        for (j = i; j < 3; ++j) {
            ekf_scalar_t ggt = EKF_C(0);
            for (k = 0; k < 3; ++k) {
                ggt = ekf_mac(ggt, ekf_mul(g[i * 3 + k], var[k]), g[j * 3 + k]);
            }
            PIJ(c, ATT_PHID + i, ATT_PHID + j) = ekf_add(PIJ(c, ATT_PHID + i, ATT_PHID + j), ggt);
            if (j != i) {
                PIJ(c, ATT_PHID + j, ATT_PHID + i) = PIJ(c, ATT_PHID + i, ATT_PHID + j);
            }
        }
    }
}

void att_cov_add_diag(att_cov_t *c, int first, int len, ekf_scalar_t var)
{
    int i;
    for (i = first; i < first + len; ++i) {
        PIJ(c, i, i) = ekf_add(PIJ(c, i, i), var);
    }
}

void att_cov_add_var(att_cov_t *c, int i, ekf_scalar_t var) { PIJ(c, i, i) = ekf_add(PIJ(c, i, i), var); }

void att_cov_scale_diag(att_cov_t *c, int first, int len, ekf_scalar_t rel)
{
    int i;
    for (i = first; i < first + len; ++i) {
        PIJ(c, i, i) = ekf_mac(PIJ(c, i, i), PIJ(c, i, i), rel);
    }
}

int att_cov_floor_diag(att_cov_t *c, ekf_scalar_t floor)
{
    const ekf_scalar_t k = EKF_C(32 * ATT_N);
    ekf_scalar_t low = EKF_C(0);
    int i;
    for (i = 0; i < ATT_N; ++i) {
        if (!ekf_isfinite(PIJ(c, i, i))) {
            return -1;
        }
        low = ekf_min(low, PIJ(c, i, i));
    }
    if (low < EKF_C(0)) { /* rare: the allowance relative to the largest variance */
        ekf_scalar_t top = EKF_C(0);
        for (i = 0; i < ATT_N; ++i) {
            top = ekf_max(top, PIJ(c, i, i));
        }
        if (low < ekf_neg(ekf_mac(ekf_mul(ekf_mul(k, EKF_SCALAR_EPS), top), ekf_mul(k, EKF_SCALAR_ABS_EPS),
                                  ekf_add(EKF_C(1), top)))) {
            return -1;
        }
    }
    for (i = 0; i < ATT_N; ++i) {
        PIJ(c, i, i) = ekf_max(PIJ(c, i, i), floor);
    }
    return 0;
}

void att_cov_reset_state(att_cov_t *c, int i, ekf_scalar_t var)
{
    int j;
    for (j = 0; j < ATT_N; ++j) {
        PIJ(c, i, j) = EKF_C(0);
        PIJ(c, j, i) = EKF_C(0);
    }
    PIJ(c, i, i) = var;
}

int att_cov_limit_variance(att_cov_t *c, int i, ekf_scalar_t max_var)
{
    /* the test first: ekf_cov_limit_variance is called only when it has something to do */
    if (!(PIJ(c, i, i) > max_var) || !ekf_isfinite(PIJ(c, i, i))) {
        return 0;
    }
    return ekf_cov_limit_variance(c->P, ATT_N, (uint8_t)i, max_var);
}

void att_cov_negate_state(att_cov_t *c, int i)
{
    int j;
    for (j = 0; j < ATT_N; ++j) {
        PIJ(c, i, j) = ekf_neg(PIJ(c, i, j));
        PIJ(c, j, i) = ekf_neg(PIJ(c, j, i));
    }
    /* the diagonal entry was negated twice: unchanged, as the congruence requires */
}

ekf_status_t att_cov_update_unit(att_cov_t *c, ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu,
                                 ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor,
                                 ekf_innov_t *info)
{
    static const ekf_scalar_t one = EKF_C(1);
    const uint8_t col = (uint8_t)idx;
    const ekf_hrow_t h = {&col, &one, 1u};
    return ekf_update_scalar(x, c->P, ATT_N, &h, nu, r_var, gate, var_floor, info);
}

ekf_status_t att_cov_update_angles(att_cov_t *c, ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3], ekf_scalar_t nu,
                                   ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor, ekf_innov_t *info)
{
    /* the entries of pitch and heading only where they are not zero (the accelerometer's
     * rows): the same sums as the packed implementation's, bit for bit */
    uint8_t cols[3];
    ekf_scalar_t hv[3];
    uint8_t n = 0u;
    int k;
    for (k = 0; k < 3; ++k) {
        if (k == 0 || h[k] != EKF_C(0)) {
            cols[n] = (uint8_t)(ATT_PHI + k);
            hv[n++] = h[k];
        }
    }
    {
        const ekf_hrow_t row = {cols, hv, n};
        return ekf_update_scalar(x, c->P, ATT_N, &row, nu, r_var, gate, var_floor, info);
    }
}

int att_cov_is_pd(const att_cov_t *c, ekf_scalar_t rel_margin)
{
    ekf_scalar_t ldl[ATT_N * (ATT_N + 1) / 2];
    return ekf_cov_is_pd(c->P, ATT_N, rel_margin, ldl);
}

int att_cov_ensure_pd(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor)
{
    ekf_scalar_t ldl[ATT_N * (ATT_N + 1) / 2];
    return ekf_cov_ensure_pd(c->P, ATT_N, rel_margin, var_floor, ldl);
}

int att_cov_guard(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor)
{
    if (att_cov_floor_diag(c, var_floor) != 0) {
        return -1;
    }
    return att_cov_ensure_pd(c, rel_margin, var_floor);
}


