/*
 * radar.c - radar/lidar target tracker (see radar.h; docs/models.md, "Radar and lidar").
 */
#include "radar.h"

#include <stddef.h>

#include "ekf_util.h"

const radar_settings_t radar_default_settings = {
    .accel_var_x = EKF_C(9.0), /* 3 m/s^2, 1 sigma */
    .accel_var_y = EKF_C(9.0),
    .rho_var = EKF_C(0.09),    /* 0.3 m */
    .phi_var = EKF_C(0.0009),  /* 0.03 rad */
    .rhodot_var = EKF_C(0.09), /* 0.3 m/s */
    .lidar_var = EKF_C(0.0225), /* 0.15 m */
    .min_range = EKF_C(1e-3),
    .gate_sigma = EKF_C(0.0),
    .max_dt = EKF_C(10.0),
    .var_floor = EKF_C(1e-12),
};

/* rho and 1/rho at x, or EKF_ERR_SINGULAR below min_range. The comparison is made on
 * rho^2 against min_range^2 first, so a state at the origin never reaches a division. */
static ekf_status_t range_terms(const ekf_scalar_t x[RADAR_N], ekf_scalar_t min_range, ekf_scalar_t *rho,
                                ekf_scalar_t *inv_rho)
{
    const ekf_scalar_t q = ekf_add(ekf_sq(x[RADAR_PX]), ekf_sq(x[RADAR_PY]));
    if (!ekf_isfinite(q)) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(q >= ekf_sq(min_range)) || !(q > EKF_C(0))) {
        return EKF_ERR_SINGULAR;
    }
    *rho = ekf_sqrt(q);
    *inv_rho = ekf_div(EKF_C(1), *rho);
    return ekf_isfinite(*inv_rho) ? EKF_OK : EKF_ERR_SINGULAR;
}

/* h(x) and 1/rho, for a finite x. */
static ekf_status_t measure(const ekf_scalar_t x[RADAR_N], ekf_scalar_t min_range, ekf_scalar_t h[RADAR_M],
                           ekf_scalar_t *inv_rho)
{
    ekf_scalar_t rho, rhodot;
    const ekf_status_t st = range_terms(x, min_range, &rho, inv_rho);
    if (st != EKF_OK) {
        return st;
    }
    radar_gen_range_rate(x, *inv_rho, &rhodot);
    h[RADAR_RHO] = rho;
    h[RADAR_PHI] = ekf_atan2(x[RADAR_PY], x[RADAR_PX]);
    h[RADAR_RHODOT] = rhodot;
    return EKF_OK;
}

ekf_status_t radar_measurement(const ekf_scalar_t x[RADAR_N], ekf_scalar_t min_range, ekf_scalar_t h[RADAR_M])
{
    ekf_scalar_t inv_rho, hx[RADAR_M];
    ekf_status_t st;
    int m;
    if (x == NULL || h == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_all_finite(x, RADAR_N) || !ekf_isfinite(min_range)) {
        return EKF_ERR_NOT_FINITE;
    }
    st = measure(x, min_range, hx, &inv_rho);
    if (st == EKF_OK) {
        for (m = 0; m < RADAR_M; ++m) {
            h[m] = hx[m];
        }
    }
    return st;
}

ekf_status_t radar_jacobian(const ekf_scalar_t x[RADAR_N], ekf_scalar_t min_range, ekf_scalar_t H[RADAR_M * RADAR_N])
{
    ekf_scalar_t rho, inv_rho, hv[RADAR_GEN_H_NNZ];
    ekf_status_t st;
    int m, k;
    if (x == NULL || H == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_all_finite(x, RADAR_N) || !ekf_isfinite(min_range)) {
        return EKF_ERR_NOT_FINITE;
    }
    st = range_terms(x, min_range, &rho, &inv_rho);
    if (st != EKF_OK) {
        return st;
    }
    radar_gen_h_jacobian(x, inv_rho, hv);
    for (k = 0; k < RADAR_M * RADAR_N; ++k) {
        H[k] = EKF_C(0);
    }
    for (m = 0; m < RADAR_M; ++m) {
        for (k = radar_gen_h_row_start[m]; k < radar_gen_h_row_start[m + 1]; ++k) {
            H[m * RADAR_N + radar_gen_h_col[k]] = hv[k];
        }
    }
    return EKF_OK;
}

