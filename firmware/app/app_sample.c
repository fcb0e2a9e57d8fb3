/*
 * app_sample.c - one IMU sample through the application, one job per function: saturated
 * sensors, the stream's continuity (gaps, long gaps, time errors, stale samples, confirmed
 * sender restarts), the filter's input, predicting across a gap, the filter step, the output
 * schedule. Policies and their reasons: docs/can_protocol.md, "Node behaviour".
 */
#include "app_internal.h"

#include <string.h>

static int32_t us_to_ms(uint64_t us)
{
    const uint64_t ms = us / 1000u;
    return (ms > (uint64_t)INT32_MAX) ? INT32_MAX : (int32_t)ms;
}

/* Back to "not aligned" with the settings in force; a new sample clock. */
static void restart_filter(app_t *a)
{
    (void)att_reset(&a->ekf);
    a->have_sample = 0u;
    a->was_aligned = 0u;
}

/* The sensors of the sample that may be fused: saturated ones are not (counted, flagged). */
static uint8_t usable_sensors(app_t *a, const hal_sample_t *s)
{
    uint8_t use = (uint8_t)(s->valid & HAL_HAS_ALL);
    if ((s->saturated & use) != 0u) {
        /* A clamped value is wrong by an unknown amount: better not fused at all. A clamped
         * gyro still says the rate is at least that large: the estimator is told
         * (ATT_GYRO_SATURATED) and widens its rate uncertainty. */
        hal_count(&a->counters[APP_CNT_SATURATED]);
        a->latched |= APP_FLAG_IN_SATURATED;
        app_log(a, HAL_LOG_DEBUG, "saturated", (int32_t)(s->saturated & use));
        use = (uint8_t)(use & ~s->saturated);
    }
    return use;
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
        hal_count(&a->counters[APP_CNT_LATE]);
        a->latched |= APP_FLAG_FRAME_ERROR;
        app_log(a, HAL_LOG_WARN, "late", (int32_t)s->seq);
    } else {
        hal_count(&a->counters[APP_CNT_TIME_ERRORS]);
        a->latched |= APP_FLAG_TIME_ERROR;
        app_log(a, HAL_LOG_WARN, "time_error", (int32_t)s->seq);
    }
    return 0;
}

/* Whether the sample continues the stream, and the time since the last one (*dt_us; 0 for
 * the first sample of a new stream). 0: drop the sample. */
static int continues_stream(app_t *a, const hal_sample_t *s, uint64_t *dt_us)
{
    const app_settings_t *cfg = &a->settings;
    *dt_us = 0u;
    if (a->have_sample) {
        const uint16_t dseq = (uint16_t)(s->seq - a->last_seq);
        if (dseq == 0u || dseq > cfg->seq_window || s->t_us <= a->last_t_us) {
            if (!confirms_restart(a, s, dseq)) {
                return 0; /* dropped; the next good sample sees it as a gap */
            }
            /* APP_RESTART_CONFIRM consistent samples: the sender restarted. Follow it. */
            hal_count(&a->counters[APP_CNT_RESYNC]);
            a->latched |= APP_FLAG_RESTARTED;
            app_log(a, HAL_LOG_WARN, "resync", (int32_t)s->seq);
            restart_filter(a);
        } else {
            *dt_us = s->t_us - a->last_t_us;
            if (dseq > 1u) {
                hal_count(&a->counters[APP_CNT_GAPS]);
                hal_count_n(&a->counters[APP_CNT_MISSING], (uint32_t)(dseq - 1u));
                a->latched |= APP_FLAG_GAP;
                app_log(a, HAL_LOG_INFO, "gap", (int32_t)(dseq - 1u));
            }
            if (*dt_us > cfg->max_gap_us) {
                /* Too long to predict across usefully: start again from the sensors. */
                hal_count(&a->counters[APP_CNT_REALIGN]);
                a->latched |= APP_FLAG_RESTARTED;
                app_log(a, HAL_LOG_WARN, "realign", us_to_ms(*dt_us));
                restart_filter(a);
            }
        }
    }
    a->restart_n = 0u;
    if (!a->have_sample) {
        a->next_out_t_us = s->t_us; /* new sample clock: output at once */
        *dt_us = 0u;
    }
    a->have_sample = 1u;
    a->last_seq = s->seq;
    a->last_t_us = s->t_us;
    return 1;
}

