/*
 * ekf_util.h - small helpers shared by the attitude filter and the model library: a
 * saturating event counter, the range test of a setting, and the innovation gate of the
 * scalar update.
 */
#ifndef EKF_UTIL_H
#define EKF_UTIL_H

#include <stddef.h>
#include <stdint.h>

#include "ekf.h"
#include "ekf_scalar.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Counts one event; the counter stays at UINT32_MAX instead of wrapping. */
static inline void ekf_count(uint32_t *c)
{
    if (*c != UINT32_MAX) {
        ++*c;
    }
}

/* 1 if v is finite and lo <= v <= hi. */
static inline int ekf_in_range(ekf_scalar_t v, ekf_scalar_t lo, ekf_scalar_t hi)
{
    return ekf_isfinite(v) && v >= lo && v <= hi;
}

/* The innovation gate of ekf_update_scalar (ekf.h), shared by it and the generated
 * covariance kernels (att_cov_gen.c), which must decide bit for bit alike: with gate > 0,
 * EKF_GATED if nu^2 > gate^2 s (or the ratio is not finite), else EKF_OK; the ratio
 * nu^2 / (gate^2 s) goes to info->test_ratio (info may be NULL). A gate so small that
 * gate^2 s underflows to 0 passes only a zero innovation (the ratio would be a division by
 * zero); 1e6 stands for "far out". */
static inline ekf_status_t ekf_gate_test(ekf_scalar_t nu, ekf_scalar_t s, ekf_scalar_t gate, ekf_innov_t *info)
{
    if (gate > EKF_C(0)) {
        const ekf_scalar_t nu2 = ekf_sq(nu);
        const ekf_scalar_t lim = ekf_mul(ekf_sq(gate), s);
        const ekf_scalar_t ratio = (lim > EKF_C(0)) ? ekf_div(nu2, lim) : ((nu2 > EKF_C(0)) ? EKF_C(1e6) : EKF_C(0));
        if (info != NULL) {
            info->test_ratio = ratio;
        }
        if (!ekf_isfinite(ratio) || ratio > EKF_C(1)) {
            return EKF_GATED;
        }
    }
    return EKF_OK;
}

#ifdef __cplusplus
}
#endif

#endif /* EKF_UTIL_H */