ekf_status_t radar_settings_check(const radar_settings_t *s)
{
    const ekf_scalar_t big = EKF_C(1e12), tiny = EKF_C(1e-12);
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_in_range(s->accel_var_x, EKF_C(0), big) || !ekf_in_range(s->accel_var_y, EKF_C(0), big) ||
        !ekf_in_range(s->rho_var, tiny, big) || !ekf_in_range(s->phi_var, tiny, EKF_C(10)) ||
        !ekf_in_range(s->rhodot_var, tiny, big) || !ekf_in_range(s->lidar_var, tiny, big) ||
        !ekf_in_range(s->min_range, EKF_C(1e-6), EKF_C(1e6)) || !ekf_in_range(s->gate_sigma, EKF_C(0), EKF_C(1e3)) ||
        !ekf_in_range(s->max_dt, EKF_C(1e-6), EKF_C(1e6)) || !ekf_in_range(s->var_floor, EKF_C(0), EKF_C(1))) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

ekf_status_t radar_init(radar_ekf_t *f, const radar_settings_t *s, const ekf_scalar_t x0[RADAR_N],
                        const ekf_scalar_t p0_diag[RADAR_N])
{
    ekf_status_t st;
    int i;
    if (f == NULL || s == NULL || x0 == NULL || p0_diag == NULL) {
        return EKF_ERR_NULL;
    }
    st = radar_settings_check(s);
    if (st != EKF_OK) {
        return st;
    }
    if (!ekf_all_finite(x0, RADAR_N) || !ekf_all_finite(p0_diag, RADAR_N)) {
        return EKF_ERR_NOT_FINITE;
    }
    for (i = 0; i < RADAR_N; ++i) {
        if (!(p0_diag[i] > EKF_C(0))) {
            return EKF_ERR_RANGE;
        }
    }
    f->settings = *s;
    for (i = 0; i < RADAR_N; ++i) {
        f->x[i] = x0[i];
    }
    for (i = 0; i < RADAR_N * RADAR_N; ++i) {
        f->P[i] = (i % (RADAR_N + 1) == 0) ? p0_diag[i / (RADAR_N + 1)] : EKF_C(0);
    }
    f->initialised = 1u;
    f->predicts = f->fused = f->gated = f->singular = f->rejected = 0u;
    return EKF_OK;
}

static ekf_status_t reject(radar_ekf_t *f, ekf_status_t st)
{
    ekf_count(st == EKF_ERR_SINGULAR ? &f->singular : &f->rejected);
    return st;
}

