/*
 * app.h - the estimator application: the one loop every target runs.
 *
 *     static app_t app;                               caller owns the memory (~1.2 KiB)
 *     hal_t hal = { &my_backend_ops, &my_backend };   any backend of hal.h
 *     app_init(&app, &app_default_settings, &att_default_settings, &hal);
 *     for (;;) {
 *         hal_status_t st = app_poll(&app, 10000);    wait <= 10 ms for a sample
 *         if (st == HAL_END) break;                   a replay ran out
 *     }
 *
 * app_poll reads at most one sample from the HAL, runs the filter on it (att_step) and
 * publishes the attitude when an output is due. What it does with imperfect input
 * (docs/can_protocol.md, "Node behaviour", has the full table):
 *   - outputs are due on the SAMPLE clock: the first sample, then whenever the sample time
 *     reaches the next multiple of output_period_us after it (several due at once: one
 *     output). So a replay gives the same outputs whatever the wall-clock pacing.
 *   - a sequence gap (seq advanced by 2..seq_window) is predicted across with the measured
 *     time difference, counted (HAL_CNT_GAPS, HAL_CNT_MISSING) and flagged (HAL_FLAG_GAP);
 *     steps longer than the filter's dt_max are split into several predictions.
 *   - a time gap above max_gap_us with the sequence continuing (the sensor paused) restarts
 *     the filter (re-alignment): HAL_CNT_REALIGN, HAL_FLAG_RESTARTED.
 *   - a sample that does not continue the stream (sequence outside the window, or time not
 *     after the previous sample's) is dropped: HAL_CNT_LATE if it is from the past (sequence
 *     outside the window, time not after: a stale frame), else HAL_CNT_TIME_ERRORS. Only
 *     APP_RESTART_CONFIRM such samples in a row that continue each other are taken as a
 *     restarted sender: the filter restarts on the last of them (HAL_CNT_RESYNC,
 *     HAL_FLAG_RESTARTED).
 *   - a saturated sensor is not fused for that sample (HAL_CNT_SATURATED).
 *   - no sample for stale_timeout_us on the local clock: HAL_FLAG_STALE, and a heartbeat
 *     output (status only) every heartbeat period until samples come back.
 *   - HAL errors (link down, I/O) are latched into HAL_FLAG_LINK_ERROR; the backend recovers.
 * Every decision is counted in the counters published with each output.
 */
#ifndef APP_H
#define APP_H

#include <stdint.h>

#include "att.h"
#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Consecutive samples that continue each other but not the stream (consecutive sequence
 * numbers within seq_window, increasing times within max_gap_us) after which the sender is
 * taken to have restarted. A stale or corrupted frame yields one such sample (the CAN
 * assembly hands on a frame more than 64 samples old as a sample of its own): never a restart.
 * Each further sample delays a real restart by one sample period (20 ms at 100 Hz for 3),
 * small next to the re-alignment that follows (align_samples, 10 by default). */
#define APP_RESTART_CONFIRM 3u

typedef struct {
    uint32_t output_period_us; /* attitude output period on the sample clock, us; 0 = every
                                  sample. 10000 = 100 Hz */
    uint32_t stale_timeout_us; /* local time without a sample after which the input is
                                  stale, us, > 0 */
    uint32_t heartbeat_period_us; /* period of status-only outputs while stale, us, > 0 */
    uint32_t max_gap_us;       /* sample-time gap above which the filter restarts, us, > 0 */
    uint16_t seq_window;       /* a sequence step of 1..seq_window continues the stream (2..:
                                  a gap); anything else is a sensor restart. 1..32767 */
} app_settings_t;

/* 100 Hz output, stale after 100 ms, heartbeat 10 Hz, restart after a 2 s gap, window 1000. */
extern const app_settings_t app_default_settings;

/* Application state. Treat as opaque; read it through the functions below. */
typedef struct {
    app_settings_t settings;
    att_settings_t att_settings;      /* kept for restarts (re-alignment) */
    att_ekf_t ekf;
    const hal_t *hal;
    uint32_t counters[HAL_CNT_COUNT]; /* application-level entries, and late samples (added
                                         to the backend's late frames) */
    hal_output_t out;                 /* the last output; heartbeats repeat its estimate */
    uint64_t last_t_us;               /* sample time of the last accepted sample, us */
    uint64_t last_local_us;           /* local time of the last sample (or of app_init), us */
    uint64_t next_out_t_us;           /* sample time at which the next output is due, us */
    uint64_t next_heartbeat_us;       /* local time of the next heartbeat while stale, us */
    uint64_t restart_t_us;            /* sample time of the last off-stream sample, us */
    uint16_t last_seq;
    uint16_t latched;                 /* HAL_FLAG_* events since the last output */
    uint16_t out_index;
    uint16_t restart_seq;             /* seq of the last off-stream sample */
    uint8_t have_sample;              /* a sample was accepted since start or restart */
    uint8_t stale;
    uint8_t restart_n;                /* off-stream samples in a row that continue each other */
    uint8_t was_aligned;
} app_t;

/* Checks the settings (EKF_ERR_SETTINGS if out of range, EKF_ERR_NULL, or att_init's
 * answer for att) and starts the application; the HAL must be valid (hal_valid) or
 * EKF_ERR_NULL is returned. Reports HAL_EV_STARTED. */
ekf_status_t app_init(app_t *app, const app_settings_t *settings, const att_settings_t *att,
                      const hal_t *hal);

/* 0 if the settings are usable, else EKF_ERR_SETTINGS (EKF_ERR_NULL for NULL). */
ekf_status_t app_settings_check(const app_settings_t *settings);

/* One iteration: waits up to timeout_us for a sample, processes it, publishes what is due
 * (attitude or heartbeat). Returns what the HAL's read_sample returned: HAL_OK (a sample
 * was processed), HAL_EMPTY, HAL_END, or a HAL error (already counted and flagged; keep
 * calling, the backend recovers). HAL_ERR_ARG for a NULL app. */
hal_status_t app_poll(app_t *app, uint32_t timeout_us);

/* Every counter, link-level ones from the backend included. */
void app_get_counters(const app_t *app, uint32_t counters[HAL_CNT_COUNT]);

/* The filter (read-only use: att_get_euler etc.). */
const att_ekf_t *app_filter(const app_t *app);

/* The last output published (all zero before the first). */
const hal_output_t *app_last_output(const app_t *app);

#ifdef __cplusplus
}
#endif

#endif /* APP_H */
