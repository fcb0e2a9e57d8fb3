/*
 * att_cov_ref_wrap.h - the reference covariance implementation (firmware/att/att_cov_ref.c)
 * under other names, on a full row-major P[ATT_N * ATT_N], linked beside the library's
 * generated one so that a test can run both on the same input (test_att_cov.c). Each
 * function is the att_cov.h operation of the same name (refcov_update_unit:
 * att_cov_update_unit, ...), P read and written in full.
 */
#ifndef ATT_COV_REF_WRAP_H
#define ATT_COV_REF_WRAP_H

#include "att_defs.h"
#include "att_gen.h"
#include "ekf.h"

#define ATT_NN (ATT_N * ATT_N)

void refcov_set_diag(ekf_scalar_t P[ATT_NN], const ekf_scalar_t var[ATT_N]);
ekf_status_t refcov_predict(ekf_scalar_t P[ATT_NN], const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                            const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const ekf_scalar_t var[3], ekf_scalar_t inc_var[3]);
void refcov_add_rate_noise(ekf_scalar_t P[ATT_NN], const ekf_scalar_t g[9], const ekf_scalar_t var[3]);
void refcov_add_diag(ekf_scalar_t P[ATT_NN], int first, int len, ekf_scalar_t var);
void refcov_add_var(ekf_scalar_t P[ATT_NN], int i, ekf_scalar_t var);
void refcov_scale_diag(ekf_scalar_t P[ATT_NN], int first, int len, ekf_scalar_t rel);
int refcov_floor_diag(ekf_scalar_t P[ATT_NN], ekf_scalar_t floor);
void refcov_reset_state(ekf_scalar_t P[ATT_NN], int i, ekf_scalar_t var);
int refcov_limit_variance(ekf_scalar_t P[ATT_NN], int i, ekf_scalar_t max_var);
void refcov_negate_state(ekf_scalar_t P[ATT_NN], int i);
ekf_status_t refcov_update_unit(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu,
                                ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor, ekf_innov_t *info);
ekf_status_t refcov_update_angles(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3],
                                  ekf_scalar_t nu, ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor,
                                  ekf_innov_t *info);
int refcov_is_pd(const ekf_scalar_t P[ATT_NN], ekf_scalar_t rel_margin);
int refcov_guard(ekf_scalar_t P[ATT_NN], ekf_scalar_t rel_margin, ekf_scalar_t var_floor);

#endif /* ATT_COV_REF_WRAP_H */
