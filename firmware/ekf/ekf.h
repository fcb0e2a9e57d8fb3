/*
 * ekf.h - generic, model-agnostic EKF primitives.
 *
 * The filter state is a vector x[n] and a covariance P[n*n] (row-major, kept exactly
 * symmetric), both owned by the caller. A model supplies:
 *   - its transition x+ = f(x, u, dt), computed by itself, and the Jacobian F = df/dx as
 *     F = I + D, D sparse (a constant pattern plus values) -> ekf_cov_propagate();
 *   - its process noise Q, added by itself (it knows Q's structure);
 *   - each measurement as a scalar: innovation z - h(x), the sparse row H = dh/dx and
 *     the noise variance R -> ekf_update_scalar(). Vector measurements are fused one
 *     component at a time (sequential scalar updates), so no matrix is ever inverted.
 *
 * Covariance update: P - K b^T (b = P H^T, K = b / S: the Joseph form at the optimal gain),
 * O(n^2) for a scalar measurement (docs/derivation.md, "Covariance update"), symmetric by
 * construction, with a floor on the diagonal; its robustness against the Joseph evaluation
 * is measured in docs/performance.md. Innovation gate: chi-square with one degree of
 * freedom per scalar.
 *
 * No allocation, no recursion, no VLAs; n <= EKF_MAX_STATES.
 */
#ifndef EKF_H
#define EKF_H

#include <stdint.h>

#include "ekf_scalar.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Result of every entry point of the library (generic core and models). Errors leave
 * the filter exactly as it was; EKF_GATED and EKF_SKIPPED are not errors (the filter
 * stays consistent) but report that a measurement was not fused. */
typedef enum {
    EKF_OK = 0,               /* done */
    EKF_ERR_NULL = 1,         /* a required pointer is NULL */
    EKF_ERR_NOT_FINITE = 2,   /* an input is NaN or infinite */
    EKF_ERR_DT_NONPOSITIVE = 3, /* time step <= 0 */
    EKF_ERR_DT_TOO_LARGE = 4, /* time step above the configured maximum */
    EKF_ERR_RANGE = 5,        /* an input outside its configured physical range */
    EKF_ERR_NOT_INITIALISED = 6, /* filter not initialised (aligned) yet */
    EKF_ERR_SETTINGS = 7,     /* settings invalid (see the settings struct's ranges) */
    EKF_ERR_DIMENSION = 8,    /* dimension or index outside what the routine supports */
    EKF_ERR_NUMERIC = 9,      /* the update would make the covariance non-finite or
                                 non-positive: refused */
    EKF_ERR_SINGULAR = 10,    /* measurement geometry singular (e.g. range ~ 0) */
    EKF_GATED = 11,           /* innovation outside the chi-square gate: not fused */
    EKF_SKIPPED = 12          /* not fused by policy (disturbance, gimbal lock) */
} ekf_status_t;

/* Short constant name of a status, e.g. "EKF_ERR_NOT_FINITE". Never NULL. */
const char *ekf_status_str(ekf_status_t status);

/* 1 for a status that refuses the call (nothing applied); 0 for EKF_OK, EKF_GATED and
 * EKF_SKIPPED (the call was applied). */
static inline int ekf_status_is_error(ekf_status_t status)
{
    return status != EKF_OK && status != EKF_GATED && status != EKF_SKIPPED;
}

/* One structurally non-zero entry of a sparse matrix. */
typedef struct {
    uint8_t row;
    uint8_t col;
} ekf_nz_t;

/* Sparse row vector (a measurement Jacobian H): value[k] at column idx[k]. */
typedef struct {
    const uint8_t *idx;
    const ekf_scalar_t *value;
    uint8_t nnz;
} ekf_hrow_t;

/* What a scalar update saw, for diagnostics and the innovation test report. */
typedef struct {
    ekf_scalar_t innovation; /* z - h(x), as passed (model units) */
    ekf_scalar_t variance;   /* S = H P H^T + R */
    ekf_scalar_t test_ratio; /* innovation^2 / (gate^2 S); > 1 means gated (0 if no gate) */
} ekf_innov_t;

/*
 * P <- F P F^T with F = I + D.
 *
 * pattern[k] is the (row, col) of D's k-th non-zero value d[k]; pattern must be sorted by
 * row (entries of one row contiguous); any n <= EKF_MAX_STATES (the set of modified rows is
 * a bit mask of EKF_MAX_STATES bits). Only rows of F that differ from the identity are
 * touched, so the cost is O(r n + nnz n + r * nnz) for r such rows: linear in n when the
 * model's F is identity outside a small block (EKF-SLAM's static landmarks).
 *
 * work: caller scratch of at least r * n scalars (r = number of distinct rows in
 * pattern); work_len is its length in scalars.
 * Returns EKF_ERR_NULL, EKF_ERR_DIMENSION (n or an index out of range, pattern unsorted,
 * work too small) or EKF_ERR_NOT_FINITE (a value of d) with P unchanged; else EKF_OK.
 */
