/*
 * ekf_util.h - small helpers shared by the attitude filter and the model library: a
 * saturating event counter and the range test of a setting.
 */
#ifndef EKF_UTIL_H
#define EKF_UTIL_H

#include <stdint.h>

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

#ifdef __cplusplus
}
#endif

#endif /* EKF_UTIL_H */
