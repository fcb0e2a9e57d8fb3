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
    RUN_TEST(test_limit_variance_is_a_congruence);
    RUN_TEST(test_wrap_pi);
    RUN_TEST(test_status_names);
    return UNITY_END();
}