/* The filter's input: the sensors in use, the saturated gyro flagged, dt in s. */
static void to_filter_input(const hal_sample_t *s, uint8_t use, uint64_t dt_us, att_sample_t *in)
{
    int i;
    memset(in, 0, sizeof(*in));
    for (i = 0; i < 3; ++i) {
        in->gyro[i] = ekf_from_float(s->gyro[i]);
        in->accel[i] = ekf_from_float(s->accel[i]);
        in->mag[i] = ekf_from_float(s->mag[i]);
    }
    in->valid = (uint8_t)(((use & HAL_HAS_GYRO) ? ATT_HAS_GYRO : 0u) | ((use & HAL_HAS_ACCEL) ? ATT_HAS_ACCEL : 0u) |
                          ((use & HAL_HAS_MAG) ? ATT_HAS_MAG : 0u) |
                          ((s->valid & s->saturated & HAL_HAS_GYRO) ? ATT_GYRO_SATURATED : 0u));
    in->dt = (ekf_scalar_t)dt_us * EKF_C(1e-6);
}

/* Longer than one filter step allows (a gap): predict across it in pieces, leaving the last
 * piece to the sample's own step. A refused piece (numeric) ends the loop; the sample's step
 * then sees the rest of the gap. Returns the refusal, or EKF_OK. */
static ekf_status_t predict_across_gap(app_t *a, att_sample_t *in)
{
    const ekf_scalar_t dt_max = a->ekf.settings.dt_max;
    if ((att_flags(&a->ekf) & ATT_FLAG_ALIGNED) == 0u) {
        return EKF_OK;
    }
    while (in->dt > dt_max) {
        const ekf_status_t st = att_predict(&a->ekf, dt_max);
        if (st != EKF_OK) {
            return st;
        }
        in->dt = ekf_sub(in->dt, dt_max);
    }
    return EKF_OK;
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

/* The filter step; a sample refused for one bad sensor vector is fused without it. Returns
 * the first refusal, or EKF_OK. */
static ekf_status_t step_filter(app_t *a, att_sample_t *in)
{
    att_step_report_t rep;
    ekf_status_t refused = EKF_OK;
    ekf_status_t st = att_step(&a->ekf, in, &rep);
    if (is_rejection(st) && retry_without_bad_sensors(in, &rep)) {
        refused = st;
        st = att_step(&a->ekf, in, &rep);
    }
    return is_rejection(st) ? st : refused;
}

/* Outputs are due on the sample clock: at the next multiple of the period after the last
 * output (one output however many periods a gap skipped). */
static int output_due(app_t *a, uint64_t t_us)
{
    const uint32_t period = a->settings.output_period_us;
    if (period == 0u) {
        return 1;
    }
    if (t_us < a->next_out_t_us) {
        return 0;
    }
    a->next_out_t_us += ((t_us - a->next_out_t_us) / period + 1u) * period;
    return 1;
}

void app_process_sample(app_t *a, const hal_sample_t *s)
{
    att_sample_t in;
    ekf_status_t gap, refused;
    uint64_t dt_us;
    uint8_t use;
    int i;

    hal_count(&a->counters[APP_CNT_SAMPLES]);
    if (a->stale) {
        a->stale = 0u;
        app_log(a, HAL_LOG_INFO, "resumed", us_to_ms(hal_now_us(a->hal) - a->last_local_us));
    }
    use = usable_sensors(a, s);
    if (!continues_stream(a, s, &dt_us)) {
        return;
    }
    to_filter_input(s, use, dt_us, &in);
    gap = predict_across_gap(a, &in);
    refused = step_filter(a, &in);
    if (refused == EKF_OK) {
        refused = gap;
    }
    if (refused != EKF_OK) {
        hal_count(&a->counters[APP_CNT_EKF_REJECTED]);
        a->latched |= APP_FLAG_EKF_REJECT;
        app_log(a, HAL_LOG_DEBUG, "ekf_reject", (int32_t)refused);
    }
    if (!a->was_aligned && (att_flags(&a->ekf) & ATT_FLAG_ALIGNED) != 0u) {
        a->was_aligned = 1u;
        app_log(a, HAL_LOG_INFO, "aligned", (int32_t)s->seq);
    }
    if ((use & HAL_HAS_ACCEL) != 0u) {
        for (i = 0; i < 3; ++i) {
            a->last_accel[i] = s->accel[i];
        }
    }
    a->out.t_us = s->t_us;
    a->out.rx_us = s->rx_us;
    a->out.seq = s->seq;
    if (output_due(a, s->t_us)) {
        app_publish(a, APP_OUT_ATTITUDE);
    }
}
