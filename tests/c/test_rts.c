/*
 * test_rts.c - the Rauch-Tung-Striebel step of host_tools/native/rts.c against a brute-force
 * batch least-squares solution (docs/derivation.md, "Smoother", "Check").
 *
 * For a linear-Gaussian model the fixed-interval smoother is exact: the smoothed means are the
 * minimiser of the whole problem's weighted least squares, and the smoothed covariances the
 * diagonal blocks of the inverse of its information matrix. This file sets up short random
 * problems (random F, H, Q, R, prior; measurements drawn from the model), solves them twice:
 *   batch   every state of every epoch at once: the information matrix J (prior, dynamics
 *           and measurement terms) and vector g, J X = g solved by Gauss-Jordan elimination
 *           with partial pivoting, J^-1 for the covariances (nothing of rts.c is used);
 *   RTS     a Kalman filter written here (matrix gain, covariance (I - K H) P), then rts_step
 *           backwards,
 * and compares. A reset is checked the same way: the forward filter resets a component the
 * way the attitude filter resets its heading (the component set to a direct measurement of
 * it, its row and column of P cleared, its variance that measurement's), which is exactly
 * the limit of an unbounded jump of that component followed by that measurement; the batch
 * problem therefore leaves the component's dynamics out of that step (infinite process
 * noise) and adds the measurement, and rts_step cuts the component there.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "rts.h"
#include "testsim.h"
#include "unity.h"

/* Built twice (tests/c/CMakeLists.txt): 4 states, and the attitude filter's 9, for which rts.c
 * has its own instance of every routine. */
#ifndef RTS_TEST_STATES
#define RTS_TEST_STATES 4
#endif
#define NS RTS_TEST_STATES /* states */
#define NZ 3               /* measurements per epoch */
#define NE 12             /* epochs */
#define NB (NS * NE)      /* batch unknowns */

void setUp(void) {}
void tearDown(void) {}

typedef struct {
    double F[NE][NS * NS];  /* F[k]: epoch k -> k+1 (k < NE - 1) */
    double Q[NE][NS * NS];  /* process noise of that step (diagonal here) */
    double H[NE][NZ * NS];
    double R[NE][NZ];       /* measurement noise variances (diagonal) */
    double z[NE][NZ];
    double m0[NS], P0[NS * NS];
    int cut_step;           /* step k -> k+1 after which component cut_comp is reset; -1: none */
    int cut_comp;
    double z_reset, r_reset; /* the reset's measurement of that component and its variance */
} problem_t;

/* ---- small dense helpers of the test (row-major) ---- */
static void matmul(int n, int k, int m, const double *A, const double *B, double *C)
{
    int i, j, l;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < m; ++j) {
            double s = 0.0;
            for (l = 0; l < k; ++l) {
                s += A[i * k + l] * B[l * m + j];
            }
            C[i * m + j] = s;
        }
    }
}

static void transpose(int n, int m, const double *A, double *T)
{
    int i, j;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < m; ++j) {
            T[j * n + i] = A[i * m + j];
        }
    }
}

/* A^-1 by Gauss-Jordan elimination with partial pivoting (n <= NB); 0 if singular. */
static int invert(int n, const double *A, double *inv)
{
    static double M[NB * 2 * NB];
    int i, j, c, w = 2 * n;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            M[i * w + j] = A[i * n + j];
            M[i * w + n + j] = (i == j) ? 1.0 : 0.0;
        }
    }
    for (c = 0; c < n; ++c) {
        int p = c;
        double piv;
        for (i = c + 1; i < n; ++i) {
            if (fabs(M[i * w + c]) > fabs(M[p * w + c])) {
                p = i;
            }
        }
        if (fabs(M[p * w + c]) < 1e-300) {
            return 0;
        }
        for (j = 0; j < w; ++j) {
            const double t = M[c * w + j];
            M[c * w + j] = M[p * w + j];
            M[p * w + j] = t;
        }
        piv = M[c * w + c];
        for (j = 0; j < w; ++j) {
            M[c * w + j] /= piv;
        }
        for (i = 0; i < n; ++i) {
            if (i != c && M[i * w + c] != 0.0) {
                const double f = M[i * w + c];
                for (j = 0; j < w; ++j) {
                    M[i * w + j] -= f * M[c * w + j];
                }
            }
        }
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            inv[i * n + j] = M[i * w + n + j];
        }
    }
    return 1;
}

