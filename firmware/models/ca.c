/*
 * ca.c - constant-acceleration model (see ca.h; docs/models.md). The per-axis algebra is
 * generated (ca_gen.c); this file stacks the axes and runs the core's EKF primitives.
 */
#include "ca.h"

#include <stddef.h>

#include "ekf_util.h"

const ca_settings_t ca_default_settings = {
    .accel_increment_var = EKF_C(1.0),
    .position_var = EKF_C(1.0),
    .gate_sigma = EKF_C(0.0),
    .max_dt = EKF_C(10.0),
    .var_floor = EKF_C(1e-12),
};

static ekf_status_t check_dims_dt(uint8_t dims, ekf_scalar_t dt)
{
    if (dims < 1u || dims > CA_MAX_DIMS) {
        return EKF_ERR_DIMENSION;
    }
    if (!ekf_isfinite(dt)) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(dt > EKF_C(0))) {
        return EKF_ERR_DT_NONPOSITIVE;
    }
    return EKF_OK;
}

ekf_status_t ca_transition(const ekf_scalar_t *x, uint8_t dims, const ekf_scalar_t *w, ekf_scalar_t dt,
                           ekf_scalar_t *xn)
{
    ekf_scalar_t out[CA_MAX_N];
    ekf_status_t st;
    uint8_t k, i;

    if (x == NULL || xn == NULL) {
        return EKF_ERR_NULL;
    }
    st = check_dims_dt(dims, dt);
    if (st != EKF_OK) {
        return st;
    }
    if (!ekf_all_finite(x, (uint16_t)(CA_BLOCK * dims)) || (w != NULL && !ekf_all_finite(w, dims))) {
        return EKF_ERR_NOT_FINITE;
    }
    for (k = 0; k < dims; ++k) {
        ca_gen_block_transition(&x[CA_BLOCK * k], (w != NULL) ? w[k] : EKF_C(0), dt, &out[CA_BLOCK * k]);
    }
    for (i = 0; i < CA_BLOCK * dims; ++i) {
        xn[i] = out[i];
    }
    return EKF_OK;
}

ekf_status_t ca_jacobian(uint8_t dims, ekf_scalar_t dt, ekf_scalar_t *Jx, ekf_scalar_t *Jw)
{
    ekf_scalar_t d[CA_GEN_BLOCK_NNZ], g[CA_BLOCK];
    ekf_status_t st;
    uint8_t n, i, j, k;

    if (Jx == NULL) {
        return EKF_ERR_NULL;
    }
    st = check_dims_dt(dims, dt);
    if (st != EKF_OK) {
        return st;
    }
    n = (uint8_t)(CA_BLOCK * dims);
    ca_gen_block_jacobian(dt, d);
    ca_gen_block_noise(dt, g);
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            Jx[i * n + j] = (i == j) ? EKF_C(1) : EKF_C(0);
        }
    }
    for (k = 0; k < dims; ++k) {
        const uint8_t o = (uint8_t)(CA_BLOCK * k);
        for (i = 0; i < CA_GEN_BLOCK_NNZ; ++i) {
            Jx[(o + ca_gen_block_pattern[i].row) * n + o + ca_gen_block_pattern[i].col] = d[i];
        }
    }
    if (Jw != NULL) {
        for (i = 0; i < n; ++i) {
            for (k = 0; k < dims; ++k) {
                Jw[i * dims + k] = (i / CA_BLOCK == k) ? g[i % CA_BLOCK] : EKF_C(0);
            }
        }
    }
    return EKF_OK;
}

ekf_status_t ca_settings_check(const ca_settings_t *s)
{
    const ekf_scalar_t big = EKF_C(1e12);
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_in_range(s->accel_increment_var, EKF_C(0), big) || !ekf_in_range(s->position_var, EKF_C(1e-12), big) ||
        !ekf_in_range(s->gate_sigma, EKF_C(0), EKF_C(1e3)) || !ekf_in_range(s->max_dt, EKF_C(1e-6), EKF_C(1e6)) ||
        !ekf_in_range(s->var_floor, EKF_C(0), EKF_C(1))) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

ekf_status_t ca_init(ca_ekf_t *f, const ca_settings_t *s, uint8_t dims, const ekf_scalar_t *x0,
                     const ekf_scalar_t *p0_diag)
{
    ekf_status_t st;
    uint8_t n, i, j;

    if (f == NULL || s == NULL || x0 == NULL || p0_diag == NULL) {
        return EKF_ERR_NULL;
    }
    st = ca_settings_check(s);
    if (st != EKF_OK) {
        return st;
    }
    if (dims < 1u || dims > CA_MAX_DIMS) {
        return EKF_ERR_DIMENSION;
    }
    n = (uint8_t)(CA_BLOCK * dims);
    if (!ekf_all_finite(x0, n) || !ekf_all_finite(p0_diag, n)) {
        return EKF_ERR_NOT_FINITE;
    }
    for (i = 0; i < n; ++i) {
        if (!(p0_diag[i] > EKF_C(0))) {
            return EKF_ERR_RANGE;
        }
    }
    f->settings = *s;
    f->dims = dims;
    f->n = n;
    for (i = 0; i < CA_MAX_N; ++i) {
        f->x[i] = (i < n) ? x0[i] : EKF_C(0);
    }
    for (i = 0; i < CA_MAX_N; ++i) { /* row by row: a uint8_t index covers CA_MAX_N^2 > 255 too */
        for (j = 0; j < CA_MAX_N; ++j) {
            f->P[i * CA_MAX_N + j] = EKF_C(0);
        }
    }
    for (i = 0; i < n; ++i) {
        f->P[i * n + i] = p0_diag[i];
    }
    f->predicts = f->fused = f->gated = f->rejected = 0u;
    return EKF_OK;
}

