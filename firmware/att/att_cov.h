/*
 * att_cov.h - the covariance P of the attitude filter: its storage and every operation the
 * filter applies to it. The stages (att_align.c, att_predict.c, att_gyro.c, att_accel.c,
 * att_mag.c) change P only through these functions and read it only by value, so that an
 * implementation may store P in any form. No function hands out a pointer into P.
 *
 * Indices are the state indices of att_defs.h (0 .. ATT_N-1); callers pass valid ones.
 * Every operation keeps P exactly symmetric. Which operations keep P positive
 * (semi-)definite is stated with each; the guard (att_cov_guard) runs once at the end of
 * every public call of the filter (docs/derivation.md, "Covariance bounds").
 *
 * One implementation per scalar type, chosen by the build (firmware/CMakeLists.txt): float
 * and double, packed symmetric storage (att_cov.c, with the generated arithmetic kernels of
 * att_cov_gen.c); fixed point, 32-bit words with a power-of-two scale per state
 * (att_cov_fx.c, att_cov_fx_kernels.c). The tests compare both, operation by operation, with
 * the full-matrix reference on the generic core (tests/c/support/att_cov_ref.c, compiled with
 * ATT_COV_REFERENCE).
 */
#ifndef ATT_COV_H
#define ATT_COV_H

#include "att_defs.h"
#include "att_gen.h"
#include "ekf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The storage. Its layout belongs to the implementation: read it only through the
 * functions below (att_cov_to_full for all of it). */
#if defined(ATT_COV_REFERENCE)
typedef struct {
    ekf_scalar_t P[ATT_N * ATT_N]; /* row-major, exactly symmetric */
} att_cov_t;
#elif defined(EKF_SCALAR_FIXED)
/* Fixed point (att_cov_fx.c, docs/fixed_point.md "Covariance"): P_ij = C_ij 2^(e_i + e_j - 29),
 * C normalised so that C_ii is in [2^29, 2^31) (1 <= c_ii < 4) by the state's exponent. */
#define ATT_COV_FX 1
typedef struct {
    int32_t c[ATT_COV_NP]; /* C_ij for i <= j, row by row (45 words) */
    int8_t e[ATT_N];       /* scale exponent of each state */
    uint8_t spare;         /* always 0 (no padding byte in the struct) */
    uint16_t inf;          /* bit i: state i's variance is infinite (overflowed) */
} att_cov_t;
/* The guard's absolute margin (att_cov_is_pd), Q29.34: 8 LSB, above the 4.5 LSB by which
 * rounding each entry of P to the scalar (att_cov_to_full) can lower its eigenvalues. */
#define ATT_COV_FX_TAU ((ekf_scalar_t)8)
#else
/* Float and double (att_cov.c): the entries of the lower triangle. */
#define ATT_COV_PACKED 1
typedef struct {
    ekf_scalar_t p[ATT_COV_NP]; /* P_ij (i >= j) at p[i (i + 1) / 2 + j] */
} att_cov_t;
#endif

/* ---- set and read ----
 * On packed storage the reads and updates of single variances are inline: one load at a
 * constant offset, where a call and the index table cost more than the body
 * (ATT_COV_DIAG_FN, ATT_COV_DIAG_BODY); elsewhere they are functions. */
#if defined(ATT_COV_PACKED)
/* P_ii's index in the packed lower triangle */
#define ATT_COV_II(i) ((i) * ((i) + 3) / 2)
#if defined(__GNUC__)
#define ATT_COV_DIAG_FN static inline __attribute__((always_inline))
#else
#define ATT_COV_DIAG_FN static inline
#endif
#define ATT_COV_DIAG_BODY(body) body
#else
#define ATT_COV_DIAG_FN
#define ATT_COV_DIAG_BODY(body) ;
#endif

/* P = diag(var): every off-diagonal entry zero. */
void att_cov_set_diag(att_cov_t *c, const ekf_scalar_t var[ATT_N]);
/* P_ij. */
ekf_scalar_t att_cov_get(const att_cov_t *c, int i, int j);
/* P_ii. */
ATT_COV_DIAG_FN ekf_scalar_t att_cov_var(const att_cov_t *c, int i) ATT_COV_DIAG_BODY({ return c->p[ATT_COV_II(i)]; })
/* All of P, row-major, in the filter's scalar type. */
void att_cov_to_full(const att_cov_t *c, ekf_scalar_t P[ATT_N * ATT_N]);
/* P from a row-major symmetric matrix (its lower triangle is read, and mirrored). */
void att_cov_from_full(att_cov_t *c, const ekf_scalar_t P[ATT_N * ATT_N]);

/* ---- prediction ---- */

/* The covariance part of the prediction:
 *     P <- F P F^T + G diag(var) G^T,   F = F2 F1,  G = F2 [I; 0; 0] = [I; 0; W+],
 * F1 = I + D1, F2 = I + D2 the factors of the transition Jacobian, d1 and d2 their values
 * in the order of att_gen_f1_pattern (any values: the angle rows on the body rates and
 * angles) and att_gen_f2_pattern (an implementation may take the entries that are
 * structural constants, 1 and -1 in D2, as such); var[j] >= 0 the body-rate noise per axis
 * (as for att_cov_add_rate_noise). A congruence plus a positive semi-definite term. Also
 * returns the first-order variance of each angle's increment over the step,
 * inc_var[i] = (D1 P D1^T)_ii for the rows ATT_PHI + i (i = 0, 1, 2), evaluated on P before
 * the prediction; >= 0 (rounding below zero is returned as 0). EKF_OK, or EKF_ERR_NUMERIC
 * with P and inc_var unchanged if a value of d1 or d2 is not finite. */