/* ---- the random problem ---- */
static void make_problem(problem_t *pb, uint64_t seed, int cut_step, int cut_comp)
{
    ts_rng_t r;
    double x[NS];
    int k, i, j;
    ts_rng_seed(&r, seed);
    memset(pb, 0, sizeof *pb);
    pb->cut_step = cut_step;
    pb->cut_comp = cut_comp;
    for (i = 0; i < NS; ++i) {
        pb->m0[i] = ts_uniform_in(&r, -1.0, 1.0);
        pb->P0[i * NS + i] = ts_uniform_in(&r, 0.5, 2.0);
    }
    pb->P0[1] = pb->P0[NS] = 0.3; /* a correlated prior */
    for (i = 0; i < NS; ++i) {
        x[i] = pb->m0[i] + sqrt(pb->P0[i * NS + i]) * ts_gauss(&r);
    }
    for (k = 0; k < NE; ++k) {
        for (i = 0; i < NZ; ++i) {
            double zi = 0.0;
            for (j = 0; j < NS; ++j) {
                pb->H[k][i * NS + j] = ts_uniform_in(&r, -1.0, 1.0);
                zi += pb->H[k][i * NS + j] * x[j];
            }
            pb->R[k][i] = ts_uniform_in(&r, 0.05, 0.5);
            pb->z[k][i] = zi + sqrt(pb->R[k][i]) * ts_gauss(&r);
        }
        if (k < NE - 1) {
            double xn[NS];
            for (i = 0; i < NS; ++i) {
                for (j = 0; j < NS; ++j) {
                    pb->F[k][i * NS + j] = (i == j ? 0.9 : 0.0) + ts_uniform_in(&r, -0.3, 0.3);
                }
                pb->Q[k][i * NS + i] = ts_uniform_in(&r, 0.01, 0.2);
            }
            matmul(NS, NS, 1, pb->F[k], x, xn);
            for (i = 0; i < NS; ++i) {
                x[i] = xn[i] + sqrt(pb->Q[k][i * NS + i]) * ts_gauss(&r);
            }
            if (k == cut_step) {
                x[cut_comp] += 5.0; /* the jump (any value: the smoother must not carry it back) */
                pb->r_reset = 0.2;
                pb->z_reset = x[cut_comp] + sqrt(pb->r_reset) * ts_gauss(&r);
            }
        }
    }
}

