/*
 * test_models_slam.c - EKF-SLAM: Jacobians (motion, observation, landmark initialisation)
 * against finite differences; the sparse prediction, the augmentation and the sequential
 * update against dense textbook algebra; static landmarks untouched by the prediction;
 * bearing wrap; refusals. The simulated loop is test_models_slam_loop.c. Built for float
 * and double.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model_test_util.h"
#include "slam.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const double PI = MT_PI;

#ifdef EKF_SCALAR_DOUBLE
static const double FD_REL_STEP = 1e-4, FD_TOL = 1e-7, DENSE_TOL = 1e-9;
#else
static const double FD_REL_STEP = 2e-2, FD_TOL = 3e-3, DENSE_TOL = 3e-3;
#endif

static double g_worst_motion_F, g_worst_motion_G, g_worst_obs, g_worst_init;

/* Richardson central difference of column j of a vector function given as a callback. */
typedef void (*vec_fn)(const double *in, double *out, const void *ctx);

/* Richardson central difference of column j; *round receives the rounding floor of the
 * difference, 8 eps max|output| / step: no finite difference of the library's own (float
 * or double) function can be more accurate than that. */
static void fd_column(vec_fn fn, const void *ctx, const double *in, int n_in, int n_out, int j, double step,
                      const int *angle_out, double *col, double *round)
{
    double d[2][4], outmax = 1.0;
    int pass, m;
    for (pass = 0; pass < 2; ++pass) {
        const double h = step / (pass == 0 ? 1.0 : 2.0);
        double ip[8], im[8], op[4], om[4];
        memcpy(ip, in, sizeof(double) * (size_t)n_in);
        memcpy(im, in, sizeof(double) * (size_t)n_in);
        ip[j] += h;
        im[j] -= h;
        fn(ip, op, ctx);
        fn(im, om, ctx);
        for (m = 0; m < n_out; ++m) {
            double diff = op[m] - om[m];
            outmax = fmax(outmax, fmax(fabs(op[m]), fabs(om[m])));
            if (angle_out != NULL && angle_out[m]) {
                diff = mt_wrap_pi(diff);
            }
            d[pass][m] = diff / (2.0 * h);
        }
    }
    for (m = 0; m < n_out; ++m) {
        col[m] = (4.0 * d[1][m] - d[0][m]) / 3.0;
    }
    *round = 8.0 * MT_EPS * outmax / step;
}

/* Largest raw relative error seen by entry_error (reported, not asserted). */
static double g_raw;

/* |an - fd| beyond the rounding floor, relative to max(|an|, scale). */
static double entry_error(double an, double fd, double round, double scale)
{
    g_raw = fmax(g_raw, fabs(an - fd) / fmax(fabs(an), scale));
    return fmax(0.0, fabs(an - fd) - round) / fmax(fabs(an), scale);
}

/* ---- motion ---- */

typedef struct {
    int wrt_u;
    double fixed[6]; /* pose, u */
    double dt;
} motion_ctx_t;

static void motion_fn(const double *in, double *out, const void *vctx)
{
    const motion_ctx_t *c = (const motion_ctx_t *)vctx;
    ekf_scalar_t pose[3], u[3], o[3];
    int i;
    for (i = 0; i < 3; ++i) {
        pose[i] = (ekf_scalar_t)(c->wrt_u ? c->fixed[i] : in[i]);
        u[i] = (ekf_scalar_t)(c->wrt_u ? in[i] : c->fixed[3 + i]);
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_motion(pose, u, (ekf_scalar_t)c->dt, o, NULL, NULL));
    mt_to_double(o, out, 3);
}

