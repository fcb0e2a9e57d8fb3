/*
 * att.c - the attitude estimator (see att.h; equations in docs/derivation.md): lifecycle,
 * the step, the public stages and the outputs. The stages themselves are in att_align.c,
 * att_predict.c and att_update.c; the covariance behind att_cov.h.
 */
#include "att.h"

#include <stddef.h>

#include "att_internal.h"
#include "att_model.h"
#include "ekf_util.h"

ekf_status_t att_init(att_ekf_t *f, const att_settings_t *settings)
{
    ekf_status_t st;
    att_ekf_t zero = {0};
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    st = att_settings_check(settings);
    if (st != EKF_OK) {
        return st;
    }
    *f = zero;
    f->settings = *settings;
    att_rest_reset(&f->vars.rest);
    return EKF_OK;
}

/* ---- helpers shared by the stages (att_internal.h) ---- */

ekf_status_t att_note(att_vars_t *v, ekf_status_t st)
{
    if (st == EKF_ERR_NUMERIC) {
        ekf_count(&v->diag.numeric);
    } else if (st != EKF_OK && st != EKF_GATED && st != EKF_SKIPPED) {
        ekf_count(&v->diag.rejected);
    }
    return st;
}

ekf_status_t att_check_vec(const ekf_scalar_t vec[3], ekf_scalar_t range)
{
    int i;
    if (vec == NULL) {
        return EKF_ERR_NULL;
    }
    for (i = 0; i < 3; ++i) {
        if (!ekf_isfinite(vec[i])) {
            return EKF_ERR_NOT_FINITE;
        }
    }
    for (i = 0; i < 3; ++i) {
        if (ekf_abs(vec[i]) > range) {
            return EKF_ERR_RANGE;
        }
    }
    return EKF_OK;
}

ekf_status_t att_check_dt(const att_settings_t *s, ekf_scalar_t dt)
{
    if (!ekf_isfinite(dt)) {
        return EKF_ERR_NOT_FINITE;
    }
    if (!(dt > EKF_C(0))) {
        return EKF_ERR_DT_NONPOSITIVE;
    }
    if (dt > s->dt_max) {
        return EKF_ERR_DT_TOO_LARGE;
    }
    return EKF_OK;
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
        return 1;
    }
    return 0;
}

/* Rounding in F P F^T and in the updates can make P indefinite when it is ill-conditioned
 * (Euler rates near gimbal lock at high rates, very long steps, float); repair it once
 * per public call, and say so (docs/derivation.md, "Covariance bounds"). */
void att_guard_covariance(att_vars_t *v, const att_settings_t *s)
{
    if ((v->flags & ATT_FLAG_ALIGNED) == 0u) {
        return;
    }
    /* The updates floor the variances they reduce, but the prediction can reduce one too
     * (F P F^T with a negative correlation, and no process noise on it if angle_walk = 0).
     * Raising a diagonal entry keeps P positive (semi-)definite. */
    att_cov_floor_diag(&v->cov, s->var_floor);
    if (att_cov_ensure_pd(&v->cov, ATT_PD_MARGIN, s->var_floor) > 0) {
        v->flags |= ATT_FLAG_COV_REPAIRED;
        ekf_count(&v->diag.cov_repairs);
    } else {
        v->flags &= ~ATT_FLAG_COV_REPAIRED;
    }
}

/* ---- public stages ---- */

ekf_status_t att_align(att_ekf_t *f, const ekf_scalar_t accel[3], const ekf_scalar_t mag[3])
{
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    return att_stage_align(&f->vars, &f->settings, accel, mag);
}

/* The public stages: each one leaves P positive definite. */
static ekf_status_t guarded(att_ekf_t *f, ekf_status_t st)
{
    att_guard_covariance(&f->vars, &f->settings);
    return st;
}

ekf_status_t att_predict(att_ekf_t *f, ekf_scalar_t dt)
{
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    return guarded(f, att_stage_predict(&f->vars, &f->settings, dt));
}

ekf_status_t att_update_gyro(att_ekf_t *f, const ekf_scalar_t gyro[3])
{
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    return guarded(f, att_stage_gyro(&f->vars, &f->settings, gyro));
}

ekf_status_t att_update_accel(att_ekf_t *f, const ekf_scalar_t accel[3])
{
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    return guarded(f, att_stage_accel(&f->vars, &f->settings, accel));
}

ekf_status_t att_update_mag(att_ekf_t *f, const ekf_scalar_t mag[3])
{
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    return guarded(f, att_stage_mag(&f->vars, &f->settings, mag));
}

/* ---- the step ---- */

