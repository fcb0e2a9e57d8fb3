/*
 * app_msg.h - what the estimator application publishes, whatever the protocol: the counters
 * of everything it saw, its status word, and one output (the attitude with its uncertainty,
 * or a status-only heartbeat). The protocols (dbc/: our CAN database; dronecan/; the text
 * lines of app_text.c) encode these; docs/can_protocol.md describes each on the wire.
 */
#ifndef APP_MSG_H
#define APP_MSG_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Every robustness counter of the node, in one array indexed by app_counter_id_t (the DBC's
 * ATT_COUNTERS pages keep this order: `python -m attekf.canproto check` compares them). The link
 * ones come from the backend (hal_link_stats_t), the others are the application's. All
 * saturate at UINT32_MAX. Row: X(ID, name, meaning). */
#define APP_COUNTERS(X) \
    X(RX_FRAMES, rx_frames, "inputs received (frames, samples, lines)") \
    X(FOREIGN, foreign, "frames of other protocols or nodes on a shared bus: ignored, not errors") \
    X(BAD_DLC, bad_dlc, "IMU frames of the wrong length: rejected") \
    X(DUPLICATE, duplicate, "frames already received for their sample: dropped") \
    X(LATE, late, "frames for a sample already completed or far outside the stream's sequence " \
                  "window, and samples older than the stream's last one: dropped") \
    X(INCOMPLETE, incomplete, "samples completed with a declared sensor frame missing") \
    X(DISCARDED, discarded, "samples given up because their time (sync) frame never came") \
    X(RX_OVERFLOW, rx_overflow, "inputs lost before reaching the node (kernel or driver queue full)") \
    X(LINK_DOWN, link_down, "times the link went down (or the device failed)") \
    X(TX_FRAMES, tx_frames, "frames or lines sent") \
    X(TX_ERRORS, tx_errors, "frames or lines that could not be sent") \
    X(SAMPLES, samples, "IMU samples received") \
    X(GAPS, gaps, "sequence gaps (one or more samples missing) predicted across") \
    X(MISSING, missing, "samples missing in those gaps, in total") \
    X(STALE, stale, "times the input went stale (no sample for stale_timeout)") \
    X(TIME_ERRORS, time_errors, "samples dropped: time not after the previous sample's, or a " \
                                "sequence jump not (yet) confirmed as a sensor restart") \
    X(RESYNC, resync, "sensor restarts: sequence out of window, clock restarted") \
    X(SATURATED, saturated, "samples with a saturated sensor (that sensor not fused)") \
    X(EKF_REJECTED, ekf_rejected, "samples the filter refused in part or whole (bad input)") \
    X(REALIGN, realign, "filter restarts after a gap longer than max_gap") \
    X(OUTPUTS, outputs, "attitude outputs published") \
    X(TRANSFER_ERRORS, transfer_errors, "DroneCAN transfers for the node that failed (CRC, toggle, " \
                                        "order, timeout, a payload that does not decode)") \
    X(REQUESTS, requests, "configuration requests served (parameters, opcodes, restarts, node " \
                          "info, text commands)") \
    X(REFUSED, refused, "requests refused (no such parameter, value out of range, bad command)")

#define APP_COUNTER_ENUM(id, name, help) APP_CNT_##id,
typedef enum { APP_COUNTERS(APP_COUNTER_ENUM) APP_CNT_COUNT } app_counter_id_t;
#undef APP_COUNTER_ENUM

/* Short lower-case name of a counter ("foreign"), as in logs, --stats and the DBC. */
const char *app_counter_name(app_counter_id_t id);

/* Status word of an output (app_output_t.flags). Event flags are latched: set if the event
 * happened at least once since the previous output, so a consumer misses none. */
#define APP_FLAG_ALIGNED        (1u << 0)  /* the filter has an attitude (else values are 0) */
#define APP_FLAG_STALE          (1u << 1)  /* no input sample for stale_timeout (state) */
#define APP_FLAG_GAP            (1u << 2)  /* event: missing samples were predicted across */
#define APP_FLAG_IN_SATURATED   (1u << 3)  /* event: an input sensor value was saturated */
#define APP_FLAG_OUT_SATURATED  (1u << 4)  /* this output: a value was clamped to the wire range */
#define APP_FLAG_LINK_ERROR     (1u << 5)  /* event: link down, rx overflow or tx failure */
#define APP_FLAG_FRAME_ERROR    (1u << 6)  /* event: bad length, duplicate or late frame, failed
                                              DroneCAN transfer (foreign frames are not errors) */
#define APP_FLAG_INCOMPLETE     (1u << 7)  /* event: a sample lacked a sensor it declared, or was discarded */
#define APP_FLAG_EKF_REJECT     (1u << 8)  /* event: the filter refused (part of) a sample */
#define APP_FLAG_TIME_ERROR     (1u << 9)  /* event: a sample with a bad time was dropped */
#define APP_FLAG_RESTARTED      (1u << 10) /* event: filter re-aligned (long gap), sensor resync or
                                              node restart */
#define APP_FLAG_HEARTBEAT      (1u << 11) /* this output is a heartbeat: no new sample since the
                                              last one; the estimate fields repeat the last */
#define APP_FLAG_CONFIG_PENDING (1u << 12) /* state: a setting was changed that takes effect at
                                              the next restart of the node */

typedef enum {
    APP_OUT_ATTITUDE = 0,  /* regular output, due on the sample clock */
    APP_OUT_HEARTBEAT = 1  /* status only, sent on the local clock while the input is stale */
} app_output_kind_t;

/* One output. Angles and vectors in the filter's frames: body (z up at rest) to ENU,
 * R = Rz(psi) Ry(theta) Rx(phi) (docs/derivation.md); the DroneCAN encoder converts. */
typedef struct {
    uint64_t t_us;          /* sample time of the newest sample in the estimate, us */
    uint64_t rx_us;         /* local receive time of that sample, us (latency reference) */
    float euler[3];         /* roll, pitch, yaw, rad */
    float quat[4];          /* w, x, y, z: body to ENU */
    float rates[3];         /* body angular rates p, q, r, rad/s (filter state) */
    float sigma[3];         /* 1-sigma uncertainty of roll, pitch, yaw, rad */
    float angle_cov[6];     /* covariance of roll, pitch, yaw errors, rad^2, packed as
                               att_get_angle_covariance: phi phi, theta theta, psi psi,
                               phi theta, phi psi, theta psi */
    float rate_var[3];      /* variances of p, q, r, (rad/s)^2 */
    float accel[3];         /* the newest accelerometer sample, m/s^2, body frame */
    uint32_t att_flags;     /* ATT_FLAG_* of firmware/att/att.h */
    uint32_t counters[APP_CNT_COUNT];
    uint16_t flags;         /* APP_FLAG_* */
    uint16_t seq;           /* sequence counter of that sample */
    uint16_t index;         /* output counter, +1 per publish (wraps); lets a consumer see losses */
    uint8_t kind;           /* app_output_kind_t */
} app_output_t;

#ifdef __cplusplus
}
#endif

#endif /* APP_MSG_H */