static void test_motion_jacobians(void)
{
    static const int angle_out[3] = {0, 0, 1};
    ts_rng_t rng;
    int trial;
    g_raw = 0.0;
    ts_rng_seed(&rng, 31);
    for (trial = 0; trial < 500; ++trial) {
        motion_ctx_t c;
        ekf_scalar_t pose[3], u[3], out[3], F[9], G[9];
        double in[3], col[3], rnd;
        int i, j;
        c.dt = ts_uniform_in(&rng, 0.01, 0.5);
        for (i = 0; i < 3; ++i) {
            c.fixed[i] = (i < 2) ? ts_uniform_in(&rng, -50, 50) : ts_uniform_in(&rng, -PI, PI);
            c.fixed[3 + i] = (i < 2) ? ts_uniform_in(&rng, -3, 3) : ts_uniform_in(&rng, -1, 1);
            pose[i] = (ekf_scalar_t)c.fixed[i];
            u[i] = (ekf_scalar_t)c.fixed[3 + i];
            c.fixed[i] = (double)pose[i];
            c.fixed[3 + i] = (double)u[i];
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_motion(pose, u, (ekf_scalar_t)c.dt, out, F, G));
        for (c.wrt_u = 0; c.wrt_u < 2; ++c.wrt_u) {
            for (i = 0; i < 3; ++i) {
                in[i] = c.fixed[(c.wrt_u ? 3 : 0) + i];
            }
            for (j = 0; j < 3; ++j) {
                const double step = FD_REL_STEP * (c.wrt_u ? 3.0 : 1.0);
                fd_column(motion_fn, &c, in, 3, 3, j, step, angle_out, col, &rnd);
                for (i = 0; i < 3; ++i) {
                    const double an = (double)(c.wrt_u ? G[i * 3 + j] : F[i * 3 + j]);
                    const double e = entry_error(an, col[i], rnd, c.dt);
                    double *w = c.wrt_u ? &g_worst_motion_G : &g_worst_motion_F;
                    *w = e > *w ? e : *w;
                }
            }
        }
    }
    printf("SLAM motion Jacobians max relative error vs finite differences: raw %.3g; beyond the rounding floor "
           "F %.3g, G_u %.3g (%s)\n",
           g_raw, g_worst_motion_F, g_worst_motion_G, EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE(g_worst_motion_F < FD_TOL && g_worst_motion_G < FD_TOL);
}

/* ---- observation ---- */

static void obs_fn(const double *in, double *out, const void *ctx)
{
    ekf_scalar_t pose[3], m[2], h[2];
    (void)ctx;
    mt_from_double(in, pose, 3);
    mt_from_double(in + 3, m, 2);
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observation(pose, m, EKF_C(1e-3), h, NULL, NULL));
    mt_to_double(h, out, 2);
}

static void test_observation_jacobians(void)
{
    static const int angle_out[2] = {0, 1};
    ts_rng_t rng;
    int trial;
    g_raw = 0.0;
    ts_rng_seed(&rng, 32);
    for (trial = 0; trial < 1000; ++trial) {
        ekf_scalar_t pose[3], m[2], h[2], A[6], B[4];
        double in[5], col[2], rnd;
        const double range = exp(ts_uniform_in(&rng, log(0.3), log(100.0))), ang = ts_uniform_in(&rng, -PI, PI);
        int i, j;
        pose[0] = (ekf_scalar_t)ts_uniform_in(&rng, -20, 20);
        pose[1] = (ekf_scalar_t)ts_uniform_in(&rng, -20, 20);
        pose[2] = (ekf_scalar_t)ts_uniform_in(&rng, -PI, PI);
        m[0] = (ekf_scalar_t)((double)pose[0] + range * cos(ang));
        m[1] = (ekf_scalar_t)((double)pose[1] + range * sin(ang));
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observation(pose, m, EKF_C(1e-3), h, A, B));
        mt_to_double(pose, in, 3);
        mt_to_double(m, in + 3, 2);
        for (j = 0; j < 5; ++j) {
            const double step = FD_REL_STEP * ((j == 2) ? 1.0 : range);
            fd_column(obs_fn, NULL, in, 5, 2, j, step, angle_out, col, &rnd);
            for (i = 0; i < 2; ++i) {
                const double an = (double)((j < 3) ? A[i * 3 + j] : B[i * 2 + (j - 3)]);
                const double e = entry_error(an, col[i], rnd, 1.0 / range);
                g_worst_obs = e > g_worst_obs ? e : g_worst_obs;
            }
        }
    }
    printf("SLAM observation Jacobian (A_j, B_j) max relative error vs finite differences: raw %.3g; beyond the "
           "rounding floor %.3g (%s)\n",
           g_raw, g_worst_obs, EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE(g_worst_obs < FD_TOL);
}

static void init_fn(const double *in, double *out, const void *ctx)
{
    ekf_scalar_t pose[3], m[2];
    (void)ctx;
    mt_from_double(in, pose, 3);
    TEST_ASSERT_EQUAL_INT(EKF_OK,
                          slam_inverse_observation(pose, (ekf_scalar_t)in[3], (ekf_scalar_t)in[4], m, NULL, NULL));
    mt_to_double(m, out, 2);
}