/* ---- batch least squares: J X = g ---- */
static void batch_solution(const problem_t *pb, double *X, double *Cov)
{
    static double J[NB * NB], Jinv[NB * NB];
    double g[NB] = {0}, P0inv[NS * NS], W[NS * NS], FT[NS * NS], FTW[NS * NS], FTWF[NS * NS], WF[NS * NS];
    int k, i, j, l;
    memset(J, 0, sizeof J);
    TEST_ASSERT_TRUE(invert(NS, pb->P0, P0inv));
    for (i = 0; i < NS; ++i) {
        for (j = 0; j < NS; ++j) {
            J[i * NB + j] += P0inv[i * NS + j];
            g[i] += P0inv[i * NS + j] * pb->m0[j];
        }
    }
    for (k = 0; k < NE; ++k) {
        const int o = k * NS;
        if (pb->cut_step >= 0 && k == pb->cut_step + 1) { /* the reset's measurement */
            J[(o + pb->cut_comp) * NB + o + pb->cut_comp] += 1.0 / pb->r_reset;
            g[o + pb->cut_comp] += pb->z_reset / pb->r_reset;
        }
        for (l = 0; l < NZ; ++l) {
            const double w = 1.0 / pb->R[k][l];
            for (i = 0; i < NS; ++i) {
                g[o + i] += pb->H[k][l * NS + i] * w * pb->z[k][l];
                for (j = 0; j < NS; ++j) {
                    J[(o + i) * NB + o + j] += pb->H[k][l * NS + i] * w * pb->H[k][l * NS + j];
                }
            }
        }
        if (k == NE - 1) {
            continue;
        }
        /* dynamics residual x_{k+1} - F x_k with weight W = Q^-1; a reset component has no
         * dynamics over its step (the limit of infinite process noise: its row and column
         * of W are zero) */
        TEST_ASSERT_TRUE(invert(NS, pb->Q[k], W));
        if (k == pb->cut_step) {
            for (i = 0; i < NS; ++i) {
                W[pb->cut_comp * NS + i] = W[i * NS + pb->cut_comp] = 0.0;
            }
        }
        transpose(NS, NS, pb->F[k], FT);
        matmul(NS, NS, NS, FT, W, FTW);
        matmul(NS, NS, NS, FTW, pb->F[k], FTWF);
        matmul(NS, NS, NS, W, pb->F[k], WF);
        for (i = 0; i < NS; ++i) {
            for (j = 0; j < NS; ++j) {
                J[(o + i) * NB + o + j] += FTWF[i * NS + j];
                J[(o + i) * NB + o + NS + j] -= FTW[i * NS + j];
                J[(o + NS + i) * NB + o + j] -= WF[i * NS + j];
                J[(o + NS + i) * NB + o + NS + j] += W[i * NS + j];
            }
        }
    }
    TEST_ASSERT_TRUE(invert(NB, J, Jinv));
    matmul(NB, NB, 1, Jinv, g, X);
    for (k = 0; k < NE; ++k) {
        for (i = 0; i < NS; ++i) {
            for (j = 0; j < NS; ++j) {
                Cov[k * NS * NS + i * NS + j] = Jinv[(k * NS + i) * NB + k * NS + j];
            }
        }
    }
}

/* ---- Kalman filter (this file's own) and rts_step backwards ---- */
typedef struct {
    double xf[NE][NS], Pf[NE][NS * NS];      /* filtered, epoch k */
    double xp[NE][NS], Pp[NE][NS * NS];      /* predicted, epoch k (k >= 1) */
} forward_t;

/* Matrix-gain update in the Joseph form (I - K H) P (I - K H)^T + K R K^T, which keeps P
 * positive definite also when a variance is huge (the reset's 1e9 below). */
static void kalman_update(const problem_t *pb, int k, double *x, double *P)
{
    double HT[NS * NZ], PHT[NS * NZ], S[NZ * NZ], Sinv[NZ * NZ], K[NS * NZ], nu[NZ];
    double IKH[NS * NS], IKHT[NS * NS], T[NS * NS], KR[NS * NZ], KT[NZ * NS], KRK[NS * NS];
    int i, j;
    transpose(NZ, NS, pb->H[k], HT);
    matmul(NS, NS, NZ, P, HT, PHT);
    matmul(NZ, NS, NZ, pb->H[k], PHT, S);
    for (i = 0; i < NZ; ++i) {
        S[i * NZ + i] += pb->R[k][i];
        nu[i] = pb->z[k][i];
        for (j = 0; j < NS; ++j) {
            nu[i] -= pb->H[k][i * NS + j] * x[j];
        }
    }
    TEST_ASSERT_TRUE(invert(NZ, S, Sinv));
    matmul(NS, NZ, NZ, PHT, Sinv, K);
    for (i = 0; i < NS; ++i) {
        for (j = 0; j < NZ; ++j) {
            x[i] += K[i * NZ + j] * nu[j];
        }
    }
    matmul(NS, NZ, NS, K, pb->H[k], IKH);
    for (i = 0; i < NS * NS; ++i) {
        IKH[i] = ((i % (NS + 1)) == 0 ? 1.0 : 0.0) - IKH[i];
    }
    transpose(NS, NS, IKH, IKHT);
    matmul(NS, NS, NS, IKH, P, T);
    matmul(NS, NS, NS, T, IKHT, P);
    for (i = 0; i < NS; ++i) {
        for (j = 0; j < NZ; ++j) {
            KR[i * NZ + j] = K[i * NZ + j] * pb->R[k][j];
        }
    }
    transpose(NS, NZ, K, KT);
    matmul(NS, NZ, NS, KR, KT, KRK);
    for (i = 0; i < NS * NS; ++i) {
        P[i] += KRK[i];
    }
    for (i = 0; i < NS; ++i) { /* exactly symmetric */
        for (j = i + 1; j < NS; ++j) {
            P[j * NS + i] = P[i * NS + j] = 0.5 * (P[i * NS + j] + P[j * NS + i]);
        }
    }
}

