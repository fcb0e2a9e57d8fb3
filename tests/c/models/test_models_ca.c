/*
 * test_models_ca.c - constant-acceleration model: MATLAB constacc/constaccjac documented
 * examples reproduced exactly, 1-D/2-D/3-D structure, noise Jacobian convention, finite
 * differences, the filter against dense reference algebra, bad input, and consistency
 * (NEES) on simulated CA targets. Built for float and double.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ca.h"
#include "model_test_util.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* MATLAB documentation (constaccjac, constacc; docs/models.md cites the pages):
 * state = [1,1,1,2,1,0], 2-D. */
static const ekf_scalar_t MATLAB_STATE[6] = {1, 1, 1, 2, 1, 0};

static void assert_exact(const ekf_scalar_t *expected, const ekf_scalar_t *actual, int len, const char *what)
{
    int i;
    for (i = 0; i < len; ++i) {
        if (!(expected[i] == actual[i])) {
            char msg[96];
            snprintf(msg, sizeof msg, "%s: entry %d is %.9g, expected %.9g", what, i, (double)actual[i],
                     (double)expected[i]);
            TEST_FAIL_MESSAGE(msg);
        }
    }
}

static void test_matlab_constaccjac_dt_default(void)
{
    /* jacobian = constaccjac([1,1,1,2,1,0]) (default dt = 1 s) */
    static const ekf_scalar_t expected[36] = {
        1, 1, 0.5, 0, 0, 0,
        0, 1, 1, 0, 0, 0,
        0, 0, 1, 0, 0, 0,
        0, 0, 0, 1, 1, 0.5,
        0, 0, 0, 0, 1, 1,
        0, 0, 0, 0, 0, 1};
    ekf_scalar_t J[36];
    TEST_ASSERT_EQUAL_INT(EKF_OK, ca_jacobian(2, CA_DEFAULT_DT_S, J, NULL));
    assert_exact(expected, J, 36, "constaccjac(state)");
}

static void test_matlab_constaccjac_dt_half(void)
{
    /* jacobian = constaccjac([1,1,1,2,1,0].', 0.5) */
    static const ekf_scalar_t expected[36] = {
        1, 0.5, 0.125, 0, 0, 0,
        0, 1, 0.5, 0, 0, 0,
        0, 0, 1, 0, 0, 0,
        0, 0, 0, 1, 0.5, 0.125,
        0, 0, 0, 0, 1, 0.5,
        0, 0, 0, 0, 0, 1};
    ekf_scalar_t J[36];
    TEST_ASSERT_EQUAL_INT(EKF_OK, ca_jacobian(2, EKF_C(0.5), J, NULL));
    assert_exact(expected, J, 36, "constaccjac(state, 0.5)");
}

static void test_matlab_constacc_examples(void)
{
    /* constacc([1;1;1;2;1;0]) = [2.5;2;1;3;1;0]; constacc(state, 0.5) = [1.625;1.5;1;2.5;1;0] */
    static const ekf_scalar_t one_s[6] = {2.5, 2, 1, 3, 1, 0};
    static const ekf_scalar_t half_s[6] = {1.625, 1.5, 1, 2.5, 1, 0};
    ekf_scalar_t out[6];
    TEST_ASSERT_EQUAL_INT(EKF_OK, ca_transition(MATLAB_STATE, 2, NULL, CA_DEFAULT_DT_S, out));
    assert_exact(one_s, out, 6, "constacc(state)");
    TEST_ASSERT_EQUAL_INT(EKF_OK, ca_transition(MATLAB_STATE, 2, NULL, EKF_C(0.5), out));
    assert_exact(half_s, out, 6, "constacc(state, 0.5)");
}

/* Block structure for 1-D and 3-D (and 2-D): block k of Jx is [1 T T^2/2; 0 1 T; 0 0 1],
 * zero off the blocks; Jw is 3 dims x dims with [T^2/2; T; 1] in column k. */
