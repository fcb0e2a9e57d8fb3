/*
 * test_ekf_core.c - the generic EKF primitives (ekf.h) against dense reference
 * computations in double, and their refusal paths. Built for float and double.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ekf.h"
#include "testsim.h"
#include "unity.h"

#define NMAX 20

#if defined(EKF_SCALAR_DOUBLE)
#define REL_TOL 1e-12
#else
#define REL_TOL 2e-5
#endif

void setUp(void) {}
void tearDown(void) {}

/* Random symmetric positive definite matrix A A^T + n I / 10 (double and scalar copies). */
static void random_spd(ts_rng_t *r, int n, double *Pd, ekf_scalar_t *P)
{
    double A[NMAX * NMAX];
    int i, j, k;
    for (i = 0; i < n * n; ++i) {
        A[i] = ts_uniform_in(r, -1.0, 1.0);
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j <= i; ++j) {
            double acc = (i == j) ? 0.1 * n : 0.0;
            for (k = 0; k < n; ++k) {
                acc += A[i * n + k] * A[j * n + k];
            }
            Pd[i * n + j] = Pd[j * n + i] = acc;
        }
    }
    for (i = 0; i < n * n; ++i) {
        P[i] = (ekf_scalar_t)Pd[i];
        Pd[i] = (double)P[i]; /* reference starts from exactly the same numbers */
    }
}

static double max_abs(const double *v, int len)
{
    double m = 0.0;
    int i;
    for (i = 0; i < len; ++i) {
        if (fabs(v[i]) > m) {
            m = fabs(v[i]);
        }
    }
    return m;
}

static void test_cov_propagate_matches_dense(void)
{
    ts_rng_t r;
    double worst = 0.0;
    int trial;
    ts_rng_seed(&r, 11);
    for (trial = 0; trial < 300; ++trial) {
        const int n = 2 + (int)(ts_uniform(&r) * (NMAX - 1));
        double Pd[NMAX * NMAX], F[NMAX * NMAX], FP[NMAX * NMAX], ref[NMAX * NMAX];
        ekf_scalar_t P[NMAX * NMAX], d[NMAX * NMAX], work[NMAX * NMAX];
        ekf_nz_t pat[NMAX * NMAX];
        uint16_t nnz = 0;
        int i, j, k, rows = 0;
        random_spd(&r, n, Pd, P);
        for (i = 0; i < n * n; ++i) {
            F[i] = 0.0;
        }
        for (i = 0; i < n; ++i) {
            F[i * n + i] = 1.0;
            if (ts_uniform(&r) < 0.4) { /* this row of F differs from the identity */
                int any = 0;
                for (j = 0; j < n; ++j) {
                    if (ts_uniform(&r) < 0.3 || (j == n - 1 && !any)) {
                        const ekf_scalar_t v = (ekf_scalar_t)ts_uniform_in(&r, -2.0, 2.0);
                        pat[nnz].row = (uint8_t)i;
                        pat[nnz].col = (uint8_t)j;
                        d[nnz] = v;
                        F[i * n + j] += (double)v;
                        ++nnz;
                        any = 1;
                    }
                }
                ++rows;
            }
        }
        for (i = 0; i < n; ++i) {
            for (j = 0; j < n; ++j) {
                double acc = 0.0;
                for (k = 0; k < n; ++k) {
                    acc += F[i * n + k] * Pd[k * n + j];
                }
                FP[i * n + j] = acc;
            }
        }
        for (i = 0; i < n; ++i) {
            for (j = 0; j < n; ++j) {
                double acc = 0.0;
                for (k = 0; k < n; ++k) {
                    acc += FP[i * n + k] * F[j * n + k];
                }
                ref[i * n + j] = acc;
            }
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_cov_propagate(P, (uint8_t)n, pat, d, nnz, work,
                                                        (uint16_t)(rows * n)));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(P, n));
        {
            const double scale = max_abs(ref, n * n);
            for (i = 0; i < n * n; ++i) {
                const double e = fabs((double)P[i] - ref[i]) / scale;
                if (e > worst) {
                    worst = e;
                }
            }
        }
    }
    printf("ekf_cov_propagate vs dense F P F^T (300 random cases): max rel error %.2e\n", worst);
    TEST_ASSERT_TRUE(worst < REL_TOL);
}

