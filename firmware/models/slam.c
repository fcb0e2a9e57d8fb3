/*
 * slam.c - EKF-SLAM (see slam.h; derivations in docs/models.md, "EKF-SLAM").
 */
#include "slam.h"

#include <stddef.h>

#include "ekf_util.h"

const slam_settings_t slam_default_settings = {
    .vel_var = EKF_C(0.01),         /* 0.1 m/s */
    .yaw_rate_var = EKF_C(0.0003),  /* ~1 deg/s */
    .range_var = EKF_C(0.01),       /* 0.1 m */
    .bearing_var = EKF_C(0.0003),   /* ~1 deg */
    .min_range = EKF_C(0.05),
    .gate_sigma = EKF_C(0.0),
    .max_dt = EKF_C(1.0),
    .var_floor = EKF_C(1e-12),
};

static ekf_status_t check_dt(ekf_scalar_t dt)
{
    if (!ekf_isfinite(dt)) {
        return EKF_ERR_NOT_FINITE;
    }
    return (dt > EKF_C(0)) ? EKF_OK : EKF_ERR_DT_NONPOSITIVE;
}

/* ---- model functions ---- */

ekf_status_t slam_motion(const ekf_scalar_t pose[SLAM_POSE_N], const ekf_scalar_t u[3], ekf_scalar_t dt,
                         ekf_scalar_t out[SLAM_POSE_N], ekf_scalar_t F[9], ekf_scalar_t G[9])
{
    ekf_scalar_t c, s, d[SLAM_GEN_F_NNZ], pn[SLAM_POSE_N];
    ekf_status_t st;
    int i;
    if (pose == NULL || u == NULL || out == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_all_finite(pose, SLAM_POSE_N) || !ekf_all_finite(u, 3)) {
        return EKF_ERR_NOT_FINITE;
    }
    st = check_dt(dt);
    if (st != EKF_OK) {
        return st;
    }
    c = ekf_cos(pose[SLAM_PSI]);
    s = ekf_sin(pose[SLAM_PSI]);
    slam_gen_motion(pose, u, c, s, dt, pn);
    if (F != NULL) {
        slam_gen_motion_jacobian(u, c, s, dt, d);
        for (i = 0; i < 9; ++i) {
            F[i] = (i % 4 == 0) ? EKF_C(1) : EKF_C(0);
        }
        for (i = 0; i < SLAM_GEN_F_NNZ; ++i) {
            F[slam_gen_f_pattern[i].row * 3 + slam_gen_f_pattern[i].col] =
                ekf_add(F[slam_gen_f_pattern[i].row * 3 + slam_gen_f_pattern[i].col], d[i]);
        }
    }
    if (G != NULL) {
        /* G = df/du, the odometry noise Jacobian: rotation into the world frame times dt */
        G[0] = ekf_mul(dt, c);
        G[1] = ekf_neg(ekf_mul(dt, s));
        G[2] = EKF_C(0);
        G[3] = ekf_mul(dt, s);
        G[4] = ekf_mul(dt, c);
        G[5] = EKF_C(0);
        G[6] = EKF_C(0);
        G[7] = EKF_C(0);
        G[8] = dt;
    }
    for (i = 0; i < SLAM_POSE_N; ++i) {
        out[i] = pn[i];
    }
    out[SLAM_PSI] = ekf_wrap_pi(out[SLAM_PSI]);
    return EKF_OK;
}

/* Range terms of an observation from pose to landmark m: dx, dy, 1/range and h. */
typedef struct {
    ekf_scalar_t dx, dy, inv_r;
    ekf_scalar_t h[SLAM_M];
} obs_terms_t;

