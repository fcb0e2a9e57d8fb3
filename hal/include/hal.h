/*
 * hal.h - the hardware abstraction the estimator application (firmware/app) runs against.
 *
 * A backend provides four things through a small table of functions (hal_ops_t):
 *   now_us       a monotonic clock, microseconds;
 *   read_sample  a source of timestamped IMU samples (gyro, accelerometer, magnetometer,
 *                each optional);
 *   publish      a sink for the attitude output (estimate, status word, counters);
 *   report       error and event reporting (logging; may do nothing);
 * plus get_counters, which fills the link-level robustness counters it keeps.
 *
 * Backends in this repository:
 *   hal/socketcan  Linux SocketCAN (can0, vcan0): frames of hal/can/attekf.dbc
 *   hal/virtual    in-process queues: tests and replays push frames or samples and
 *                  collect the outputs (no threads, no clock of its own)
 *   firmware/target  the bare-metal Cortex-M backend
 * The application only calls the inline wrappers below, so it is the same code on every
 * target; the backend is chosen by whoever fills the hal_t (at link time on a target,
 * from the command line in the Linux node).
 *
 * Rules: no allocation anywhere (the caller owns every struct), C99, no blocking longer
 * than the timeout the caller passes.
 *
 * Units: time in microseconds (uint64_t, never wraps in practice), rates rad/s,
 * specific force m/s^2, magnetic field uT, angles rad.
 */
#ifndef HAL_H
#define HAL_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------------------------ */
/* Results                                                                               */
/* ------------------------------------------------------------------------------------ */
typedef enum {
    HAL_OK = 0,            /* done / a sample was returned */
    HAL_EMPTY = 1,         /* no sample within the timeout (not an error) */
    HAL_END = 2,           /* the source is exhausted for good (end of a replay) */
    HAL_ERR_ARG = -1,      /* NULL pointer or argument out of range */
    HAL_ERR_IO = -2,       /* the device or socket failed (reported and counted) */
    HAL_ERR_LINK_DOWN = -3,/* the link (bus, interface) is down; the backend keeps trying
                              to bring it back on later calls */
    HAL_ERR_FULL = -4      /* an output or input queue is full; the item was not taken */
} hal_status_t;

/* Short constant name of a status ("HAL_ERR_IO"). Never NULL. */
const char *hal_status_name(hal_status_t status);

/* ------------------------------------------------------------------------------------ */
/* Input: one IMU sample                                                                 */
/* ------------------------------------------------------------------------------------ */
/* Sensor bits of hal_sample_t.valid and .saturated (same values as att.h's ATT_HAS_*). */
#define HAL_HAS_GYRO  (1u << 0)
#define HAL_HAS_ACCEL (1u << 1)
#define HAL_HAS_MAG   (1u << 2)
#define HAL_HAS_ALL   (HAL_HAS_GYRO | HAL_HAS_ACCEL | HAL_HAS_MAG)

typedef struct {
    uint64_t t_us;     /* sample time on the sensor's clock, us (unwrapped by the backend) */
    uint64_t rx_us;    /* local time (now_us clock) the sample became available, us; for the
                          CAN backends the kernel receive time of its last frame */
    float gyro[3];     /* angular rate, rad/s, body frame */
    float accel[3];    /* specific force, m/s^2, body frame (+g up at rest) */
    float mag[3];      /* magnetic field, uT, body frame */
    uint16_t seq;      /* sample sequence counter of the sensor (wraps at 65536) */
    uint8_t valid;     /* HAL_HAS_* of the sensors present in this sample */
    uint8_t saturated; /* HAL_HAS_* of the sensors whose value hit its wire or device range */
} hal_sample_t;

/* ------------------------------------------------------------------------------------ */
/* Counters                                                                             */
/* ------------------------------------------------------------------------------------ */
/* Every robustness counter of the node, in one array indexed by these ids. The link-level
 * ones are kept by the backend (get_counters), the rest by the application. All counters
 * saturate at UINT32_MAX. The CAN protocol publishes them all (docs/can_protocol.md). */
