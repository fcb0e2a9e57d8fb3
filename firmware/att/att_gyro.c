/*
 * att_gyro.c - the gyroscope stage, and a saturated gyroscope's (docs/derivation.md,
 * "Measurement models", "Gyroscope saturation", "Innovation gate").
 */
#include "att_gyro.h"

#include "att_gen.h"
#include "att_model.h"
#include "att_sensor.h"
#include "att_state.h"
#include "ekf_util.h"

/* A clamped gyro reading (ATT_GYRO_SATURATED): the rate is at least its largest component
 * in magnitude, by an unknown amount. Not fused; each body-rate variance is raised to at
 * least that square (P += G diag(extra) G^T, positive semi-definite, so P stays positive
 * definite), docs/derivation.md "Gyroscope saturation". Without this the rates would only
 * random-walk at rate_walk while a tumble beyond full scale turns the vehicle, and the
 * attitude would come out of the tumble wrong with a small covariance: confidently wrong,
 * and gated by the sensors that could correct it. */
ekf_status_t att_stage_gyro_saturated(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3])
{
    ekf_scalar_t g[9], extra[3], var;
    att_trig_t t;
    int i;

    var = ekf_sq(ekf_max(ekf_max(ekf_abs(gyro[0]), ekf_abs(gyro[1])), ekf_abs(gyro[2])));
    for (i = 0; i < 3; ++i) {
        extra[i] = ekf_max(ekf_sub(var, att_cov_var(&v->cov, ATT_P + i)), EKF_C(0));
    }
    (void)att_trig(v->x[ATT_PHI], v->x[ATT_THETA], s->gimbal_limit, &t);
    att_gen_noise_jacobian(&t, g);
    att_cov_add_rate_noise(&v->cov, g, extra);
    /* the angles' error is now the unmeasured rotation's, not the offset's */
    att_bias_restart(&v->bias);
    att_bias_hold(&v->bias, s->bias.hold_time);
    /* the low-passed force is carried over the step with the body rates, which this sample
     * does not measure: start it again from the next sample whose rates are measured */
    v->accel_lp_valid = 0u;
    v->rate_unmeasured = 1u;
    ekf_count(&v->diag.gyro_saturated);
    return EKF_SKIPPED;
}

ekf_status_t att_stage_gyro(att_vars_t *v, const att_settings_t *s, const ekf_scalar_t gyro[3], ekf_scalar_t dt)
{
    v->rate_unmeasured = 0u;
    ekf_scalar_t gate, r_var;
    ekf_status_t st;
    ekf_innov_t info;
    int i, gated = 0, bypass_failed = 0;

    gate = att_sensor_gate(v, s, ATT_SENSOR_GYRO, s->gyro_gate);
    r_var = ekf_div(ekf_sq(s->gyro_noise), dt); /* a density: the variance of the sample's mean */
    for (i = 0; i < 3; ++i) {
        /* the offset learned in motion stays within bias_max of zero together with the
         * rest offset */
        const ekf_scalar_t m = s->rest.bias_max;
        v->bias.b[i] = ekf_clamp(v->bias.b[i], ekf_sub(ekf_neg(m), v->rest.bias[i]), ekf_sub(m, v->rest.bias[i]));
    }
    for (i = 0; i < 3; ++i) {
        /* the rates net of the offset (att_rest.h, att_bias.h) */
        const ekf_scalar_t nu =
            ekf_sub(ekf_sub(gyro[i], ekf_add(v->rest.bias[i], v->bias.b[i])), v->x[ATT_P + i]);
        st = att_cov_update_unit(&v->cov, v->x, ATT_P + i, nu, r_var, gate, s->var_floor, &info);
        v->diag.gyro_ratio[i] = info.test_ratio;
        if (st == EKF_GATED) {
            gated = 1;
            ekf_count(&v->diag.gyro_gated);
        } else if (st != EKF_OK) {
            return st; /* EKF_ERR_NUMERIC: the caller puts the saved variables back */
        } else {
            ekf_count(&v->diag.gyro_fused);
            bypass_failed |= att_sensor_fails_gate(&info, s->gyro_gate);
        }
    }
    /* the rates correlate with the angles: the update may have moved them too */
    if (att_normalise(v)) {
        ekf_count(&v->diag.remaps);
    }
    att_update_gimbal_flag(v, s);
    att_sensor_gate_result(v, s, ATT_SENSOR_GYRO, gated || bypass_failed);
    if (gated) {
        v->flags |= ATT_FLAG_GYRO_GATED;
        return EKF_GATED;
    }
    v->flags &= ~ATT_FLAG_GYRO_GATED;
    return EKF_OK;
}