static void test_cov_propagate_refusals_leave_P_unchanged(void)
{
    ekf_scalar_t P[9] = {2, 0.5, 0, 0.5, 1, 0, 0, 0, 3}, before[9], work[9];
    ekf_scalar_t d[2] = {EKF_C(0.1), EKF_C(0.2)};
    const ekf_nz_t good[2] = {{0, 1}, {2, 0}};
    const ekf_nz_t unsorted[2] = {{2, 0}, {0, 1}};
    const ekf_nz_t outside[2] = {{0, 1}, {3, 0}};
    memcpy(before, P, sizeof P);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, ekf_cov_propagate(NULL, 3, good, d, 2, work, 9));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, ekf_cov_propagate(P, 3, good, d, 2, NULL, 9));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ekf_cov_propagate(P, 3, unsorted, d, 2, work, 9));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ekf_cov_propagate(P, 3, outside, d, 2, work, 9));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ekf_cov_propagate(P, 3, good, d, 2, work, 5));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ekf_cov_propagate(P, 0, good, d, 2, work, 9));
    d[1] = (ekf_scalar_t)NAN;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ekf_cov_propagate(P, 3, good, d, 2, work, 9));
    TEST_ASSERT_EQUAL_MEMORY(before, P, sizeof P);
}

/* Scalar update against the textbook formulas evaluated in double. */
static void test_update_matches_textbook(void)
{
    ts_rng_t r;
    double worst_x = 0.0, worst_p = 0.0;
    int trial;
    ts_rng_seed(&r, 12);
    for (trial = 0; trial < 300; ++trial) {
        const int n = 2 + (int)(ts_uniform(&r) * (NMAX - 1));
        double Pd[NMAX * NMAX], xd[NMAX], b[NMAX], s, nu, rv;
        ekf_scalar_t P[NMAX * NMAX], x[NMAX], hv[3];
        uint8_t idx[3];
        ekf_hrow_t h;
        ekf_innov_t info;
        int i, j, k, nh = 1 + (int)(ts_uniform(&r) * 3);
        random_spd(&r, n, Pd, P);
        for (i = 0; i < n; ++i) {
            x[i] = (ekf_scalar_t)ts_uniform_in(&r, -1, 1);
            xd[i] = (double)x[i];
        }
        if (nh > n) {
            nh = n;
        }
        for (k = 0; k < nh; ++k) {
            idx[k] = (uint8_t)((k * 7 + trial) % n);
            for (j = 0; j < k; ++j) {
                if (idx[j] == idx[k]) {
                    idx[k] = (uint8_t)((idx[k] + 1) % n);
                    j = -1;
                }
            }
            hv[k] = (ekf_scalar_t)ts_uniform_in(&r, -1, 1);
        }
        h.idx = idx;
        h.value = hv;
        h.nnz = (uint8_t)nh;
        nu = (double)(ekf_scalar_t)ts_uniform_in(&r, -0.5, 0.5);
        rv = (double)(ekf_scalar_t)ts_uniform_in(&r, 0.01, 1.0);
        for (i = 0; i < n; ++i) {
            b[i] = 0.0;
            for (k = 0; k < nh; ++k) {
                b[i] += Pd[i * n + idx[k]] * (double)hv[k];
            }
        }
        s = rv;
        for (k = 0; k < nh; ++k) {
            s += (double)hv[k] * b[idx[k]];
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_update_scalar(x, P, (uint8_t)n, &h, (ekf_scalar_t)nu,
                                                        (ekf_scalar_t)rv, EKF_C(0), EKF_C(1e-12), &info));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(P, n));
        TEST_ASSERT_TRUE(ts_is_positive_definite(P, n, NULL));
        for (i = 0; i < n; ++i) {
            const double ex = fabs((double)x[i] - (xd[i] + b[i] / s * nu));
            if (ex > worst_x) {
                worst_x = ex;
            }
            for (j = 0; j < n; ++j) {
                const double ref = Pd[i * n + j] - b[i] * b[j] / s;
                const double ep = fabs((double)P[i * n + j] - ref) / (1.0 + fabs(Pd[i * n + j]));
                if (ep > worst_p) {
                    worst_p = ep;
                }
            }
        }
        TEST_ASSERT_TRUE(fabs((double)info.variance - s) <= 1e-5 * s);
    }
    printf("ekf_update_scalar vs textbook (300 random cases): state %.2e, covariance %.2e\n", worst_x, worst_p);
    TEST_ASSERT_TRUE(worst_x < REL_TOL * 10);
    TEST_ASSERT_TRUE(worst_p < REL_TOL * 10);
}