typedef enum {
    /* link level (backend) */
    HAL_CNT_RX_FRAMES = 0,   /* frames received (any id, any length) */
    HAL_CNT_UNKNOWN_ID,      /* frames with an id that is not an IMU input: ignored */
    HAL_CNT_BAD_DLC,         /* input frames of the wrong length: rejected */
    HAL_CNT_DUPLICATE,       /* frames already received for their sample: dropped */
    HAL_CNT_LATE,            /* frames for a sample already completed (out of order) or far
                                outside the stream's sequence window (stale), and samples
                                older than the stream's last one: dropped */
    HAL_CNT_INCOMPLETE,      /* samples completed with a declared sensor frame missing */
    HAL_CNT_DISCARDED,       /* samples given up because their time (sync) frame never came */
    HAL_CNT_RX_OVERFLOW,     /* frames lost before reaching us (kernel/driver queue overflow) */
    HAL_CNT_LINK_DOWN,       /* times the link went down (or the device failed) */
    HAL_CNT_TX_FRAMES,       /* output frames sent */
    HAL_CNT_TX_ERRORS,       /* output frames that could not be sent */
    /* application level (firmware/app) */
    HAL_CNT_SAMPLES,         /* samples received from the backend */
    HAL_CNT_GAPS,            /* sequence gaps (one or more samples missing) predicted across */
    HAL_CNT_MISSING,         /* samples missing in those gaps, in total */
    HAL_CNT_STALE,           /* times the input went stale (no sample for stale_timeout) */
    HAL_CNT_TIME_ERRORS,     /* samples dropped: time not after the previous sample's, or a
                                sequence jump not (yet) confirmed as a sensor restart */
    HAL_CNT_RESYNC,          /* sensor restarts: sequence out of window, clock restarted */
    HAL_CNT_SATURATED,       /* samples with a saturated sensor (that sensor not fused) */
    HAL_CNT_EKF_REJECTED,    /* samples the filter refused in part or whole (bad input) */
    HAL_CNT_REALIGN,         /* filter restarts after a gap longer than max_gap */
    HAL_CNT_OUTPUTS,         /* attitude outputs published */
    HAL_CNT_COUNT
} hal_counter_id_t;

#define HAL_CNT_LINK_FIRST HAL_CNT_RX_FRAMES
#define HAL_CNT_LINK_END   HAL_CNT_SAMPLES   /* one past the last link-level counter */

/* Short lower-case name of a counter ("unknown_id"), as used in logs and the DBC. */
const char *hal_counter_name(hal_counter_id_t id);

/* Adds 1, saturating at UINT32_MAX. */
void hal_count(uint32_t *counter);
/* Adds n, saturating at UINT32_MAX. */
void hal_count_n(uint32_t *counter, uint32_t n);

/* ------------------------------------------------------------------------------------ */
/* Output                                                                                */
/* ------------------------------------------------------------------------------------ */
/* Status word of an output (hal_output_t.flags). Event flags are latched: set if the event
 * happened at least once since the previous output, so a consumer misses none. */
#define HAL_FLAG_ALIGNED        (1u << 0)  /* the filter has an attitude (else values are 0) */
#define HAL_FLAG_STALE          (1u << 1)  /* no input sample for stale_timeout (state) */
#define HAL_FLAG_GAP            (1u << 2)  /* event: missing samples were predicted across */
#define HAL_FLAG_IN_SATURATED   (1u << 3)  /* event: an input sensor value was saturated */
#define HAL_FLAG_OUT_SATURATED  (1u << 4)  /* this output: a value was clamped to the wire range */
#define HAL_FLAG_LINK_ERROR     (1u << 5)  /* event: link down, rx overflow or tx failure */
#define HAL_FLAG_FRAME_ERROR    (1u << 6)  /* event: unknown id, bad length, duplicate or late frame */
#define HAL_FLAG_INCOMPLETE     (1u << 7)  /* event: a sample lacked a sensor it declared, or was discarded */
#define HAL_FLAG_EKF_REJECT     (1u << 8)  /* event: the filter refused (part of) a sample */
#define HAL_FLAG_TIME_ERROR     (1u << 9)  /* event: a sample with a bad time was dropped */
#define HAL_FLAG_RESTARTED      (1u << 10) /* event: filter re-aligned (long gap) or sensor resync */
#define HAL_FLAG_HEARTBEAT      (1u << 11) /* this output is a heartbeat: no new sample since the
                                              last one; the estimate fields repeat the last */

typedef enum {
    HAL_OUT_ATTITUDE = 0,  /* regular output, due on the sample clock */
    HAL_OUT_HEARTBEAT = 1  /* status only, sent on the local clock while the input is stale */
} hal_output_kind_t;

typedef struct {
    uint64_t t_us;         /* sample time of the newest sample in the estimate, us */
    uint64_t rx_us;        /* local receive time of that sample, us (latency reference) */
    float euler[3];        /* roll, pitch, yaw, rad (ZYX, body to ENU; docs/derivation.md) */
    float rates[3];        /* body angular rates p, q, r, rad/s (filter state) */
    float sigma[3];        /* 1-sigma uncertainty of roll, pitch, yaw, rad */
    uint32_t att_flags;    /* ATT_FLAG_* of firmware/att/att.h */
    uint32_t counters[HAL_CNT_COUNT];
    uint16_t flags;        /* HAL_FLAG_* */
    uint16_t seq;          /* sequence counter of that sample */
    uint16_t index;        /* output counter, +1 per publish (wraps); lets a consumer see losses */
    uint8_t kind;          /* hal_output_kind_t */
} hal_output_t;

