/*
 * app.c - the estimator application loop (app.h). Target-independent: it talks only to the
 * HAL (hal.h) and the filter (att.h). Policies and their reasons: docs/can_protocol.md,
 * "Node behaviour".
 */
#include "app.h"

#include <stddef.h>
#include <string.h>

/* A gap is predicted across in steps of at most the filter's dt_max; more steps than this
 * (max_gap_us / dt_max) is refused at app_init so one sample never costs unbounded time. */
#define APP_MAX_PREDICT_STEPS 1000u

const app_settings_t app_default_settings = {
    .output_period_us = 10000u,
    .stale_timeout_us = 100000u,
    .heartbeat_period_us = 100000u,
    .max_gap_us = 2000000u,
    .seq_window = 1000u,
};

ekf_status_t app_settings_check(const app_settings_t *s)
{
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    if (s->stale_timeout_us == 0u || s->heartbeat_period_us == 0u || s->max_gap_us == 0u ||
        s->max_gap_us > 60000000u || s->seq_window == 0u || s->seq_window > 32767u) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

ekf_status_t app_init(app_t *app, const app_settings_t *settings, const att_settings_t *att,
                      const hal_t *hal)
{
    ekf_status_t st;
    if (app == NULL || settings == NULL || att == NULL || !hal_valid(hal)) {
        return EKF_ERR_NULL;
    }
    st = app_settings_check(settings);
    if (st != EKF_OK) {
        return st;
    }
    st = att_settings_check(att);
    if (st != EKF_OK) {
        return st;
    }
    /* dt_max is in s, max_gap in us: steps = max_gap * 1e-6 / dt_max. */
    if ((ekf_scalar_t)settings->max_gap_us * EKF_C(1e-6) >
        att->dt_max * (ekf_scalar_t)APP_MAX_PREDICT_STEPS) {
        return EKF_ERR_SETTINGS;
    }
    memset(app, 0, sizeof(*app));
    st = att_init(&app->ekf, att);
    if (st != EKF_OK) {
        return st;
    }
    app->settings = *settings;
    app->att_settings = *att;
    app->hal = hal;
    app->last_local_us = hal_now_us(hal);
    hal_report(hal, HAL_LOG_INFO, HAL_EV_STARTED, 0);
    return EKF_OK;
}

static int32_t us_to_ms(uint64_t us)
{
    const uint64_t ms = us / 1000u;
    return (ms > (uint64_t)INT32_MAX) ? INT32_MAX : (int32_t)ms;
}

/* Back to "not aligned", new sample clock. The filter's settings were validated at init. */
static void restart_filter(app_t *a)
{
    (void)att_init(&a->ekf, &a->att_settings);
    a->have_sample = 0u;
    a->was_aligned = 0u;
}

static void publish(app_t *a, hal_output_kind_t kind)
{
    hal_output_t *o = &a->out;
    const int aligned = (att_flags(&a->ekf) & ATT_FLAG_ALIGNED) != 0u;
    hal_status_t st;
    int i;

    if (kind == HAL_OUT_ATTITUDE) {
        ekf_scalar_t e[3], w[3], var[ATT_N];
        att_get_euler(&a->ekf, e);
        att_get_body_rates(&a->ekf, w);
        att_get_variances(&a->ekf, var);
        for (i = 0; i < 3; ++i) {
            o->euler[i] = aligned ? ekf_to_float(e[i]) : 0.0f;
            o->rates[i] = aligned ? ekf_to_float(w[i]) : 0.0f;
            o->sigma[i] = aligned ? ekf_to_float(ekf_sqrt(var[ATT_PHI + i])) : 0.0f;
        }
        hal_count(&a->counters[HAL_CNT_OUTPUTS]);
    }
    o->att_flags = att_flags(&a->ekf);
    o->flags = (uint16_t)(a->latched | (aligned ? HAL_FLAG_ALIGNED : 0u) |
                          (a->stale ? HAL_FLAG_STALE : 0u) |
                          (kind == HAL_OUT_HEARTBEAT ? HAL_FLAG_HEARTBEAT : 0u));
    memset(o->counters, 0, sizeof(o->counters));
    hal_get_counters(a->hal, o->counters);
    hal_count_n(&o->counters[HAL_CNT_LATE], a->counters[HAL_CNT_LATE]); /* late samples */
    for (i = HAL_CNT_LINK_END; i < HAL_CNT_COUNT; ++i) {
        o->counters[i] = a->counters[i];
    }
    o->index = a->out_index++;
    o->kind = (uint8_t)kind;
    st = hal_publish(a->hal, o);
    if (st == HAL_OK) {
        a->latched = 0u;
    } else {
        /* Keep the events for the next output; the backend counted the failure. */
        a->latched |= HAL_FLAG_LINK_ERROR;
    }
}

/* Frame-level trouble seen by the backend since the last sample becomes status flags. */
static void latch_link_events(app_t *a, const uint32_t before[HAL_CNT_COUNT],
                              const uint32_t after[HAL_CNT_COUNT])
{
    if (after[HAL_CNT_UNKNOWN_ID] != before[HAL_CNT_UNKNOWN_ID] ||
        after[HAL_CNT_BAD_DLC] != before[HAL_CNT_BAD_DLC] ||
        after[HAL_CNT_DUPLICATE] != before[HAL_CNT_DUPLICATE] || after[HAL_CNT_LATE] != before[HAL_CNT_LATE]) {
        a->latched |= HAL_FLAG_FRAME_ERROR;
    }
    if (after[HAL_CNT_INCOMPLETE] != before[HAL_CNT_INCOMPLETE] ||
        after[HAL_CNT_DISCARDED] != before[HAL_CNT_DISCARDED]) {
        a->latched |= HAL_FLAG_INCOMPLETE;
    }
    if (after[HAL_CNT_RX_OVERFLOW] != before[HAL_CNT_RX_OVERFLOW] ||
        after[HAL_CNT_LINK_DOWN] != before[HAL_CNT_LINK_DOWN] ||
        after[HAL_CNT_TX_ERRORS] != before[HAL_CNT_TX_ERRORS]) {
        a->latched |= HAL_FLAG_LINK_ERROR;
    }
}

/* A sample that does not continue the stream (dseq: its sequence step from the last accepted
 * sample). It is a stale or corrupted frame, or one of the first samples of a restarted
 * sender; only APP_RESTART_CONFIRM of them in a row that continue each other tell the two
 * apart. Returns 1 when this one completes such a run (the caller restarts on it); else
 * counts it, late if it is from the past (sequence outside the window, time not after the
 * last sample's), a time error otherwise, and returns 0: drop it. */
static int confirms_restart(app_t *a, const hal_sample_t *s, uint16_t dseq)
{
    const app_settings_t *cfg = &a->settings;
    const uint16_t dc = (uint16_t)(s->seq - a->restart_seq);
    if (a->restart_n > 0u && dc != 0u && dc <= cfg->seq_window && s->t_us > a->restart_t_us &&
        s->t_us - a->restart_t_us <= cfg->max_gap_us) {
        ++a->restart_n;
    } else {
        a->restart_n = 1u;
    }
    a->restart_seq = s->seq;
    a->restart_t_us = s->t_us;
    if (a->restart_n >= APP_RESTART_CONFIRM) {
        return 1;
    }
    if (dseq != 0u && dseq > cfg->seq_window && s->t_us <= a->last_t_us) {
        hal_count(&a->counters[HAL_CNT_LATE]);
        a->latched |= HAL_FLAG_FRAME_ERROR;
        hal_report(a->hal, HAL_LOG_WARN, HAL_EV_LATE, (int32_t)s->seq);
    } else {
        hal_count(&a->counters[HAL_CNT_TIME_ERRORS]);
        a->latched |= HAL_FLAG_TIME_ERROR;
        hal_report(a->hal, HAL_LOG_WARN, HAL_EV_TIME_ERROR, (int32_t)s->seq);
    }
    return 0;
}

static int is_rejection(ekf_status_t st)
{
    /* Gated / skipped are filter decisions, not bad input; "not initialised" is a sample
     * without accelerometer while aligning (it waits for one). */
    return st != EKF_OK && st != EKF_GATED && st != EKF_SKIPPED && st != EKF_ERR_NOT_INITIALISED;
}

static int bad_vector(ekf_status_t st) { return st == EKF_ERR_NOT_FINITE || st == EKF_ERR_RANGE; }

/* Clears the presence bit of every sensor whose vector att_step refused (non-finite or
 * out of range). Returns 1 if a sensor was dropped and the sample is worth another call. */
static int retry_without_bad_sensors(att_sample_t *in, const att_step_report_t *rep)
{
    const uint8_t before = in->valid;
    if (bad_vector(rep->gyro)) {
        in->valid = (uint8_t)(in->valid & ~(ATT_HAS_GYRO | ATT_GYRO_SATURATED));
    }
    if (bad_vector(rep->accel)) {
        in->valid = (uint8_t)(in->valid & ~ATT_HAS_ACCEL);
    }
    if (bad_vector(rep->mag)) {
        in->valid = (uint8_t)(in->valid & ~ATT_HAS_MAG);
    }
    return in->valid != before && !is_rejection(rep->predict);
}

static void process(app_t *a, const hal_sample_t *s)
{
    const hal_t *hal = a->hal;
    const app_settings_t *cfg = &a->settings;
    att_sample_t in;
    att_step_report_t rep;
    ekf_status_t st, refused;
    uint64_t dt_us = 0u;
    uint8_t use = (uint8_t)(s->valid & HAL_HAS_ALL);
    int i;

    hal_count(&a->counters[HAL_CNT_SAMPLES]);

    if ((s->saturated & use) != 0u) {
        /* A clamped value is wrong by an unknown amount: better not fused at all. A clamped
         * gyro still says the rate is at least that large: the estimator is told
         * (ATT_GYRO_SATURATED) and widens its rate uncertainty. */
        hal_count(&a->counters[HAL_CNT_SATURATED]);
        a->latched |= HAL_FLAG_IN_SATURATED;
        hal_report(hal, HAL_LOG_DEBUG, HAL_EV_SATURATED, (int32_t)(s->saturated & use));
        use = (uint8_t)(use & ~s->saturated);
    }

    if (a->have_sample) {
        const uint16_t dseq = (uint16_t)(s->seq - a->last_seq);
        if (dseq == 0u || dseq > cfg->seq_window || s->t_us <= a->last_t_us) {
            if (!confirms_restart(a, s, dseq)) {
                return; /* dropped; the next good sample sees it as a gap */
            }
            /* APP_RESTART_CONFIRM consistent samples: the sender restarted. Follow it. */
            hal_count(&a->counters[HAL_CNT_RESYNC]);
            a->latched |= HAL_FLAG_RESTARTED;
            hal_report(hal, HAL_LOG_WARN, HAL_EV_RESYNC, (int32_t)s->seq);
            restart_filter(a);
        } else {
            dt_us = s->t_us - a->last_t_us;
            if (dseq > 1u) {
                hal_count(&a->counters[HAL_CNT_GAPS]);
                hal_count_n(&a->counters[HAL_CNT_MISSING], (uint32_t)(dseq - 1u));
                a->latched |= HAL_FLAG_GAP;
                hal_report(hal, HAL_LOG_INFO, HAL_EV_GAP, (int32_t)(dseq - 1u));
            }
            if (dt_us > cfg->max_gap_us) {
                /* Too long to predict across usefully: start again from the sensors. */
                hal_count(&a->counters[HAL_CNT_REALIGN]);
                a->latched |= HAL_FLAG_RESTARTED;
                hal_report(hal, HAL_LOG_WARN, HAL_EV_REALIGN, us_to_ms(dt_us));
                restart_filter(a);
            }
        }
    }
    a->restart_n = 0u;
    if (!a->have_sample) {
        a->next_out_t_us = s->t_us; /* new sample clock: output at once */
        dt_us = 0u;
    }
    a->have_sample = 1u;
    a->last_seq = s->seq;
    a->last_t_us = s->t_us;

    memset(&in, 0, sizeof(in));
    for (i = 0; i < 3; ++i) {
        in.gyro[i] = ekf_from_float(s->gyro[i]);
        in.accel[i] = ekf_from_float(s->accel[i]);
        in.mag[i] = ekf_from_float(s->mag[i]);
    }
    in.valid = (uint8_t)(((use & HAL_HAS_GYRO) ? ATT_HAS_GYRO : 0u) |
                         ((use & HAL_HAS_ACCEL) ? ATT_HAS_ACCEL : 0u) |
                         ((use & HAL_HAS_MAG) ? ATT_HAS_MAG : 0u) |
                         ((s->valid & s->saturated & HAL_HAS_GYRO) ? ATT_GYRO_SATURATED : 0u));
    in.dt = (ekf_scalar_t)dt_us * EKF_C(1e-6);
    refused = EKF_OK;
    if ((att_flags(&a->ekf) & ATT_FLAG_ALIGNED) != 0u) {
        /* Longer than one filter step allows (a gap): predict across it in pieces. A
         * refused piece (numeric) ends the loop; the sample's own step then sees the
         * rest of the gap. */
        const ekf_scalar_t dt_max = a->att_settings.dt_max;
        while (in.dt > dt_max) {
            st = att_predict(&a->ekf, dt_max);
            if (st != EKF_OK) {
                refused = st;
                break;
            }
            in.dt = ekf_sub(in.dt, dt_max);
        }
    }
    st = att_step(&a->ekf, &in, &rep);
    if (is_rejection(st) && retry_without_bad_sensors(&in, &rep)) {
        /* att_step refuses a whole sample for one bad sensor vector: the rest of the
         * sample is still worth fusing (the refusal is counted below) */
        refused = st;
        st = att_step(&a->ekf, &in, &rep);
    }
    if (is_rejection(st)) {
        refused = st;
    }
    if (refused != EKF_OK) {
        hal_count(&a->counters[HAL_CNT_EKF_REJECTED]);
        a->latched |= HAL_FLAG_EKF_REJECT;
        hal_report(hal, HAL_LOG_DEBUG, HAL_EV_EKF_REJECT, (int32_t)refused);
    }
    if (!a->was_aligned && (att_flags(&a->ekf) & ATT_FLAG_ALIGNED) != 0u) {
        a->was_aligned = 1u;
        hal_report(hal, HAL_LOG_INFO, HAL_EV_ALIGNED, (int32_t)s->seq);
    }

    a->out.t_us = s->t_us;
    a->out.rx_us = s->rx_us;
    a->out.seq = s->seq;
    if (cfg->output_period_us == 0u || s->t_us >= a->next_out_t_us) {
        if (cfg->output_period_us != 0u) {
            /* Next multiple of the period after this sample (one output however many
             * periods a gap skipped). */
            const uint64_t k = (s->t_us - a->next_out_t_us) / cfg->output_period_us + 1u;
            a->next_out_t_us += k * cfg->output_period_us;
        }
        publish(a, HAL_OUT_ATTITUDE);
    }
}

hal_status_t app_poll(app_t *app, uint32_t timeout_us)
{
    hal_sample_t s;
    hal_status_t st;
    uint32_t before[HAL_CNT_COUNT], after[HAL_CNT_COUNT];
    uint64_t now;

    if (app == NULL) {
        return HAL_ERR_ARG;
    }
    memset(before, 0, sizeof(before));
    memset(after, 0, sizeof(after));
    hal_get_counters(app->hal, before);
    st = hal_read_sample(app->hal, &s, timeout_us);
    hal_get_counters(app->hal, after);
    latch_link_events(app, before, after);
    now = hal_now_us(app->hal);
    if (st == HAL_OK) {
        if (app->stale) {
            app->stale = 0u;
            hal_report(app->hal, HAL_LOG_INFO, HAL_EV_RESUMED,
                       us_to_ms(now - app->last_local_us));
        }
        app->last_local_us = now;
        process(app, &s);
    } else if (st == HAL_ERR_LINK_DOWN || st == HAL_ERR_IO) {
        app->latched |= HAL_FLAG_LINK_ERROR;
    }

    if (!app->stale && now > app->last_local_us &&
        now - app->last_local_us >= app->settings.stale_timeout_us) {
        app->stale = 1u;
        hal_count(&app->counters[HAL_CNT_STALE]);
        hal_report(app->hal, HAL_LOG_WARN, HAL_EV_STALE, us_to_ms(now - app->last_local_us));
        app->next_heartbeat_us = now;
    }
    if (app->stale && now >= app->next_heartbeat_us) {
        publish(app, HAL_OUT_HEARTBEAT);
        app->next_heartbeat_us = now + app->settings.heartbeat_period_us;
    }
    return st;
}

void app_get_counters(const app_t *app, uint32_t counters[HAL_CNT_COUNT])
{
    int i;
    memset(counters, 0, sizeof(uint32_t) * (size_t)HAL_CNT_COUNT);
    hal_get_counters(app->hal, counters);
    hal_count_n(&counters[HAL_CNT_LATE], app->counters[HAL_CNT_LATE]); /* late samples */
    for (i = HAL_CNT_LINK_END; i < HAL_CNT_COUNT; ++i) {
        counters[i] = app->counters[i];
    }
}

const att_ekf_t *app_filter(const app_t *app) { return &app->ekf; }

const hal_output_t *app_last_output(const app_t *app) { return &app->out; }
