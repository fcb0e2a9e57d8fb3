/*
 * rts.c - see rts.h.
 *
 * Every routine is written once for a size n and instantiated twice: for any n, and for the
 * attitude filter's 9 states, where constant bounds let the compiler unroll and vectorise the
 * loops (the backward step is most of the smoother's cost beyond the filter's). The working
 * matrices have rows of an even length ld (n, rounded up; the padding column is zero) so that
 * every inner loop runs over whole pairs of doubles.
 */
#include "rts.h"

#include <math.h>
#include <string.h>

#define RTS_N9 9
#define LD9 RTS_LD(RTS_N9)

/* L L^T = A (A and L m x m with row stride ld; L lower, its upper part zero). */
static inline int chol_n(const size_t m, const size_t ld, const double *A, double *L)
{
    size_t i, j, k;
    for (j = 0; j < m; ++j) {
        double d = A[j * ld + j];
        for (k = 0; k < j; ++k) {
            d -= L[j * ld + k] * L[j * ld + k];
        }
        if (!(d > 0.0) || !isfinite(d)) {
            return 0;
        }
        d = sqrt(d);
        L[j * ld + j] = d;
        d = 1.0 / d; /* one division per column */
        for (i = j + 1; i < m; ++i) {
            double s = A[i * ld + j];
            for (k = 0; k < j; ++k) {
                s -= L[i * ld + k] * L[j * ld + k];
            }
            L[i * ld + j] = s * d;
        }
        for (i = 0; i < j; ++i) {
            L[i * ld + j] = 0.0;
        }
    }
    return 1;
}

/* L L^T Y = Y in place (L m x m with row stride ld; Y m rows of k columns): L Z = Y, then
 * L^T Y = Z, every column at once. */
static inline void solve_n(const size_t m, const size_t ld, const double *L, const size_t k, double *Y)
{
    size_t i, j, c;
    for (i = 0; i < m; ++i) {
        const double inv = 1.0 / L[i * ld + i];
        for (j = 0; j < i; ++j) {
            const double l = L[i * ld + j];
            for (c = 0; c < k; ++c) {
                Y[i * k + c] -= l * Y[j * k + c];
            }
        }
        for (c = 0; c < k; ++c) {
            Y[i * k + c] *= inv;
        }
    }
    for (i = m; i-- > 0;) {
        const double inv = 1.0 / L[i * ld + i];
        for (j = i + 1; j < m; ++j) {
            const double l = L[j * ld + i];
            for (c = 0; c < k; ++c) {
                Y[i * k + c] -= l * Y[j * k + c];
            }
        }
        for (c = 0; c < k; ++c) {
            Y[i * k + c] *= inv;
        }
    }
}

int rts_cholesky(size_t m, const double *A, double *L) { return chol_n(m, m, A, L); }

void rts_cholesky_solve(size_t m, const double *L, size_t k, const double *B, double *Y)
{
    if (Y != B) {
        memcpy(Y, B, sizeof(double) * m * k);
    }
    solve_n(m, m, L, k, Y);
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

static inline rts_status_t gain_n(const size_t n, const size_t ld, const double *P_f, const double *F,
                                  const double *P_pred, unsigned cut, rts_gain_t *g)
{
    double S[RTS_NMAX * RTS_NMAX], Pf[RTS_NMAX * RTS_NMAX];
    double *Y = g->Y;
    size_t i, j, l;
    g->n = n;
    g->cut = cut;
    g->factored = cut;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < ld; ++j) {
            S[i * ld + j] = (j < n) ? P_pred[i * n + j] : 0.0;
            Pf[i * ld + j] = (j < n) ? P_f[i * n + j] : 0.0;
        }
    }
    /* Y = F P_f (row i: P_f's rows weighted by F's row i) */
    for (i = 0; i < n; ++i) {
        for (j = 0; j < ld; ++j) {
            Y[i * ld + j] = 0.0;
        }
        for (l = 0; l < n; ++l) {
            const double f = F[i * n + l];
            if (f == 0.0) {
                continue; /* F is sparse (its zeros are the same in every step: predicted well) */
            }
            for (j = 0; j < ld; ++j) {
                Y[i * ld + j] += f * Pf[l * ld + j];
            }
        }
    }
    if (cut != 0u) {
        /* a cut state's row and column of P_pred become the identity's, its row of F P_f zero:
         * the system is then block diagonal, and Y's kept rows solve the kept block */
        for (i = 0; i < n; ++i) {
            if (((cut >> i) & 1u) == 0u) {
                continue;
            }
            for (j = 0; j < n; ++j) {
                S[i * ld + j] = S[j * ld + i] = 0.0;
            }
            for (j = 0; j < ld; ++j) {
                Y[i * ld + j] = 0.0;
            }
            S[i * ld + i] = 1.0;
        }
    }
    if (!chol_n(n, ld, S, g->L)) {
        cut_all(n, g);
        return RTS_ERR_NOT_PD;
    }
    solve_n(n, ld, g->L, ld, Y); /* Y = P_pred^-1 F P_f on the kept rows: C = Y^T */
    return RTS_OK;
}

