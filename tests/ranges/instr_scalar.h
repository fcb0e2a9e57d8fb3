/*
 * instr_scalar.h - the double build with every scalar operation recorded: the measured
 * ranges behind the fixed-point formats (docs/fixed_point.md, "Measured ranges";
 * scripts/fixed_ranges.py builds and runs it).
 *
 * Force-included (gcc -include) before every source of the estimator: it includes the real
 * ekf_scalar.h (double branch) and then replaces each arithmetic operation, the public
 * att_step and each att_cov.h operation by a recording wrapper (instr.c). The estimator's
 * own sources are compiled unchanged; att.c is compiled with INSTR_NO_API and the covariance
 * implementation with INSTR_NO_COV, so that their definitions keep their names.
 * Measurement only: never part of a shipped build.
 */
#ifndef INSTR_SCALAR_H
#define INSTR_SCALAR_H

#include "ekf_scalar.h"

#if !defined(EKF_SCALAR_DOUBLE)
#error "instr_scalar.h instruments the double build only"
#endif

double instr_add(double a, double b);
double instr_sub(double a, double b);
double instr_mul(double a, double b);
double instr_div(double a, double b);
double instr_mac(double c, double a, double b);
double instr_sqrt(double a);
double instr_sin(double a);
double instr_cos(double a);
double instr_atan2(double y, double x);

#define ekf_add(a, b) instr_add((a), (b))
#define ekf_sub(a, b) instr_sub((a), (b))
#define ekf_mul(a, b) instr_mul((a), (b))
#define ekf_div(a, b) instr_div((a), (b))
#define ekf_mac(c, a, b) instr_mac((c), (a), (b))
#define ekf_sq(a) instr_mul((a), (a))
#define ekf_sqrt(a) instr_sqrt(a)
#define ekf_sin(a) instr_sin(a)
#define ekf_cos(a) instr_cos(a)
#define ekf_atan2(y, x) instr_atan2((y), (x))

#if !defined(INSTR_NO_API)
#define att_step instr_att_step
#endif

#if !defined(INSTR_NO_COV)
#define att_cov_set_diag instr_cov_set_diag
#define att_cov_predict instr_cov_predict
#define att_cov_add_rate_noise instr_cov_add_rate_noise
#define att_cov_add_diag instr_cov_add_diag
#define att_cov_add_var instr_cov_add_var
#define att_cov_scale_diag instr_cov_scale_diag
#define att_cov_floor_diag instr_cov_floor_diag
#define att_cov_reset_state instr_cov_reset_state
#define att_cov_limit_variance instr_cov_limit_variance
#define att_cov_update_unit instr_cov_update_unit
#define att_cov_update_tilt instr_cov_update_tilt
#define att_cov_ensure_pd instr_cov_ensure_pd
#define att_cov_guard instr_cov_guard
#endif

#endif /* INSTR_SCALAR_H */