/* The reset of the attitude filter's heading: component c := its measurement, no correlation. */
static void reset_component(const problem_t *pb, double *x, double *P)
{
    const int c = pb->cut_comp;
    int j;
    for (j = 0; j < NS; ++j) {
        P[c * NS + j] = P[j * NS + c] = 0.0;
    }
    P[c * NS + c] = pb->r_reset;
    x[c] = pb->z_reset;
}

static void forward_filter(const problem_t *pb, forward_t *fw)
{
    double x[NS], P[NS * NS], FP[NS * NS], FT[NS * NS];
    int k, i;
    memcpy(x, pb->m0, sizeof x);
    memcpy(P, pb->P0, sizeof P);
    for (k = 0; k < NE; ++k) {
        if (k > 0) {
            double xn[NS];
            matmul(NS, NS, 1, pb->F[k - 1], x, xn);
            matmul(NS, NS, NS, pb->F[k - 1], P, FP);
            transpose(NS, NS, pb->F[k - 1], FT);
            matmul(NS, NS, NS, FP, FT, P);
            for (i = 0; i < NS * NS; ++i) {
                P[i] += pb->Q[k - 1][i];
            }
            memcpy(x, xn, sizeof x);
            memcpy(fw->xp[k], x, sizeof x);
            memcpy(fw->Pp[k], P, sizeof P);
            if (k - 1 == pb->cut_step) {
                reset_component(pb, x, P);
            }
        }
        kalman_update(pb, k, x, P);
        memcpy(fw->xf[k], x, sizeof x);
        memcpy(fw->Pf[k], P, sizeof P);
    }
}

static void smooth(const problem_t *pb, const forward_t *fw, unsigned use_cut, double *X, double *Cov)
{
    double xs[NS], Ps[NS * NS];
    int k, i;
    memcpy(xs, fw->xf[NE - 1], sizeof xs);
    memcpy(Ps, fw->Pf[NE - 1], sizeof Ps);
    memcpy(&X[(NE - 1) * NS], xs, sizeof xs);
    memcpy(&Cov[(NE - 1) * NS * NS], Ps, sizeof Ps);
    for (k = NE - 2; k >= 0; --k) {
        double dx[NS], xo[NS], Po[NS * NS];
        const unsigned cut = (use_cut && k == pb->cut_step) ? (1u << pb->cut_comp) : 0u;
        for (i = 0; i < NS; ++i) {
            dx[i] = xs[i] - fw->xp[k + 1][i];
        }
        TEST_ASSERT_EQUAL_INT(RTS_OK, rts_step(NS, fw->xf[k], fw->Pf[k], pb->F[k], fw->Pp[k + 1], dx, Ps, cut, xo, Po));
        memcpy(xs, xo, sizeof xs);
        memcpy(Ps, Po, sizeof Ps);
        memcpy(&X[k * NS], xs, sizeof xs);
        memcpy(&Cov[k * NS * NS], Ps, sizeof Ps);
    }
}

static double max_rel_diff(const double *a, const double *b, int n)
{
    double scale = 0.0, d = 0.0;
    int i;
    for (i = 0; i < n; ++i) {
        scale = fmax(scale, fabs(b[i]));
        d = fmax(d, fabs(a[i] - b[i]));
    }
    return d / scale;
}

