/*
 * att.c - the attitude estimator (see att.h; equations in docs/derivation.md): lifecycle,
 * the step and the public stages: validation, the saved copy, the stages in order, the commit.
 * The stages are in att_align.c, att_predict.c, att_gyro.c, att_accel.c and att_mag.c; the
 * outputs in att_outputs.c; the covariance behind att_cov.h.
 */
#include "att.h"

#include <stddef.h>
#include <string.h>

#include "att_accel.h"
#include "att_align.h"
#include "att_gyro.h"
#include "att_mag.h"
#include "att_predict.h"
#include "att_settings.h"
#include "att_state.h"
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
    return att_reset(f);
}

ekf_status_t att_reset(att_ekf_t *f)
{
    const att_vars_t zero = {0};
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    f->vars = zero;
    att_rest_reset(&f->vars.rest);
    att_bias_reset(&f->vars.bias, &f->settings.bias);
    att_consider_reset(&f->vars.consider);
    return EKF_OK;
}

ekf_status_t att_set_settings(att_ekf_t *f, const att_settings_t *settings)
{
    ekf_status_t st;
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    st = att_settings_check(settings);
    if (st != EKF_OK) {
        return st;
    }
    if (!att_settings_same_fixed_part(&f->settings, settings)) {
        return EKF_ERR_SETTINGS; /* a setting that needs att_init changed */
    }
    f->settings = *settings;
    return EKF_OK;
}

/* ---- validation (before any write) ---- */

/* Finite, every component within +-range. */
static ekf_status_t check_vec(const ekf_scalar_t vec[3], ekf_scalar_t range)
{
    int i;
    if (vec == NULL) {
        return EKF_ERR_NULL;
    }
    /* the normal case in three comparisons (range is finite: NaN and inf fail them) */
    if (ekf_abs(vec[0]) <= range && ekf_abs(vec[1]) <= range && ekf_abs(vec[2]) <= range) {
        return EKF_OK;
    }
    /* a component is not finite (that error first) or beyond the range */
    for (i = 0; i < 3; ++i) {
        if (!ekf_isfinite(vec[i])) {
            return EKF_ERR_NOT_FINITE;
        }
    }
    return EKF_ERR_RANGE;
}

/* Finite (the accelerometer: its stages judge a reading at the range as clipped). */
static ekf_status_t check_finite(const ekf_scalar_t vec[3])
{
    if (vec == NULL) {
        return EKF_ERR_NULL;
    }
    return (ekf_isfinite(vec[0]) && ekf_isfinite(vec[1]) && ekf_isfinite(vec[2])) ? EKF_OK : EKF_ERR_NOT_FINITE;
}

/* A time step in (0, dt_max]. */
static ekf_status_t check_dt(const att_settings_t *s, ekf_scalar_t dt)
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

/* A refused call: its one error counter, nothing else. */
static ekf_status_t refuse(att_ekf_t *f, ekf_status_t st)
{
    ekf_count(st == EKF_ERR_NUMERIC ? &f->vars.diag.numeric : &f->vars.diag.rejected);
    return st;
}

/* ---- the saved copy and the commit ----
 * Every call that changes the filter first saves its variables (everything but the
 * settings) in one copy, runs its stages on the variables themselves, and puts the copy
 * back if anything in the call fails, so that a refusal anywhere (a numeric failure in the
 * middle of a stage, or the guard at the end) leaves the filter exactly as it was but for
 * its error counter (att.h). Bad input is refused before the copy is taken. One copy of
 * sizeof(att_vars_t) per call on the normal path (docs/architecture.md, "Contract"). */

/* A call refused after its stages ran: the variables back, then the one error counter. */
static ekf_status_t restore(att_ekf_t *f, const att_vars_t *saved, ekf_status_t st)
{
    att_vars_copy(&f->vars, saved);
    return refuse(f, st);
}

/* The end of every call that ran stages (the variables saved in *saved): the guard and a
 * last finiteness check. EKF_OK, or EKF_ERR_NUMERIC (the variables restored, counted). */
static ekf_status_t commit(att_ekf_t *f, const att_vars_t *saved)
{
    if (att_guard_covariance(&f->vars, &f->settings) != EKF_OK || !att_state_finite(f->vars.x)) {
        return restore(f, saved, EKF_ERR_NUMERIC);
    }
    return EKF_OK;
}

