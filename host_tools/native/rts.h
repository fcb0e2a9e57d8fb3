/*
 * rts.h - one backward step of the Rauch-Tung-Striebel fixed-interval smoother, in double
 * precision, for any state of up to RTS_NMAX components (docs/derivation.md, "Smoother").
 *
 * The forward filter gives, for the step from epoch k to epoch k+1: the filtered state x_f
 * and covariance P_f of epoch k, the Jacobian F of the transition's mean, and the predicted
 * covariance P_pred of epoch k+1 (with its process noise, whatever it was). With the smoothed
 * state of epoch k+1 known (x_s1, P_s1), the smoothed state of epoch k is
 *
 *     C   = P_f F^T P_pred^-1                  (the smoother gain, n x n)
 *     x_s = x_f + C (x_s1 - x_pred)
 *     P_s = P_f + C (P_s1 - P_pred) C^T
 *
 * The caller forms dx = x_s1 - x_pred (an attitude smoother wraps angles there). P_pred is
 * never inverted: its Cholesky factor solves P_pred Y = F P_f, and C = Y^T.
 *
 * A cut (bit i of cut set) says that component i of epoch k+1 took a jump of unbounded
 * variance in the step (a reset of that component): the limit of the gain for that process
 * noise going to infinity is the same formula with P_pred restricted to the other
 * components (C's column i is zero), so dx's and P_s1's cut components play no part. Cutting
 * every component gives x_s = x_f, P_s = P_f (no information crosses the step).
 *
 * Generic and independent of the attitude model (tests/c/test_rts.c checks it against a
 * batch least-squares solution of linear-Gaussian problems). Host-side C99, no allocation.
 */
#ifndef RTS_H
#define RTS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define RTS_NMAX 12

/* Status of the calls below. */
typedef enum {
    RTS_OK = 0,
    RTS_ERR_ARGUMENT = 1,  /* n is 0 or above RTS_NMAX, a state out of range, or a gain that
                              rts_gain_cut cannot cut further */
    RTS_ERR_NOT_PD = 2     /* P_pred (its kept block) is not positive definite, or not finite */
} rts_status_t;

/* Row stride of a gain's matrices: n rounded up to even (whole pairs of doubles). */
#define RTS_LD(n) ((n) + ((n) & 1u))

/* The gain of one step: Y = C^T (n rows of stride RTS_LD(n), the padding zero; zero rows for
 * the cut states) and the Cholesky factor L (likewise) of P_pred with the cut states' rows and
 * columns replaced by the identity's (which makes the system block diagonal: Y's kept rows
 * are the kept block's solution). */
typedef struct {
    size_t n;
    unsigned cut;
    unsigned factored; /* the cut set of L (rts_gain_cut changes cut, not L) */
    double Y[RTS_NMAX * RTS_NMAX];
    double L[RTS_NMAX * RTS_NMAX];
} rts_gain_t;

/* The gain for the step (row-major n x n matrices; P_f and P_pred symmetric). RTS_ERR_NOT_PD
 * leaves a gain that cuts every state (rts_apply then gives x_s = x_f, P_s = P_f). */
rts_status_t rts_gain(size_t n, const double *P_f, const double *F, const double *P_pred, unsigned cut,
                      rts_gain_t *g);

/* The gain of the same step with state i cut too, from a gain of rts_gain (a rank-one change:
 * with u = P_pred^-1 e_i on the kept states, Y' = Y - u Y[i, :] / u_i); out may be g.
 * RTS_ERR_ARGUMENT for a state out of range or a gain already cut by this function. */
rts_status_t rts_gain_cut(const rts_gain_t *g, size_t i, rts_gain_t *out);

/* The smoothed state and covariance of epoch k with the gain g (x_s, P_s may not alias the
 * inputs). */
void rts_apply(const rts_gain_t *g, const double *x_f, const double *P_f, const double *P_pred, const double *dx,
               const double *P_s1, double *x_s, double *P_s);

/* rts_gain and rts_apply: one backward step. On RTS_ERR_NOT_PD x_s = x_f and P_s = P_f. */
rts_status_t rts_step(size_t n, const double *x_f, const double *P_f, const double *F, const double *P_pred,
                      const double *dx, const double *P_s1, unsigned cut, double *x_s, double *P_s);

/* Cholesky factor L (lower, row-major m x m, L L^T = A) of a symmetric matrix; 0 if A is
 * not positive definite (a pivot not above 0 or not finite), else 1. */
int rts_cholesky(size_t m, const double *A, double *L);

/* Solves L L^T Y = B for k right-hand sides (B and Y m x k, row-major; Y may be B). */
void rts_cholesky_solve(size_t m, const double *L, size_t k, const double *B, double *Y);

#ifdef __cplusplus
}
#endif

#endif /* RTS_H */