static void test_dims_1_2_3_structure(void)
{
    const ekf_scalar_t T = EKF_C(0.25);
    const ekf_scalar_t blk[9] = {1, T, T * T / 2, 0, 1, T, 0, 0, 1};
    const ekf_scalar_t g[3] = {T * T / 2, T, 1};
    ekf_scalar_t Jx[CA_MAX_N * CA_MAX_N], Jw[CA_MAX_N * CA_MAX_DIMS];
    uint8_t dims;
    for (dims = 1; dims <= 3; ++dims) {
        const int n = 3 * dims;
        int i, j;
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_jacobian(dims, T, Jx, Jw));
        for (i = 0; i < n; ++i) {
            for (j = 0; j < n; ++j) {
                const ekf_scalar_t want = (i / 3 == j / 3) ? blk[(i % 3) * 3 + j % 3] : EKF_C(0);
                TEST_ASSERT_TRUE_MESSAGE(Jx[i * n + j] == want, "Jx block structure");
            }
            for (j = 0; j < dims; ++j) {
                const ekf_scalar_t want = (i / 3 == j) ? g[i % 3] : EKF_C(0);
                TEST_ASSERT_TRUE_MESSAGE(Jw[i * dims + j] == want, "Jw block structure");
            }
        }
    }
}

/* f(x, w) = Jx x + Jw w exactly (the model is linear): the noise Jacobian is the noise
 * convention of the transition, not a separate choice. */
static void test_noise_convention_linear(void)
{
    ts_rng_t rng;
    int trial;
    double worst = 0.0;
    ts_rng_seed(&rng, 11);
    for (trial = 0; trial < 200; ++trial) {
        const uint8_t dims = (uint8_t)(1 + trial % 3);
        const int n = 3 * dims;
        ekf_scalar_t x[CA_MAX_N], w[CA_MAX_DIMS], out[CA_MAX_N], Jx[CA_MAX_N * CA_MAX_N], Jw[CA_MAX_N * 3];
        const ekf_scalar_t dt = (ekf_scalar_t)ts_uniform_in(&rng, 0.01, 2.0);
        int i, j;
        for (i = 0; i < n; ++i) {
            x[i] = (ekf_scalar_t)ts_uniform_in(&rng, -10, 10);
        }
        for (i = 0; i < dims; ++i) {
            w[i] = (ekf_scalar_t)ts_uniform_in(&rng, -3, 3);
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_transition(x, dims, w, dt, out));
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_jacobian(dims, dt, Jx, Jw));
        for (i = 0; i < n; ++i) {
            /* error relative to the sum of the magnitudes of the terms (what rounding scales with) */
            double lin = 0.0, mag = 1.0, e;
            for (j = 0; j < n; ++j) {
                lin += (double)Jx[i * n + j] * (double)x[j];
                mag += fabs((double)Jx[i * n + j] * (double)x[j]);
            }
            for (j = 0; j < dims; ++j) {
                lin += (double)Jw[i * dims + j] * (double)w[j];
                mag += fabs((double)Jw[i * dims + j] * (double)w[j]);
            }
            e = fabs(lin - (double)out[i]) / mag;
            worst = e > worst ? e : worst;
        }
    }
    TEST_ASSERT_TRUE_MESSAGE(worst < 64 * MT_EPS, "f(x, w) != Jx x + Jw w");
}

/* Central differences of ca_transition against ca_jacobian, state and noise columns. The
 * model is linear, so the differences are exact but for rounding: the tolerance is the
 * rounding of x over the step, 8 eps |x| / h. */
