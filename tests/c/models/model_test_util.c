/*
 * model_test_util.c - see model_test_util.h.
 */
#include "model_test_util.h"

#include <math.h>
#include <string.h>

double mt_wrap_pi(double a)
{
    return a - 2.0 * MT_PI * floor((a + MT_PI) / (2.0 * MT_PI));
}

void mt_matmul(const double *A, const double *B, double *C, int n, int m, int p)
{
    int i, j, k;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < p; ++j) {
            double acc = 0.0;
            for (k = 0; k < m; ++k) {
                acc += A[i * m + k] * B[k * p + j];
            }
            C[i * p + j] = acc;
        }
    }
}

void mt_transpose(const double *A, double *B, int n, int m)
{
    int i, j;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < m; ++j) {
            B[j * n + i] = A[i * m + j];
        }
    }
}

int mt_inverse(double *A, int n)
{
    double M[MT_MAX * 2 * MT_MAX];
    const int w = 2 * n;
    int i, j, k;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            M[i * w + j] = A[i * n + j];
            M[i * w + n + j] = (i == j) ? 1.0 : 0.0;
        }
    }
    for (k = 0; k < n; ++k) {
        int piv = k;
        double best = fabs(M[k * w + k]), inv;
        for (i = k + 1; i < n; ++i) {
            if (fabs(M[i * w + k]) > best) {
                best = fabs(M[i * w + k]);
                piv = i;
            }
        }
        if (!(best > 0.0)) {
            return 0;
        }
        if (piv != k) {
            for (j = 0; j < w; ++j) {
                const double t = M[k * w + j];
                M[k * w + j] = M[piv * w + j];
                M[piv * w + j] = t;
            }
        }
        inv = 1.0 / M[k * w + k];
        for (j = 0; j < w; ++j) {
            M[k * w + j] *= inv;
        }
        for (i = 0; i < n; ++i) {
            if (i != k) {
                const double fac = M[i * w + k];
                for (j = 0; j < w; ++j) {
                    M[i * w + j] -= fac * M[k * w + j];
                }
            }
        }
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            A[i * n + j] = M[i * w + n + j];
        }
    }
    return 1;
}

void mt_propagate(double *P, const double *F, const double *Q, int n)
{
    /* zero-initialised only to keep gcc -O2's -Wmaybe-uninitialized quiet */
    double FP[MT_MAX * MT_MAX] = {0}, Ft[MT_MAX * MT_MAX] = {0};
    int i;
    mt_matmul(F, P, FP, n, n, n);
    mt_transpose(F, Ft, n, n);
    mt_matmul(FP, Ft, P, n, n, n);
    if (Q != NULL) {
        for (i = 0; i < n * n; ++i) {
            P[i] += Q[i];
        }
    }
}

int mt_ekf_update(double *x, double *P, int n, const double *H, const double *nu, const double *r_var, int m)
{
    /* zero-initialised only to keep gcc -O2's -Wmaybe-uninitialized quiet */
    double Ht[MT_MAX * 4] = {0}, PHt[MT_MAX * 4] = {0}, S[16] = {0}, K[MT_MAX * 4] = {0};
    double IKH[MT_MAX * MT_MAX] = {0}, T1[MT_MAX * MT_MAX] = {0}, T2[MT_MAX * MT_MAX] = {0};
    double IKHt[MT_MAX * MT_MAX] = {0};
    int i, j, k;
    mt_transpose(H, Ht, m, n);
    mt_matmul(P, Ht, PHt, n, n, m);
    mt_matmul(H, PHt, S, m, n, m);
    for (i = 0; i < m; ++i) {
        S[i * m + i] += r_var[i];
    }
    if (!mt_inverse(S, m)) {
        return 0;
    }
    mt_matmul(PHt, S, K, n, m, m);
    for (i = 0; i < n; ++i) {
        for (k = 0; k < m; ++k) {
            x[i] += K[i * m + k] * nu[k];
        }
    }
    mt_matmul(K, H, IKH, n, m, n);
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            IKH[i * n + j] = ((i == j) ? 1.0 : 0.0) - IKH[i * n + j];
        }
    }
    mt_matmul(IKH, P, T1, n, n, n);
    mt_transpose(IKH, IKHt, n, n);
    mt_matmul(T1, IKHt, T2, n, n, n);
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            double krk = 0.0;
            for (k = 0; k < m; ++k) {
                krk += K[i * m + k] * r_var[k] * K[j * m + k];
            }
            P[i * n + j] = T2[i * n + j] + krk;
        }
    }
    return 1;
}

double mt_max_rel_diff(const double *a, const double *b, int len)
{
    double worst = 0.0;
    int i;
    for (i = 0; i < len; ++i) {
        const double scale = fabs(b[i]) > 1.0 ? fabs(b[i]) : 1.0;
        const double e = fabs(a[i] - b[i]) / scale;
        if (e > worst || e != e) {
            worst = (e != e) ? HUGE_VAL : e;
        }
    }
    return worst;
}

void mt_to_double(const ekf_scalar_t *a, double *b, int len)
{
    int i;
    for (i = 0; i < len; ++i) {
        b[i] = (double)a[i];
    }
}

void mt_from_double(const double *a, ekf_scalar_t *b, int len)
{
    int i;
    for (i = 0; i < len; ++i) {
        b[i] = (ekf_scalar_t)a[i];
    }
}

double mt_chi2_quantile(double k, double z)
{
    const double c = 2.0 / (9.0 * k);
    const double t = 1.0 - c + z * sqrt(c);
    return k * t * t * t;
}

int mt_same_bits(const void *a, const void *b, unsigned long bytes)
{
    return memcmp(a, b, bytes) == 0;
}