static ekf_status_t obs_terms(const ekf_scalar_t pose[SLAM_POSE_N], const ekf_scalar_t m[2],
                              ekf_scalar_t min_range, obs_terms_t *t)
{
    ekf_scalar_t q, r;
    t->dx = ekf_sub(m[0], pose[SLAM_X]);
    t->dy = ekf_sub(m[1], pose[SLAM_Y]);
    q = ekf_add(ekf_sq(t->dx), ekf_sq(t->dy));
    if (!ekf_isfinite(q)) {
        return EKF_ERR_NOT_FINITE;
    }
    /* compare squares first: a landmark on top of the robot never reaches a division */
    if (!(q >= ekf_sq(min_range)) || !(q > EKF_C(0))) {
        return EKF_ERR_SINGULAR;
    }
    r = ekf_sqrt(q);
    t->inv_r = ekf_div(EKF_C(1), r);
    t->h[SLAM_RANGE] = r;
    t->h[SLAM_BEARING] = ekf_wrap_pi(ekf_sub(ekf_atan2(t->dy, t->dx), pose[SLAM_PSI]));
    return ekf_isfinite(t->inv_r) ? EKF_OK : EKF_ERR_SINGULAR;
}

ekf_status_t slam_observation(const ekf_scalar_t pose[SLAM_POSE_N], const ekf_scalar_t m[2],
                              ekf_scalar_t min_range, ekf_scalar_t h[SLAM_M], ekf_scalar_t A[6],
                              ekf_scalar_t B[4])
{
    obs_terms_t t;
    ekf_scalar_t hv[SLAM_GEN_OBS_NNZ], local[SLAM_M * SLAM_L_N];
    ekf_status_t st;
    int row, k;
    if (pose == NULL || m == NULL || h == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_all_finite(pose, SLAM_POSE_N) || !ekf_all_finite(m, 2) || !ekf_isfinite(min_range)) {
        return EKF_ERR_NOT_FINITE;
    }
    st = obs_terms(pose, m, min_range, &t);
    if (st != EKF_OK) {
        return st;
    }
    slam_gen_obs_jacobian(t.dx, t.dy, t.inv_r, hv);
    for (k = 0; k < SLAM_M * SLAM_L_N; ++k) {
        local[k] = EKF_C(0);
    }
    for (row = 0; row < SLAM_M; ++row) {
        for (k = slam_gen_obs_row_start[row]; k < slam_gen_obs_row_start[row + 1]; ++k) {
            local[row * SLAM_L_N + slam_gen_obs_local_col[k]] = hv[k];
        }
    }
    for (row = 0; row < SLAM_M; ++row) {
        h[row] = t.h[row];
        for (k = 0; k < SLAM_POSE_N && A != NULL; ++k) {
            A[row * 3 + k] = local[row * SLAM_L_N + k];
        }
        for (k = 0; k < 2 && B != NULL; ++k) {
            B[row * 2 + k] = local[row * SLAM_L_N + SLAM_L_MX + k];
        }
    }
    return EKF_OK;
}

ekf_status_t slam_inverse_observation(const ekf_scalar_t pose[SLAM_POSE_N], ekf_scalar_t range,
                                      ekf_scalar_t bearing, ekf_scalar_t m[2], ekf_scalar_t Gx[6],
                                      ekf_scalar_t Gz[4])
{
    ekf_scalar_t mm[2], gx[6], gz[4];
    ekf_scalar_t a;
    int k;
    if (pose == NULL || m == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_all_finite(pose, SLAM_POSE_N) || !ekf_isfinite(range) || !ekf_isfinite(bearing)) {
        return EKF_ERR_NOT_FINITE;
    }
    a = ekf_add(pose[SLAM_PSI], bearing);
    slam_gen_landmark_init(pose, range, ekf_cos(a), ekf_sin(a), mm, gx, gz);
    m[0] = mm[0];
    m[1] = mm[1];
    for (k = 0; k < 6 && Gx != NULL; ++k) {
        Gx[k] = gx[k];
    }
    for (k = 0; k < 4 && Gz != NULL; ++k) {
        Gz[k] = gz[k];
    }
    return EKF_OK;
}

/* ---- filter ---- */

