/*
 * hal.h - the hardware abstraction the estimator application (firmware/app) runs against:
 * transport only. The messages on it (the CAN protocols, the text lines) belong to the
 * application.
 *
 * A backend provides, through a small table of functions (hal_ops_t):
 *   now_us       a monotonic clock, microseconds;
 *   receive      the next input: a CAN frame (a bus), an IMU sample (a backend that reads the
 *                sensors or a recording itself) or a text line (a console, a command file);
 *   send_frames  CAN frames out (NULL on a backend without a bus);
 *   write_line   a text line out (NULL on a backend without a text channel);
 *   get_stats    the link counters it keeps (frames in and out, losses, outages);
 *   log          events for a log (may do nothing).
 * Whatever comes in (frames, samples, lines) also carries the node's commands and
 * configuration: every backend has a way in for them (docs/architecture.md, "The node").
 *
 * Backends in this repository:
 *   hal/socketcan    Linux SocketCAN (can0, vcan0): frames
 *   hal/virtual      in-process queues of frames, samples and lines: tests and replays (no
 *                    threads, a simulated clock)
 *   firmware/target  the bare-metal Cortex-M backend: samples of a recording, command lines,
 *                    output lines, over semihosting
 * The application only calls the inline wrappers below, so it is the same code on every
 * target; the backend is chosen by whoever fills the hal_t.
 *
 * Rules: no allocation anywhere (the caller owns every struct), C99, no blocking longer
 * than the timeout the caller passes.
 *
 * Units: time in microseconds (uint64_t, never wraps in practice), rates rad/s,
 * specific force m/s^2, magnetic field uT.
 */
#ifndef HAL_H
#define HAL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------------------------ */
/* Results                                                                               */
/* ------------------------------------------------------------------------------------ */
typedef enum {
    HAL_OK = 0,            /* done / an input was returned */
    HAL_EMPTY = 1,         /* no input within the timeout (not an error) */
    HAL_END = 2,           /* the source is exhausted for good (end of a replay) */
    HAL_ERR_ARG = -1,      /* NULL pointer, argument out of range, operation not provided */
    HAL_ERR_IO = -2,       /* the device or socket failed (reported and counted) */
    HAL_ERR_LINK_DOWN = -3,/* the link (bus, interface) is down; the backend keeps trying
                              to bring it back on later calls */
    HAL_ERR_FULL = -4      /* an output or input queue is full; the item was not taken */
} hal_status_t;

/* Short constant name of a status ("HAL_ERR_IO"). Never NULL. */
const char *hal_status_name(hal_status_t status);

/* ------------------------------------------------------------------------------------ */
/* What a backend carries                                                                */
/* ------------------------------------------------------------------------------------ */
/* One classic CAN data frame. A 29-bit (extended) id has HAL_FRAME_EXT set. */
#define HAL_FRAME_EXT 0x80000000u
typedef struct {
    uint64_t t_us;     /* receive (or send) time, us, on the now_us clock */
    uint32_t id;       /* 11-bit id, or 29-bit id | HAL_FRAME_EXT */
    uint8_t dlc;       /* 0..8 as received (a larger value is the receiver's to refuse) */
    uint8_t data[8];
} hal_frame_t;

/* Sensor bits of hal_sample_t.valid and .saturated (same values as att.h's ATT_HAS_*). */
#define HAL_HAS_GYRO  (1u << 0)
#define HAL_HAS_ACCEL (1u << 1)
#define HAL_HAS_MAG   (1u << 2)
#define HAL_HAS_ALL   (HAL_HAS_GYRO | HAL_HAS_ACCEL | HAL_HAS_MAG)

/* One IMU sample, body frame. Backends that read the sensors themselves deliver these; the
 * application's bus protocols assemble the same struct from frames. */
typedef struct {
    uint64_t t_us;     /* sample time on the sensor's clock, us (unwrapped) */
    uint64_t rx_us;    /* local time (now_us clock) the sample became available, us; on a bus
                          the receive time of its last frame */
    float gyro[3];     /* angular rate, rad/s */
    float accel[3];    /* specific force, m/s^2 (+g up at rest) */
    float mag[3];      /* magnetic field, uT */
    uint16_t seq;      /* sample sequence counter of the sensor (wraps at 65536) */
    uint8_t valid;     /* HAL_HAS_* of the sensors present in this sample */
    uint8_t saturated; /* HAL_HAS_* of the sensors whose value hit its wire or device range */
} hal_sample_t;

/* One line of text without its line break, NUL-terminated (a command, a reply). */
#define HAL_LINE_MAX 128
typedef struct {
    uint64_t t_us;     /* when it arrived, us */
    char text[HAL_LINE_MAX];
} hal_line_t;

