/*
 * rts.c - see rts.h.
 *
 * Every routine is written once for a size n and instantiated twice: for any n, and for the
 * attitude filter's 9 states, where the constant bounds let the compiler unroll and vectorise
 * the loops (the backward step is most of the smoother's cost beyond the filter's).
 */
#include "rts.h"

#include <math.h>
#include <string.h>

#define RTS_N9 9

static inline int chol_n(const size_t m, const double *A, double *L)
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

/* L L^T Y = Y in place, k columns: L Z = Y, then L^T Y = Z, each column at once. */
static inline void solve_n(const size_t m, const double *L, const size_t k, double *Y)
{
    size_t i, j, c;
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

int rts_cholesky(size_t m, const double *A, double *L) { return chol_n(m, A, L); }

void rts_cholesky_solve(size_t m, const double *L, size_t k, const double *B, double *Y)
{
    if (Y != B) {
        memcpy(Y, B, sizeof(double) * m * k);
    }
    solve_n(m, L, k, Y);
}

/* A gain that cuts every state: nothing crosses the step. */
static void cut_all(size_t n, rts_gain_t *g)
{
    g->n = n;
    g->cut = (1u << n) - 1u;
    g->factored = g->cut;
    memset(g->Y, 0, sizeof g->Y);
    memset(g->L, 0, sizeof g->L);
}

static inline rts_status_t gain_n(const size_t n, const double *P_f, const double *F, const double *P_pred,
                                  unsigned cut, rts_gain_t *g)
{
    double S[RTS_NMAX * RTS_NMAX];
    double *Y = g->Y;
    size_t i, j, l;
    g->n = n;
    g->cut = cut;
    g->factored = cut;
    for (i = 0; i < n; ++i) {
        const unsigned cut_i = (cut >> i) & 1u;
        for (j = 0; j < n; ++j) {
            S[i * n + j] = (cut_i != 0u || ((cut >> j) & 1u) != 0u) ? (i == j ? 1.0 : 0.0) : P_pred[i * n + j];
            Y[i * n + j] = 0.0;
        }
        if (cut_i != 0u) {
            continue;
        }
        /* Y = F P_f on the kept rows (F is sparse: its zeros skipped) */
        for (l = 0; l < n; ++l) {
            const double f = F[i * n + l];
            if (f != 0.0) {
                for (j = 0; j < n; ++j) {
                    Y[i * n + j] += f * P_f[l * n + j];
                }
            }
        }
    }
    if (!chol_n(n, S, g->L)) {
        cut_all(n, g);
        return RTS_ERR_NOT_PD;
    }
    solve_n(n, g->L, n, Y); /* Y = P_pred^-1 F P_f on the kept rows: C = Y^T */
    return RTS_OK;
}

static inline void apply_n(const size_t n, const rts_gain_t *g, const double *x_f, const double *P_f,
                           const double *P_pred, const double *dx, const double *P_s1, double *x_s, double *P_s)
{
    double T[RTS_NMAX * RTS_NMAX];
    const double *Y = g->Y;
    size_t i, j, l;
    /* x_s = x_f + C dx (Y's cut rows are zero, and so is their dx here) */
    for (j = 0; j < n; ++j) {
        x_s[j] = x_f[j];
    }
    for (i = 0; i < n; ++i) {
        const double d = ((g->cut >> i) & 1u) != 0u ? 0.0 : dx[i];
        for (j = 0; j < n; ++j) {
            x_s[j] += Y[i * n + j] * d;
        }
    }
    /* P_s = P_f + Y^T D Y with D = P_s1 - P_pred: T = D Y first */
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            T[i * n + j] = 0.0;
        }
        if (((g->cut >> i) & 1u) != 0u) {
            continue; /* Y^T's column i is zero: T's row i is never used */
        }
        for (l = 0; l < n; ++l) {
            const double d = P_s1[i * n + l] - P_pred[i * n + l];
            for (j = 0; j < n; ++j) {
                T[i * n + j] += d * Y[l * n + j];
            }
        }
    }
    for (i = 0; i < n; ++i) {
        for (j = i; j < n; ++j) {
            double s = P_f[i * n + j];
            for (l = 0; l < n; ++l) {
                s += Y[l * n + i] * T[l * n + j];
            }
            P_s[i * n + j] = s;
            P_s[j * n + i] = s;
        }
    }
}

static inline void gain_cut_n(const size_t n, const rts_gain_t *g, size_t k, rts_gain_t *out)
{
    double u[RTS_NMAX] = {0};
    size_t i, j;
    if (out != g) {
        *out = *g;
    }
    /* u = P^-1 e_k on the kept states (the cut ones are decoupled: their u is 0) */
    u[k] = 1.0;
    solve_n(n, g->L, 1, u);
    for (i = 0; i < n; ++i) {
        const double f = u[i] / u[k];
        if (i == k || f == 0.0) {
            continue;
        }
        for (j = 0; j < n; ++j) {
            out->Y[i * n + j] -= f * out->Y[k * n + j];
        }
    }
    for (j = 0; j < n; ++j) {
        out->Y[k * n + j] = 0.0;
    }
    out->cut |= 1u << k; /* L stays that of g's system (factored) */
}

rts_status_t rts_gain(size_t n, const double *P_f, const double *F, const double *P_pred, unsigned cut,
                      rts_gain_t *g)
{
    if (n == 0 || n > RTS_NMAX) {
        cut_all(RTS_NMAX, g);
        return RTS_ERR_ARGUMENT;
    }
    if ((cut & ((1u << n) - 1u)) == ((1u << n) - 1u)) {
        cut_all(n, g);
        return RTS_OK;
    }
    return (n == RTS_N9) ? gain_n(RTS_N9, P_f, F, P_pred, cut, g) : gain_n(n, P_f, F, P_pred, cut, g);
}

rts_status_t rts_gain_cut(const rts_gain_t *g, size_t i, rts_gain_t *out)
{
    if (i >= g->n || g->cut != g->factored) {
        return RTS_ERR_ARGUMENT;
    }
    if (((g->cut >> i) & 1u) != 0u) {
        if (out != g) {
            *out = *g;
        }
        return RTS_OK;
    }
    if (g->n == RTS_N9) {
        gain_cut_n(RTS_N9, g, i, out);
    } else {
        gain_cut_n(g->n, g, i, out);
    }
    return RTS_OK;
}

void rts_apply(const rts_gain_t *g, const double *x_f, const double *P_f, const double *P_pred, const double *dx,
               const double *P_s1, double *x_s, double *P_s)
{
    if (g->n == RTS_N9) {
        apply_n(RTS_N9, g, x_f, P_f, P_pred, dx, P_s1, x_s, P_s);
    } else {
        apply_n(g->n, g, x_f, P_f, P_pred, dx, P_s1, x_s, P_s);
    }
}

rts_status_t rts_step(size_t n, const double *x_f, const double *P_f, const double *F, const double *P_pred,
                      const double *dx, const double *P_s1, unsigned cut, double *x_s, double *P_s)
{
    rts_gain_t g;
    const rts_status_t st = rts_gain(n, P_f, F, P_pred, cut, &g);
    if (st == RTS_ERR_ARGUMENT) {
        return st;
    }
    rts_apply(&g, x_f, P_f, P_pred, dx, P_s1, x_s, P_s);
    return st;
}
