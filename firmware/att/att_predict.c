/*
 * att_predict.c - the prediction stage: transition, F P F^T, process noise, variance
 * limits, the accelerometer low-pass carried with the body (docs/derivation.md,
 * "Transition", "Process noise", "Covariance bounds", "Linear acceleration").
 */
#include <stddef.h>

#include "att_predict.h"

#include "att_gen.h"
#include "att_lowpass.h"
#include "att_model.h"
#include "att_state.h"
#include "ekf_util.h"

/* Keeps every variance below a physical bound (docs/derivation.md, "Covariance bounds"):
 * body rates within the gyro range, roll and pitch within half a turn, Euler rates within
 * what W can produce from in-range body rates at the gimbal limit. Only reached under
 * inputs far outside normal use (very long steps at extreme rates), where it keeps P
 * finite; a congruence, so P stays positive definite. */
static void limit_variances(att_vars_t *v, const att_settings_t *s)
{
    const ekf_scalar_t rate_max = ekf_sq(s->gyro_range);
    /* The Euler-rate bound is at least (3 gyro_range)^2 (sec >= 1): its cosine is evaluated
     * only when a variance exceeds that, never in normal use. Capping a body rate does not
     * change the Euler-rate variances, so the test before the loop holds in it. */
    ekf_scalar_t euler_rate_max = ekf_sq(ekf_mul(s->gyro_range, EKF_C(3)));
    int i;
    for (i = ATT_PHID; i <= ATT_PSID; ++i) {
        if (att_cov_var(&v->cov, i) > euler_rate_max) {
            const ekf_scalar_t sec_lim = ekf_div(EKF_C(1), ekf_cos(s->gimbal_limit));
            euler_rate_max = ekf_sq(ekf_mul(s->gyro_range, ekf_add(EKF_C(1), ekf_mul(EKF_C(2), sec_lim))));
            break;
        }
    }
    for (i = 0; i < 3; ++i) {
        (void)att_cov_limit_variance(&v->cov, ATT_P + i, rate_max);
        (void)att_cov_limit_variance(&v->cov, ATT_PHID + i, euler_rate_max);
    }
    (void)att_cov_limit_variance(&v->cov, ATT_PHI, ekf_sq(EKF_PI));
    (void)att_cov_limit_variance(&v->cov, ATT_THETA, ekf_sq(EKF_HALF_PI));
}

/* A step longer than the sample interval by more than half of it is a gap: the body rate
 * was not measured over the excess e, and its random walk integrates into the angles,
 * rate_walk^2 e^3 / 3 in each body axis (the integrated random walk), mapped to the Euler
 * angles by W's rows (sec^2 theta, 1, sec^2 theta; their correlations left out, which only
 * overstates). The offset learned in motion does not learn from the errors that follow.
 * Steps that are not gaps keep the interval's running mean (docs/derivation.md, "Gaps"). */
static void gap_noise(att_vars_t *v, const att_settings_t *s, const att_motion_t *mo, ekf_scalar_t dt)
{
    if (!(v->dt_nom > EKF_C(0))) {
        v->dt_nom = dt;
    } else if (dt > ekf_mul(EKF_C(1.5), v->dt_nom)) {
        const ekf_scalar_t e = ekf_sub(dt, v->dt_nom);
        const ekf_scalar_t q = ekf_div(ekf_mul(ekf_mul(ekf_sq(s->rate_walk), ekf_sq(e)), e), EKF_C(3));
        const ekf_scalar_t sec2 = ekf_sq(mo->t.secth);
        att_cov_add_var(&v->cov, ATT_PHI, ekf_mul(q, sec2));
        att_cov_add_var(&v->cov, ATT_THETA, q);
        att_cov_add_var(&v->cov, ATT_PSI, ekf_mul(q, sec2));
        if (q > ekf_min(att_cov_var(&v->cov, ATT_PHI), att_cov_var(&v->cov, ATT_THETA))) {
            /* an error the tilt's own uncertainty does not cover */
            att_bias_hold(&v->bias, s->bias.hold_time);
        }
    } else {
        v->dt_nom = ekf_mac(v->dt_nom, ekf_div(dt, ekf_add(EKF_C(0.2), dt)), ekf_sub(dt, v->dt_nom));
    }
}

/* F = F2 F1 (row-major), for the trace. */
static void full_jacobian(const ekf_scalar_t d1[ATT_GEN_F1_NNZ], const ekf_scalar_t d2[ATT_GEN_F2_NNZ],
                          ekf_scalar_t F[ATT_N * ATT_N])
{
    ekf_scalar_t F1[ATT_N * ATT_N], F2[ATT_N * ATT_N];
    int i, j, k;
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        F1[i] = F2[i] = (i % (ATT_N + 1) == 0) ? EKF_C(1) : EKF_C(0);
    }
    for (k = 0; k < ATT_GEN_F1_NNZ; ++k) {
        const int at = att_gen_f1_pattern[k].row * ATT_N + att_gen_f1_pattern[k].col;
        F1[at] = ekf_add(F1[at], d1[k]);
    }
    for (k = 0; k < ATT_GEN_F2_NNZ; ++k) {
        const int at = att_gen_f2_pattern[k].row * ATT_N + att_gen_f2_pattern[k].col;
        F2[at] = ekf_add(F2[at], d2[k]);
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            ekf_scalar_t a = EKF_C(0);
            for (k = 0; k < ATT_N; ++k) {
                a = ekf_mac(a, F2[i * ATT_N + k], F1[k * ATT_N + j]);
            }
            F[i * ATT_N + j] = a;
        }
    }
}