/* ---- public stages ---- */

ekf_status_t att_align(att_ekf_t *f, const ekf_scalar_t accel[3], const ekf_scalar_t mag[3])
{
    att_vars_t saved;
    ekf_status_t st;
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    st = check_vec(accel, f->settings.accel_range);
    if (st == EKF_OK && !att_align_has_gravity(&f->settings, accel)) {
        st = EKF_ERR_RANGE; /* no usable gravity direction (free fall) */
    }
    if (st == EKF_OK && mag != NULL) {
        st = check_vec(mag, f->settings.mag_range);
    }
    if (st != EKF_OK) {
        return refuse(f, st);
    }
    att_vars_copy(&saved, &f->vars);
    (void)att_stage_align(&f->vars, &f->settings, accel, mag);
    return commit(f, &saved);
}

ekf_status_t att_predict(att_ekf_t *f, ekf_scalar_t dt)
{
    att_vars_t saved;
    ekf_status_t st;
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    st = ((f->vars.flags & ATT_FLAG_ALIGNED) == 0u) ? EKF_ERR_NOT_INITIALISED : check_dt(&f->settings, dt);
    if (st != EKF_OK) {
        return refuse(f, st);
    }
    att_vars_copy(&saved, &f->vars);
    st = att_stage_predict(&f->vars, &f->settings, dt, NULL);
    if (ekf_status_is_error(st)) {
        return restore(f, &saved, st);
    }
    return (commit(f, &saved) == EKF_OK) ? st : EKF_ERR_NUMERIC;
}

typedef ekf_status_t (*sensor_stage_t)(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t vec[3],
                                       ekf_scalar_t dt);

/* att_update_gyro, _accel, _mag: aligned filter, a valid vector and interval, one stage
 * (range 0: finite only). */
static ekf_status_t public_update(att_ekf_t *f, const ekf_scalar_t vec[3], ekf_scalar_t dt, ekf_scalar_t range,
                                  sensor_stage_t stage)
{
    att_vars_t saved;
    ekf_status_t st;
    if (f == NULL) {
        return EKF_ERR_NULL;
    }
    st = ((f->vars.flags & ATT_FLAG_ALIGNED) == 0u) ? EKF_ERR_NOT_INITIALISED
         : (range > EKF_C(0))                       ? check_vec(vec, range)
                                                    : check_finite(vec);
    if (st == EKF_OK) {
        st = check_dt(&f->settings, dt);
    }
    if (st != EKF_OK) {
        return refuse(f, st);
    }
    att_vars_copy(&saved, &f->vars);
    st = stage(&f->vars, &f->settings, vec, dt);
    if (ekf_status_is_error(st)) {
        return restore(f, &saved, st);
    }
    return (commit(f, &saved) == EKF_OK) ? st : EKF_ERR_NUMERIC;
}

ekf_status_t att_update_gyro(att_ekf_t *f, const ekf_scalar_t gyro[3], ekf_scalar_t dt)
{
    return public_update(f, gyro, dt, (f != NULL) ? f->settings.gyro_range : EKF_C(0), att_stage_gyro);
}

ekf_status_t att_update_accel(att_ekf_t *f, const ekf_scalar_t accel[3], ekf_scalar_t dt)
{
    return public_update(f, accel, dt, EKF_C(0), att_stage_accel); /* (clipping: the stage) */
}

ekf_status_t att_update_mag(att_ekf_t *f, const ekf_scalar_t mag[3], ekf_scalar_t dt)
{
    return public_update(f, mag, dt, (f != NULL) ? f->settings.mag_range : EKF_C(0), att_stage_mag);
}

/* ---- the step ---- */

static void report_all(att_step_report_t *rep, ekf_status_t st)
{
    rep->predict = st;
    rep->gyro = st;
    rep->accel = st;
    rep->mag = st;
}

/* The first error of the report (order predict, gyro, accel, mag), EKF_OK if none. */
static ekf_status_t first_error(const att_step_report_t *rep)
{
    return ekf_status_is_error(rep->predict) ? rep->predict
           : ekf_status_is_error(rep->gyro)  ? rep->gyro
           : ekf_status_is_error(rep->accel) ? rep->accel
           : ekf_status_is_error(rep->mag)   ? rep->mag
                                  : EKF_OK;
}