static void test_inverse_observation_jacobians(void)
{
    ts_rng_t rng;
    int trial;
    g_raw = 0.0;
    ts_rng_seed(&rng, 33);
    for (trial = 0; trial < 1000; ++trial) {
        ekf_scalar_t pose[3], m[2], Gx[6], Gz[4];
        double in[5], col[2], rnd;
        int i, j;
        pose[0] = (ekf_scalar_t)ts_uniform_in(&rng, -20, 20);
        pose[1] = (ekf_scalar_t)ts_uniform_in(&rng, -20, 20);
        pose[2] = (ekf_scalar_t)ts_uniform_in(&rng, -PI, PI);
        mt_to_double(pose, in, 3);
        in[3] = (double)(ekf_scalar_t)ts_uniform_in(&rng, 0.5, 50.0);
        in[4] = (double)(ekf_scalar_t)ts_uniform_in(&rng, -PI, PI);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_inverse_observation(pose, (ekf_scalar_t)in[3], (ekf_scalar_t)in[4], m,
                                                               Gx, Gz));
        for (j = 0; j < 5; ++j) {
            const double step = FD_REL_STEP * ((j == 3) ? in[3] : 1.0);
            fd_column(init_fn, NULL, in, 5, 2, j, step, NULL, col, &rnd);
            for (i = 0; i < 2; ++i) {
                const double an = (double)((j < 3) ? Gx[i * 3 + j] : Gz[i * 2 + (j - 3)]);
                const double e = entry_error(an, col[i], rnd, 1.0);
                g_worst_init = e > g_worst_init ? e : g_worst_init;
            }
        }
    }
    printf("SLAM landmark initialisation Jacobians (G_x, G_z) max relative error vs finite differences: raw %.3g; "
           "beyond the rounding floor %.3g (%s)\n",
           g_raw, g_worst_init, EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE(g_worst_init < FD_TOL);
}

/* ---- filter against dense algebra ---- */

static const ekf_scalar_t POSE0[3] = {0, 0, 0};
static const ekf_scalar_t POSE_VAR0[3] = {EKF_C(0.01), EKF_C(0.01), EKF_C(0.001)};

/* A filter with k landmarks on a circle around the origin, then P replaced by a random
 * symmetric positive definite matrix (so that every block is populated). */
static void filter_with_landmarks(slam_ekf_t *f, int k, ts_rng_t *rng)
{
    double A[MT_MAX * MT_MAX], P[MT_MAX * MT_MAX];
    int i, j, l, n;
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_init(f, &slam_default_settings, POSE0, POSE_VAR0));
    for (i = 0; i < k; ++i) {
        slam_observation_t o;
        o.id = (uint8_t)(10 + i);
        o.range = (ekf_scalar_t)ts_uniform_in(rng, 2.0, 8.0);
        o.bearing = (ekf_scalar_t)ts_uniform_in(rng, -PI, PI);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(f, &o, NULL));
    }
    n = f->n;
    TEST_ASSERT_EQUAL_INT(3 + 2 * k, n);
    for (i = 0; i < n * n; ++i) {
        A[i] = ts_uniform_in(rng, -0.3, 0.3);
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            double acc = (i == j) ? 0.05 : 0.0;
            for (l = 0; l < n; ++l) {
                acc += A[i * n + l] * A[j * n + l];
            }
            P[i * n + j] = acc;
        }
    }
    mt_from_double(P, f->P, n * n);
}