/* ---- tests ---- */
static void check_against_batch(uint64_t seed, int cut_step, int cut_comp, double tol)
{
    static problem_t pb;
    static forward_t fw;
    static double Xb[NB], Cb[NE * NS * NS], Xs[NB], Cs[NE * NS * NS];
    double dx, dc;
    make_problem(&pb, seed, cut_step, cut_comp);
    batch_solution(&pb, Xb, Cb);
    forward_filter(&pb, &fw);
    smooth(&pb, &fw, 1u, Xs, Cs);
    dx = max_rel_diff(Xs, Xb, NB);
    dc = max_rel_diff(Cs, Cb, NE * NS * NS);
    if (dx > tol || dc > tol) {
        printf("seed %llu cut %d/%d: means %.3g, covariances %.3g relative\n", (unsigned long long)seed, cut_step,
               cut_comp, dx, dc);
    }
    TEST_ASSERT_TRUE(dx <= tol);
    TEST_ASSERT_TRUE(dc <= tol);
}

static void test_rts_equals_batch_least_squares(void)
{
    uint64_t seed;
    for (seed = 1; seed <= 50; ++seed) {
        check_against_batch(seed, -1, 0, 1e-9);
    }
}

/* A reset: the smoother's cut equals the batch problem without that component's dynamics
 * over the step and with the reset's measurement. */
static void test_cut_equals_batch_without_that_dynamics(void)
{
    uint64_t seed;
    for (seed = 1; seed <= 50; ++seed) {
        check_against_batch(seed, (int)(seed % (NE - 1)), (int)(seed % NS), 1e-9);
    }
}

/* The same reset smoothed without the cut carries the jump back: the check above can fail. */
static void test_without_the_cut_the_jump_leaks_back(void)
{
    static problem_t pb;
    static forward_t fw;
    static double Xb[NB], Cb[NE * NS * NS], Xs[NB], Cs[NE * NS * NS];
    make_problem(&pb, 7, 4, 1);
    batch_solution(&pb, Xb, Cb);
    forward_filter(&pb, &fw);
    smooth(&pb, &fw, 0u, Xs, Cs);
    TEST_ASSERT_TRUE(max_rel_diff(Xs, Xb, NB) > 1e-3);
}

/* Every component cut: nothing crosses the step. */
static void test_full_cut_keeps_the_filtered_values(void)
{
    const double xf[2] = {1.0, 2.0}, Pf[4] = {2.0, 0.5, 0.5, 1.0}, F[4] = {1.0, 0.1, 0.0, 1.0};
    const double Pp[4] = {3.0, 0.6, 0.6, 1.5}, dx[2] = {5.0, -3.0}, Ps1[4] = {1.0, 0.0, 0.0, 1.0};
    double xs[2], Ps[4];
    TEST_ASSERT_EQUAL_INT(RTS_OK, rts_step(2, xf, Pf, F, Pp, dx, Ps1, 3u, xs, Ps));
    TEST_ASSERT_EQUAL_DOUBLE(1.0, xs[0]);
    TEST_ASSERT_EQUAL_DOUBLE(2.0, xs[1]);
    TEST_ASSERT_EQUAL_MEMORY(Pf, Ps, sizeof Ps);
}

/* A scalar step by hand: C = Pf F / Pp. */
static void test_scalar_step_by_hand(void)
{
    const double xf = 1.0, Pf = 2.0, F = 0.5, Pp = 1.5, dx = 0.3, Ps1 = 0.9;
    double xs, Ps;
    const double C = Pf * F / Pp;
    TEST_ASSERT_EQUAL_INT(RTS_OK, rts_step(1, &xf, &Pf, &F, &Pp, &dx, &Ps1, 0u, &xs, &Ps));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, xf + C * dx, xs);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, Pf + C * C * (Ps1 - Pp), Ps);
}