ekf_status_t slam_settings_check(const slam_settings_t *s)
{
    const ekf_scalar_t big = EKF_C(1e12), tiny = EKF_C(1e-12);
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    if (!ekf_in_range(s->vel_var, EKF_C(0), big) || !ekf_in_range(s->yaw_rate_var, EKF_C(0), big) ||
        !ekf_in_range(s->range_var, tiny, big) || !ekf_in_range(s->bearing_var, tiny, EKF_C(10)) ||
        !ekf_in_range(s->min_range, EKF_C(1e-6), EKF_C(1e6)) || !ekf_in_range(s->gate_sigma, EKF_C(0), EKF_C(1e3)) ||
        !ekf_in_range(s->max_dt, EKF_C(1e-6), EKF_C(1e6)) || !ekf_in_range(s->var_floor, EKF_C(0), EKF_C(1))) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

ekf_status_t slam_init(slam_ekf_t *f, const slam_settings_t *s, const ekf_scalar_t pose0[SLAM_POSE_N],
                       const ekf_scalar_t pose_var[SLAM_POSE_N])
{
    ekf_status_t st;
    int i;
    if (f == NULL || s == NULL || pose0 == NULL || pose_var == NULL) {
        return EKF_ERR_NULL;
    }
    st = slam_settings_check(s);
    if (st != EKF_OK) {
        return st;
    }
    if (!ekf_all_finite(pose0, SLAM_POSE_N) || !ekf_all_finite(pose_var, SLAM_POSE_N)) {
        return EKF_ERR_NOT_FINITE;
    }
    for (i = 0; i < SLAM_POSE_N; ++i) {
        if (pose_var[i] < EKF_C(0)) {
            return EKF_ERR_RANGE;
        }
    }
    f->settings = *s;
    for (i = 0; i < SLAM_MAX_N; ++i) {
        f->x[i] = (i < SLAM_POSE_N) ? pose0[i] : EKF_C(0);
    }
    f->x[SLAM_PSI] = ekf_wrap_pi(f->x[SLAM_PSI]);
    for (i = 0; i < SLAM_MAX_N * SLAM_MAX_N; ++i) {
        f->P[i] = EKF_C(0);
    }
    for (i = 0; i < SLAM_POSE_N; ++i) {
        f->P[i * SLAM_POSE_N + i] = pose_var[i];
    }
    for (i = 0; i < SLAM_MAX_LANDMARKS; ++i) {
        f->id[i] = 0u;
    }
    f->n = SLAM_POSE_N;
    f->landmarks = 0u;
    f->predicts = f->fused = f->gated = f->singular = f->rejected = 0u;
    return EKF_OK;
}

static ekf_status_t reject(slam_ekf_t *f, ekf_status_t st)
{
    ekf_count(st == EKF_ERR_SINGULAR ? &f->singular : &f->rejected);
    return st;
}

ekf_status_t slam_predict(slam_ekf_t *f, const ekf_scalar_t u[3], ekf_scalar_t dt)
{
    ekf_scalar_t c, s, pn[SLAM_POSE_N], d[SLAM_GEN_F_NNZ], qp[SLAM_POSE_N * SLAM_POSE_N];
    ekf_scalar_t work[SLAM_GEN_F_NNZ * SLAM_MAX_N]; /* rows X, Y of F differ from the identity */
    ekf_status_t st;
    int i, j;
    if (f == NULL || u == NULL) {
        return EKF_ERR_NULL;
    }
    if (f->n == 0u) {
        return EKF_ERR_NOT_INITIALISED;
    }
    if (!ekf_all_finite(u, 3)) {
        return reject(f, EKF_ERR_NOT_FINITE);
    }
    st = check_dt(dt);
    if (st == EKF_OK && dt > f->settings.max_dt) {
        st = EKF_ERR_DT_TOO_LARGE;
    }
    if (st != EKF_OK) {
        return reject(f, st);
    }
    c = ekf_cos(f->x[SLAM_PSI]);
    s = ekf_sin(f->x[SLAM_PSI]);
    slam_gen_motion(f->x, u, c, s, dt, pn);
    if (!ekf_all_finite(pn, SLAM_POSE_N)) {
        return reject(f, EKF_ERR_NUMERIC);
    }
    /* P <- F P F^T with F = I + D, D non-zero only in rows X and Y (column psi): the core
     * touches the pose rows and columns of P only, O(n). */
    slam_gen_motion_jacobian(u, c, s, dt, d);
    st = ekf_cov_propagate(f->P, f->n, slam_gen_f_pattern, d, SLAM_GEN_F_NNZ, work,
                           (uint16_t)(sizeof work / sizeof work[0]));
    if (st != EKF_OK) {
        return reject(f, st == EKF_ERR_NOT_FINITE ? EKF_ERR_NUMERIC : st);
    }
    /* + G_u M G_u^T, which lives in the 3x3 pose block */
    slam_gen_motion_noise(c, s, dt, f->settings.vel_var, f->settings.vel_var, f->settings.yaw_rate_var, qp);
    for (i = 0; i < SLAM_POSE_N; ++i) {
        for (j = 0; j < SLAM_POSE_N; ++j) {
            f->P[i * f->n + j] = ekf_add(f->P[i * f->n + j], qp[i * SLAM_POSE_N + j]);
        }
    }
    for (i = 0; i < SLAM_POSE_N; ++i) {
        f->x[i] = pn[i];
    }
    f->x[SLAM_PSI] = ekf_wrap_pi(f->x[SLAM_PSI]);
    ekf_count(&f->predicts);
    return EKF_OK;
}

static int find_slot(const slam_ekf_t *f, uint8_t id)
{
    int k;
    for (k = 0; k < f->landmarks; ++k) {
        if (f->id[k] == id) {
            return k;
        }
    }
    return -1;
}

/*
 * State augmentation with a new landmark m = g(pose, z) (docs/models.md):
 *     P_mx = Gx P_px           (2 x n: cross-covariance with every state, through the pose)
 *     P_mm = Gx P_pp Gx^T + Gz R Gz^T
 * P is first re-laid out from stride n to stride n + 2.
 */
static ekf_status_t add_landmark(slam_ekf_t *f, const slam_observation_t *obs, int *slot)
{
    const uint8_t n = f->n, n2 = (uint8_t)(f->n + 2u);
    ekf_scalar_t m[2], gx[6], gz[4], cross[2 * SLAM_MAX_N], pmm[4];
    const ekf_scalar_t r_var[2] = {f->settings.range_var, f->settings.bearing_var};
    ekf_status_t st;
    int a, b, i, j, k;

    if (f->landmarks >= SLAM_MAX_LANDMARKS) {
        return EKF_ERR_DIMENSION;
    }
    if (obs->range < f->settings.min_range) {
        return EKF_ERR_SINGULAR;
    }
    st = slam_inverse_observation(f->x, obs->range, obs->bearing, m, gx, gz);
    if (st != EKF_OK) { /* inputs were checked; this keeps gx/gz from ever being used unset */
        return st;
    }
    for (a = 0; a < 2; ++a) {
        for (j = 0; j < n; ++j) {
            ekf_scalar_t acc = EKF_C(0);
            for (k = 0; k < SLAM_POSE_N; ++k) {
                acc = ekf_mac(acc, gx[a * 3 + k], f->P[k * n + j]);
            }
            cross[a * n + j] = acc;
        }
    }
    for (a = 0; a < 2; ++a) {
        for (b = 0; b < 2; ++b) {
            /* (Gx P_pp Gx^T)_ab = sum_k cross_a,k Gx_b,k over the pose columns k */
            ekf_scalar_t acc = EKF_C(0);
            for (k = 0; k < SLAM_POSE_N; ++k) {
                acc = ekf_mac(acc, cross[a * n + k], gx[b * 3 + k]);
            }
            for (k = 0; k < 2; ++k) {
                acc = ekf_mac(acc, ekf_mul(gz[a * 2 + k], gz[b * 2 + k]), r_var[k]);
            }
            pmm[a * 2 + b] = acc;
        }
    }
    pmm[1] = pmm[2] = ekf_mul(EKF_C(0.5), ekf_add(pmm[1], pmm[2])); /* exactly symmetric */
    if (!ekf_all_finite(m, 2) || !ekf_all_finite(cross, (uint16_t)(2u * n)) || !ekf_all_finite(pmm, 4) ||
        !(pmm[0] > EKF_C(0)) || !(pmm[3] > EKF_C(0))) {
        return EKF_ERR_NUMERIC;
    }

    /* Re-layout in place, last row first: row i moves from [i n, i n + n) to
     * [i n2, i n2 + n), which never overlaps a row not yet moved (i n2 >= i n). */
    for (i = n - 1; i >= 0; --i) {
        for (j = n - 1; j >= 0; --j) {
            f->P[i * n2 + j] = f->P[i * n + j];
        }
    }
    for (a = 0; a < 2; ++a) {
        for (j = 0; j < n; ++j) {
            f->P[(n + a) * n2 + j] = cross[a * n + j];
            f->P[j * n2 + n + a] = cross[a * n + j];
        }
        for (b = 0; b < 2; ++b) {
            f->P[(n + a) * n2 + n + b] = pmm[a * 2 + b];
        }
    }
    f->x[n] = m[0];
    f->x[n + 1] = m[1];
    *slot = f->landmarks;
    f->id[f->landmarks] = obs->id;
    f->landmarks = (uint8_t)(f->landmarks + 1u);
    f->n = n2;
    return EKF_OK;
}

/* Range and bearing of a mapped landmark as two scalar updates, linearised at the prior. */
static ekf_status_t update_landmark(slam_ekf_t *f, const slam_observation_t *obs, int slot,
                                    slam_obs_report_t *rep)
{
    const uint8_t mcol = (uint8_t)(SLAM_POSE_N + 2 * slot);
    const uint8_t global[SLAM_L_N] = {SLAM_X, SLAM_Y, SLAM_PSI, mcol, (uint8_t)(mcol + 1u)};
    const ekf_scalar_t z[SLAM_M] = {obs->range, obs->bearing};
    const ekf_scalar_t r_var[SLAM_M] = {f->settings.range_var, f->settings.bearing_var};
    uint8_t cols[SLAM_GEN_OBS_NNZ];
    ekf_scalar_t hv[SLAM_GEN_OBS_NNZ], x0[SLAM_L_N];
    obs_terms_t t;
    ekf_status_t st, result = EKF_OK;
    int row, k;

    st = obs_terms(f->x, &f->x[mcol], f->settings.min_range, &t);
    if (st != EKF_OK) {
        return st;
    }
    slam_gen_obs_jacobian(t.dx, t.dy, t.inv_r, hv);
    for (k = 0; k < SLAM_GEN_OBS_NNZ; ++k) {
        cols[k] = global[slam_gen_obs_local_col[k]];
    }
    for (k = 0; k < SLAM_L_N; ++k) {
        x0[k] = f->x[global[k]];
    }
    for (row = 0; row < SLAM_M; ++row) {
        const uint8_t k0 = slam_gen_obs_row_start[row];
        const ekf_hrow_t h = {&cols[k0], &hv[k0], (uint8_t)(slam_gen_obs_row_start[row + 1] - k0)};
        /* z - h(x) ~ (z - h(x0)) - H (x - x0): x0 is the prior, x the state after the
         * components before this one (docs/models.md) */
        ekf_scalar_t nu = ekf_sub(z[row], t.h[row]);
        if (row == SLAM_BEARING) {
            nu = ekf_wrap_pi(nu);
        }
        for (k = k0; k < slam_gen_obs_row_start[row + 1]; ++k) {
            nu = ekf_sub(nu, ekf_mul(hv[k], ekf_sub(f->x[cols[k]], x0[slam_gen_obs_local_col[k]])));
        }
        st = ekf_update_scalar(f->x, f->P, f->n, &h, nu, r_var[row], f->settings.gate_sigma,
                               f->settings.var_floor, &rep->innov[row]);
        rep->status[row] = st;
        if (st == EKF_OK) {
            ekf_count(&f->fused);
        } else if (st == EKF_GATED) {
            ekf_count(&f->gated);
            result = EKF_GATED;
        } else {
            result = st;
            break;
        }
    }
    f->x[SLAM_PSI] = ekf_wrap_pi(f->x[SLAM_PSI]);
    return result;
}

ekf_status_t slam_observe(slam_ekf_t *f, const slam_observation_t *obs, slam_obs_report_t *rep)
{
    slam_obs_report_t local;
    ekf_status_t st;
    int slot, m;

    if (f == NULL || obs == NULL) {
        return EKF_ERR_NULL;
    }
    if (f->n == 0u) {
        return EKF_ERR_NOT_INITIALISED;
    }
    if (rep == NULL) {
        rep = &local;
    }
    rep->new_landmark = 0u;
    rep->slot = 0u;
    for (m = 0; m < SLAM_M; ++m) {
        rep->status[m] = EKF_SKIPPED;
        rep->innov[m].innovation = rep->innov[m].variance = rep->innov[m].test_ratio = EKF_C(0);
    }
    if (!ekf_isfinite(obs->range) || !ekf_isfinite(obs->bearing)) {
        return reject(f, EKF_ERR_NOT_FINITE);
    }
    if (obs->range < EKF_C(0)) {
        return reject(f, EKF_ERR_RANGE);
    }
    if (obs->range < f->settings.min_range) {
        return reject(f, EKF_ERR_SINGULAR);
    }
    slot = find_slot(f, obs->id);
    if (slot < 0) {
        st = add_landmark(f, obs, &slot);
        if (st != EKF_OK) {
            return reject(f, st);
        }
        rep->new_landmark = 1u;
        rep->slot = (uint8_t)slot;
        return EKF_OK;
    }
    rep->slot = (uint8_t)slot;
    st = update_landmark(f, obs, slot, rep);
    return (st == EKF_OK || st == EKF_GATED) ? st : reject(f, st);
}

void slam_get_pose(const slam_ekf_t *f, ekf_scalar_t pose[SLAM_POSE_N])
{
    int i;
    if (f == NULL || pose == NULL) {
        return;
    }
    for (i = 0; i < SLAM_POSE_N; ++i) {
        pose[i] = f->x[i];
    }
}

ekf_status_t slam_get_landmark(const slam_ekf_t *f, uint8_t id, ekf_scalar_t m[2], ekf_scalar_t cov[4])
{
    int slot, a, b, c0;
    if (f == NULL || m == NULL) {
        return EKF_ERR_NULL;
    }
    slot = find_slot(f, id);
    if (slot < 0) {
        return EKF_ERR_DIMENSION;
    }
    c0 = SLAM_POSE_N + 2 * slot;
    m[0] = f->x[c0];
    m[1] = f->x[c0 + 1];
    for (a = 0; a < 2 && cov != NULL; ++a) {
        for (b = 0; b < 2; ++b) {
            cov[a * 2 + b] = f->P[(c0 + a) * f->n + c0 + b];
        }
    }
    return EKF_OK;
}

uint8_t slam_dim(const slam_ekf_t *f)
{
    return (f != NULL) ? f->n : 0u;
}

const ekf_scalar_t *slam_state(const slam_ekf_t *f)
{
    return (f != NULL) ? f->x : NULL;
}

const ekf_scalar_t *slam_covariance(const slam_ekf_t *f)
{
    return (f != NULL) ? f->P : NULL;
}
