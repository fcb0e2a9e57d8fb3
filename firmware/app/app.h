/*
 * app.h - the estimator application: the one loop every target runs.
 *
 *     static app_t app;                               caller owns the memory
 *     hal_t hal = { &my_backend_ops, &my_backend };   any backend of hal.h
 *     app_config_t cfg;
 *     app_default_config(&cfg);                       then change what you need
 *     app_init(&app, &cfg, &hal);
 *     for (;;) {
 *         hal_status_t st = app_poll(&app, 10000);    wait <= 10 ms for input
 *         if (st == HAL_END) break;                   a replay ran out
 *     }
 *
 * app_poll takes what the backend delivers (CAN frames, IMU samples, text lines), turns it
 * into samples with the configured protocol, runs the filter on each (att_step) and publishes
 * the attitude when an output is due, in the configured protocol: our CAN database (dbc/),
 * DroneCAN (dronecan/) or text lines (app_text.c). The same input carries configuration: the
 * DBC's parameter frames, DroneCAN's param.GetSet / ExecuteOpcode / RestartNode services, or
 * text commands; every setting of the filter and of the node is a parameter (app_param.h).
 *
 * What it does with imperfect input (docs/can_protocol.md, "Node behaviour", has the table):
 *   - outputs are due on the SAMPLE clock: the first sample, then whenever the sample time
 *     reaches the next multiple of output_period_us after it (several due at once: one
 *     output). So a replay gives the same outputs whatever the wall-clock pacing.
 *   - a sequence gap (seq advanced by 2..seq_window) is predicted across with the measured
 *     time difference, counted and flagged (APP_FLAG_GAP); steps longer than the filter's
 *     dt_max are split into several predictions.
 *   - a time gap above max_gap_us with the sequence continuing restarts the filter.
 *   - a sample that does not continue the stream is dropped (late or a time error); only
 *     APP_RESTART_CONFIRM such samples in a row that continue each other are taken as a
 *     restarted sender: the filter restarts on the last of them.
 *   - a saturated sensor is not fused for that sample.
 *   - no sample for stale_timeout_us on the local clock: APP_FLAG_STALE, and a heartbeat output
 *     (status only) every heartbeat period until samples come back.
 *   - HAL errors (link down, I/O) are latched into APP_FLAG_LINK_ERROR; the backend recovers.
 *   - frames of other protocols or nodes are counted as foreign, never as errors.
 * Every decision is counted in the counters published with each output.
 */
#ifndef APP_H
#define APP_H

#include <stddef.h>
#include <stdint.h>

#include "app_msg.h"
#include "att.h"
#include "dbc.h"
#include "dcan_transfer.h"
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

/* The application's timing (docs/can_protocol.md, "Node behaviour"). */
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

/* The message formats of the node. */
typedef enum {
    APP_PROTO_DBC = 0,      /* firmware/app/dbc/attekf.dbc: IMU_* in, ATT_* out */
    APP_PROTO_DRONECAN = 1, /* RawIMU + MagneticFieldStrength2 in; ahrs.Solution, NodeStatus and
                               the node services out */
    APP_PROTO_TEXT = 2      /* samples from the backend, text commands in; CSV lines out */
} app_protocol_t;

#define APP_UNIQUE_ID_BYTES 16

/* Who the node is on its bus. */
typedef struct {
    uint8_t protocol;       /* app_protocol_t of the outputs, status and configuration */
    uint8_t input;          /* app_protocol_t of the IMU frames taken on a bus: APP_PROTO_DBC
                               (IMU_* frames) or APP_PROTO_DRONECAN (RawIMU, MagneticFieldStrength2);
                               samples a backend delivers itself are always taken */
    uint8_t node_id;        /* DroneCAN node id, 1..127 */
    uint8_t imu_node;       /* DroneCAN: node id whose RawIMU is taken; 0: the first node heard */
    uint8_t mag_node;       /* DroneCAN: node id whose MagneticFieldStrength2 is taken; 0: the
                               first node heard */
    uint16_t dbc_base;      /* DBC: id of ATT_EULER, the first of the node's frames */
    uint16_t dbc_imu_base;  /* DBC: id of IMU_GYRO, the first of the IMU's frames */
    uint8_t unique_id[APP_UNIQUE_ID_BYTES]; /* DroneCAN GetNodeInfo's hardware unique id */
} app_node_settings_t;

/* Node id 100, DBC at 0x180 / 0x100 (the DBC's ids), protocol and input DBC. */
extern const app_node_settings_t app_default_node;

/* Everything a node is configured with: the parameters (app_param.h) and the unique id. */
typedef struct {
    app_settings_t app;
    app_node_settings_t node;
    att_settings_t att;
} app_config_t;

/* The defaults of all three. */
void app_default_config(app_config_t *cfg);

/* EKF_OK if the configuration is usable: each part in range (app_settings_check,
 * app_node_check, att_settings_check) and the parts consistent (a gap up to max_gap_us is
 * predicted across in at most 1000 steps of dt_max). EKF_ERR_SETTINGS or EKF_ERR_NULL. */
ekf_status_t app_config_check(const app_config_t *cfg);
ekf_status_t app_settings_check(const app_settings_t *settings);
ekf_status_t app_node_check(const app_node_settings_t *node);