static void test_predict_sparse_matches_dense(void)
{
    ts_rng_t rng;
    double worst = 0.0;
    int trial;
    ts_rng_seed(&rng, 34);
    for (trial = 0; trial < 20; ++trial) {
        slam_ekf_t f;
        const int k = 1 + trial % SLAM_MAX_LANDMARKS;
        ekf_scalar_t u[3], F3[9], G3[9], pose_n[3], before[SLAM_MAX_N * SLAM_MAX_N];
        double P[MT_MAX * MT_MAX], F[MT_MAX * MT_MAX], Q[MT_MAX * MT_MAX], out[MT_MAX * MT_MAX], M[3];
        const ekf_scalar_t dt = EKF_C(0.1);
        int n, i, j, a, b;
        filter_with_landmarks(&f, k, &rng);
        n = f.n;
        u[0] = (ekf_scalar_t)ts_uniform_in(&rng, -2, 2);
        u[1] = (ekf_scalar_t)ts_uniform_in(&rng, -1, 1);
        u[2] = (ekf_scalar_t)ts_uniform_in(&rng, -1, 1);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_motion(f.x, u, dt, pose_n, F3, G3));
        mt_to_double(f.P, P, n * n);
        memcpy(before, f.P, sizeof(ekf_scalar_t) * (size_t)(n * n));
        memset(F, 0, sizeof F);
        memset(Q, 0, sizeof Q);
        for (i = 0; i < n; ++i) {
            F[i * n + i] = 1.0;
        }
        M[0] = M[1] = (double)slam_default_settings.vel_var;
        M[2] = (double)slam_default_settings.yaw_rate_var;
        for (i = 0; i < 3; ++i) {
            for (j = 0; j < 3; ++j) {
                F[i * n + j] = (double)F3[i * 3 + j];
                for (a = 0; a < 3; ++a) {
                    Q[i * n + j] += (double)G3[i * 3 + a] * M[a] * (double)G3[j * 3 + a];
                }
            }
        }
        mt_propagate(P, F, Q, n);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_predict(&f, u, dt));
        mt_to_double(f.P, out, n * n);
        worst = fmax(worst, mt_max_rel_diff(out, P, n * n));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(f.P, n));
        /* static landmarks: their block of P is not touched at all (not merely equal) */
        for (a = 3; a < n; ++a) {
            for (b = 3; b < n; ++b) {
                TEST_ASSERT_TRUE_MESSAGE(f.P[a * n + b] == before[a * n + b], "prediction touched the map block");
            }
        }
        for (i = 0; i < 3; ++i) {
            TEST_ASSERT_TRUE(f.x[i] == pose_n[i]);
        }
    }
    TEST_ASSERT_TRUE_MESSAGE(worst < DENSE_TOL, "sparse prediction != dense F P F^T + Q");
}

/* New landmark: P_aug = J diag(P, R) J^T with J = [I 0; Gx 0 Gz] (the textbook augmentation). */
static void test_augmentation_matches_dense(void)
{
    ts_rng_t rng;
    double worst = 0.0;
    int trial;
    ts_rng_seed(&rng, 35);
    for (trial = 0; trial < 20; ++trial) {
        slam_ekf_t f;
        const int k = trial % SLAM_MAX_LANDMARKS; /* 0 .. max-1 landmarks before */
        slam_observation_t o;
        slam_obs_report_t rep;
        ekf_scalar_t m[2], Gx[6], Gz[4];
        double Pe[MT_MAX * MT_MAX], J[MT_MAX * MT_MAX], Jt[MT_MAX * MT_MAX], T[MT_MAX * MT_MAX],
            ref[MT_MAX * MT_MAX], out[MT_MAX * MT_MAX];
        int n, ne, i, j;
        if (k == 0) {
            TEST_ASSERT_EQUAL_INT(EKF_OK, slam_init(&f, &slam_default_settings, POSE0, POSE_VAR0));
        } else {
            filter_with_landmarks(&f, k, &rng);
        }
        n = f.n;
        ne = n + 2;
        o.id = 200;
        o.range = (ekf_scalar_t)ts_uniform_in(&rng, 1.0, 10.0);
        o.bearing = (ekf_scalar_t)ts_uniform_in(&rng, -PI, PI);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_inverse_observation(f.x, o.range, o.bearing, m, Gx, Gz));
        memset(Pe, 0, sizeof Pe);
        memset(J, 0, sizeof J);
        for (i = 0; i < n; ++i) {
            for (j = 0; j < n; ++j) {
                Pe[i * (n + 2) + j] = (double)f.P[i * n + j];
            }
            J[i * (n + 2) + i] = 1.0;
        }
        Pe[n * ne + n] = (double)slam_default_settings.range_var;
        Pe[(n + 1) * ne + n + 1] = (double)slam_default_settings.bearing_var;
        for (i = 0; i < 2; ++i) {
            for (j = 0; j < 3; ++j) {
                J[(n + i) * ne + j] = (double)Gx[i * 3 + j];
            }
            for (j = 0; j < 2; ++j) {
                J[(n + i) * ne + n + j] = (double)Gz[i * 2 + j];
            }
        }
        mt_matmul(J, Pe, T, ne, ne, ne);
        mt_transpose(J, Jt, ne, ne);
        mt_matmul(T, Jt, ref, ne, ne, ne);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, &rep));
        TEST_ASSERT_EQUAL_INT(1, rep.new_landmark);
        TEST_ASSERT_EQUAL_INT(ne, f.n);
        mt_to_double(f.P, out, ne * ne);
        worst = fmax(worst, mt_max_rel_diff(out, ref, ne * ne));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(f.P, ne));
        TEST_ASSERT_TRUE(f.x[n] == m[0] && f.x[n + 1] == m[1]);
    }
    TEST_ASSERT_TRUE_MESSAGE(worst < DENSE_TOL, "augmentation != dense J P J^T");
}