/* ------------------------------------------------------------------------------------ */
/* Events and logging                                                                    */
/* ------------------------------------------------------------------------------------ */
typedef enum { HAL_LOG_ERROR = 0, HAL_LOG_WARN = 1, HAL_LOG_INFO = 2, HAL_LOG_DEBUG = 3 } hal_level_t;

typedef enum {
    HAL_EV_STARTED = 0,    /* detail: 0 */
    HAL_EV_LINK_DOWN,      /* detail: errno or device code */
    HAL_EV_LINK_UP,        /* detail: 0 */
    HAL_EV_RX_OVERFLOW,    /* detail: frames lost */
    HAL_EV_TX_ERROR,       /* detail: errno or device code */
    HAL_EV_ALIGNED,        /* detail: sample seq */
    HAL_EV_GAP,            /* detail: samples missing */
    HAL_EV_STALE,          /* detail: ms since the last sample */
    HAL_EV_RESUMED,        /* detail: ms the input was stale */
    HAL_EV_TIME_ERROR,     /* detail: sample seq */
    HAL_EV_RESYNC,         /* detail: new sample seq */
    HAL_EV_REALIGN,        /* detail: gap, ms */
    HAL_EV_EKF_REJECT,     /* detail: ekf_status_t of the first refused stage */
    HAL_EV_SATURATED,      /* detail: HAL_HAS_* bits */
    HAL_EV_LATE,           /* detail: sample seq (a sample from before the stream's last one) */
    HAL_EV_COUNT
} hal_event_t;

/* Short lower-case name of an event ("link_down"). Never NULL. */
const char *hal_event_name(hal_event_t event);

/* ------------------------------------------------------------------------------------ */
/* The backend                                                                           */
/* ------------------------------------------------------------------------------------ */
typedef struct {
    /* Monotonic time, us. Must never go backwards. */
    uint64_t (*now_us)(void *ctx);
    /* Waits at most timeout_us (0: just look) for the next sample. HAL_OK: *out filled;
     * HAL_EMPTY: none yet; HAL_END: never any more; HAL_ERR_LINK_DOWN / HAL_ERR_IO: the
     * backend counted and reported the failure and will try to recover on the next call. */
    hal_status_t (*read_sample)(void *ctx, hal_sample_t *out, uint32_t timeout_us);
    /* Emits one output. Must not block longer than a frame time; a failure is counted
     * (HAL_CNT_TX_ERRORS) by the backend and returned. */
    hal_status_t (*publish)(void *ctx, const hal_output_t *out);
    /* Writes the link-level counters, counters[HAL_CNT_LINK_FIRST .. HAL_CNT_LINK_END-1];
     * leaves the others alone. May be NULL (no link-level counters: all zero). */
    void (*get_counters)(void *ctx, uint32_t counters[HAL_CNT_COUNT]);
    /* An event for the log. May be NULL (events dropped). Must not block for long. */
    void (*report)(void *ctx, hal_level_t level, hal_event_t event, int32_t detail);
} hal_ops_t;

/* A backend instance: its operations and its state (owned by whoever set it up). */
typedef struct {
    const hal_ops_t *ops;
    void *ctx;
} hal_t;

/* Wrappers the application uses (NULL-tolerant for the optional operations). */
static inline uint64_t hal_now_us(const hal_t *h) { return h->ops->now_us(h->ctx); }
static inline hal_status_t hal_read_sample(const hal_t *h, hal_sample_t *out, uint32_t timeout_us)
{
    return h->ops->read_sample(h->ctx, out, timeout_us);
}
static inline hal_status_t hal_publish(const hal_t *h, const hal_output_t *out)
{
    return h->ops->publish(h->ctx, out);
}
static inline void hal_get_counters(const hal_t *h, uint32_t counters[HAL_CNT_COUNT])
{
    if (h->ops->get_counters != 0) {
        h->ops->get_counters(h->ctx, counters);
    }
}
static inline void hal_report(const hal_t *h, hal_level_t level, hal_event_t event, int32_t detail)
{
    if (h->ops->report != 0) {
        h->ops->report(h->ctx, level, event, detail);
    }
}

/* 1 if the table has the mandatory operations (now_us, read_sample, publish), else 0. */
int hal_valid(const hal_t *h);

#ifdef __cplusplus
}
#endif

#endif /* HAL_H */