static void test_update_gate_and_refusals(void)
{
    ekf_scalar_t P[4] = {EKF_C(1), EKF_C(0.2), EKF_C(0.2), EKF_C(0.5)};
    ekf_scalar_t x[2] = {EKF_C(1), EKF_C(2)};
    ekf_scalar_t Pb[4], xb[2];
    const uint8_t idx0 = 0, bad_idx = 2;
    const ekf_scalar_t one = EKF_C(1), nan_v = (ekf_scalar_t)NAN;
    ekf_hrow_t h = {&idx0, &one, 1};
    ekf_innov_t info;
    memcpy(Pb, P, sizeof P);
    memcpy(xb, x, sizeof x);
    /* S = 1 + 1 = 2; innovation 5 -> ratio 25 / (9 * 2) > 1 with a 3-sigma gate */
    TEST_ASSERT_EQUAL_INT(EKF_GATED, ekf_update_scalar(x, P, 2, &h, EKF_C(5), EKF_C(1), EKF_C(3), EKF_C(0), &info));
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 25.0 / 18.0, (float)info.test_ratio);
    TEST_ASSERT_EQUAL_MEMORY(Pb, P, sizeof P);
    TEST_ASSERT_EQUAL_MEMORY(xb, x, sizeof x);
    /* inside the gate: fused */
    TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_update_scalar(x, P, 2, &h, EKF_C(4), EKF_C(1), EKF_C(3), EKF_C(0), &info));
    TEST_ASSERT_TRUE(info.test_ratio < EKF_C(1));
    memcpy(Pb, P, sizeof P);
    memcpy(xb, x, sizeof x);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ekf_update_scalar(x, P, 2, &h, nan_v, EKF_C(1), EKF_C(0), EKF_C(0), NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ekf_update_scalar(x, P, 2, &h, EKF_C(1), nan_v, EKF_C(0), EKF_C(0), NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(0), EKF_C(0), EKF_C(0), NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(-1), EKF_C(0), EKF_C(0), NULL));
    h.idx = &bad_idx;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(1), EKF_C(0), EKF_C(0), NULL));
    h.idx = &idx0;
    h.value = &nan_v;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(1), EKF_C(0), EKF_C(0), NULL));
    h.value = &one;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, ekf_update_scalar(NULL, P, 2, &h, EKF_C(1), EKF_C(1), EKF_C(0), EKF_C(0), NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, ekf_update_scalar(x, P, 2, NULL, EKF_C(1), EKF_C(1), EKF_C(0), EKF_C(0), NULL));
    /* covariance that is not positive along H (negative variance): refused */
    P[0] = EKF_C(-5);
    memcpy(Pb, P, sizeof P);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(1), EKF_C(0), EKF_C(0), NULL));
    TEST_ASSERT_EQUAL_MEMORY(Pb, P, sizeof P);
    TEST_ASSERT_EQUAL_MEMORY(xb, x, sizeof x);
}