/* Range + bearing as two sequential sparse scalar updates == batch EKF with dense H (2 x n). */
static void test_update_matches_batch(void)
{
    ts_rng_t rng;
    double worst = 0.0;
    int trial;
    ts_rng_seed(&rng, 36);
    for (trial = 0; trial < 40; ++trial) {
        slam_ekf_t f;
        const int k = 1 + trial % SLAM_MAX_LANDMARKS;
        const int slot = trial % k;
        slam_observation_t o;
        ekf_scalar_t h[2], A[6], B[4];
        double x[MT_MAX], P[MT_MAX * MT_MAX], H[2 * MT_MAX], nu[2], r[2], out[MT_MAX * MT_MAX];
        int n, i, j;
        filter_with_landmarks(&f, k, &rng);
        n = f.n;
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observation(f.x, &f.x[3 + 2 * slot], f.settings.min_range, h, A, B));
        o.id = f.id[slot];
        o.range = (ekf_scalar_t)((double)h[0] + 0.1 * ts_gauss(&rng));
        o.bearing = (ekf_scalar_t)mt_wrap_pi((double)h[1] + 0.02 * ts_gauss(&rng));
        memset(H, 0, sizeof H);
        for (i = 0; i < 2; ++i) {
            for (j = 0; j < 3; ++j) {
                H[i * n + j] = (double)A[i * 3 + j];
            }
            for (j = 0; j < 2; ++j) {
                H[i * n + 3 + 2 * slot + j] = (double)B[i * 2 + j];
            }
        }
        nu[0] = (double)o.range - (double)h[0];
        nu[1] = mt_wrap_pi((double)o.bearing - (double)h[1]);
        r[0] = (double)f.settings.range_var;
        r[1] = (double)f.settings.bearing_var;
        mt_to_double(f.x, x, n);
        mt_to_double(f.P, P, n * n);
        TEST_ASSERT_TRUE(mt_ekf_update(x, P, n, H, nu, r, 2));
        x[2] = mt_wrap_pi(x[2]);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, NULL));
        mt_to_double(f.x, out, n);
        worst = fmax(worst, mt_max_rel_diff(out, x, n));
        mt_to_double(f.P, out, n * n);
        worst = fmax(worst, mt_max_rel_diff(out, P, n * n));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(f.P, n));
    }
    printf("SLAM sequential sparse update vs batch dense EKF: max relative difference %.3g (%s)\n", worst,
           EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE_MESSAGE(worst < DENSE_TOL, "sequential update != batch update");
}

/* Landmark straight behind the robot: predicted bearing ~ +-pi; a measurement on the
 * other side of the cut must give a small wrapped innovation. */
static void test_bearing_wrap(void)
{
    slam_ekf_t f;
    slam_observation_t o;
    slam_obs_report_t rep;
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_init(&f, &slam_default_settings, POSE0, POSE_VAR0));
    o.id = 1;
    o.range = EKF_C(5.0);
    o.bearing = (ekf_scalar_t)(PI - 0.01);
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, &rep));
    TEST_ASSERT_EQUAL_INT(1, rep.new_landmark);
    o.bearing = (ekf_scalar_t)(-PI + 0.01);
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, &rep));
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 0.02, (double)rep.innov[SLAM_BEARING].innovation);
    TEST_ASSERT_TRUE(fabs((double)f.x[SLAM_PSI]) < 0.02);
}