ekf_status_t att_step(att_ekf_t *f, const att_sample_t *sample, att_step_report_t *report)
{
    att_step_report_t local = {EKF_OK, EKF_OK, EKF_OK, EKF_OK}; /* set below; initialised for the analysers */
    att_step_report_t *rep = (report != NULL) ? report : &local;
    const att_settings_t *s;
    att_vars_t *v;
    ekf_status_t st;

    rep->predict = EKF_OK;
    rep->gyro = EKF_OK;
    rep->accel = EKF_OK;
    rep->mag = EKF_OK;
    if (f == NULL || sample == NULL) {
        return EKF_ERR_NULL;
    }
    s = &f->settings;
    v = &f->vars;
    /* rest detection sees every complete sample, from the first one on, so that the
     * initial rest already yields the gyroscope offset */
    v->flags &= ~ATT_FLAG_AT_REST;
    if ((sample->valid & (ATT_HAS_GYRO | ATT_HAS_ACCEL | ATT_GYRO_SATURATED)) == (ATT_HAS_GYRO | ATT_HAS_ACCEL) &&
        att_check_dt(s, sample->dt) == EKF_OK && att_check_vec(sample->gyro, s->gyro_range) == EKF_OK &&
        att_check_vec(sample->accel, s->accel_range) == EKF_OK &&
        att_rest_update(&v->rest, &s->rest, sample->gyro, sample->accel, sample->dt)) {
        v->flags |= ATT_FLAG_AT_REST;
    }
    if ((v->flags & ATT_FLAG_ALIGNED) == 0u) {
        return att_stage_align_step(f, sample, rep);
    }
    st = att_check_dt(s, sample->dt);
    if (st != EKF_OK) {
        rep->predict = att_note(v, st);
        return st;
    }
    /* The gyro sample describes the rotation over the interval ending now: fuse it
     * before propagating, so the angles integrate it (docs/derivation.md, "Step order"). */
    if ((sample->valid & ATT_GYRO_SATURATED) != 0u) {
        rep->gyro = att_stage_gyro_saturated(v, s, sample->gyro);
    } else if ((sample->valid & ATT_HAS_GYRO) != 0u) {
        rep->gyro = att_stage_gyro(v, s, sample->gyro);
    }
    rep->predict = att_stage_predict(v, s, sample->dt);
    if (rep->predict == EKF_OK) {
        ekf_count(&v->diag.steps);
    }
    if ((sample->valid & ATT_HAS_ACCEL) != 0u) {
        rep->accel = att_stage_accel(v, s, sample->accel);
    }
    if ((sample->valid & ATT_HAS_MAG) != 0u) {
        rep->mag = att_stage_mag(v, s, sample->mag);
    }
    att_guard_covariance(v, s);
    if (rep->predict != EKF_OK) {
        return rep->predict;
    }
    if (rep->gyro != EKF_OK) {
        return rep->gyro;
    }
    if (rep->accel != EKF_OK) {
        return rep->accel;
    }
    return rep->mag;
}

/* ---- outputs ---- */

void att_get_euler(const att_ekf_t *f, ekf_scalar_t euler[3])
{
    euler[0] = f->vars.x[ATT_PHI];
    euler[1] = f->vars.x[ATT_THETA];
    euler[2] = f->vars.x[ATT_PSI];
}

void att_get_body_rates(const att_ekf_t *f, ekf_scalar_t w[3])
{
    w[0] = f->vars.x[ATT_P];
    w[1] = f->vars.x[ATT_Q];
    w[2] = f->vars.x[ATT_R];
}

void att_get_gyro_bias(const att_ekf_t *f, ekf_scalar_t b[3])
{
    b[0] = f->vars.rest.bias[0];
    b[1] = f->vars.rest.bias[1];
    b[2] = f->vars.rest.bias[2];
}

void att_get_euler_rates(const att_ekf_t *f, ekf_scalar_t e[3])
{
    e[0] = f->vars.x[ATT_PHID];
    e[1] = f->vars.x[ATT_THETAD];
    e[2] = f->vars.x[ATT_PSID];
}

void att_get_quaternion(const att_ekf_t *f, ekf_scalar_t q[4])
{
    att_model_euler_to_quat(f->vars.x[ATT_PHI], f->vars.x[ATT_THETA], f->vars.x[ATT_PSI], q);
}

void att_get_variances(const att_ekf_t *f, ekf_scalar_t var[ATT_N])
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        var[i] = att_cov_var(&f->vars.cov, i);
    }
}

void att_get_covariance(const att_ekf_t *f, ekf_scalar_t P[ATT_N * ATT_N]) { att_cov_to_full(&f->vars.cov, P); }
const ekf_scalar_t *att_state(const att_ekf_t *f) { return f->vars.x; }
uint32_t att_flags(const att_ekf_t *f) { return f->vars.flags; }
const att_diag_t *att_diag(const att_ekf_t *f) { return &f->vars.diag; }