static void test_jacobians_finite_differences(void)
{
    ts_rng_t rng;
    int trial;
    double worst_x = 0.0, worst_w = 0.0;
    const double h = 0.5;
    ts_rng_seed(&rng, 12);
    for (trial = 0; trial < 300; ++trial) {
        const uint8_t dims = (uint8_t)(1 + trial % 3);
        const int n = 3 * dims;
        ekf_scalar_t x[CA_MAX_N], xp[CA_MAX_N], xm[CA_MAX_N], w[3], wp[3], wm[3], fp[CA_MAX_N], fm[CA_MAX_N];
        ekf_scalar_t Jx[CA_MAX_N * CA_MAX_N], Jw[CA_MAX_N * 3];
        const ekf_scalar_t dt = (ekf_scalar_t)ts_uniform_in(&rng, 0.01, 2.0);
        int i, j;
        for (i = 0; i < n; ++i) {
            x[i] = (ekf_scalar_t)ts_uniform_in(&rng, -10, 10);
        }
        for (i = 0; i < 3; ++i) {
            w[i] = (ekf_scalar_t)ts_uniform_in(&rng, -1, 1);
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_jacobian(dims, dt, Jx, Jw));
        for (j = 0; j < n + dims; ++j) {
            memcpy(xp, x, sizeof x);
            memcpy(xm, x, sizeof x);
            memcpy(wp, w, sizeof w);
            memcpy(wm, w, sizeof w);
            if (j < n) {
                xp[j] = (ekf_scalar_t)((double)x[j] + h);
                xm[j] = (ekf_scalar_t)((double)x[j] - h);
            } else {
                wp[j - n] = (ekf_scalar_t)((double)w[j - n] + h);
                wm[j - n] = (ekf_scalar_t)((double)w[j - n] - h);
            }
            TEST_ASSERT_EQUAL_INT(EKF_OK, ca_transition(xp, dims, wp, dt, fp));
            TEST_ASSERT_EQUAL_INT(EKF_OK, ca_transition(xm, dims, wm, dt, fm));
            for (i = 0; i < n; ++i) {
                const double fd = ((double)fp[i] - (double)fm[i]) / (2.0 * h);
                const double an = (j < n) ? (double)Jx[i * n + j] : (double)Jw[i * dims + (j - n)];
                const double e = fabs(fd - an);
                if (j < n) {
                    worst_x = e > worst_x ? e : worst_x;
                } else {
                    worst_w = e > worst_w ? e : worst_w;
                }
            }
        }
    }
    printf("CA Jacobian max |analytic - central difference|: Jx %.3g, Jw %.3g (%s)\n", worst_x, worst_w,
           EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE(worst_x < 8.0 * MT_EPS * 20.0 / h);
    TEST_ASSERT_TRUE(worst_w < 8.0 * MT_EPS * 20.0 / h);
}

/* A random symmetric positive definite n x n matrix: A A^T + I. */
static void random_spd(ts_rng_t *rng, double *P, int n)
{
    double A[MT_MAX * MT_MAX];
    int i, j, k;
    for (i = 0; i < n * n; ++i) {
        A[i] = ts_uniform_in(rng, -1, 1);
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            double acc = (i == j) ? 1.0 : 0.0;
            for (k = 0; k < n; ++k) {
                acc += A[i * n + k] * A[j * n + k];
            }
            P[i * n + j] = acc;
        }
    }
}

static void init_filter(ca_ekf_t *f, uint8_t dims, const ca_settings_t *s)
{
    ekf_scalar_t x0[CA_MAX_N], p0[CA_MAX_N];
    int i;
    for (i = 0; i < CA_MAX_N; ++i) {
        x0[i] = EKF_C(0);
        p0[i] = EKF_C(1);
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, ca_init(f, s, dims, x0, p0));
}

