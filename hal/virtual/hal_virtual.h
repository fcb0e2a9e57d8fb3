/*
 * hal_virtual.h - in-process HAL backend: tests and replays push CAN frames, IMU samples or text
 * lines; what the application sends (frames, lines) comes back through callbacks. No threads,
 * no allocation.
 *
 *     static hal_frame_t inbuf[1024];
 *     hal_virtual_t v;
 *     hal_t hal;
 *     hal_virtual_init(&v, inbuf, 1024, NULL, 0, NULL, 0);   frame queue only
 *     hal_virtual_bind(&v, &hal);
 *     hal_virtual_push_frame(&v, &frame);              t_us = when it "arrives"
 *     hal_virtual_end(&v);                             no more input: HAL_END when drained
 *     ... app_init(&app, &cfg, &hal); while (app_poll(&app, 10000) != HAL_END) {}
 *
 * Frames go through the same protocol code as on a real bus, so a replay through this backend
 * computes exactly what the node computes on vcan0 from the same frames.
 *
 * Clock: simulated. receive(timeout) delivers the next queued item whose time is at most
 * now + timeout and moves the clock to that time; if there is none it moves the clock to
 * now + timeout and returns HAL_EMPTY, as if it had waited. So stale detection and heartbeats
 * happen at the same simulated times as they would in real time.
 */
#ifndef HAL_VIRTUAL_H
#define HAL_VIRTUAL_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Called with every frame and line the application sends, and its log events. */
typedef void (*hal_virtual_frame_fn)(void *user, const hal_frame_t *frame);
typedef void (*hal_virtual_line_fn)(void *user, const char *line);
typedef void (*hal_virtual_log_fn)(void *user, hal_level_t level, const char *event, int32_t detail);

typedef struct {
    hal_frame_t *frames;       /* caller's ring of input frames (may be NULL) */
    size_t frames_cap, frames_head, frames_n;
    hal_sample_t *samples;     /* caller's ring of input samples (may be NULL) */
    size_t samples_cap, samples_head, samples_n;
    hal_line_t *lines;         /* caller's ring of input lines (may be NULL) */
    size_t lines_cap, lines_head, lines_n;
    hal_virtual_frame_fn on_frame;
    hal_virtual_line_fn on_line;
    hal_virtual_log_fn on_log;
    void *user;
    uint64_t now_us;
    hal_link_stats_t stats;
    uint8_t ended;
    uint8_t link_up;
    uint8_t down_reported;
    uint8_t tx_fail;
} hal_virtual_t;

/* Queues in caller memory (any may be NULL with capacity 0). Link up, clock at 0. */
void hal_virtual_init(hal_virtual_t *v, hal_frame_t *frames, size_t frames_cap, hal_sample_t *samples,
                      size_t samples_cap, hal_line_t *lines, size_t lines_cap);

/* Fills *hal with this backend's operations. */
void hal_virtual_bind(hal_virtual_t *v, hal_t *hal);

/* Callbacks for the frames and lines sent, and for log events (any may be NULL). */
void hal_virtual_set_sinks(hal_virtual_t *v, hal_virtual_frame_fn on_frame, hal_virtual_line_fn on_line,
                           hal_virtual_log_fn on_log, void *user);

/* Queues input. frame->t_us / sample->rx_us / line->t_us is its arrival time (earlier than
 * the clock: delivered at once). HAL_ERR_FULL (counted as rx_overflow) when the queue is full.
 * Items of different kinds are delivered in time order (frames first at equal times). */
hal_status_t hal_virtual_push_frame(hal_virtual_t *v, const hal_frame_t *frame);
hal_status_t hal_virtual_push_sample(hal_virtual_t *v, const hal_sample_t *sample);
hal_status_t hal_virtual_push_line(hal_virtual_t *v, uint64_t t_us, const char *text);

/* Free space in the frame queue. */
size_t hal_virtual_frame_space(const hal_virtual_t *v);

/* No more input: once the queues are drained receive returns HAL_END. */
void hal_virtual_end(hal_virtual_t *v);

/* Simulates the link going down (receive: HAL_ERR_LINK_DOWN once, counted; send: HAL_ERR_LINK_DOWN,
 * counted as transmit errors) and coming back. */
void hal_virtual_set_link(hal_virtual_t *v, int up);

/* Simulates transmit failures with the link up (bus off, full queue): sends return HAL_ERR_IO
 * and count as transmit errors, until cleared. */
void hal_virtual_set_tx_fail(hal_virtual_t *v, int fail);

/* Moves the simulated clock forward to t_us (never back): start a replay at its first
 * frame's time, so that the application does not see a long silence before it. */
void hal_virtual_set_clock(hal_virtual_t *v, uint64_t t_us);

/* The simulated clock, us. */
uint64_t hal_virtual_now_us(const hal_virtual_t *v);

#ifdef __cplusplus
}
#endif

#endif /* HAL_VIRTUAL_H */
