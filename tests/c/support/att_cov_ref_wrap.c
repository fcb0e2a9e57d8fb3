/*
 * att_cov_ref_wrap.c - see att_cov_ref_wrap.h. Compiled with ATT_COV_REFERENCE (the
 * target's definition in tests/c/CMakeLists.txt): att_cov_ref.c itself is included with its
 * functions renamed, so that they do not clash with the library's generated ones; what they
 * call (ekf_update_scalar, att_gen_cov_propagate_f1, ...) is the library's.
 */
#include "att_cov_ref_wrap.h"

#include <string.h>

#if !defined(ATT_COV_REFERENCE)
#error "att_cov_ref_wrap.c must be compiled with ATT_COV_REFERENCE"
#endif

#define att_cov_set_diag refimpl_set_diag
#define att_cov_get refimpl_get
#define att_cov_var refimpl_var
#define att_cov_to_full refimpl_to_full
#define att_cov_from_full refimpl_from_full
#define att_cov_predict refimpl_predict
#define att_cov_add_rate_noise refimpl_add_rate_noise
#define att_cov_add_diag refimpl_add_diag
#define att_cov_add_var refimpl_add_var
#define att_cov_scale_diag refimpl_scale_diag
#define att_cov_floor_diag refimpl_floor_diag
#define att_cov_reset_state refimpl_reset_state
#define att_cov_limit_variance refimpl_limit_variance
#define att_cov_negate_state refimpl_negate_state
#define att_cov_update_unit refimpl_update_unit
#define att_cov_update_angles refimpl_update_angles
#define att_cov_is_pd refimpl_is_pd
#define att_cov_ensure_pd refimpl_ensure_pd
#define att_cov_guard refimpl_guard
#include "att_cov_ref.c"

static void load(att_cov_t *c, const ekf_scalar_t P[ATT_NN]) { memcpy(c->P, P, sizeof c->P); }
static void store(const att_cov_t *c, ekf_scalar_t P[ATT_NN]) { memcpy(P, c->P, sizeof c->P); }

void refcov_set_diag(ekf_scalar_t P[ATT_NN], const ekf_scalar_t var[ATT_N])
{
    att_cov_t c;
    refimpl_set_diag(&c, var);
    store(&c, P);
}

ekf_status_t refcov_predict(ekf_scalar_t P[ATT_NN], const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                            const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const ekf_scalar_t var[3], ekf_scalar_t inc_var[3])
{
    att_cov_t c;
    ekf_status_t st;
    load(&c, P);
    st = refimpl_predict(&c, d1, d2, var, inc_var);
    store(&c, P);
    return st;
}

void refcov_add_rate_noise(ekf_scalar_t P[ATT_NN], const ekf_scalar_t g[9], const ekf_scalar_t var[3])
{
    att_cov_t c;
    load(&c, P);
    refimpl_add_rate_noise(&c, g, var);
    store(&c, P);
}

void refcov_add_diag(ekf_scalar_t P[ATT_NN], int first, int len, ekf_scalar_t var)
{
    att_cov_t c;
    load(&c, P);
    refimpl_add_diag(&c, first, len, var);
    store(&c, P);
}

void refcov_add_var(ekf_scalar_t P[ATT_NN], int i, ekf_scalar_t var)
{
    att_cov_t c;
    load(&c, P);
    refimpl_add_var(&c, i, var);
    store(&c, P);
}

void refcov_scale_diag(ekf_scalar_t P[ATT_NN], int first, int len, ekf_scalar_t rel)
{
    att_cov_t c;
    load(&c, P);
    refimpl_scale_diag(&c, first, len, rel);
    store(&c, P);
}

int refcov_floor_diag(ekf_scalar_t P[ATT_NN], ekf_scalar_t floor)
{
    att_cov_t c;
    int r;
    load(&c, P);
    r = refimpl_floor_diag(&c, floor);
    store(&c, P);
    return r;
}

void refcov_reset_state(ekf_scalar_t P[ATT_NN], int i, ekf_scalar_t var)
{
    att_cov_t c;
    load(&c, P);
    refimpl_reset_state(&c, i, var);
    store(&c, P);
}

int refcov_limit_variance(ekf_scalar_t P[ATT_NN], int i, ekf_scalar_t max_var)
{
    att_cov_t c;
    int r;
    load(&c, P);
    r = refimpl_limit_variance(&c, i, max_var);
    store(&c, P);
    return r;
}

void refcov_negate_state(ekf_scalar_t P[ATT_NN], int i)
{
    att_cov_t c;
    load(&c, P);
    refimpl_negate_state(&c, i);
    store(&c, P);
}

ekf_status_t refcov_update_unit(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], int idx, ekf_scalar_t nu,
                                ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor, ekf_innov_t *info)
{
    att_cov_t c;
    ekf_status_t st;
    load(&c, P);
    st = refimpl_update_unit(&c, x, idx, nu, r_var, gate, var_floor, info);
    store(&c, P);
    return st;
}

ekf_status_t refcov_update_angles(ekf_scalar_t P[ATT_NN], ekf_scalar_t x[ATT_N], const ekf_scalar_t h[3],
                                  ekf_scalar_t nu, ekf_scalar_t r_var, ekf_scalar_t gate, ekf_scalar_t var_floor,
                                  ekf_innov_t *info)
{
    att_cov_t c;
    ekf_status_t st;
    load(&c, P);
    st = refimpl_update_angles(&c, x, h, nu, r_var, gate, var_floor, info);
    store(&c, P);
    return st;
}

int refcov_is_pd(const ekf_scalar_t P[ATT_NN], ekf_scalar_t rel_margin)
{
    att_cov_t c;
    load(&c, P);
    return refimpl_is_pd(&c, rel_margin);
}

int refcov_guard(ekf_scalar_t P[ATT_NN], ekf_scalar_t rel_margin, ekf_scalar_t var_floor)
{
    att_cov_t c;
    int r;
    load(&c, P);
    r = refimpl_guard(&c, rel_margin, var_floor);
    store(&c, P);
    return r;
}