/* Every input of the sample, before anything is written: the report gets each bad input's
 * error in its slot, EKF_SKIPPED in every other slot. Returns the first error or EKF_OK. */
static ekf_status_t validate_sample(const att_ekf_t *f, const att_sample_t *sm, att_step_report_t *rep)
{
    const att_settings_t *s = &f->settings;
    const int aligned = (f->vars.flags & ATT_FLAG_ALIGNED) != 0u;
    ekf_status_t st;
    report_all(rep, EKF_SKIPPED);
    if (aligned) {
        rep->predict = check_dt(s, sm->dt); /* while aligning dt is not an input */
    } else if ((sm->valid & ATT_HAS_ACCEL) == 0u) {
        rep->accel = EKF_ERR_NOT_INITIALISED; /* nothing to align on */
    }
    if ((sm->valid & (ATT_HAS_GYRO | ATT_GYRO_SATURATED)) != 0u) {
        rep->gyro = check_vec(sm->gyro, s->gyro_range);
    }
    if ((sm->valid & ATT_HAS_ACCEL) != 0u) {
        rep->accel = check_finite(sm->accel); /* a clipped reading is the stages' to skip */
    }
    if ((sm->valid & ATT_HAS_MAG) != 0u) {
        rep->mag = check_vec(sm->mag, s->mag_range);
    }
    st = first_error(rep);
    if (st == EKF_OK) {
        report_all(rep, EKF_OK); /* the stages fill it in */
        return EKF_OK;
    }
    /* only the inputs at fault keep their error */
    if (!ekf_status_is_error(rep->predict)) {
        rep->predict = EKF_SKIPPED;
    }
    if (!ekf_status_is_error(rep->gyro)) {
        rep->gyro = EKF_SKIPPED;
    }
    if (!ekf_status_is_error(rep->accel)) {
        rep->accel = EKF_SKIPPED;
    }
    if (!ekf_status_is_error(rep->mag)) {
        rep->mag = EKF_SKIPPED;
    }
    return st;
}

/* A numeric failure in stage *slot: the whole step is discarded. */
static ekf_status_t discard(att_ekf_t *f, const att_vars_t *saved, att_step_report_t *rep, ekf_status_t *slot)
{
    report_all(rep, EKF_SKIPPED);
    *slot = EKF_ERR_NUMERIC;
    return restore(f, saved, EKF_ERR_NUMERIC);
}

/* The gyroscope stage of a sample: a saturated reading widens the rate uncertainty, a
 * normal one is fused (its variance needs the sample's interval: the sample that completes
 * the alignment may have none, and its gyro is then not fused). */
static ekf_status_t gyro_stage(att_vars_t *w, const att_settings_t *s, const att_sample_t *sm)
{
    if ((sm->valid & ATT_GYRO_SATURATED) != 0u) {
        return att_stage_gyro_saturated(w, s, sm->gyro);
    }
    if ((sm->valid & ATT_HAS_GYRO) != 0u) {
        return (check_dt(s, sm->dt) == EKF_OK) ? att_stage_gyro(w, s, sm->gyro, sm->dt) : EKF_SKIPPED;
    }
    return EKF_OK;
}

/* Rest detection sees every complete sample, from the first one on, so that the initial rest
 * already yields the gyroscope offset; while aligning, only samples with a valid time step
 * (the first one after a start has none). */
static void rest_stage(att_vars_t *w, const att_settings_t *s, const att_sample_t *sm)
{
    w->flags &= ~ATT_FLAG_AT_REST;
    if ((sm->valid & ATT_HAS_ACCEL) != 0u && att_accel_clipped(s, sm->accel)) {
        att_rest_motion(&w->rest); /* (values at the range: not averaged) */
        return;
    }
    if ((sm->valid & (ATT_HAS_GYRO | ATT_HAS_ACCEL | ATT_GYRO_SATURATED)) == (ATT_HAS_GYRO | ATT_HAS_ACCEL) &&
        check_dt(s, sm->dt) == EKF_OK && att_rest_update(&w->rest, &s->rest, sm->gyro, sm->accel, sm->dt)) {
        w->flags |= ATT_FLAG_AT_REST;
        /* the rest offset averaged this sample with weight dt / bias_time (att_rest.c): the
         * offset learned in motion hands over to it at that rate */
        att_bias_rest(&w->bias, ekf_div(sm->dt, w->rest.bias_time), ekf_div(ekf_sq(s->gyro_noise), sm->dt));
    }
}