ekf_status_t att_cov_predict(att_cov_t *c, const ekf_scalar_t d1[ATT_GEN_F1_NNZ], const ekf_scalar_t d2[ATT_GEN_F2_NNZ],
                     const ekf_scalar_t var[3], ekf_scalar_t inc_var[3]);
/* P += G diag(var) G^T for the body-rate noise input (var[j] >= 0 per body axis j),
 * G = [I; 0; g] with g the Euler-rate block (row-major 3x3). Adds a positive
 * semi-definite matrix. */
void att_cov_add_rate_noise(att_cov_t *c, const ekf_scalar_t g[9], const ekf_scalar_t var[3]);
/* P_ii += var (>= 0) for i in first .. first+len-1. */
ATT_COV_DIAG_FN void att_cov_add_diag(att_cov_t *c, int first, int len, ekf_scalar_t var) ATT_COV_DIAG_BODY({
    int i;
    for (i = first; i < first + len; ++i) {
        c->p[ATT_COV_II(i)] = ekf_add(c->p[ATT_COV_II(i)], var);
    }
})
/* P_ii += var (>= 0) for the one state i. */
ATT_COV_DIAG_FN void att_cov_add_var(att_cov_t *c, int i, ekf_scalar_t var) ATT_COV_DIAG_BODY({
    c->p[ATT_COV_II(i)] = ekf_add(c->p[ATT_COV_II(i)], var);
})
/* P_ii <- P_ii + rel P_ii (rel >= 0) for i in first .. first+len-1. */
ATT_COV_DIAG_FN void att_cov_scale_diag(att_cov_t *c, int first, int len, ekf_scalar_t rel) ATT_COV_DIAG_BODY({
    int i;
    for (i = first; i < first + len; ++i) {
        c->p[ATT_COV_II(i)] = ekf_mac(c->p[ATT_COV_II(i)], c->p[ATT_COV_II(i)], rel);
    }
})

/* ---- bounds and remaps ---- */

/* P_ii <- max(P_ii, floor) for every i (adds a positive semi-definite matrix), for
 * variances that rounding left below the floor or small positive ones. Returns 0, or -1
 * with P unchanged if a variance is not finite or negative beyond rounding (below -32 n eps
 * times the largest variance; fixed point: -32 n LSB (1 + the largest variance)): no floor
 * hides that (the caller refuses). */
int att_cov_floor_diag(att_cov_t *c, ekf_scalar_t floor);
/* Row and column i zero, P_ii = var (> 0): state i uncorrelated with the others (a reset).
 * Keeps P positive (semi-)definite. */
void att_cov_reset_state(att_cov_t *c, int i, ekf_scalar_t var);
/* If P_ii > max_var (> 0): row and column i scaled by sqrt(max_var / P_ii), a congruence.
 * Returns 1 if P was changed, else 0 (also for a non-finite P_ii, left for the guard to
 * refuse). */
#if defined(ATT_COV_PACKED)
int att_cov_packed_limit_variance(att_cov_t *c, int i, ekf_scalar_t max_var);
#endif
ATT_COV_DIAG_FN int att_cov_limit_variance(att_cov_t *c, int i, ekf_scalar_t max_var) ATT_COV_DIAG_BODY({
    return (c->p[ATT_COV_II(i)] > max_var) ? att_cov_packed_limit_variance(c, i, max_var) : 0;
})
/* Row and column i negated (diagonal unchanged): the covariance of the state with x_i
 * replaced by -x_i, a congruence (the pitch remap, att_model_normalise). */
void att_cov_negate_state(att_cov_t *c, int i);

/* ---- measurement updates ----
 * One scalar measurement, innovation nu, noise variance r_var > 0, gate in sigmas (<= 0:
 * off), diagonal floor var_floor; x is the state the gain is applied to. The semantics of
 * ekf_update_scalar (ekf.h): EKF_OK, EKF_GATED, or an error with x and P unchanged; info
 * (may be NULL) as documented there. */

/* H = e_idx (a unit row: a body rate, or the heading). */
ekf_status_t att_cov_update_unit(att_cov_t *c, ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu,
                                 ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor,
                                 ekf_innov_t *info);
/* H with h[0], h[1], h[2] at ATT_PHI, ATT_THETA, ATT_PSI and zero elsewhere (an
 * accelerometer component; a measurement of the attitude in any angle coordinates). */
ekf_status_t att_cov_update_angles(att_cov_t *c, ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3], ekf_scalar_t nu,
                                   ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor,
                                   ekf_innov_t *info);

/* ---- definiteness ---- */

/* 1 if P has an LDL^T factorisation (in the scalar type) with every pivot
 * d_j >= rel_margin P_jj > 0 (ekf_cov_is_pd), else 0. ATT_COV_FX factorises P - tau I with
 * tau = ATT_COV_FX_TAU, an absolute margin: P then stays positive definite when its entries
 * are rounded to the scalar type (att_cov_to_full). */
int att_cov_is_pd(const att_cov_t *c, ekf_scalar_t rel_margin);
/* The guard: if att_cov_is_pd fails, P is repaired by diagonal loading
 * (ekf_cov_ensure_pd); afterwards every P_ii >= var_floor. Returns the number of repair
 * rounds, 0 if P passed, -1 with P unchanged if P has a non-finite entry. */
int att_cov_ensure_pd(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor);
/* The guard at the end of every public call of the filter: att_cov_floor_diag(c, var_floor),
 * then att_cov_ensure_pd(c, rel_margin, var_floor). Returns the number of repair rounds, 0 if
 * P passed, -1 if a variance is not finite or negative beyond rounding or an entry is not
 * finite (P may have been floored; the caller refuses the call). */
int att_cov_guard(att_cov_t *c, ekf_scalar_t rel_margin, ekf_scalar_t var_floor);

#ifdef __cplusplus
}
#endif

#endif /* ATT_COV_H */
