/*
 * rts.c - see rts.h.
 */
#include "rts.h"

#include <math.h>
#include <string.h>

int rts_cholesky(size_t m, const double *A, double *L)
{
    size_t i, j, k;
    for (j = 0; j < m; ++j) {
        double d = A[j * m + j];
        for (k = 0; k < j; ++k) {
            d -= L[j * m + k] * L[j * m + k];
        }
        if (!(d > 0.0) || !isfinite(d)) {
            return 0;
        }
        d = sqrt(d);
        L[j * m + j] = d;
        for (i = j + 1; i < m; ++i) {
            double s = A[i * m + j];
            for (k = 0; k < j; ++k) {
                s -= L[i * m + k] * L[j * m + k];
            }
            L[i * m + j] = s / d;
        }
        for (i = 0; i < j; ++i) {
            L[i * m + j] = 0.0;
        }
    }
    return 1;
}

void rts_cholesky_solve(size_t m, const double *L, size_t k, const double *B, double *Y)
{
    size_t i, j, c;
    if (Y != B) {
        memcpy(Y, B, sizeof(double) * m * k);
    }
    /* L Z = B, then L^T Y = Z, each column c at once */
    for (i = 0; i < m; ++i) {
        const double inv = 1.0 / L[i * m + i];
        for (j = 0; j < i; ++j) {
            const double l = L[i * m + j];
            for (c = 0; c < k; ++c) {
                Y[i * k + c] -= l * Y[j * k + c];
            }
        }
        for (c = 0; c < k; ++c) {
            Y[i * k + c] *= inv;
        }
    }
    for (i = m; i-- > 0;) {
        const double inv = 1.0 / L[i * m + i];
        for (j = i + 1; j < m; ++j) {
            const double l = L[j * m + i];
            for (c = 0; c < k; ++c) {
                Y[i * k + c] -= l * Y[j * k + c];
            }
        }
        for (c = 0; c < k; ++c) {
            Y[i * k + c] *= inv;
        }
    }
}

/* x_s = x_f, P_s = P_f: nothing crosses the step. */
static void keep_filtered(size_t n, const double *x_f, const double *P_f, double *x_s, double *P_s)
{
    memcpy(x_s, x_f, sizeof(double) * n);
    memcpy(P_s, P_f, sizeof(double) * n * n);
}

rts_status_t rts_step(size_t n, const double *x_f, const double *P_f, const double *F, const double *P_pred,
                      const double *dx, const double *P_s1, unsigned cut, double *x_s, double *P_s)
{
    size_t idx[RTS_NMAX];
    double S[RTS_NMAX * RTS_NMAX], L[RTS_NMAX * RTS_NMAX], Y[RTS_NMAX * RTS_NMAX], T[RTS_NMAX * RTS_NMAX];
    size_t m = 0, a, b, i, j, l;
    if (n == 0 || n > RTS_NMAX) {
        return RTS_ERR_DIMENSION;
    }
    for (i = 0; i < n; ++i) {
        if ((cut & (1u << i)) == 0u) {
            idx[m++] = i;
        }
    }
    if (m == 0) {
        keep_filtered(n, x_f, P_f, x_s, P_s);
        return RTS_OK;
    }
    /* the kept block of P_pred, and Y = (F P_f) on its rows: P_pred Y = F P_f solved below */
    for (a = 0; a < m; ++a) {
        const double *frow = &F[idx[a] * n];
        for (b = 0; b < m; ++b) {
            S[a * m + b] = P_pred[idx[a] * n + idx[b]];
        }
        for (j = 0; j < n; ++j) {
            Y[a * n + j] = 0.0;
        }
        for (l = 0; l < n; ++l) {
            const double f = frow[l];
            if (f != 0.0) {
                const double *prow = &P_f[l * n];
                for (j = 0; j < n; ++j) {
                    Y[a * n + j] += f * prow[j];
                }
            }
        }
    }
    if (!rts_cholesky(m, S, L)) {
        keep_filtered(n, x_f, P_f, x_s, P_s);
        return RTS_ERR_NOT_PD;
    }
    rts_cholesky_solve(m, L, n, Y, Y); /* Y = P_pred^-1 F P_f (kept rows): C = Y^T */
    /* x_s = x_f + C dx */
    for (j = 0; j < n; ++j) {
        double s = x_f[j];
        for (a = 0; a < m; ++a) {
            s += Y[a * n + j] * dx[idx[a]];
        }
        x_s[j] = s;
    }
    /* P_s = P_f + Y^T D Y with D = P_s1 - P_pred (kept block): T = D Y first */
    for (a = 0; a < m; ++a) {
        for (j = 0; j < n; ++j) {
            T[a * n + j] = 0.0;
        }
        for (b = 0; b < m; ++b) {
            const double d = P_s1[idx[a] * n + idx[b]] - P_pred[idx[a] * n + idx[b]];
            for (j = 0; j < n; ++j) {
                T[a * n + j] += d * Y[b * n + j];
            }
        }
    }
    for (i = 0; i < n; ++i) {
        for (j = i; j < n; ++j) {
            double s = P_f[i * n + j];
            for (a = 0; a < m; ++a) {
                s += Y[a * n + i] * T[a * n + j];
            }
            P_s[i * n + j] = s;
            P_s[j * n + i] = s;
        }
    }
    return RTS_OK;
}