static ekf_status_t reject(ca_ekf_t *f, ekf_status_t st)
{
    ekf_count(&f->rejected);
    return st;
}

ekf_status_t ca_predict(ca_ekf_t *f, ekf_scalar_t dt)
{
    ekf_nz_t pattern[CA_GEN_BLOCK_NNZ * CA_MAX_DIMS];
    ekf_scalar_t d[CA_GEN_BLOCK_NNZ * CA_MAX_DIMS];
    ekf_scalar_t work[2 * CA_MAX_DIMS * CA_MAX_N]; /* two rows per axis of F differ from I */
    ekf_scalar_t xn[CA_MAX_N] = {0}, g[CA_BLOCK]; /* zeroed: the analyser cannot see n <= CA_MAX_N */
    ekf_status_t st;
    uint8_t k, i, j;
    uint16_t nnz = 0;

    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    if (f->n == 0u) {
        return EKF_ERR_NOT_INITIALISED;
    }
    st = check_dims_dt(f->dims, dt);
    if (st == EKF_OK && dt > f->settings.max_dt) {
        st = EKF_ERR_DT_TOO_LARGE;
    }
    if (st != EKF_OK) {
        return reject(f, st);
    }
    st = ca_transition(f->x, f->dims, NULL, dt, xn);
    if (st != EKF_OK || !ekf_all_finite(xn, f->n)) {
        return reject(f, EKF_ERR_NUMERIC);
    }

    /* F is block diagonal: the pattern of each axis's block, shifted to its place. Rows
     * stay sorted because the blocks follow each other down the diagonal. */
    for (k = 0; k < f->dims; ++k) {
        const uint8_t o = (uint8_t)(CA_BLOCK * k);
        ca_gen_block_jacobian(dt, &d[nnz]);
        for (i = 0; i < CA_GEN_BLOCK_NNZ; ++i, ++nnz) {
            pattern[nnz].row = (uint8_t)(o + ca_gen_block_pattern[i].row);
            pattern[nnz].col = (uint8_t)(o + ca_gen_block_pattern[i].col);
        }
    }
    st = ekf_cov_propagate(f->P, f->n, pattern, d, nnz, work, (uint16_t)(sizeof work / sizeof work[0]));
    if (st != EKF_OK) {
        return reject(f, st == EKF_ERR_NOT_FINITE ? EKF_ERR_NUMERIC : st);
    }

    /* Q = G Var(w) G^T: a rank-one 3x3 block per axis (the axes' noises are independent) */
    ca_gen_block_noise(dt, g);
    for (k = 0; k < f->dims; ++k) {
        const uint8_t o = (uint8_t)(CA_BLOCK * k);
        for (i = 0; i < CA_BLOCK; ++i) {
            for (j = 0; j < CA_BLOCK; ++j) {
                ekf_scalar_t *p = &f->P[(o + i) * f->n + o + j];
                *p = ekf_mac(*p, ekf_mul(g[i], g[j]), f->settings.accel_increment_var);
            }
        }
    }
    for (i = 0; i < f->n; ++i) {
        f->x[i] = xn[i];
    }
    ekf_count(&f->predicts);
    return EKF_OK;
}

ekf_status_t ca_update_position(ca_ekf_t *f, const ekf_scalar_t *z, ekf_innov_t *info)
{
    ekf_scalar_t x_save[CA_MAX_N], P_save[CA_MAX_N * CA_MAX_N];
    const ekf_scalar_t one = EKF_C(1);
    ekf_status_t result = EKF_OK;
    uint8_t k, n;
    uint16_t i;

    if (f == NULL || z == NULL) {
        return EKF_ERR_NULL;
    }
    if (f->n == 0u) {
        return EKF_ERR_NOT_INITIALISED;
    }
    if (!ekf_all_finite(z, f->dims)) {
        return reject(f, EKF_ERR_NOT_FINITE);
    }
    /* The axes are fused one after the other; keep a copy so that a numeric failure of a
     * later axis can undo the earlier ones (errors leave the filter as it was). n: one
     * copy of f->n, so that save and restore visibly cover the same entries. */
    n = f->n;
    for (i = 0; i < n; ++i) {
        x_save[i] = f->x[i];
    }
    for (i = 0; i < (uint16_t)(n * n); ++i) {
        P_save[i] = f->P[i];
    }
    for (k = 0; k < f->dims; ++k) {
        const uint8_t col = (uint8_t)(CA_BLOCK * k);
        const ekf_hrow_t h = {&col, &one, 1u};
        const ekf_status_t st = ekf_update_scalar(f->x, f->P, f->n, &h, ekf_sub(z[k], f->x[col]),
                                                  f->settings.position_var, f->settings.gate_sigma,
                                                  f->settings.var_floor, (info != NULL) ? &info[k] : NULL);
        if (st == EKF_GATED) {
            ekf_count(&f->gated);
            result = EKF_GATED;
        } else if (st != EKF_OK) {
            for (i = 0; i < n; ++i) {
                f->x[i] = x_save[i];
            }
            for (i = 0; i < (uint16_t)(n * n); ++i) {
                f->P[i] = P_save[i];
            }
            return reject(f, st);
        } else {
            ekf_count(&f->fused);
        }
    }
    return result;
}