static inline void apply_n(const size_t n, const size_t ld, const rts_gain_t *g, const double *x_f,
                           const double *P_f, const double *P_pred, const double *dx, const double *P_s1, double *x_s,
                           double *P_s)
{
    double D[RTS_NMAX * RTS_NMAX], T[RTS_NMAX * RTS_NMAX], M[RTS_NMAX * RTS_NMAX], xs[RTS_NMAX];
    const double *Y = g->Y;
    size_t i, j, l;
    /* x_s = x_f + C dx (Y's cut rows are zero, and so is their dx here) */
    for (j = 0; j < ld; ++j) {
        xs[j] = 0.0;
    }
    for (i = 0; i < n; ++i) {
        const double d = ((g->cut >> i) & 1u) != 0u ? 0.0 : dx[i];
        for (j = 0; j < ld; ++j) {
            xs[j] += Y[i * ld + j] * d;
        }
    }
    for (j = 0; j < n; ++j) {
        x_s[j] = x_f[j] + xs[j];
    }
    /* P_s = P_f + Y^T D Y with D = P_s1 - P_pred: T = D Y, then M = Y^T T as a sum of outer
     * products of their rows, its upper triangle mirrored */
    for (i = 0; i < n; ++i) {
        for (j = 0; j < ld; ++j) {
            D[i * ld + j] = (j < n) ? P_s1[i * n + j] - P_pred[i * n + j] : 0.0;
            T[i * ld + j] = 0.0;
            M[i * ld + j] = 0.0;
        }
    }
    for (i = 0; i < n; ++i) {
        if (((g->cut >> i) & 1u) != 0u) {
            continue; /* Y's row i is zero: T's row i is never used */
        }
        for (l = 0; l < n; ++l) {
            const double d = D[i * ld + l];
            for (j = 0; j < ld; ++j) {
                T[i * ld + j] += d * Y[l * ld + j];
            }
        }
    }
    for (l = 0; l < n; ++l) {
        for (i = 0; i < n; ++i) {
            const double y = Y[l * ld + i];
            for (j = 0; j < ld; ++j) {
                M[i * ld + j] += y * T[l * ld + j];
            }
        }
    }
    for (i = 0; i < n; ++i) {
        for (j = i; j < n; ++j) {
            P_s[i * n + j] = P_s[j * n + i] = P_f[i * n + j] + M[i * ld + j];
        }
    }
}

#if defined(__GNUC__) && defined(__SSE2__)
/* The 9-state step on pairs of doubles (the compiler's vector extension, SSE2 on x86-64): a
 * row of 9 is 5 pairs, the last padded with 0. The same operations as gain_n and apply_n, in
 * the same order per entry; elsewhere those serve for 9 states too. */
#define RTS_PAIRS 5
typedef double rts_v2 __attribute__((vector_size(16)));

/* Rows of a row-major 9 x 9 matrix as pairs. */
static void pairs_of(const double *A, rts_v2 out[RTS_N9][RTS_PAIRS])
{
    size_t i, p;
    for (i = 0; i < RTS_N9; ++i) {
        for (p = 0; p + 1 < RTS_PAIRS; ++p) {
            const rts_v2 v = {A[i * RTS_N9 + 2 * p], A[i * RTS_N9 + 2 * p + 1]};
            out[i][p] = v;
        }
        {
            const rts_v2 v = {A[i * RTS_N9 + 8], 0.0};
            out[i][RTS_PAIRS - 1] = v;
        }
    }
}

