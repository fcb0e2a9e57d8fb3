/*
 * att_state.h - keeping the filter's variables (att_vars_t) consistent: the saved copy, the
 * state's finiteness, the angles' ranges, the gimbal flag, the covariance guard. Not part of
 * the public API.
 */
#ifndef ATT_STATE_H
#define ATT_STATE_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Smallest accepted LDL^T pivot relative to its variance. The factorisation computed in
 * the filter's scalar is the exact one of P + dP with |dP_ij| up to about n^2 eps
 * sqrt(P_ii P_jj): the margin must be well above that, or a float P that is indefinite by
 * 5e-5 of its diagonal passes. 10 n^2 eps is 1e-4 in float, far below the Euler-rate
 * pivots (~euler_rate_rel = 1e-3) that the model keeps by design (docs/derivation.md,
 * "Covariance bounds"). */
#define ATT_PD_MARGIN ekf_mul(EKF_C(10 * ATT_N * ATT_N), EKF_SCALAR_EPS)

/* Repair rounds the guard accepts: one, a diagonal loading by ten times the margin above
 * (ekf_cov_ensure_pd's first round), the size of what rounding in one call can do. A P that
 * needs more was indefinite beyond rounding (a kernel's bug, a corrupted filter): the call
 * is refused rather than repaired (docs/derivation.md, "Covariance bounds"). */
#define ATT_REPAIR_ROUNDS 1

/* *dst = *src byte for byte (padding included, so that a restored filter compares equal):
 * the one copy of the variables each call takes before its stages run. */
void att_vars_copy(att_vars_t *dst, const att_vars_t *src);

/* 1 if every state is finite (ekf_all_finite for n = ATT_N, unrolled: one multiply-add per
 * state on an FPU, no loop). */
int att_state_finite(const ekf_scalar_t x[ATT_N]);
/* |vec|. */
ekf_scalar_t att_norm3(const ekf_scalar_t vec[3]);
/* ATT_FLAG_GIMBAL_LOCK from the pitch. */
void att_update_gimbal_flag(att_vars_t *v, const att_settings_t *s);
/* Angles into their ranges (att_model_normalise), the covariance remapped with them.
 * Returns 1 if the pitch passed +-90 deg (remap). */
int att_normalise(att_vars_t *v);
/* The definiteness guard at the end of a call (docs/derivation.md, "Covariance bounds"):
 * floors the variances, repairs P if needed (counted, ATT_FLAG_COV_REPAIRED). EKF_OK, or
 * EKF_ERR_NUMERIC if P is not finite (the call is then refused). */
ekf_status_t att_guard_covariance(att_vars_t *v, const att_settings_t *s);

#ifdef __cplusplus
}
#endif

#endif /* ATT_STATE_H */