static void test_refusals(void)
{
    slam_ekf_t f, saved;
    slam_observation_t o;
    const ekf_scalar_t nan = (ekf_scalar_t)NAN;
    ekf_scalar_t u[3] = {1, 0, 0}, m[2];
    int i;
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_init(&f, &slam_default_settings, POSE0, POSE_VAR0));
    for (i = 0; i < SLAM_MAX_LANDMARKS; ++i) {
        o.id = (uint8_t)i;
        o.range = EKF_C(3.0);
        o.bearing = (ekf_scalar_t)(0.3 * i);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, NULL));
    }
    saved = f;
    o.id = 250; /* capacity */
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, slam_observe(&f, &o, NULL));
    o.id = 0;
    o.range = EKF_C(0.01); /* below min_range */
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SINGULAR, slam_observe(&f, &o, NULL));
    o.range = EKF_C(-1);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, slam_observe(&f, &o, NULL));
    o.range = nan;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, slam_observe(&f, &o, NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, slam_predict(&f, u, EKF_C(0)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_TOO_LARGE, slam_predict(&f, u, EKF_C(100)));
    u[1] = nan;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, slam_predict(&f, u, EKF_C(0.1)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, slam_get_landmark(&f, 77, m, NULL));
    TEST_ASSERT_TRUE(mt_same_bits(f.x, saved.x, sizeof f.x) && mt_same_bits(f.P, saved.P, sizeof f.P));
    TEST_ASSERT_EQUAL_INT(saved.n, f.n);

    /* the robot on top of a mapped landmark: predicted range 0 -> refused, unchanged */
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_init(&f, &slam_default_settings, POSE0, POSE_VAR0));
    o.id = 3;
    o.range = EKF_C(1.0);
    o.bearing = EKF_C(0.0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, NULL));
    f.x[SLAM_X] = f.x[3];
    f.x[SLAM_Y] = f.x[4];
    saved = f;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SINGULAR, slam_observe(&f, &o, NULL));
    TEST_ASSERT_TRUE(mt_same_bits(f.x, saved.x, sizeof f.x) && mt_same_bits(f.P, saved.P, sizeof f.P));
    TEST_ASSERT_EQUAL_UINT32(saved.singular + 1u, f.singular);
}

/* The documented exception: the bearing update refused with EKF_ERR_NUMERIC (here a
 * corrupted, indefinite P along the bearing row) leaves the range update fused; the filter
 * stays finite and the report says which component went in. */
static void test_partial_update_reported(void)
{
    slam_ekf_t f;
    slam_observation_t o;
    slam_obs_report_t rep;
    int i, n;
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_init(&f, &slam_default_settings, POSE0, POSE_VAR0));
    o.id = 9;
    o.range = EKF_C(5.0);
    o.bearing = EKF_C(0.0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, NULL)); /* landmark at (5, 0) */
    n = f.n;
    for (i = 0; i < n * n; ++i) {
        f.P[i] = EKF_C(0.0);
    }
    /* range row (-1, 0, 0, 1, 0) sees only X and m_x: S > 0. Bearing row (0, -0.2, -1, 0, 0.2)
     * sees the indefinite (Y, m_y) block [[1, 2], [2, 1]]: 0.04 (1 + 1 - 4) < 0, S < R. */
    f.P[SLAM_X * n + SLAM_X] = f.P[3 * n + 3] = EKF_C(1.0);
    f.P[SLAM_Y * n + SLAM_Y] = f.P[4 * n + 4] = EKF_C(1.0);
    f.P[SLAM_Y * n + 4] = f.P[4 * n + SLAM_Y] = EKF_C(2.0);
    o.range = EKF_C(5.2);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, slam_observe(&f, &o, &rep));
    TEST_ASSERT_EQUAL_INT(EKF_OK, rep.status[SLAM_RANGE]);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, rep.status[SLAM_BEARING]);
    TEST_ASSERT_TRUE(f.x[3] > EKF_C(5.0)); /* the range innovation +0.2 m went in */
    TEST_ASSERT_TRUE(ekf_all_finite(f.x, (uint16_t)n) && ekf_all_finite(f.P, (uint16_t)(n * n)));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_motion_jacobians);
    RUN_TEST(test_observation_jacobians);
    RUN_TEST(test_inverse_observation_jacobians);
    RUN_TEST(test_predict_sparse_matches_dense);
    RUN_TEST(test_augmentation_matches_dense);
    RUN_TEST(test_update_matches_batch);
    RUN_TEST(test_bearing_wrap);
    RUN_TEST(test_refusals);
    RUN_TEST(test_partial_update_reported);
    return UNITY_END();
}