typedef enum { HAL_IN_FRAME = 1, HAL_IN_SAMPLE = 2, HAL_IN_LINE = 3 } hal_input_kind_t;

/* One input: kind says which member is filled. */
typedef struct {
    uint8_t kind;      /* hal_input_kind_t */
    union {
        hal_frame_t frame;
        hal_sample_t sample;
        hal_line_t line;
    } u;
} hal_input_t;

/* Link counters a backend keeps (saturating at UINT32_MAX). */
typedef struct {
    uint32_t rx_frames;   /* inputs received (frames, samples or lines) */
    uint32_t rx_overflow; /* inputs lost before reaching us (kernel or driver queue full) */
    uint32_t link_down;   /* times the link went down (or the device failed) */
    uint32_t tx_frames;   /* frames or lines sent */
    uint32_t tx_errors;   /* frames or lines that could not be sent */
} hal_link_stats_t;

/* Adds 1 / n, saturating at UINT32_MAX. */
void hal_count(uint32_t *counter);
void hal_count_n(uint32_t *counter, uint32_t n);

/* ------------------------------------------------------------------------------------ */
/* Logging                                                                               */
/* ------------------------------------------------------------------------------------ */
typedef enum { HAL_LOG_ERROR = 0, HAL_LOG_WARN = 1, HAL_LOG_INFO = 2, HAL_LOG_DEBUG = 3 } hal_level_t;

/* ------------------------------------------------------------------------------------ */
/* The backend                                                                           */
/* ------------------------------------------------------------------------------------ */
typedef struct {
    /* Monotonic time, us. Must never go backwards. */
    uint64_t (*now_us)(void *ctx);
    /* Waits at most timeout_us (0: just look) for the next input. HAL_OK: *in filled;
     * HAL_EMPTY: none yet; HAL_END: never any more; HAL_ERR_LINK_DOWN / HAL_ERR_IO: the
     * backend counted and reported the failure and will try to recover on the next call. */
    hal_status_t (*receive)(void *ctx, hal_input_t *in, uint32_t timeout_us);
    /* Sends n frames in order, without blocking longer than a few frame times. HAL_OK when
     * all went out; otherwise the failures are counted (tx_errors) and the first is returned.
     * NULL: no bus. */
    hal_status_t (*send_frames)(void *ctx, const hal_frame_t *frames, size_t n);
    /* Writes one line (a line break is added). NULL: no text output. */
    hal_status_t (*write_line)(void *ctx, const char *text);
    /* Its link counters. May be NULL (all zero). */
    void (*get_stats)(void *ctx, hal_link_stats_t *stats);
    /* An event for the log: a short lower-case name ("link_down") and a number. May be NULL
     * (events dropped). Must not block for long. */
    void (*log)(void *ctx, hal_level_t level, const char *event, int32_t detail);
} hal_ops_t;

/* A backend instance: its operations and its state (owned by whoever set it up). */
typedef struct {
    const hal_ops_t *ops;
    void *ctx;
} hal_t;

/* Wrappers the application uses (NULL-tolerant for the optional operations). */
static inline uint64_t hal_now_us(const hal_t *h) { return h->ops->now_us(h->ctx); }
static inline hal_status_t hal_receive(const hal_t *h, hal_input_t *in, uint32_t timeout_us)
{
    return h->ops->receive(h->ctx, in, timeout_us);
}
static inline hal_status_t hal_send_frames(const hal_t *h, const hal_frame_t *frames, size_t n)
{
    return (h->ops->send_frames != 0) ? h->ops->send_frames(h->ctx, frames, n) : HAL_ERR_ARG;
}
static inline hal_status_t hal_write_line(const hal_t *h, const char *text)
{
    return (h->ops->write_line != 0) ? h->ops->write_line(h->ctx, text) : HAL_ERR_ARG;
}
static inline void hal_get_stats(const hal_t *h, hal_link_stats_t *stats)
{
    if (h->ops->get_stats != 0) {
        h->ops->get_stats(h->ctx, stats);
    } else {
        stats->rx_frames = stats->rx_overflow = stats->link_down = 0u;
        stats->tx_frames = stats->tx_errors = 0u;
    }
}
static inline void hal_log(const hal_t *h, hal_level_t level, const char *event, int32_t detail)
{
    if (h->ops->log != 0) {
        h->ops->log(h->ctx, level, event, detail);
    }
}

/* 1 if the table has the mandatory operations (now_us, receive), else 0. */
int hal_valid(const hal_t *h);

#ifdef __cplusplus
}
#endif

#endif /* HAL_H */