static void test_update_diagonal_floor(void)
{
    /* a perfect measurement drives the variance to ~0: the floor holds it */
    ekf_scalar_t P[1] = {EKF_C(1)}, x[1] = {EKF_C(0)};
    const uint8_t idx = 0;
    const ekf_scalar_t one = EKF_C(1);
    const ekf_hrow_t h = {&idx, &one, 1};
    TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_update_scalar(x, P, 1, &h, EKF_C(1), EKF_C(1e-20), EKF_C(0), EKF_C(1e-6), NULL));
    TEST_ASSERT_TRUE(P[0] >= EKF_C(1e-6));
}

/* Indefinite covariances are refused, not floored (x, P unchanged); info is written. */
static void test_update_refuses_indefinite_covariance(void)
{
    /* eigenvalues 3 and -1: the update along e0 would give P_11 = 1 - 4 / 2 = -1 */
    ekf_scalar_t P[4] = {EKF_C(1), EKF_C(2), EKF_C(2), EKF_C(1)};
    ekf_scalar_t x[2] = {EKF_C(0.5), EKF_C(-0.5)};
    ekf_scalar_t Pb[4], xb[2];
    const uint8_t idx0 = 0, idx1 = 1;
    const ekf_scalar_t one = EKF_C(1);
    ekf_hrow_t h = {&idx0, &one, 1};
    ekf_innov_t info;
    memcpy(Pb, P, sizeof P);
    memcpy(xb, x, sizeof x);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, ekf_update_scalar(x, P, 2, &h, EKF_C(0.3), EKF_C(1), EKF_C(0), EKF_C(1e-6), &info));
    TEST_ASSERT_EQUAL_MEMORY(Pb, P, sizeof P);
    TEST_ASSERT_EQUAL_MEMORY(xb, x, sizeof x);
    /* S was formed: the diagnostics say what was refused */
    TEST_ASSERT_TRUE(info.innovation == EKF_C(0.3));
    TEST_ASSERT_TRUE(info.variance == EKF_C(2));
    TEST_ASSERT_TRUE(info.test_ratio == EKF_C(0));
    /* a variance of -1 is never floored to var_floor: an update along the other state is
     * refused too (the -1 is not raised behind the caller's back) */
    P[0] = EKF_C(-1);
    P[1] = P[2] = EKF_C(0);
    memcpy(Pb, P, sizeof P);
    h.idx = &idx1;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, ekf_update_scalar(x, P, 2, &h, EKF_C(0.3), EKF_C(1), EKF_C(0), EKF_C(1e-6), NULL));
    TEST_ASSERT_EQUAL_MEMORY(Pb, P, sizeof P);
    TEST_ASSERT_EQUAL_MEMORY(xb, x, sizeof x);
    /* along the negative variance itself: S = -1 + 1 = 0 < r_var */
    h.idx = &idx0;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, ekf_update_scalar(x, P, 2, &h, EKF_C(0.3), EKF_C(1), EKF_C(0), EKF_C(1e-6), NULL));
    TEST_ASSERT_EQUAL_MEMORY(Pb, P, sizeof P);
}

/* Rank-one covariances P = a (1, c)(1, c)^T, positive semi-definite before their entries
 * are rounded, updated with a near-perfect measurement of x0: the second variance comes
 * out at rounding size (zero in exact arithmetic), sometimes negative. Always accepted and
 * floored: the refusal is for indefiniteness beyond rounding only. */
