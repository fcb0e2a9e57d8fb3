/*
 * app_output.c - the application's outputs (app_msg.h): the attitude with its uncertainty and
 * the status word, built from the filter and handed to the configured protocol; the clock
 * work of every poll (staleness, heartbeats, the DroneCAN status).
 */
#include "app_internal.h"

#include <string.h>

/* The estimate of the filter into o; zeros until it is aligned. */
static void fill_estimate(const app_t *a, app_output_t *o, int aligned)
{
    ekf_scalar_t e[3], q[4], w[3], var[ATT_N], c[6];
    int i;
    memset(o->euler, 0, sizeof(o->euler));
    memset(o->quat, 0, sizeof(o->quat));
    memset(o->rates, 0, sizeof(o->rates));
    memset(o->sigma, 0, sizeof(o->sigma));
    memset(o->angle_cov, 0, sizeof(o->angle_cov));
    memset(o->rate_var, 0, sizeof(o->rate_var));
    for (i = 0; i < 3; ++i) {
        o->accel[i] = a->last_accel[i];
    }
    if (!aligned) {
        return;
    }
    att_get_euler(&a->ekf, e);
    att_get_quaternion(&a->ekf, q);
    att_get_body_rates(&a->ekf, w);
    att_get_variances(&a->ekf, var);
    att_get_angle_covariance(&a->ekf, c);
    for (i = 0; i < 3; ++i) {
        o->euler[i] = ekf_to_float(e[i]);
        o->rates[i] = ekf_to_float(w[i]);
        o->sigma[i] = ekf_to_float(ekf_sqrt(var[ATT_PHI + i]));
        o->rate_var[i] = ekf_to_float(var[ATT_P + i]);
    }
    for (i = 0; i < 4; ++i) {
        o->quat[i] = ekf_to_float(q[i]);
    }
    for (i = 0; i < 6; ++i) {
        o->angle_cov[i] = ekf_to_float(c[i]);
    }
}

void app_publish(app_t *a, app_output_kind_t kind)
{
    app_output_t *o = &a->out;
    const int aligned = (att_flags(&a->ekf) & ATT_FLAG_ALIGNED) != 0u;
    hal_status_t st = HAL_OK;

    app_latch_errors(a);
    if (kind == APP_OUT_ATTITUDE) {
        fill_estimate(a, o, aligned);
        hal_count(&a->counters[APP_CNT_OUTPUTS]);
    }
    o->att_flags = att_flags(&a->ekf);
    o->flags = (uint16_t)(a->latched | (aligned ? APP_FLAG_ALIGNED : 0u) | (a->stale ? APP_FLAG_STALE : 0u) |
                          (kind == APP_OUT_HEARTBEAT ? APP_FLAG_HEARTBEAT : 0u) |
                          (a->n_pending > 0u ? APP_FLAG_CONFIG_PENDING : 0u));
    app_get_counters(a, o->counters);
    o->index = a->out_index++;
    o->kind = (uint8_t)kind;
    a->dcan.status_flags |= o->flags;
    switch (a->node.protocol) {
    case APP_PROTO_DBC: st = app_dbc_publish(a, o); break;
    case APP_PROTO_DRONECAN: st = app_dcan_publish(a, o); break;
    default: st = app_text_publish(a, o); break;
    }
    if (st == HAL_OK) {
        a->latched = 0u;
        if (a->hooks.on_output != NULL) {
            a->hooks.on_output(a->hooks.user, o);
        }
    } else {
        /* Keep the events for the next output; the backend counted the failure. */
        a->latched |= APP_FLAG_LINK_ERROR;
    }
}

void app_tick(app_t *a, uint64_t now)
{
    if (!a->stale && now > a->last_local_us && now - a->last_local_us >= a->settings.stale_timeout_us) {
        const uint64_t ms = (now - a->last_local_us) / 1000u;
        a->stale = 1u;
        hal_count(&a->counters[APP_CNT_STALE]);
        app_log(a, HAL_LOG_WARN, "stale", ms > (uint64_t)INT32_MAX ? INT32_MAX : (int32_t)ms);
        a->next_heartbeat_us = now;
    }
    if (a->stale && now >= a->next_heartbeat_us) {
        app_publish(a, APP_OUT_HEARTBEAT);
        a->next_heartbeat_us = now + a->settings.heartbeat_period_us;
    }
    if (a->node.protocol == APP_PROTO_DRONECAN) {
        app_dcan_tick(a, now);
    }
}