ekf_status_t radar_predict(radar_ekf_t *f, ekf_scalar_t dt)
{
    ekf_scalar_t d[RADAR_GEN_F_NNZ], q[RADAR_N * RADAR_N], xn[RADAR_N];
    ekf_scalar_t work[RADAR_GEN_F_NNZ * RADAR_N]; /* one work row per modified row of F */
    ekf_status_t st;
    int i;
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    if (!f->initialised) {
        return EKF_ERR_NOT_INITIALISED;
    }
    if (!ekf_isfinite(dt)) {
        return reject(f, EKF_ERR_NOT_FINITE);
    }
    if (!(dt > EKF_C(0))) {
        return reject(f, EKF_ERR_DT_NONPOSITIVE);
    }
    if (dt > f->settings.max_dt) {
        return reject(f, EKF_ERR_DT_TOO_LARGE);
    }
    /* x+ = F x: the constant-velocity transition is exactly linear */
    xn[RADAR_PX] = ekf_mac(f->x[RADAR_PX], dt, f->x[RADAR_VX]);
    xn[RADAR_PY] = ekf_mac(f->x[RADAR_PY], dt, f->x[RADAR_VY]);
    xn[RADAR_VX] = f->x[RADAR_VX];
    xn[RADAR_VY] = f->x[RADAR_VY];
    if (!ekf_all_finite(xn, RADAR_N)) {
        return reject(f, EKF_ERR_NUMERIC);
    }
    radar_gen_cv_jacobian(dt, d);
    st = ekf_cov_propagate(f->P, RADAR_N, radar_gen_f_pattern, d, RADAR_GEN_F_NNZ, work,
                           (uint16_t)(sizeof work / sizeof work[0]));
    if (st != EKF_OK) {
        return reject(f, st == EKF_ERR_NOT_FINITE ? EKF_ERR_NUMERIC : st);
    }
    radar_gen_cv_noise(dt, f->settings.accel_var_x, f->settings.accel_var_y, q);
    for (i = 0; i < RADAR_N * RADAR_N; ++i) {
        f->P[i] = ekf_add(f->P[i], q[i]);
    }
    for (i = 0; i < RADAR_N; ++i) {
        f->x[i] = xn[i];
    }
    ekf_count(&f->predicts);
    return EKF_OK;
}

/* Copy of the filter taken before a multi-component update, restored on error. */
typedef struct {
    ekf_scalar_t x[RADAR_N];
    ekf_scalar_t P[RADAR_N * RADAR_N];
} snapshot_t;

static void save(const radar_ekf_t *f, snapshot_t *s)
{
    int i;
    for (i = 0; i < RADAR_N; ++i) {
        s->x[i] = f->x[i];
    }
    for (i = 0; i < RADAR_N * RADAR_N; ++i) {
        s->P[i] = f->P[i];
    }
}

static void restore(radar_ekf_t *f, const snapshot_t *s)
{
    int i;
    for (i = 0; i < RADAR_N; ++i) {
        f->x[i] = s->x[i];
    }
    for (i = 0; i < RADAR_N * RADAR_N; ++i) {
        f->P[i] = s->P[i];
    }
}

/* One scalar update. Returns EKF_OK or EKF_GATED, or the error after restoring the
 * snapshot (so that the components fused before it are undone too). */
static ekf_status_t fuse(radar_ekf_t *f, const snapshot_t *snap, const ekf_hrow_t *h, ekf_scalar_t nu,
                         ekf_scalar_t r_var, ekf_status_t *status, ekf_innov_t *info)
{
    const ekf_status_t st = ekf_update_scalar(f->x, f->P, RADAR_N, h, nu, r_var, f->settings.gate_sigma,
                                              f->settings.var_floor, info);
    *status = st;
    if (st != EKF_OK && st != EKF_GATED) {
        restore(f, snap);
    }
    return st;
}

/* Counts the components of a completed (not refused) update. */
static void count_components(radar_ekf_t *f, const radar_report_t *rep, int components)
{
    int m;
    for (m = 0; m < components; ++m) {
        ekf_count(rep->status[m] == EKF_OK ? &f->fused : &f->gated);
    }
}

/* What both updates check first: arguments, initialisation, a finite measurement of nz
 * components; the report starts as "skipped". */
static ekf_status_t begin_update(radar_ekf_t *f, const ekf_scalar_t *z, uint8_t nz, radar_report_t *rep)
{
    int m;
    if (f == NULL || z == NULL) {
        return EKF_ERR_NULL;
    }
    if (!f->initialised) {
        return EKF_ERR_NOT_INITIALISED;
    }
    for (m = 0; m < RADAR_M; ++m) {
        rep->status[m] = EKF_SKIPPED;
        rep->innov[m].innovation = rep->innov[m].variance = rep->innov[m].test_ratio = EKF_C(0);
    }
    if (!ekf_all_finite(z, nz)) {
        return reject(f, EKF_ERR_NOT_FINITE);
    }
    return EKF_OK;
}