static void test_refuses_an_indefinite_prediction_and_bad_sizes(void)
{
    const double xf[2] = {1.0, 2.0}, Pf[4] = {2.0, 0.5, 0.5, 1.0}, F[4] = {1.0, 0.0, 0.0, 1.0};
    const double Pp[4] = {1.0, 2.0, 2.0, 1.0}, dx[2] = {5.0, -3.0}, Ps1[4] = {1.0, 0.0, 0.0, 1.0};
    const double Pnan[4] = {1.0, 0.0, 0.0, (double)NAN};
    double xs[2], Ps[4];
    TEST_ASSERT_EQUAL_INT(RTS_ERR_NOT_PD, rts_step(2, xf, Pf, F, Pp, dx, Ps1, 0u, xs, Ps));
    TEST_ASSERT_EQUAL_DOUBLE(1.0, xs[0]);
    TEST_ASSERT_EQUAL_MEMORY(Pf, Ps, sizeof Ps);
    TEST_ASSERT_EQUAL_INT(RTS_ERR_NOT_PD, rts_step(2, xf, Pf, F, Pnan, dx, Ps1, 0u, xs, Ps));
    /* the indefinite block cut away: what is left is positive definite */
    TEST_ASSERT_EQUAL_INT(RTS_OK, rts_step(2, xf, Pf, F, Pnan, dx, Ps1, 2u, xs, Ps));
    TEST_ASSERT_EQUAL_INT(RTS_ERR_ARGUMENT, rts_step(0, xf, Pf, F, Pp, dx, Ps1, 0u, xs, Ps));
    TEST_ASSERT_EQUAL_INT(RTS_ERR_ARGUMENT, rts_step(RTS_NMAX + 1, xf, Pf, F, Pp, dx, Ps1, 0u, xs, Ps));
}


/* One more cut from a gain equals the gain computed with that cut (the rank-one change),
 * and the smoothed values with it; a gain already cut so is refused. */
static void test_gain_cut_equals_gain_with_the_cut(void)
{
    static problem_t pb;
    static forward_t fw;
    uint64_t seed;
    for (seed = 1; seed <= 20; ++seed) {
        const int k = (int)(seed % (NE - 1));
        const unsigned first = (seed % 3 == 0) ? (1u << ((seed + 1) % NS)) : 0u;
        const size_t extra = (size_t)(seed % NS);
        rts_gain_t a, b;
        double xa[NS], xb[NS], Pa[NS * NS], Pb[NS * NS], dx[NS];
        int i;
        make_problem(&pb, seed, -1, 0);
        forward_filter(&pb, &fw);
        for (i = 0; i < NS; ++i) {
            dx[i] = 0.1 * (double)(i + 1);
        }
        TEST_ASSERT_EQUAL_INT(RTS_OK, rts_gain(NS, fw.Pf[k], pb.F[k], fw.Pp[k + 1], first | (1u << extra), &a));
        TEST_ASSERT_EQUAL_INT(RTS_OK, rts_gain(NS, fw.Pf[k], pb.F[k], fw.Pp[k + 1], first, &b));
        TEST_ASSERT_EQUAL_INT(RTS_OK, rts_gain_cut(&b, extra, &b));
        TEST_ASSERT_EQUAL_UINT(a.cut, b.cut);
        TEST_ASSERT_TRUE(max_rel_diff(b.Y, a.Y, NS * NS) < 1e-12);
        rts_apply(&a, fw.xf[k], fw.Pf[k], fw.Pp[k + 1], dx, fw.Pf[k + 1], xa, Pa);
        rts_apply(&b, fw.xf[k], fw.Pf[k], fw.Pp[k + 1], dx, fw.Pf[k + 1], xb, Pb);
        TEST_ASSERT_TRUE(max_rel_diff(xb, xa, NS) < 1e-12);
        TEST_ASSERT_TRUE(max_rel_diff(Pb, Pa, NS * NS) < 1e-12);
        TEST_ASSERT_EQUAL_INT(RTS_ERR_ARGUMENT, rts_gain_cut(&b, (extra + 1) % NS, &a));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_rts_equals_batch_least_squares);
    RUN_TEST(test_cut_equals_batch_without_that_dynamics);
    RUN_TEST(test_without_the_cut_the_jump_leaks_back);
    RUN_TEST(test_full_cut_keeps_the_filtered_values);
    RUN_TEST(test_scalar_step_by_hand);
    RUN_TEST(test_refuses_an_indefinite_prediction_and_bad_sizes);
    RUN_TEST(test_gain_cut_equals_gain_with_the_cut);
    return UNITY_END();
}