/* Rows of stride LD9 (a gain's Y) as pairs, and back. */
static void pairs_of_ld(const double *A, rts_v2 out[RTS_N9][RTS_PAIRS])
{
    size_t i, p;
    for (i = 0; i < RTS_N9; ++i) {
        for (p = 0; p < RTS_PAIRS; ++p) {
            const rts_v2 v = {A[i * LD9 + 2 * p], A[i * LD9 + 2 * p + 1]};
            out[i][p] = v;
        }
    }
}

static void ld_of_pairs(rts_v2 in[RTS_N9][RTS_PAIRS], double *A)
{
    size_t i, p;
    for (i = 0; i < RTS_N9; ++i) {
        for (p = 0; p < RTS_PAIRS; ++p) {
            A[i * LD9 + 2 * p] = in[i][p][0];
            A[i * LD9 + 2 * p + 1] = in[i][p][1];
        }
    }
}

static rts_status_t gain9(const double *P_f, const double *F, const double *P_pred, unsigned cut, rts_gain_t *g)
{
    rts_v2 Pf[RTS_N9][RTS_PAIRS], Y[RTS_N9][RTS_PAIRS];
    double S[LD9 * LD9];
    size_t i, j, l, p;
    g->n = RTS_N9;
    g->cut = cut;
    g->factored = cut;
    pairs_of(P_f, Pf);
    for (i = 0; i < RTS_N9; ++i) {
        for (j = 0; j < RTS_N9; ++j) {
            S[i * LD9 + j] = P_pred[i * RTS_N9 + j];
        }
        {
            rts_v2 acc[RTS_PAIRS] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
            for (l = 0; l < RTS_N9 && ((cut >> i) & 1u) == 0u; ++l) {
                const double f = F[i * RTS_N9 + l];
                if (f != 0.0) {
                    for (p = 0; p < RTS_PAIRS; ++p) {
                        acc[p] += f * Pf[l][p];
                    }
                }
            }
            for (p = 0; p < RTS_PAIRS; ++p) {
                Y[i][p] = acc[p];
            }
        }
    }
    for (i = 0; i < RTS_N9; ++i) {
        if (((cut >> i) & 1u) != 0u) {
            for (j = 0; j < RTS_N9; ++j) {
                S[i * LD9 + j] = S[j * LD9 + i] = 0.0;
            }
            S[i * LD9 + i] = 1.0;
        }
    }
    if (!chol_n(RTS_N9, LD9, S, g->L)) {
        cut_all(RTS_N9, g);
        return RTS_ERR_NOT_PD;
    }
    /* L L^T Y = Y: the rows of Y are the right-hand sides' entries */
    for (i = 0; i < RTS_N9; ++i) {
        const double inv = 1.0 / g->L[i * LD9 + i];
        for (j = 0; j < i; ++j) {
            const double l2 = g->L[i * LD9 + j];
            for (p = 0; p < RTS_PAIRS; ++p) {
                Y[i][p] -= l2 * Y[j][p];
            }
        }
        for (p = 0; p < RTS_PAIRS; ++p) {
            Y[i][p] *= inv;
        }
    }
    for (i = RTS_N9; i-- > 0;) {
        const double inv = 1.0 / g->L[i * LD9 + i];
        for (j = i + 1; j < RTS_N9; ++j) {
            const double l2 = g->L[j * LD9 + i];
            for (p = 0; p < RTS_PAIRS; ++p) {
                Y[i][p] -= l2 * Y[j][p];
            }
        }
        for (p = 0; p < RTS_PAIRS; ++p) {
            Y[i][p] *= inv;
        }
    }
    ld_of_pairs(Y, g->Y);
    return RTS_OK;
}