static void test_update_floors_rounding_size_variances(void)
{
    ts_rng_t r;
    int trial, negative_raw = 0;
    const uint8_t idx0 = 0;
    const ekf_scalar_t one = EKF_C(1), floor = EKF_C(1e-12);
    const ekf_hrow_t h = {&idx0, &one, 1};
    ts_rng_seed(&r, 14);
    for (trial = 0; trial < 2000; ++trial) {
        const double a = ts_uniform_in(&r, 0.1, 10.0), c = ts_uniform_in(&r, -10.0, 10.0);
        ekf_scalar_t P[4], x[2] = {EKF_C(0), EKF_C(0)};
        ekf_scalar_t rv;
        P[0] = (ekf_scalar_t)a;
        P[1] = P[2] = (ekf_scalar_t)(a * c);
        P[3] = (ekf_scalar_t)(a * c * c);
        rv = P[0] * EKF_SCALAR_EPS * EKF_C(1e-3); /* far below the rounding of P */
        {
            /* what the routine computes before flooring */
            const ekf_scalar_t s = P[0] + rv, k1 = P[1] * (EKF_C(1) / s);
            negative_raw += (P[3] - k1 * P[1]) < EKF_C(0);
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_update_scalar(x, P, 2, &h, EKF_C(0.1), rv, EKF_C(0), floor, NULL));
        TEST_ASSERT_TRUE(P[0] >= floor && P[3] >= floor);
    }
    printf("rank-one updates: %d of 2000 with a rounding-negative variance, all floored\n", negative_raw);
    TEST_ASSERT_TRUE(negative_raw > 0); /* the case this test is about occurred */
}

/* info is zero on the paths that return before S is formed (no stale or uninitialised
 * diagnostics for a caller that copies them). */
static void test_update_info_always_written(void)
{
    ekf_scalar_t P[4] = {EKF_C(1), EKF_C(0), EKF_C(0), EKF_C(1)};
    ekf_scalar_t x[2] = {EKF_C(0), EKF_C(0)};
    const uint8_t idx0 = 0, bad_idx = 5;
    const ekf_scalar_t one = EKF_C(1), nan_v = (ekf_scalar_t)NAN;
    ekf_hrow_t h = {&idx0, &one, 1};
    ekf_innov_t info;
    const ekf_innov_t zero = {EKF_C(0), EKF_C(0), EKF_C(0)};
    memset(&info, 0x5A, sizeof info);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, ekf_update_scalar(x, P, 2, &h, nan_v, EKF_C(1), EKF_C(3), EKF_C(0), &info));
    TEST_ASSERT_EQUAL_MEMORY(&zero, &info, sizeof info);
    memset(&info, 0x5A, sizeof info);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(0), EKF_C(3), EKF_C(0), &info));
    TEST_ASSERT_EQUAL_MEMORY(&zero, &info, sizeof info);
    memset(&info, 0x5A, sizeof info);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, ekf_update_scalar(NULL, P, 2, &h, EKF_C(1), EKF_C(1), EKF_C(3), EKF_C(0), &info));
    TEST_ASSERT_EQUAL_MEMORY(&zero, &info, sizeof info);
    h.idx = &bad_idx;
    memset(&info, 0x5A, sizeof info);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DIMENSION, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(1), EKF_C(3), EKF_C(0), &info));
    TEST_ASSERT_EQUAL_MEMORY(&zero, &info, sizeof info);
    /* no gate: the ratio is 0, innovation and S are set */
    h.idx = &idx0;
    memset(&info, 0x5A, sizeof info);
    TEST_ASSERT_EQUAL_INT(EKF_OK, ekf_update_scalar(x, P, 2, &h, EKF_C(1), EKF_C(1), EKF_C(0), EKF_C(0), &info));
    TEST_ASSERT_TRUE(info.innovation == EKF_C(1) && info.variance == EKF_C(2) && info.test_ratio == EKF_C(0));
}

/* ekf_cov_ensure_pd meets its header: afterwards ekf_cov_is_pd holds with the same margin,
 * the variances are >= the floor, P is symmetric; non-finite input is refused unchanged;
 * a zero margin and values near the top of the range terminate. */