/* ca_predict (sparse propagation + per-axis noise) against dense Jx P Jx^T + Jw q Jw^T. */
static void test_predict_matches_dense(void)
{
    ts_rng_t rng;
    ca_ekf_t f;
    ca_settings_t s = ca_default_settings;
    int trial;
    double worst = 0.0;
    ts_rng_seed(&rng, 13);
    s.accel_increment_var = EKF_C(0.7);
    for (trial = 0; trial < 30; ++trial) {
        const uint8_t dims = (uint8_t)(1 + trial % 3);
        const int n = 3 * dims;
        const ekf_scalar_t dt = (ekf_scalar_t)ts_uniform_in(&rng, 0.05, 1.5);
        double P[MT_MAX * MT_MAX], Pf[MT_MAX * MT_MAX], F[MT_MAX * MT_MAX], Q[MT_MAX * MT_MAX];
        double G[MT_MAX * 3], Gt[3 * MT_MAX], GGt[MT_MAX * MT_MAX], x[CA_MAX_N], xf[CA_MAX_N];
        ekf_scalar_t Jx[CA_MAX_N * CA_MAX_N], Jw[CA_MAX_N * 3];
        int i;
        init_filter(&f, dims, &s);
        random_spd(&rng, P, n);
        mt_from_double(P, f.P, n * n);
        mt_to_double(f.P, P, n * n); /* the reference starts from the same rounded P */
        for (i = 0; i < n; ++i) {
            f.x[i] = (ekf_scalar_t)ts_uniform_in(&rng, -5, 5);
            x[i] = (double)f.x[i];
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_jacobian(dims, dt, Jx, Jw));
        mt_to_double(Jx, F, n * n);
        mt_to_double(Jw, G, n * dims);
        mt_transpose(G, Gt, n, dims);
        mt_matmul(G, Gt, GGt, n, dims, n);
        for (i = 0; i < n * n; ++i) {
            Q[i] = GGt[i] * (double)s.accel_increment_var;
        }
        mt_propagate(P, F, Q, n);
        mt_matmul(F, x, xf, n, n, 1);
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_predict(&f, dt));
        mt_to_double(f.P, Pf, n * n);
        worst = fmax(worst, mt_max_rel_diff(Pf, P, n * n));
        mt_to_double(f.x, Pf, n);
        worst = fmax(worst, mt_max_rel_diff(Pf, xf, n));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(f.P, n));
    }
    TEST_ASSERT_TRUE_MESSAGE(worst < 200 * MT_EPS, "ca_predict != dense F P F^T + G q G^T");
}

/* ca_update_position (sequential scalar updates) against the batch KF update. */
static void test_update_matches_batch(void)
{
    ts_rng_t rng;
    ca_ekf_t f;
    int trial;
    double worst = 0.0;
    ts_rng_seed(&rng, 14);
    for (trial = 0; trial < 30; ++trial) {
        const uint8_t dims = (uint8_t)(1 + trial % 3);
        const int n = 3 * dims;
        double P[MT_MAX * MT_MAX], x[CA_MAX_N], H[3 * CA_MAX_N], nu[3], r[3], out[MT_MAX * MT_MAX];
        ekf_scalar_t z[3];
        int i;
        init_filter(&f, dims, &ca_default_settings);
        random_spd(&rng, P, n);
        mt_from_double(P, f.P, n * n);
        mt_to_double(f.P, P, n * n);
        for (i = 0; i < n; ++i) {
            f.x[i] = (ekf_scalar_t)ts_uniform_in(&rng, -5, 5);
            x[i] = (double)f.x[i];
        }
        memset(H, 0, sizeof H);
        for (i = 0; i < dims; ++i) {
            z[i] = (ekf_scalar_t)ts_uniform_in(&rng, -5, 5);
            H[i * n + 3 * i] = 1.0;
            nu[i] = (double)z[i] - x[3 * i];
            r[i] = (double)ca_default_settings.position_var;
        }
        TEST_ASSERT_TRUE(mt_ekf_update(x, P, n, H, nu, r, dims));
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_update_position(&f, z, NULL));
        mt_to_double(f.P, out, n * n);
        worst = fmax(worst, mt_max_rel_diff(out, P, n * n));
        mt_to_double(f.x, out, n);
        worst = fmax(worst, mt_max_rel_diff(out, x, n));
    }
    TEST_ASSERT_TRUE_MESSAGE(worst < 500 * MT_EPS, "sequential update != batch update");
}

static void test_bad_input(void)
{
    ca_ekf_t f, saved;
    ca_settings_t s = ca_default_settings;
    ekf_scalar_t out[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0}, J[81], z[3] = {0, 0, 0};
    const ekf_scalar_t nan = (ekf_scalar_t)NAN;
    init_filter(&f, 3, &ca_default_settings);
    TEST_ASSERT_EQUAL_INT(EKF_OK, ca_predict(&f, EKF_C(0.1)));
    saved = f;

    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ca_transition(MATLAB_STATE, 0, NULL, EKF_C(1), out));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ca_jacobian(4, EKF_C(1), J, NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, ca_jacobian(2, EKF_C(0), J, NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ca_jacobian(2, nan, J, NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, ca_jacobian(2, EKF_C(1), NULL, NULL));

    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, ca_predict(&f, EKF_C(-1)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ca_predict(&f, nan));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_TOO_LARGE, ca_predict(&f, EKF_C(1e5)));
    z[1] = nan;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ca_update_position(&f, z, NULL));
    TEST_ASSERT_TRUE_MESSAGE(mt_same_bits(f.x, saved.x, sizeof f.x) && mt_same_bits(f.P, saved.P, sizeof f.P),
                             "a refused call changed the filter");

    s.position_var = EKF_C(-1);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, ca_init(&f, &s, 2, out, out));
    TEST_ASSERT_TRUE(mt_same_bits(f.P, saved.P, sizeof f.P));
}