/* P <- F P F^T + Q over the interval dt (s), with the transition factors d1, d2 of the
 * motion mo; the offset filter and the considered errors advance with it. Q = G
 * diag(rate_walk^2 dt) G^T (with the propagation; refused if the Jacobian is not finite) +
 * angle random walk + the discrete kinematics' own error: independent, euler_rate_rel of the
 * variance of each angle's increment and of each Euler rate (docs/derivation.md,
 * "Conditioning"). Reads the state before the prediction (v->x). */
static ekf_status_t propagate_covariance(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                                         const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const att_motion_t *mo, ekf_scalar_t dt)
{
    ekf_scalar_t inc_var[3];
    int i;
    {
        const ekf_scalar_t q = ekf_mul(ekf_sq(s->rate_walk), dt), var[3] = {q, q, q};
        if (att_cov_predict(&v->cov, d1, d2, var, inc_var) != EKF_OK) {
            return EKF_ERR_NUMERIC;
        }
    }
    att_cov_add_diag(&v->cov, ATT_PHI, 3, ekf_mul(ekf_sq(s->angle_walk), dt));
    for (i = 0; i < 3; ++i) {
        att_cov_add_var(&v->cov, ATT_PHI + i, ekf_mul(s->euler_rate_rel, inc_var[i]));
    }
    att_cov_scale_diag(&v->cov, ATT_PHID, 3, s->euler_rate_rel);
    gap_noise(v, s, mo, dt);
    att_bias_predict(&v->bias, &s->bias, d1, dt);
    att_consider_predict(&v->consider,
                         ekf_add(ekf_add(ekf_sq(v->x[ATT_P]), ekf_sq(v->x[ATT_Q])), ekf_sq(v->x[ATT_R])),
                         s->angle_walk_rate, ekf_sq(mo->t.secth), dt);
    return EKF_OK;
}

/* The predicted state xn (motion mo over dt, s) becomes the state, with what depends on it:
 * the trigonometry kept for the next stage, the low-pass turned with the body, the remap and
 * gimbal flags, the variance limits and the heading-limited flag, the gates' clocks. */
static void adopt_prediction(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t xn[ATT_N],
                             const att_motion_t *mo, ekf_scalar_t dt)
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        v->x[i] = xn[i];
    }
    v->last_dt = dt;
    if (!(ekf_abs(xn[ATT_THETA]) > s->gimbal_limit)) {
        /* the new angles' trigonometry, unclamped here: the measurement stage that follows
         * takes it instead of computing it again (att_sensor_trig) */
        v->trig = mo->t;
        v->trig_at[0] = xn[ATT_PHI];
        v->trig_at[1] = xn[ATT_THETA];
    }
    if (s->accel_lpf_tau > EKF_C(0)) {
        att_lowpass_turn(v, s, mo->rot);
    }
    /* the composed rotation's angles are in range already; passing over the top shows as a
     * half turn of roll and heading (the Jacobian was taken at the new angles) */
    v->flags &= ~ATT_FLAG_REMAPPED;
    if (mo->remapped) {
        v->flags |= ATT_FLAG_REMAPPED;
        ekf_count(&v->diag.remaps);
    }
    att_update_gimbal_flag(v, s);
    if ((v->flags & ATT_FLAG_GIMBAL_LOCK) != 0u) {
        /* the clamped kinematics do not follow an offset error the way V says */
        att_bias_restart(&v->bias);
    }
    limit_variances(v, s);
    /* without a reference the heading is arbitrary whatever its variance (the accelerometer's
     * updates at a pitch reduce it below the cap: "no turn about the vertical") */
    if (att_cov_limit_variance(&v->cov, ATT_PSI, s->heading_var_max) ||
        !(att_cov_var(&v->cov, ATT_PSI) < s->heading_var_max) || v->heading_ref == 0u) {
        v->flags |= ATT_FLAG_HEADING_LIMITED;
    } else {
        v->flags &= ~ATT_FLAG_HEADING_LIMITED;
    }
    /* time bookkeeping for the gate timeouts */
    for (i = 0; i < 3; ++i) {
        if (v->gated_time[i] > EKF_C(0)) {
            v->gated_time[i] = ekf_add(v->gated_time[i], dt);
        }
    }
}

ekf_status_t att_stage_predict(att_vars_t *v, const att_settings_t *s, ekf_scalar_t dt, att_trace_t *trace)
{
    ekf_scalar_t xn[ATT_N];
    ekf_scalar_t d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ];
    att_motion_t mo;
    int i;

    att_model_transition(v->x, NULL, dt, s->gimbal_limit, xn, &mo);
    if (!att_state_finite(xn)) {
        return EKF_ERR_NUMERIC;
    }
    /* F = F2 F1 (docs/derivation.md, "State Jacobian") */
    att_gen_transition_factors(&mo.t0, &mo.t, v->x, mo.rot, mo.jd, d1, d2);
    if (trace != NULL) {
        for (i = 0; i < ATT_N; ++i) {
            trace->x_pre[i] = v->x[i];
        }
        att_cov_to_full(&v->cov, trace->P_pre);
        full_jacobian(d1, d2, trace->F);
    }
    if (propagate_covariance(v, s, d1, d2, &mo, dt) != EKF_OK) {
        return EKF_ERR_NUMERIC;
    }
    adopt_prediction(v, s, xn, &mo, dt);
    if (trace != NULL) {
        for (i = 0; i < ATT_N; ++i) {
            trace->x_pred[i] = v->x[i];
        }
        att_cov_to_full(&v->cov, trace->P_pred);
        trace->predicted = 1;
    }
    return EKF_OK;
}