static void test_ensure_pd_repairs_or_refuses(void)
{
    ts_rng_t r;
    ekf_scalar_t work[NMAX * (NMAX + 1) / 2];
    const ekf_scalar_t margin = EKF_C(1e-4), floor = EKF_C(1e-9);
    int trial, repaired = 0, i;
    ts_rng_seed(&r, 15);
    for (trial = 0; trial < 500; ++trial) {
        const int n = 2 + (int)(ts_uniform(&r) * (NMAX - 1));
        ekf_scalar_t P[NMAX * NMAX];
        int a, b, rounds;
        /* symmetric, entries of mixed sign and size: most are indefinite */
        for (a = 0; a < n; ++a) {
            for (b = 0; b <= a; ++b) {
                const double v = ts_uniform_in(&r, -1.0, 1.0) * pow(10.0, ts_uniform_in(&r, -3.0, 3.0));
                P[a * n + b] = P[b * n + a] = (ekf_scalar_t)v;
            }
        }
        rounds = ekf_cov_ensure_pd(P, (uint8_t)n, margin, floor, work);
        TEST_ASSERT_TRUE(rounds >= 0);
        repaired += rounds > 0;
        TEST_ASSERT_EQUAL_INT(1, ekf_cov_is_pd(P, (uint8_t)n, margin, work));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(P, n));
        for (a = 0; a < n; ++a) {
            TEST_ASSERT_TRUE(P[a * n + a] >= floor);
        }
        /* a second call has nothing to do */
        TEST_ASSERT_EQUAL_INT(0, ekf_cov_ensure_pd(P, (uint8_t)n, margin, floor, work));
    }
    TEST_ASSERT_TRUE(repaired > 400);
    {
        ekf_scalar_t P[9] = {EKF_C(1), EKF_C(0.5), EKF_C(0), EKF_C(0.5), EKF_C(1), EKF_C(0), EKF_C(0), EKF_C(0), EKF_C(1)};
        ekf_scalar_t before[9];
        /* an infinite variance or a NaN correlation: refused, P unchanged */
        P[4] = (ekf_scalar_t)INFINITY;
        memcpy(before, P, sizeof P);
        TEST_ASSERT_EQUAL_INT(-1, ekf_cov_ensure_pd(P, 3, margin, floor, work));
        TEST_ASSERT_EQUAL_MEMORY(before, P, sizeof P);
        P[4] = EKF_C(1);
        P[1] = P[3] = (ekf_scalar_t)NAN;
        memcpy(before, P, sizeof P);
        TEST_ASSERT_EQUAL_INT(-1, ekf_cov_ensure_pd(P, 3, margin, floor, work));
        TEST_ASSERT_EQUAL_MEMORY(before, P, sizeof P);
        /* arguments out of range */
        P[1] = P[3] = EKF_C(0.5);
        TEST_ASSERT_EQUAL_INT(-1, ekf_cov_ensure_pd(P, 3, margin, EKF_C(0), work));
        TEST_ASSERT_EQUAL_INT(-1, ekf_cov_ensure_pd(P, 3, EKF_C(1), floor, work));
        TEST_ASSERT_EQUAL_INT(-1, ekf_cov_ensure_pd(P, 0, margin, floor, work));
        TEST_ASSERT_EQUAL_INT(-1, ekf_cov_ensure_pd(NULL, 3, margin, floor, work));
        /* a zero margin: terminates with a positive definite P */
        P[1] = P[3] = EKF_C(2);
        TEST_ASSERT_TRUE(ekf_cov_ensure_pd(P, 3, EKF_C(0), floor, work) > 0);
        TEST_ASSERT_EQUAL_INT(1, ekf_cov_is_pd(P, 3, EKF_C(0), work));
        /* variances near the top of the range, correlation 1 (singular): the loading
         * overflows before it helps, the fallback keeps the (finite) variances */
        for (i = 0; i < 9; ++i) {
            P[i] = EKF_C(0);
        }
        P[0] = P[4] = P[8] = (ekf_scalar_t)1e308;
#if defined(EKF_SCALAR_FLOAT)
        P[0] = P[4] = P[8] = (ekf_scalar_t)3e38;
#endif
        P[1] = P[3] = P[0];
        TEST_ASSERT_TRUE(ekf_cov_ensure_pd(P, 3, margin, floor, work) > 0);
        TEST_ASSERT_TRUE(ekf_all_finite(P, 9));
        TEST_ASSERT_EQUAL_INT(1, ekf_cov_is_pd(P, 3, margin, work));
    }
}