/* Optional hooks of the program around the application. */
typedef struct {
    /* Stores the configuration (param.ExecuteOpcode SAVE, DBC op save, text "save"): writes the
     * lines app_config_write gives, and returns 1 if they are safely stored. NULL: no storage. */
    int (*save)(void *user, const app_config_t *cfg);
    /* Erases what save stored (the defaults apply at the next start). 1 if done. */
    int (*erase)(void *user);
    /* Sees every output (tests, statistics). */
    void (*on_output)(void *user, const app_output_t *out);
    void *user;
} app_hooks_t;

/* A non-live parameter set while running: in force at the next restart. */
#define APP_PENDING_MAX 16
typedef struct {
    uint16_t index;
    float value;
} app_pending_t;

/* DroneCAN state of the node. */
typedef struct {
    dcan_rx_t rx;
    uint64_t next_status_us;   /* local time of the next NodeStatus */
    uint64_t start_us;         /* local time of the start (uptime) */
    uint16_t status_flags;     /* APP_FLAG_* seen since the last NodeStatus */
    uint8_t tid_status;        /* transfer ids of what the node publishes */
    uint8_t tid_solution;
    uint8_t imu_source;        /* node id the RawIMU messages are taken from (0: none yet) */
    uint8_t mag_source;        /* node id the magnetometer messages are taken from (0: none yet) */
    uint8_t imu_tid;           /* transfer id of its last RawIMU */
    uint8_t have_imu;
    uint16_t imu_seq;          /* sample counter made from the RawIMU transfer ids */
    float mag[3];              /* the newest magnetometer reading since the last RawIMU, uT,
                                  filter body frame */
    uint8_t have_mag;
    uint8_t mag_saturated;
} app_dcan_t;

/* Application state. Treat as opaque; read it through the functions below. */
typedef struct {
    app_settings_t settings;
    app_node_settings_t node;
    att_ekf_t ekf;                    /* the filter: holds its own settings */
    const hal_t *hal;
    app_hooks_t hooks;
    app_pending_t pending[APP_PENDING_MAX];
    uint8_t n_pending;
    uint8_t restart_requested;
    uint32_t counters[APP_CNT_COUNT]; /* application-level entries (and late samples, added to
                                         the assembler's late frames) */
    app_output_t out;                 /* the last output; heartbeats repeat its estimate */
    float last_accel[3];              /* newest accelerometer sample, m/s^2 */
    uint64_t last_t_us;               /* sample time of the last accepted sample, us */
    uint64_t last_local_us;           /* local time of the last sample (or of app_init), us */
    uint64_t next_out_t_us;           /* sample time at which the next output is due, us */
    uint64_t next_heartbeat_us;       /* local time of the next heartbeat while stale, us */
    uint64_t restart_t_us;            /* sample time of the last off-stream sample, us */
    uint32_t errors_seen[3];          /* sums of the frame, sample and link error counters at
                                         the last look (their changes become status flags) */
    uint16_t last_seq;
    uint16_t latched;                 /* APP_FLAG_* events since the last output */
    uint16_t out_index;
    uint16_t restart_seq;             /* seq of the last off-stream sample */
    uint8_t have_sample;              /* a sample was accepted since start or restart */
    uint8_t stale;
    uint8_t restart_n;                /* off-stream samples in a row that continue each other */
    uint8_t was_aligned;
    uint8_t text_header;              /* the CSV header line was written */
    dbc_rx_t dbc_rx;                  /* DBC: sample assembly */
    dbc_tx_t dbc_tx;                  /* DBC: output frames */
    app_dcan_t dcan;                  /* DroneCAN */
} app_t;

/* Checks the configuration (app_config_check) and starts the application; the HAL must be
 * valid (hal_valid) or EKF_ERR_NULL is returned. Logs "started". */
ekf_status_t app_init(app_t *app, const app_config_t *cfg, const hal_t *hal);

/* Hooks (may be NULL: none). */
void app_set_hooks(app_t *app, const app_hooks_t *hooks);

/* One iteration: waits up to timeout_us for input, handles what arrived (frames until one
 * has completed a sample or nothing more is waiting), publishes what is due (attitude,
 * heartbeat, DroneCAN status). Returns what the HAL's receive returned first: HAL_OK (input
 * was handled), HAL_EMPTY, HAL_END, or a HAL error (already counted and flagged; keep calling,
 * the backend recovers). HAL_ERR_ARG for a NULL app. */
hal_status_t app_poll(app_t *app, uint32_t timeout_us);

/* Restarts the node as a RestartNode request does: the configuration with every pending
 * parameter in force, the filter not aligned, the sample stream and the DroneCAN uptime from
 * zero; the counters go on. */
void app_restart(app_t *app);

/* Every counter, link ones from the backend included. */
void app_get_counters(const app_t *app, uint32_t counters[APP_CNT_COUNT]);

/* The filter (read-only use: att_get_euler etc.). */
const att_ekf_t *app_filter(const app_t *app);

/* The last output published (all zero before the first). */
const app_output_t *app_last_output(const app_t *app);

#ifdef __cplusplus
}
#endif

#endif /* APP_H */
