/*
 * hal_virtual.c - in-process HAL backend (hal_virtual.h).
 */
#include "hal_virtual.h"

#include <string.h>

void hal_virtual_init(hal_virtual_t *v, hal_can_frame_t *frames, size_t frames_cap,
                      hal_sample_t *samples, size_t samples_cap)
{
    memset(v, 0, sizeof(*v));
    hal_can_rx_init(&v->rx);
    hal_can_tx_init(&v->tx);
    v->frames = frames;
    v->frames_cap = (frames != NULL) ? frames_cap : 0u;
    v->samples = samples;
    v->samples_cap = (samples != NULL) ? samples_cap : 0u;
    v->link_up = 1u;
}

void hal_virtual_set_sinks(hal_virtual_t *v, hal_virtual_output_fn on_output,
                           hal_virtual_frame_fn on_frame, hal_virtual_report_fn on_report,
                           void *user)
{
    v->on_output = on_output;
    v->on_frame = on_frame;
    v->on_report = on_report;
    v->user = user;
}

hal_status_t hal_virtual_push_frame(hal_virtual_t *v, const hal_can_frame_t *frame)
{
    if (v->frames_n == v->frames_cap) {
        hal_count(&v->counters[HAL_CNT_RX_OVERFLOW]);
        return HAL_ERR_FULL;
    }
    v->frames[(v->frames_head + v->frames_n) % v->frames_cap] = *frame;
    ++v->frames_n;
    v->flushed = 0u;
    return HAL_OK;
}

hal_status_t hal_virtual_push_sample(hal_virtual_t *v, const hal_sample_t *sample)
{
    if (v->samples_n == v->samples_cap) {
        hal_count(&v->counters[HAL_CNT_RX_OVERFLOW]);
        return HAL_ERR_FULL;
    }
    v->samples[(v->samples_head + v->samples_n) % v->samples_cap] = *sample;
    ++v->samples_n;
    return HAL_OK;
}

size_t hal_virtual_frame_space(const hal_virtual_t *v) { return v->frames_cap - v->frames_n; }

void hal_virtual_end(hal_virtual_t *v) { v->ended = 1u; }

void hal_virtual_set_link(hal_virtual_t *v, int up)
{
    if (!up && v->link_up) {
        hal_count(&v->counters[HAL_CNT_LINK_DOWN]);
        v->down_reported = 0u;
    }
    v->link_up = up ? 1u : 0u;
}

uint64_t hal_virtual_now_us(const hal_virtual_t *v) { return v->now_us; }

void hal_virtual_set_tx_fail(hal_virtual_t *v, int fail) { v->tx_fail = fail ? 1u : 0u; }

void hal_virtual_set_clock(hal_virtual_t *v, uint64_t t_us)
{
    if (t_us > v->now_us) {
        v->now_us = t_us;
    }
}

static uint64_t op_now(void *ctx) { return ((const hal_virtual_t *)ctx)->now_us; }

static void advance_clock(hal_virtual_t *v, uint64_t t)
{
    if (t > v->now_us) {
        v->now_us = t;
    }
}

static hal_status_t op_read(void *ctx, hal_sample_t *out, uint32_t timeout_us)
{
    hal_virtual_t *v = (hal_virtual_t *)ctx;
    const uint64_t deadline = v->now_us + timeout_us;
    if (out == NULL) {
        return HAL_ERR_ARG;
    }
    if (!v->link_up) {
        if (!v->down_reported) {
            v->down_reported = 1u;
            return HAL_ERR_LINK_DOWN;
        }
        /* Nothing arrives while the link is down; time passes. */
        v->now_us = deadline;
        return HAL_EMPTY;
    }
    for (;;) {
        const int have_f = v->frames_n > 0u;
        const int have_s = v->samples_n > 0u;
        const uint64_t tf = have_f ? v->frames[v->frames_head].t_us : UINT64_MAX;
        const uint64_t ts = have_s ? v->samples[v->samples_head].rx_us : UINT64_MAX;
        if (hal_can_rx_pop(&v->rx, out)) {
            return HAL_OK;
        }
        if (have_s && ts <= tf && ts <= deadline) {
            advance_clock(v, ts);
            *out = v->samples[v->samples_head];
            v->samples_head = (v->samples_head + 1u) % v->samples_cap;
            --v->samples_n;
            return HAL_OK;
        }
        if (have_f && tf <= deadline) {
            advance_clock(v, tf);
            hal_can_rx_frame(&v->rx, &v->frames[v->frames_head]);
            v->frames_head = (v->frames_head + 1u) % v->frames_cap;
            --v->frames_n;
            continue;
        }
        if (!have_f && !have_s && v->ended) {
            if (!v->flushed) {
                v->flushed = 1u;
                hal_can_rx_flush(&v->rx);
                continue;
            }
            return HAL_END;
        }
        v->now_us = deadline;
        return HAL_EMPTY;
    }
}

static hal_status_t op_publish(void *ctx, const hal_output_t *out)
{
    hal_virtual_t *v = (hal_virtual_t *)ctx;
    hal_can_frame_t frames[HAL_CAN_MAX_OUT_FRAMES];
    size_t n, i;
    if (out == NULL) {
        return HAL_ERR_ARG;
    }
    n = hal_can_encode_output(&v->tx, out, frames);
    if (!v->link_up) {
        hal_count_n(&v->counters[HAL_CNT_TX_ERRORS], (uint32_t)n);
        return HAL_ERR_LINK_DOWN;
    }
    if (v->tx_fail) {
        hal_count_n(&v->counters[HAL_CNT_TX_ERRORS], (uint32_t)n);
        return HAL_ERR_IO;
    }
    if (v->on_output != NULL) {
        v->on_output(v->user, out);
    }
    for (i = 0; i < n; ++i) {
        frames[i].t_us = v->now_us;
        if (v->on_frame != NULL) {
            v->on_frame(v->user, &frames[i]);
        }
    }
    hal_count_n(&v->counters[HAL_CNT_TX_FRAMES], (uint32_t)n);
    return HAL_OK;
}

static void op_counters(void *ctx, uint32_t counters[HAL_CNT_COUNT])
{
    const hal_virtual_t *v = (const hal_virtual_t *)ctx;
    int i;
    for (i = HAL_CNT_LINK_FIRST; i < HAL_CNT_LINK_END; ++i) {
        counters[i] = v->counters[i];
    }
    hal_can_rx_add_counters(&v->rx, counters);
}

static void op_report(void *ctx, hal_level_t level, hal_event_t event, int32_t detail)
{
    const hal_virtual_t *v = (const hal_virtual_t *)ctx;
    if (v->on_report != NULL) {
        v->on_report(v->user, level, event, detail);
    }
}

static const hal_ops_t virtual_ops = {
    op_now, op_read, op_publish, op_counters, op_report,
};

void hal_virtual_bind(hal_virtual_t *v, hal_t *hal)
{
    hal->ops = &virtual_ops;
    hal->ctx = v;
}