static void apply9(const rts_gain_t *g, const double *x_f, const double *P_f, const double *P_pred, const double *dx,
                   const double *P_s1, double *x_s, double *P_s)
{
    rts_v2 Y[RTS_N9][RTS_PAIRS], T[RTS_N9][RTS_PAIRS], M[RTS_N9][RTS_PAIRS];
    rts_v2 xs[RTS_PAIRS] = {{0.0, 0.0}};
    double m[LD9 * LD9], xd[LD9];
    size_t i, j, l, p;
    pairs_of_ld(g->Y, Y);
    for (i = 0; i < RTS_N9; ++i) {
        const double d = ((g->cut >> i) & 1u) != 0u ? 0.0 : dx[i];
        for (p = 0; p < RTS_PAIRS; ++p) {
            xs[p] += Y[i][p] * d;
        }
    }
    for (p = 0; p < RTS_PAIRS; ++p) {
        xd[2 * p] = xs[p][0];
        xd[2 * p + 1] = xs[p][1];
    }
    for (j = 0; j < RTS_N9; ++j) {
        x_s[j] = x_f[j] + xd[j];
    }
    /* T = D Y with D = P_s1 - P_pred, then M = Y^T T, a row at a time (its pairs accumulate in
     * registers); Y's cut rows are zero, so are T's */
    for (i = 0; i < RTS_N9; ++i) {
        rts_v2 acc[RTS_PAIRS] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
        if (((g->cut >> i) & 1u) == 0u) {
            for (l = 0; l < RTS_N9; ++l) {
                const double d = P_s1[i * RTS_N9 + l] - P_pred[i * RTS_N9 + l];
                for (p = 0; p < RTS_PAIRS; ++p) {
                    acc[p] += d * Y[l][p];
                }
            }
        }
        for (p = 0; p < RTS_PAIRS; ++p) {
            T[i][p] = acc[p];
        }
    }
    for (i = 0; i < RTS_N9; ++i) {
        rts_v2 acc[RTS_PAIRS] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
        for (l = 0; l < RTS_N9; ++l) {
            const double y = g->Y[l * LD9 + i];
            for (p = i / 2; p < RTS_PAIRS; ++p) { /* the pairs that hold row i's upper triangle */
                acc[p] += y * T[l][p];
            }
        }
        for (p = 0; p < RTS_PAIRS; ++p) {
            M[i][p] = acc[p];
        }
    }
    ld_of_pairs(M, m);
    for (i = 0; i < RTS_N9; ++i) {
        for (j = i; j < RTS_N9; ++j) {
            P_s[i * RTS_N9 + j] = P_s[j * RTS_N9 + i] = P_f[i * RTS_N9 + j] + m[i * LD9 + j];
        }
    }
}
#define RTS_HAVE_PAIRS 1
#endif

static inline void gain_cut_n(const size_t n, const size_t ld, const rts_gain_t *g, size_t k, rts_gain_t *out)
{
    double u[RTS_NMAX] = {0};
    size_t i, j;
    if (out != g) {
        *out = *g;
    }
    /* u = P^-1 e_k on the kept states (the cut ones are decoupled: their u is 0) */
    u[k] = 1.0;
    solve_n(n, ld, g->L, 1, u);
    for (i = 0; i < n; ++i) {
        const double f = u[i] / u[k];
        if (i == k || f == 0.0) {
            continue;
        }
        for (j = 0; j < ld; ++j) {
            out->Y[i * ld + j] -= f * out->Y[k * ld + j];
        }
    }
    for (j = 0; j < ld; ++j) {
        out->Y[k * ld + j] = 0.0;
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
#if defined(RTS_HAVE_PAIRS)
    if (n == RTS_N9) {
        return gain9(P_f, F, P_pred, cut, g);
    }
#endif
    return (n == RTS_N9) ? gain_n(RTS_N9, LD9, P_f, F, P_pred, cut, g)
                         : gain_n(n, RTS_LD(n), P_f, F, P_pred, cut, g);
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
        gain_cut_n(RTS_N9, LD9, g, i, out);
    } else {
        gain_cut_n(g->n, RTS_LD(g->n), g, i, out);
    }
    return RTS_OK;
}

void rts_apply(const rts_gain_t *g, const double *x_f, const double *P_f, const double *P_pred, const double *dx,
               const double *P_s1, double *x_s, double *P_s)
{
    if (g->n == RTS_N9) {
#if defined(RTS_HAVE_PAIRS)
        apply9(g, x_f, P_f, P_pred, dx, P_s1, x_s, P_s);
#else
        apply_n(RTS_N9, LD9, g, x_f, P_f, P_pred, dx, P_s1, x_s, P_s);
#endif
    } else {
        apply_n(g->n, RTS_LD(g->n), g, x_f, P_f, P_pred, dx, P_s1, x_s, P_s);
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