/*
 * Consistency: 2-D CA targets simulated (in double, independently of the library) with the
 * MATLAB noise convention, tracked with position measurements. The normalised estimation
 * error squared of the 6-state estimate, summed over M independent runs, is chi-square
 * with 6 M degrees of freedom when the filter's covariance is right: the test requires it
 * inside the two-sided 99.9 % interval. Wrong Q (e.g. G = [T^3/6; T^2/2; T]) fails it.
 */
static void test_tracking_nees(void)
{
    enum { RUNS = 100, STEPS = 60, N = 6 };
    const double dt = 0.2, q = 0.5, r = 0.3;
    ca_settings_t s = ca_default_settings;
    ts_rng_t rng;
    double nees_sum = 0.0, lo, hi;
    int run, k, i;
    s.accel_increment_var = (ekf_scalar_t)q;
    s.position_var = (ekf_scalar_t)(r * r);
    ts_rng_seed(&rng, 15);
    for (run = 0; run < RUNS; ++run) {
        ca_ekf_t f;
        double truth[N], P[N * N], e[N], Pinv[N * N], tmp[N];
        ekf_scalar_t x0[N], p0[N], z[2];
        for (i = 0; i < N; ++i) {
            const double sd = (i % 3 == 0) ? 2.0 : (i % 3 == 1 ? 1.0 : 0.5);
            truth[i] = sd * ts_gauss(&rng);
            x0[i] = EKF_C(0);
            p0[i] = (ekf_scalar_t)(sd * sd);
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ca_init(&f, &s, 2, x0, p0));
        for (k = 0; k < STEPS; ++k) {
            int ax;
            for (ax = 0; ax < 2; ++ax) {
                double *b = &truth[3 * ax];
                const double a = b[2] + sqrt(q) * ts_gauss(&rng);
                b[0] += dt * b[1] + 0.5 * dt * dt * a;
                b[1] += dt * a;
                b[2] = a;
                z[ax] = (ekf_scalar_t)(b[0] + r * ts_gauss(&rng));
            }
            TEST_ASSERT_EQUAL_INT(EKF_OK, ca_predict(&f, (ekf_scalar_t)dt));
            TEST_ASSERT_EQUAL_INT(EKF_OK, ca_update_position(&f, z, NULL));
        }
        mt_to_double(f.P, P, N * N);
        memcpy(Pinv, P, sizeof P);
        TEST_ASSERT_TRUE(mt_inverse(Pinv, N));
        for (i = 0; i < N; ++i) {
            e[i] = truth[i] - (double)f.x[i];
        }
        mt_matmul(Pinv, e, tmp, N, N, 1);
        for (i = 0; i < N; ++i) {
            nees_sum += e[i] * tmp[i];
        }
    }
    lo = mt_chi2_quantile(N * RUNS, -3.29);
    hi = mt_chi2_quantile(N * RUNS, 3.29);
    printf("CA tracking: summed NEES %.1f over %d runs, 99.9%% interval [%.1f, %.1f] (%s)\n", nees_sum, RUNS, lo,
           hi, EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE(nees_sum > lo && nees_sum < hi);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_matlab_constaccjac_dt_default);
    RUN_TEST(test_matlab_constaccjac_dt_half);
    RUN_TEST(test_matlab_constacc_examples);
    RUN_TEST(test_dims_1_2_3_structure);
    RUN_TEST(test_noise_convention_linear);
    RUN_TEST(test_jacobians_finite_differences);
    RUN_TEST(test_predict_matches_dense);
    RUN_TEST(test_update_matches_batch);
    RUN_TEST(test_bad_input);
    RUN_TEST(test_tracking_nees);
    return UNITY_END();
}