/* The stages of an aligned filter's step, in order, each status in its slot of rep; *last
 * the slot of the last stage that ran. The gyro sample describes the rotation over the
 * interval ending now: it is fused before the propagation, so the angles integrate it
 * (docs/derivation.md, "Step order"). Returns the slot of the first error, or NULL. */
static ekf_status_t *aligned_stages(att_vars_t *w, const att_settings_t *s, const att_sample_t *sm,
                                    att_step_report_t *rep, ekf_status_t **last, att_trace_t *trace)
{
    rep->gyro = gyro_stage(w, s, sm);
    if (ekf_status_is_error(rep->gyro)) {
        return &rep->gyro;
    }
    rep->predict = att_stage_predict(w, s, sm->dt, trace);
    if (ekf_status_is_error(rep->predict)) {
        return &rep->predict;
    }
    ekf_count(&w->diag.steps);
    if ((sm->valid & ATT_HAS_ACCEL) != 0u) {
        *last = &rep->accel;
        rep->accel = att_stage_accel(w, s, sm->accel, sm->dt);
        if (ekf_status_is_error(rep->accel)) {
            return &rep->accel;
        }
    }
    if ((sm->valid & ATT_HAS_MAG) != 0u) {
        *last = &rep->mag;
        rep->mag = att_stage_mag(w, s, sm->mag, sm->dt);
        if (ekf_status_is_error(rep->mag)) {
            return &rep->mag;
        }
    }
    return NULL;
}

ekf_status_t att_step_traced(att_ekf_t *f, const att_sample_t *sample, att_step_report_t *report, att_trace_t *trace)
{
    att_step_report_t local = {EKF_OK, EKF_OK, EKF_OK, EKF_OK}; /* set below; initialised for the analysers */
    att_step_report_t *rep = (report != NULL) ? report : &local;
    ekf_status_t *last = &rep->predict; /* the slot of the last stage that ran */
    ekf_status_t *failed = NULL;
    att_vars_t saved;
    ekf_status_t st;

    if (trace != NULL) {
        trace->predicted = 0;
    }
    if (f == NULL || sample == NULL) {
        report_all(rep, EKF_ERR_NULL);
        return (f == NULL) ? EKF_ERR_NULL : refuse(f, EKF_ERR_NULL);
    }
    st = validate_sample(f, sample, rep);
    if (st != EKF_OK) {
        return refuse(f, st);
    }
    att_vars_copy(&saved, &f->vars);
    rest_stage(&f->vars, &f->settings, sample); /* the stages run in place */
    if ((f->vars.flags & ATT_FLAG_ALIGNED) == 0u) {
        /* averaging, then the alignment and the gyro of its last sample */
        last = &rep->accel;
        rep->accel = att_stage_align_sample(&f->vars, &f->settings, sample);
        if ((f->vars.flags & ATT_FLAG_ALIGNED) != 0u) {
            last = &rep->gyro;
            rep->gyro = gyro_stage(&f->vars, &f->settings, sample);
            failed = ekf_status_is_error(rep->gyro) ? &rep->gyro : NULL;
        }
    } else {
        failed = aligned_stages(&f->vars, &f->settings, sample, rep, &last, trace);
    }
    if (failed != NULL || commit(f, &saved) != EKF_OK) {
        if (trace != NULL) {
            trace->predicted = 0;
        }
        if (failed != NULL) {
            return discard(f, &saved, rep, failed);
        }
        report_all(rep, EKF_SKIPPED);
        *last = EKF_ERR_NUMERIC;
        return EKF_ERR_NUMERIC;
    }
    /* applied: the first non-OK stage (order predict, gyro, accel, mag), gated or skipped */
    return (rep->predict != EKF_OK) ? rep->predict
           : (rep->gyro != EKF_OK)  ? rep->gyro
           : (rep->accel != EKF_OK) ? rep->accel
                                    : rep->mag;
}

ekf_status_t att_step(att_ekf_t *f, const att_sample_t *sample, att_step_report_t *report)
{
    return att_step_traced(f, sample, report, NULL);
}
