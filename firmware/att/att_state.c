/*
 * att_state.c - keeping the filter's variables consistent: the one copy a call saves, the
 * finiteness of the state, the angles in their ranges with the covariance remapped, the
 * gimbal flag, the definiteness guard at the end of a call (docs/derivation.md, "Covariance
 * bounds").
 */
#include "att_state.h"

#include <string.h>

#include "att_model.h"
#include "ekf_util.h"

void att_vars_copy(att_vars_t *dst, const att_vars_t *src)
{
#if defined(__GNUC__) && defined(__thumb2__)
    /* 8 words per ldm/stm pair: 4 instructions per 32 bytes, where the C library's memcpy
     * spends 16 ldr/str pairs on 64 (docs/performance.md, "Commit") */
    unsigned char *d = (unsigned char *)dst;
    const unsigned char *s = (const unsigned char *)src;
    unsigned n = (unsigned)(sizeof *dst / 32u);
    __asm__ volatile("1:\n\t"
                     "ldmia %[s]!, {r2, r3, r4, r5, r6, r8, r9, r10}\n\t"
                     "stmia %[d]!, {r2, r3, r4, r5, r6, r8, r9, r10}\n\t"
                     "subs %[n], %[n], #1\n\t"
                     "bne 1b"
                     : [d] "+r"(d), [s] "+r"(s), [n] "+r"(n)
                     :
                     : "r2", "r3", "r4", "r5", "r6", "r8", "r9", "r10", "cc", "memory");
    memcpy(d, s, sizeof *dst % 32u);
#else
    memcpy(dst, src, sizeof *dst);
#endif
}

typedef char att_state_finite_needs_9_states[(ATT_N == 9) ? 1 : -1];

int att_state_finite(const ekf_scalar_t x[ATT_N])
{
    ekf_scalar_t acc = ekf_finite_acc(ekf_finite_acc(ekf_finite_acc(EKF_C(0), x[0]), x[1]), x[2]);
    acc = ekf_finite_acc(ekf_finite_acc(ekf_finite_acc(acc, x[3]), x[4]), x[5]);
    acc = ekf_finite_acc(ekf_finite_acc(ekf_finite_acc(acc, x[6]), x[7]), x[8]);
    return acc == EKF_C(0);
}

ekf_scalar_t att_norm3(const ekf_scalar_t vec[3])
{
    return ekf_sqrt(ekf_add(ekf_add(ekf_sq(vec[0]), ekf_sq(vec[1])), ekf_sq(vec[2])));
}

void att_update_gimbal_flag(att_vars_t *v, const att_settings_t *s)
{
    if (ekf_abs(v->x[ATT_THETA]) > s->gimbal_limit) {
        v->flags |= ATT_FLAG_GIMBAL_LOCK;
    } else {
        v->flags &= ~ATT_FLAG_GIMBAL_LOCK;
    }
}

int att_normalise(att_vars_t *v)
{
    if (att_model_normalise(v->x)) {
        /* theta -> +-pi - theta and thetad -> -thetad: their rows and columns change sign */
        att_cov_negate_state(&v->cov, ATT_THETA);
        att_cov_negate_state(&v->cov, ATT_THETAD);
        att_bias_remap(&v->bias);
        return 1;
    }
    return 0;
}

/* Rounding in F P F^T and in the updates can make P indefinite when it is ill-conditioned;
 * repair it once per public call, and say so; refuse what rounding cannot explain
 * (docs/derivation.md, "Covariance bounds"). */
ekf_status_t att_guard_covariance(att_vars_t *v, const att_settings_t *s)
{
    int rounds;
    if ((v->flags & ATT_FLAG_ALIGNED) == 0u) {
        return EKF_OK;
    }
    /* The updates floor the variances they reduce, but the prediction can reduce one too
     * (F P F^T with a negative correlation, and no process noise on it if angle_walk = 0):
     * the guard floors them first (raising a diagonal entry keeps P positive
     * (semi-)definite), then checks and if need be repairs. */
    rounds = att_cov_guard(&v->cov, ATT_PD_MARGIN, s->var_floor);
    if (rounds < 0 || rounds > ATT_REPAIR_ROUNDS) {
        /* a non-finite P, a variance negative beyond rounding, or a P that one round of
         * rounding-sized loading does not make positive definite: not rounding's doing, and
         * no repair may hide it (the call is refused; att.h, "Contract") */
        return EKF_ERR_NUMERIC;
    }
    if (rounds > 0) {
        v->flags |= ATT_FLAG_COV_REPAIRED;
        ekf_count(&v->diag.cov_repairs);
    } else {
        v->flags &= ~ATT_FLAG_COV_REPAIRED;
    }
    return EKF_OK;
}
