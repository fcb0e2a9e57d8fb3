/*
 * att_fixture.c - see att_fixture.h.
 */
#include "att_fixture.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att_cov.h"
#include "testsim.h"
#include "unity.h"

double af_eps(void)
{
#if defined(EKF_SCALAR_FIXED)
    return ldexp(1.0, -27);
#else
    return ekf_to_double(EKF_SCALAR_EPS);
#endif
}

double af_ulp(double scale)
{
#if defined(EKF_SCALAR_FIXED)
    return af_eps() * fabs(scale) + ldexp(1.0, -34);
#else
    return af_eps() * fabs(scale);
#endif
}

static double g_worst;
static char g_worst_what[80];

void af_print_worst(void)
{
    printf("largest |error| / tolerance: %.3g (%s)\n", g_worst, g_worst_what);
}

void af_near(double want, double got, double tol, const char *what, int line)
{
    char msg[160];
    const double ratio = (tol > 0.0) ? fabs(got - want) / tol : (got == want) ? 0.0 : (double)INFINITY;
    if (ratio > g_worst) {
        g_worst = ratio;
        snprintf(g_worst_what, sizeof g_worst_what, "line %d: %s", line, what);
    }
    if (fabs(got - want) <= tol) {
        return;
    }
    snprintf(msg, sizeof msg, "line %d: %s = %.17g, want %.17g within %.3g (off by %.3g)", line, what, got, want,
             tol, got - want);
    TEST_FAIL_MESSAGE(msg);
}

void af_to_body(double phi, double theta, double psi, const double v_enu[3], ekf_scalar_t out[3])
{
    double R[9];
    int i;
    ts_euler_to_R(phi, theta, psi, R);
    for (i = 0; i < 3; ++i) {
        out[i] = ekf_from_double(R[i] * v_enu[0] + R[3 + i] * v_enu[1] + R[6 + i] * v_enu[2]);
    }
}

void af_gravity_body(double g, double phi, double theta, ekf_scalar_t out[3])
{
    const double up[3] = {0.0, 0.0, g};
    af_to_body(phi, theta, 0.0, up, out);
}

void af_field_body(double bh, double bv, double decl, double phi, double theta, double psi, ekf_scalar_t out[3])
{
    const double m[3] = {bh * sin(decl), bh * cos(decl), -bv};
    af_to_body(phi, theta, psi, m, out);
}

void af_rotation(const double u[3], double C[9])
{
    const double th = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    const double a = (th > 0.0) ? sin(th) / th : 1.0;
    const double b = (th > 0.0) ? (1.0 - cos(th)) / (th * th) : 0.5;
    const double U[9] = {0.0, -u[2], u[1], u[2], 0.0, -u[0], -u[1], u[0], 0.0};
    int i, j, k;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            double u2 = 0.0;
            for (k = 0; k < 3; ++k) {
                u2 += U[3 * i + k] * U[3 * k + j];
            }
            C[3 * i + j] = ((i == j) ? 1.0 : 0.0) + a * U[3 * i + j] + b * u2;
        }
    }
}

void af_vars_full(att_vars_t *v, const att_settings_t *s, const double x[ATT_N], const double P[ATT_N * ATT_N])
{
    static att_ekf_t f;
    ekf_scalar_t Ps[ATT_N * ATT_N];
    int i;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, s));
    *v = f.vars;
    for (i = 0; i < ATT_N; ++i) {
        v->x[i] = ekf_from_double(x[i]);
    }
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        Ps[i] = ekf_from_double(P[i]);
    }
    att_cov_from_full(&v->cov, Ps);
    v->flags = ATT_FLAG_ALIGNED;
}

void af_vars(att_vars_t *v, const att_settings_t *s, const double x[ATT_N], const double var[ATT_N])
{
    double P[ATT_N * ATT_N];
    int i;
    memset(P, 0, sizeof P);
    for (i = 0; i < ATT_N; ++i) {
        P[i * (ATT_N + 1)] = var[i];
    }
    af_vars_full(v, s, x, P);
}

