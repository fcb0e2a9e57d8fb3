/*
 * hal_virtual.c - in-process HAL backend (hal_virtual.h).
 */
#include "hal_virtual.h"

#include <string.h>

void hal_virtual_init(hal_virtual_t *v, hal_frame_t *frames, size_t frames_cap, hal_sample_t *samples,
                      size_t samples_cap, hal_line_t *lines, size_t lines_cap)
{
    memset(v, 0, sizeof(*v));
    v->frames = frames;
    v->frames_cap = (frames != NULL) ? frames_cap : 0u;
    v->samples = samples;
    v->samples_cap = (samples != NULL) ? samples_cap : 0u;
    v->lines = lines;
    v->lines_cap = (lines != NULL) ? lines_cap : 0u;
    v->link_up = 1u;
}

void hal_virtual_set_sinks(hal_virtual_t *v, hal_virtual_frame_fn on_frame, hal_virtual_line_fn on_line,
                           hal_virtual_log_fn on_log, void *user)
{
    v->on_frame = on_frame;
    v->on_line = on_line;
    v->on_log = on_log;
    v->user = user;
}

static hal_status_t full(hal_virtual_t *v)
{
    hal_count(&v->stats.rx_overflow);
    return HAL_ERR_FULL;
}

hal_status_t hal_virtual_push_frame(hal_virtual_t *v, const hal_frame_t *frame)
{
    if (v->frames_n == v->frames_cap) {
        return full(v);
    }
    v->frames[(v->frames_head + v->frames_n) % v->frames_cap] = *frame;
    ++v->frames_n;
    return HAL_OK;
}

hal_status_t hal_virtual_push_sample(hal_virtual_t *v, const hal_sample_t *sample)
{
    if (v->samples_n == v->samples_cap) {
        return full(v);
    }
    v->samples[(v->samples_head + v->samples_n) % v->samples_cap] = *sample;
    ++v->samples_n;
    return HAL_OK;
}

hal_status_t hal_virtual_push_line(hal_virtual_t *v, uint64_t t_us, const char *text)
{
    hal_line_t *l;
    size_t n;
    if (text == NULL) {
        return HAL_ERR_ARG;
    }
    n = strlen(text);
    if (n >= HAL_LINE_MAX) {
        return HAL_ERR_ARG;
    }
    if (v->lines_n == v->lines_cap) {
        return full(v);
    }
    l = &v->lines[(v->lines_head + v->lines_n) % v->lines_cap];
    l->t_us = t_us;
    memcpy(l->text, text, n + 1u);
    ++v->lines_n;
    return HAL_OK;
}

size_t hal_virtual_frame_space(const hal_virtual_t *v) { return v->frames_cap - v->frames_n; }

void hal_virtual_end(hal_virtual_t *v) { v->ended = 1u; }

void hal_virtual_set_link(hal_virtual_t *v, int up)
{
    if (!up && v->link_up) {
        hal_count(&v->stats.link_down);
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

/* The queue whose head is due first: 0 frames, 1 samples, 2 lines, -1 none. */
static int next_queue(const hal_virtual_t *v, uint64_t *t)
{
    int best = -1;
    *t = UINT64_MAX;
    if (v->frames_n > 0u) {
        best = 0;
        *t = v->frames[v->frames_head].t_us;
    }
    if (v->samples_n > 0u && v->samples[v->samples_head].rx_us < *t) {
        best = 1;
        *t = v->samples[v->samples_head].rx_us;
    }
    if (v->lines_n > 0u && v->lines[v->lines_head].t_us < *t) {
        best = 2;
        *t = v->lines[v->lines_head].t_us;
    }
    return best;
}

static hal_status_t op_receive(void *ctx, hal_input_t *in, uint32_t timeout_us)
{
    hal_virtual_t *v = (hal_virtual_t *)ctx;
    const uint64_t deadline = v->now_us + timeout_us;
    uint64_t t;
    int q;
    if (in == NULL) {
        return HAL_ERR_ARG;
    }
    if (!v->link_up) {
        if (!v->down_reported) {
            v->down_reported = 1u;
            return HAL_ERR_LINK_DOWN;
        }
        v->now_us = deadline; /* nothing arrives while the link is down; time passes */
        return HAL_EMPTY;
    }
    q = next_queue(v, &t);
    if (q < 0) {
        if (v->ended) {
            return HAL_END;
        }
        v->now_us = deadline;
        return HAL_EMPTY;
    }
    if (t > deadline) {
        v->now_us = deadline;
        return HAL_EMPTY;
    }
    if (t > v->now_us) {
        v->now_us = t;
    }
    if (q == 0) {
        in->kind = HAL_IN_FRAME;
        in->u.frame = v->frames[v->frames_head];
        v->frames_head = (v->frames_head + 1u) % v->frames_cap;
        --v->frames_n;
    } else if (q == 1) {
        in->kind = HAL_IN_SAMPLE;
        in->u.sample = v->samples[v->samples_head];
        v->samples_head = (v->samples_head + 1u) % v->samples_cap;
        --v->samples_n;
    } else {
        in->kind = HAL_IN_LINE;
        in->u.line = v->lines[v->lines_head];
        v->lines_head = (v->lines_head + 1u) % v->lines_cap;
        --v->lines_n;
    }
    hal_count(&v->stats.rx_frames);
    return HAL_OK;
}

/* The link as a send sees it: HAL_OK, or the failure (counted for n items). */
static hal_status_t can_send(hal_virtual_t *v, size_t n)
{
    if (!v->link_up || v->tx_fail) {
        hal_count_n(&v->stats.tx_errors, (uint32_t)n);
        return v->link_up ? HAL_ERR_IO : HAL_ERR_LINK_DOWN;
    }
    hal_count_n(&v->stats.tx_frames, (uint32_t)n);
    return HAL_OK;
}

static hal_status_t op_send_frames(void *ctx, const hal_frame_t *frames, size_t n)
{
    hal_virtual_t *v = (hal_virtual_t *)ctx;
    hal_status_t st;
    size_t i;
    if (frames == NULL && n > 0u) {
        return HAL_ERR_ARG;
    }
    st = can_send(v, n);
    for (i = 0; st == HAL_OK && i < n; ++i) {
        if (v->on_frame != NULL) {
            hal_frame_t f = frames[i];
            f.t_us = v->now_us; /* sent now */
            v->on_frame(v->user, &f);
        }
    }
    return st;
}

static hal_status_t op_write_line(void *ctx, const char *text)
{
    hal_virtual_t *v = (hal_virtual_t *)ctx;
    const hal_status_t st = (text == NULL) ? HAL_ERR_ARG : can_send(v, 1u);
    if (st == HAL_OK && v->on_line != NULL) {
        v->on_line(v->user, text);
    }
    return st;
}

static void op_stats(void *ctx, hal_link_stats_t *s) { *s = ((const hal_virtual_t *)ctx)->stats; }

static void op_log(void *ctx, hal_level_t level, const char *event, int32_t detail)
{
    const hal_virtual_t *v = (const hal_virtual_t *)ctx;
    if (v->on_log != NULL) {
        v->on_log(v->user, level, event, detail);
    }
}

static const hal_ops_t virtual_ops = {
    op_now, op_receive, op_send_frames, op_write_line, op_stats, op_log,
};

void hal_virtual_bind(hal_virtual_t *v, hal_t *hal)
{
    hal->ops = &virtual_ops;
    hal->ctx = v;
}
