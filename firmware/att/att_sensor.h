/*
 * att_sensor.h - what the measurement stages (att_gyro.c, att_accel.c, att_mag.c) share:
 * the trigonometry of the measurement functions, the gates and their time-outs, a vector
 * sample's timing (docs/derivation.md, "Innovation gate", "Gate timeouts", "Sample timing").
 * Inline: each is a few operations on the stage's hot path, called once or twice per stage.
 * Not part of the public API.
 */
#ifndef ATT_SENSOR_H
#define ATT_SENSOR_H

#include "att.h"
#include "att_gen.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Index of a sensor in att_vars_t.gated_time. */
enum { ATT_SENSOR_GYRO = 0, ATT_SENSOR_ACCEL = 1, ATT_SENSOR_MAG = 2 };

/* Trigonometry for the measurement functions: the true (unclamped) pitch. They use only
 * sin and cos, never sec(theta), which is left at zero. */
static inline void att_sensor_trig(const att_vars_t *v, att_trig_t *t)
{
    if (v->x[ATT_PHI] == v->trig_at[0] && v->x[ATT_THETA] == v->trig_at[1] && v->trig.cth > EKF_C(0)) {
        *t = v->trig; /* the prediction's, of these very angles */
        t->secth = EKF_C(0);
        return;
    }
    ekf_sincos(v->x[ATT_PHI], &t->sphi, &t->cphi);
    ekf_sincos(v->x[ATT_THETA], &t->sth, &t->cth);
    t->secth = EKF_C(0);
}

/* Gate of the gyroscope or the accelerometer: its setting, or 0 (off) once it has gated
 * continuously for longer than gate_timeout. A filter that has drifted away from a sensor
 * would otherwise reject it forever. */
static inline ekf_scalar_t att_sensor_gate(att_vars_t *v, const att_settings_t *s, int sensor, ekf_scalar_t gate)
{
    const ekf_scalar_t timeout = s->gate_timeout;
    if (gate > EKF_C(0) && timeout > EKF_C(0) && v->gated_time[sensor] > timeout) {
        v->flags |= ATT_FLAG_GATE_BYPASS;
        /* the innovations say the state is off: not the offset's doing */
        att_bias_hold(&v->bias, s->bias.hold_time);
        return EKF_C(0);
    }
    return gate;
}

/* Records whether a sensor's update gated (starts the gate clock) or passed (stops it). */
static inline void att_sensor_gate_result(att_vars_t *v, const att_settings_t *s, int sensor, int gated)
{
    if (gated) {
        if (!(v->gated_time[sensor] > EKF_C(0))) {
            v->gated_time[sensor] = EKF_SCALAR_EPS; /* running; the prediction adds dt */
        }
    } else {
        v->gated_time[sensor] = EKF_C(0);
        if (!(v->gated_time[ATT_SENSOR_GYRO] > s->gate_timeout) &&
            !(v->gated_time[ATT_SENSOR_ACCEL] > s->gate_timeout)) {
            v->flags &= ~ATT_FLAG_GATE_BYPASS;
        }
    }
}

/* A vector sample (accelerometer or magnetometer, body frame) is the mean over its own
 * interval, the sample interval (dt, or after a gap the interval without gaps, dt_nom): for a
 * body turning at the rate state it is the vector half an interval before the state's time.
 * out = the same earth-fixed vector in the body axes at the end of the interval, turned by
 * -w dt/2 (second order in th = w dt / 2: v - th x v + th x (th x v) / 2); docs/derivation.md,
 * "Sample timing". */
static inline void att_sensor_cross3(const ekf_scalar_t a[3], const ekf_scalar_t b[3], ekf_scalar_t out[3])
{
    out[0] = ekf_sub(ekf_mul(a[1], b[2]), ekf_mul(a[2], b[1]));
    out[1] = ekf_sub(ekf_mul(a[2], b[0]), ekf_mul(a[0], b[2]));
    out[2] = ekf_sub(ekf_mul(a[0], b[1]), ekf_mul(a[1], b[0]));
}

static inline void att_sensor_to_interval_end(const att_vars_t *v, const ekf_scalar_t vec[3], ekf_scalar_t dt, ekf_scalar_t out[3])
{
    const ekf_scalar_t own = (v->dt_nom > EKF_C(0)) ? ekf_min(dt, v->dt_nom) : dt;
    /* (a saturated gyro leaves the rate state a guess: the sample is taken as it is) */
    const ekf_scalar_t half = v->rate_unmeasured ? EKF_C(0) : ekf_mul(EKF_C(0.5), own);
    ekf_scalar_t th[3], c1[3], c2[3];
    int i;
    for (i = 0; i < 3; ++i) {
        th[i] = ekf_mul(v->x[ATT_P + i], half);
    }
    att_sensor_cross3(th, vec, c1);
    att_sensor_cross3(th, c1, c2);
    for (i = 0; i < 3; ++i) {
        out[i] = ekf_mac(ekf_sub(vec[i], c1[i]), EKF_C(0.5), c2[i]);
    }
}

/* 1 if an innovation would fail the gate of gate sigmas (a bypassed gate still judges the
 * innovations, so that the bypass lasts until they are consistent again). */
static inline int att_sensor_fails_gate(const ekf_innov_t *info, ekf_scalar_t gate)
{
    return gate > EKF_C(0) && ekf_sq(info->innovation) > ekf_mul(ekf_sq(gate), info->variance);
}

/* The fraction by which an update reduced a variance (its gain on that state's error). */
static inline ekf_scalar_t att_sensor_reduction(ekf_scalar_t before, ekf_scalar_t after)
{
    return (before > EKF_C(0)) ? ekf_sub(EKF_C(1), ekf_div(after, before)) : EKF_C(0);
}

#ifdef __cplusplus
}
#endif

#endif /* ATT_SENSOR_H */
