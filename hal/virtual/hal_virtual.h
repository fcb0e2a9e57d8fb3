/*
 * hal_virtual.h - in-process HAL backend: tests and replays push CAN frames or samples,
 * the application's outputs come back through callbacks. No threads, no allocation.
 *
 *     static hal_can_frame_t inbuf[1024];
 *     hal_virtual_t v;
 *     hal_t hal;
 *     hal_virtual_init(&v, inbuf, 1024, NULL, 0);      frame queue, no sample queue
 *     hal_virtual_bind(&v, &hal);
 *     hal_virtual_push_frame(&v, &frame);              t_us = when it "arrives"
 *     hal_virtual_end(&v);                             no more input: HAL_END when drained
 *     ... app_init(&app, ..., &hal); while (app_poll(&app, 10000) != HAL_END) {}
 *
 * Frames go through the same protocol code as on a real bus (hal/can), so a replay
 * through this backend computes exactly what the node computes on vcan0 from the same
 * frames. Samples pushed directly skip the CAN layer (quantisation included).
 *
 * Clock: simulated. read_sample(timeout) delivers the next queued item whose time is at
 * most now + timeout and moves the clock to that time; if there is none it moves the clock
 * to now + timeout and returns HAL_EMPTY, as if it had waited. So stale detection and
 * heartbeats happen at the same simulated times as they would in real time.
 */
#ifndef HAL_VIRTUAL_H
#define HAL_VIRTUAL_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"
#include "hal_can.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Called with every output (and, if set, with each frame it encodes to). */
typedef void (*hal_virtual_output_fn)(void *user, const hal_output_t *out);
typedef void (*hal_virtual_frame_fn)(void *user, const hal_can_frame_t *frame);
typedef void (*hal_virtual_report_fn)(void *user, hal_level_t level, hal_event_t event, int32_t detail);

typedef struct {
    hal_can_rx_t rx;
    hal_can_tx_t tx;
    hal_can_frame_t *frames;   /* caller's ring of input frames */
    size_t frames_cap, frames_head, frames_n;
    hal_sample_t *samples;     /* caller's ring of input samples (may be NULL) */
    size_t samples_cap, samples_head, samples_n;
    hal_virtual_output_fn on_output;
    hal_virtual_frame_fn on_frame;
    hal_virtual_report_fn on_report;
    void *user;
    uint64_t now_us;
    uint32_t counters[HAL_CNT_COUNT]; /* own link-level counters (the assembler has its own) */
    uint8_t ended;
    uint8_t flushed;
    uint8_t link_up;
    uint8_t down_reported;
    uint8_t tx_fail;
} hal_virtual_t;

/* Queues in caller memory (either may be NULL with capacity 0). Link up, clock at 0. */
void hal_virtual_init(hal_virtual_t *v, hal_can_frame_t *frames, size_t frames_cap,
                      hal_sample_t *samples, size_t samples_cap);

/* Fills *hal with this backend's operations. */
void hal_virtual_bind(hal_virtual_t *v, hal_t *hal);

/* Callbacks for outputs, output frames and the application's events (any may be NULL). */
void hal_virtual_set_sinks(hal_virtual_t *v, hal_virtual_output_fn on_output,
                           hal_virtual_frame_fn on_frame, hal_virtual_report_fn on_report,
                           void *user);

/* Queues input. frame->t_us / sample->rx_us is its arrival time (earlier than the clock:
 * delivered at once). HAL_ERR_FULL (counted as HAL_CNT_RX_OVERFLOW) when the queue is full. */
hal_status_t hal_virtual_push_frame(hal_virtual_t *v, const hal_can_frame_t *frame);
hal_status_t hal_virtual_push_sample(hal_virtual_t *v, const hal_sample_t *sample);

/* Free space in the frame queue. */
size_t hal_virtual_frame_space(const hal_virtual_t *v);

/* No more input: once the queues are drained read_sample returns HAL_END. */
void hal_virtual_end(hal_virtual_t *v);

/* Simulates the link going down (read_sample: HAL_ERR_LINK_DOWN once, counted; publish:
 * HAL_ERR_LINK_DOWN, counted as a transmit error) and coming back. */
void hal_virtual_set_link(hal_virtual_t *v, int up);

/* Simulates transmit failures with the link up (bus off, full queue): publish returns
 * HAL_ERR_IO and counts the frames as transmit errors, until cleared. */
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