ekf_status_t radar_update_radar(radar_ekf_t *f, const ekf_scalar_t z[RADAR_M], radar_report_t *rep)
{
    radar_report_t local;
    snapshot_t snap;
    ekf_scalar_t r_var[RADAR_M], h0[RADAR_M], inv_rho, hv[RADAR_GEN_H_NNZ];
    ekf_status_t st, result = EKF_OK;
    int m, k;

    if (rep == NULL) {
        rep = &local;
    }
    st = begin_update(f, z, RADAR_M, rep);
    if (st != EKF_OK) {
        return st;
    }
    if (z[RADAR_RHO] < EKF_C(0)) {
        return reject(f, EKF_ERR_RANGE);
    }
    st = measure(f->x, f->settings.min_range, h0, &inv_rho); /* the filter's x is always finite */
    if (st != EKF_OK) {
        return reject(f, st);
    }
    radar_gen_h_jacobian(f->x, inv_rho, hv);
    r_var[RADAR_RHO] = f->settings.rho_var;
    r_var[RADAR_PHI] = f->settings.phi_var;
    r_var[RADAR_RHODOT] = f->settings.rhodot_var;
    save(f, &snap);

    /* Component m, linearised at the prior x0: z_m - h_m(x) ~ (z_m - h_m(x0)) - H_m (x - x0),
     * with x the state after the components before m. This makes the sequence of scalar
     * updates equal to the batch EKF update with diagonal R (docs/models.md). */
    for (m = 0; m < RADAR_M; ++m) {
        const uint8_t k0 = radar_gen_h_row_start[m];
        const ekf_hrow_t h = {&radar_gen_h_col[k0], &hv[k0], (uint8_t)(radar_gen_h_row_start[m + 1] - k0)};
        ekf_scalar_t nu = ekf_sub(z[m], h0[m]);
        if (m == RADAR_PHI) {
            nu = ekf_wrap_pi(nu);
        }
        for (k = k0; k < radar_gen_h_row_start[m + 1]; ++k) {
            const uint8_t j = radar_gen_h_col[k];
            nu = ekf_sub(nu, ekf_mul(hv[k], ekf_sub(f->x[j], snap.x[j])));
        }
        st = fuse(f, &snap, &h, nu, r_var[m], &rep->status[m], &rep->innov[m]);
        if (st == EKF_GATED) {
            result = EKF_GATED;
        } else if (st != EKF_OK) {
            return reject(f, st);
        }
    }
    count_components(f, rep, RADAR_M);
    return result;
}

ekf_status_t radar_update_lidar(radar_ekf_t *f, const ekf_scalar_t z[2], radar_report_t *rep)
{
    static const uint8_t cols[2] = {RADAR_PX, RADAR_PY};
    static const ekf_scalar_t one = EKF_C(1);
    radar_report_t local;
    snapshot_t snap;
    ekf_status_t st, result = EKF_OK;
    int m;

    if (rep == NULL) {
        rep = &local;
    }
    st = begin_update(f, z, 2, rep);
    if (st != EKF_OK) {
        return st;
    }
    save(f, &snap);
    /* H = [I 0]: linear, so sequential scalar updates are exact */
    for (m = 0; m < 2; ++m) {
        const ekf_hrow_t h = {&cols[m], &one, 1u};
        st = fuse(f, &snap, &h, ekf_sub(z[m], f->x[cols[m]]), f->settings.lidar_var, &rep->status[m],
                  &rep->innov[m]);
        if (st == EKF_GATED) {
            result = EKF_GATED;
        } else if (st != EKF_OK) {
            return reject(f, st);
        }
    }
    count_components(f, rep, 2);
    return result;
}