ekf_status_t ekf_cov_propagate(ekf_scalar_t *P, uint8_t n, const ekf_nz_t *pattern,
                               const ekf_scalar_t *d, uint16_t nnz, ekf_scalar_t *work,
                               uint16_t work_len);

/*
 * Sequential scalar measurement update.
 *
 *   b = P H^T;  S = H b + r_var;  K = b / S;  x += K innovation;
 *   P <- P - K b^T (upper triangle, mirrored), then P_ii >= var_floor.
 * That is the Joseph form (I - K H) P (I - K H)^T + K r_var K^T at this gain, whose extra
 * terms (S K - b) K^T vanish (docs/derivation.md, "Covariance update"). P must be exactly
 * symmetric (column idx of P is read as row idx).
 *
 * gate_sigma > 0 enables the chi-square test innovation^2 <= gate_sigma^2 S (one degree
 * of freedom: gate_sigma 3 keeps 99.73 % of consistent innovations); a failed test
 * returns EKF_GATED with x and P unchanged. gate_sigma <= 0 disables the test.
 *
 * info (may be NULL) is written on every path: innovation and S once S is formed (also
 * when S is then refused), the test ratio when the gate is on (else 0); every field is 0
 * on the paths that return before S is formed.
 *
 * Errors (x, P unchanged): EKF_ERR_NULL, EKF_ERR_DIMENSION, EKF_ERR_NOT_FINITE
 * (innovation, r_var or H), EKF_ERR_RANGE (r_var <= 0), EKF_ERR_NUMERIC: S not finite or
 * S < r_var (H P H^T < 0), a gain or new state not finite, or a new variance
 * P_ii - K_i b_i that is not finite or negative beyond a rounding allowance (about
 * 32 n eps (|P_ii| + K_i b_i) for IEEE types; for fixed point 32 n LSB scaled by the
 * factors): the covariance would be indefinite, and no floor hides it. Only new
 * variances within that allowance of zero, or positive ones, are raised to var_floor.
 */
ekf_status_t ekf_update_scalar(ekf_scalar_t *x, ekf_scalar_t *P, uint8_t n, const ekf_hrow_t *h,
                               ekf_scalar_t innovation, ekf_scalar_t r_var,
                               ekf_scalar_t gate_sigma, ekf_scalar_t var_floor,
                               ekf_innov_t *info);

/*
 * Caps the variance of state i at max_var by scaling row and column i of P by
 * sqrt(max_var / P_ii) (a congruence: P stays positive semi-definite and symmetric).
 * Used for states the measurements cannot observe (heading without magnetometer), whose
 * variance would otherwise grow without bound. Returns 1 if P was changed, 0 if not (also
 * for a non-finite P_ii, which no scaling can bring back: P is left as it is).
 */
int ekf_cov_limit_variance(ekf_scalar_t *P, uint8_t n, uint8_t i, ekf_scalar_t max_var);

/*
 * 1 if P is numerically positive definite: its LDL^T factorisation (computed in the
 * scalar type) has every pivot d_j >= rel_margin * P_jj > 0. work: n (n + 1) / 2 scalars.
 * 0 otherwise (also for n out of range or a NULL argument).
 */
int ekf_cov_is_pd(const ekf_scalar_t *P, uint8_t n, ekf_scalar_t rel_margin, ekf_scalar_t *work);

/*
 * Guarantees that P passes ekf_cov_is_pd(P, n, rel_margin): if it does not, the diagonal is
 * loaded, P_ii <- max(P_ii, floor) (1 + lambda), with lambda = 10 rel_margin (at least
 * 16 eps) growing tenfold per round up to 1; if even that fails (or the loading would
 * overflow), the off-diagonal entries are cleared and P_ii <- max(P_ii, floor) (a positive
 * diagonal matrix). Relative loading keeps the correlation structure and only shrinks
 * correlation coefficients by 1 / (1 + lambda). Afterwards every P_ii >= floor.
 * Returns the number of repair rounds: 0 if P was already positive definite; -1 with P
 * unchanged if P has a non-finite entry (no repair can give it a meaning: the caller
 * refuses what produced it) or an argument is out of range (NULL, n, floor not finite and
 * > 0, rel_margin not in [0, 1)).
 * A model calls it where rounding can break definiteness (docs/derivation.md,
 * "Covariance bounds"). work: n (n + 1) / 2 scalars.
 */
int ekf_cov_ensure_pd(ekf_scalar_t *P, uint8_t n, ekf_scalar_t rel_margin, ekf_scalar_t floor,
                      ekf_scalar_t *work);

/* 1 if every entry of v[0..len) is finite. */
int ekf_all_finite(const ekf_scalar_t *v, uint16_t len);

#ifdef __cplusplus
}
#endif

#endif /* EKF_H */