void af_random_cov(uint64_t seed, const double var[ATT_N], double P[ATT_N * ATT_N])
{
    double B[ATT_N * ATT_N], M[ATT_N * ATT_N];
    ts_rng_t rng;
    int i, j, k;
    ts_rng_seed(&rng, seed);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        B[i] = ts_uniform_in(&rng, -1.0, 1.0);
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            double a = (i == j) ? 9.0 : 0.0;
            for (k = 0; k < ATT_N; ++k) {
                a += B[i * ATT_N + k] * B[j * ATT_N + k];
            }
            M[i * ATT_N + j] = a;
        }
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            P[i * ATT_N + j] = M[i * ATT_N + j] / sqrt(M[i * ATT_N + i] * M[j * ATT_N + j]) * sqrt(var[i] * var[j]);
        }
    }
}

void af_cov(const att_vars_t *v, double P[ATT_N * ATT_N])
{
    ekf_scalar_t Ps[ATT_N * ATT_N];
    int i;
    att_cov_to_full(&v->cov, Ps);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        P[i] = ekf_to_double(Ps[i]);
    }
}

void af_batch_update(double x[ATT_N], double P[ATT_N * ATT_N], const double *H, const double *nu, const double *r,
                     int m)
{
    double PHt[ATT_N * 3], S[9], Si[9], K[ATT_N * 3], KHP[ATT_N * ATT_N];
    int i, j, k;
    TEST_ASSERT_TRUE(m >= 1 && m <= 3);
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < m; ++j) {
            double a = 0.0;
            for (k = 0; k < ATT_N; ++k) {
                a += P[i * ATT_N + k] * H[j * ATT_N + k];
            }
            PHt[i * 3 + j] = a;
        }
    }
    for (i = 0; i < m; ++i) {
        for (j = 0; j < m; ++j) {
            double a = (i == j) ? r[i] : 0.0;
            for (k = 0; k < ATT_N; ++k) {
                a += H[i * ATT_N + k] * PHt[k * 3 + j];
            }
            S[i * 3 + j] = a;
        }
    }
    /* S^-1 by Gauss-Jordan elimination (S is symmetric positive definite: no pivoting) */
    for (i = 0; i < 9; ++i) {
        Si[i] = (i % 4 == 0) ? 1.0 : 0.0;
    }
    for (k = 0; k < m; ++k) {
        const double d = S[k * 3 + k];
        for (j = 0; j < m; ++j) {
            S[k * 3 + j] /= d;
            Si[k * 3 + j] /= d;
        }
        for (i = 0; i < m; ++i) {
            if (i != k) {
                const double f = S[i * 3 + k];
                for (j = 0; j < m; ++j) {
                    S[i * 3 + j] -= f * S[k * 3 + j];
                    Si[i * 3 + j] -= f * Si[k * 3 + j];
                }
            }
        }
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < m; ++j) {
            double a = 0.0;
            for (k = 0; k < m; ++k) {
                a += PHt[i * 3 + k] * Si[k * 3 + j];
            }
            K[i * 3 + j] = a;
        }
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < m; ++j) {
            x[i] += K[i * 3 + j] * nu[j];
        }
        for (j = 0; j < ATT_N; ++j) {
            double a = 0.0;
            for (k = 0; k < m; ++k) {
                a += K[i * 3 + k] * PHt[j * 3 + k]; /* (H P)_kj = (P H^T)_jk */
            }
            KHP[i * ATT_N + j] = a;
        }
    }
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        P[i] -= KHP[i];
    }
}

void af_cov_near(const att_vars_t *v, const double want[ATT_N * ATT_N], double tol, int line)
{
    double P[ATT_N * ATT_N];
    char what[32];
    int i;
    af_cov(v, P);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        snprintf(what, sizeof what, "P[%d][%d]", i / ATT_N, i % ATT_N);
        af_near(want[i], P[i], tol, what, line);
    }
}