static void test_limit_variance_is_a_congruence(void)
{
    ts_rng_t r;
    double Pd[36];
    ekf_scalar_t P[36];
    int i;
    ts_rng_seed(&r, 13);
    random_spd(&r, 6, Pd, P);
    TEST_ASSERT_EQUAL_INT(0, ekf_cov_limit_variance(P, 6, 2, EKF_C(1e9)));
    TEST_ASSERT_EQUAL_INT(1, ekf_cov_limit_variance(P, 6, 2, EKF_C(0.01)));
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 0.01, (float)P[2 * 6 + 2]);
    TEST_ASSERT_TRUE(ts_is_symmetric_exact(P, 6));
    TEST_ASSERT_TRUE(ts_is_positive_definite(P, 6, NULL));
    /* correlation coefficients are preserved */
    for (i = 0; i < 6; ++i) {
        if (i != 2) {
            const double rho0 = Pd[2 * 6 + i] / sqrt(Pd[2 * 6 + 2] * Pd[i * 6 + i]);
            const double rho1 = (double)P[2 * 6 + i] / sqrt((double)P[2 * 6 + 2] * (double)P[i * 6 + i]);
            TEST_ASSERT_TRUE(fabs(rho0 - rho1) < 1e-5);
        }
    }
}

static void test_wrap_pi(void)
{
    static const double cases[] = {0.0, 1.0, -1.0, 3.2, -3.2, 6.3, -6.3, 100.0, -100.0, 12345.678, 3.14159, -3.14159};
    size_t i;
    for (i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        const ekf_scalar_t w = ekf_wrap_pi((ekf_scalar_t)cases[i]);
        const double back = remainder(cases[i] - (double)w, 6.283185307179586);
        TEST_ASSERT_TRUE(w >= -EKF_PI && w < EKF_PI);
        TEST_ASSERT_TRUE(fabs(back) < (fabs(cases[i]) + 1.0) * 1e-6);
    }
    /* any finite input gives an angle in range */
    TEST_ASSERT_TRUE(ekf_wrap_pi(EKF_C(1e30)) >= -EKF_PI && ekf_wrap_pi(EKF_C(1e30)) < EKF_PI);
    TEST_ASSERT_TRUE(ekf_wrap_pi(EKF_C(-3e25)) >= -EKF_PI && ekf_wrap_pi(EKF_C(-3e25)) < EKF_PI);
}

static void test_status_names(void)
{
    int s;
    for (s = EKF_OK; s <= EKF_SKIPPED; ++s) {
        const char *name = ekf_status_str((ekf_status_t)s);
        TEST_ASSERT_NOT_NULL(name);
        TEST_ASSERT_EQUAL_INT(0, strncmp(name, "EKF_", 4));
        TEST_ASSERT_TRUE(strcmp(name, "EKF_STATUS_UNKNOWN") != 0);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cov_propagate_matches_dense);
    RUN_TEST(test_cov_propagate_refusals_leave_P_unchanged);
    RUN_TEST(test_update_matches_textbook);
    RUN_TEST(test_update_gate_and_refusals);
    RUN_TEST(test_update_diagonal_floor);
    RUN_TEST(test_update_refuses_indefinite_covariance);
    RUN_TEST(test_update_floors_rounding_size_variances);
    RUN_TEST(test_update_info_always_written);
    RUN_TEST(test_ensure_pd_repairs_or_refuses);
    RUN_TEST(test_limit_variance_is_a_congruence);
    RUN_TEST(test_wrap_pi);
    RUN_TEST(test_status_names);
    return UNITY_END();
}
