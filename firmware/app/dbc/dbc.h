/*
 * dbc.h - the node's own CAN protocol, firmware/app/dbc/attekf.dbc, on top of the
 * cantools-generated pack/unpack code (canmsg_gen.c): IMU frames -> samples (dbc_rx.c),
 * outputs -> frames and the parameter frames (dbc_output.c); the IMU frames one at a time in
 * dbc_input.c.
 *
 * Independent of any CAN driver: the application feeds received frames to dbc_rx_frame() and
 * hands what dbc_encode_output() produces to the HAL. docs/can_protocol.md describes the
 * protocol; the assembly rules, in short:
 *   - the frames of one sample (IMU_GYRO, IMU_ACCEL, IMU_MAG, IMU_SYNC) share Seq;
 *   - a sample is complete when its IMU_SYNC has arrived together with every sensor frame
 *     IMU_SYNC declares (Has* bits), in any order: it is emitted at once;
 *   - up to DBC_RX_SLOTS samples are assembled at the same time, so frames of consecutive
 *     samples may interleave (CAN controllers send queued frames by id priority, which can put
 *     IMU_GYRO of k+1 before IMU_SYNC of k);
 *   - samples are emitted in sequence order. When a newer sample completes, older ones that
 *     already have their IMU_SYNC are emitted without the missing sensor (incomplete); when a
 *     frame needs a slot and none is free, the oldest sample is emitted the same way, or,
 *     without its IMU_SYNC (no time), discarded;
 *   - a frame repeating one already received for its sample is a duplicate; a frame for a
 *     sample already emitted or discarded (within DBC_SEQ_WINDOW) is late; both dropped and
 *     counted;
 *   - a frame more than DBC_SEQ_WINDOW away from the newest sample (either way) is held aside,
 *     the samples being assembled untouched: the next frame of the stream drops it as late (a
 *     stale frame). A frame of a newer sample continuing the held one (within the window)
 *     before that means the sender restarted: the samples being assembled are emitted or
 *     discarded as above and the assembly goes on from the held sample;
 *   - an IMU id with the wrong length: rejected (bad_dlc). Other ids are not the assembler's:
 *     dbc_rx_kind() says which frames are.
 *
 * Ids: the DBC gives those of the default base ids. The IMU frames sit at imu_base + 0..3
 * (IMU_GYRO, IMU_ACCEL, IMU_MAG, IMU_SYNC; default 0x100), the node's frames at base + 0..6
 * (ATT_EULER ... ATT_COUNTERS, ATT_PARAM, ATT_PARAM_REQ; default 0x180), so that several
 * estimators can share a bus and an IMU.
 */
#ifndef DBC_H
#define DBC_H

#include <stddef.h>
#include <stdint.h>

#include "app_msg.h"
#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DBC_RX_SLOTS 2        /* samples assembled concurrently */
#define DBC_SEQ_WINDOW 64     /* sequence numbers either side of the newest sample that belong
                                 to the stream (late, duplicate or new samples) */
#define DBC_READY_MAX 4       /* completed samples waiting for dbc_rx_pop */
#define DBC_HISTORY 4         /* emitted samples remembered to tell duplicates from late */
#define DBC_MAX_OUT_FRAMES 5  /* frames per output (dbc_encode_output) */
#define DBC_SAMPLE_FRAMES 4   /* frames per input sample (dbc_encode_sample) */
#define DBC_IMU_FRAMES 4      /* ids from imu_base: IMU_GYRO, IMU_ACCEL, IMU_MAG, IMU_SYNC */
#define DBC_NODE_FRAMES 7     /* ids from base: ATT_EULER .. ATT_COUNTERS, ATT_PARAM, ATT_PARAM_REQ */
#define DBC_ID_MAX 0x7FFu     /* 11-bit ids */

/* A sample being assembled. */
typedef struct {
    hal_sample_t s;
    uint32_t time_raw;   /* IMU_SYNC.TimeUs as received */
    uint8_t have;        /* HAL_HAS_* of the sensor frames received */
    uint8_t have_sync;   /* its IMU_SYNC has arrived */
    uint8_t declared;    /* HAL_HAS_* declared by IMU_SYNC */
    uint8_t used;
} dbc_slot_t;

/* What the assembler counted (the app_counter_id_t entries it owns). */
typedef struct {
    uint32_t bad_dlc, duplicate, late, incomplete, discarded;
} dbc_rx_counts_t;

/* Receive side: the sample assembler. Memory owned by the caller; dbc_rx_init first. */
typedef struct {
    dbc_slot_t slot[DBC_RX_SLOTS];
    hal_sample_t ready[DBC_READY_MAX];
    uint16_t hist_seq[DBC_HISTORY]; /* emitted or discarded samples, newest at hist_pos-1 */
    uint8_t hist_have[DBC_HISTORY]; /* their sensor frames (HAL_HAS_*) */
    uint8_t hist_sync[DBC_HISTORY]; /* whether their IMU_SYNC was received */
    uint8_t hist_n;
    uint8_t hist_pos;
    uint8_t ready_head;
    uint8_t ready_n;
    uint8_t have_head;      /* head_seq valid */
    uint16_t head_seq;      /* newest sequence number seen */
    uint16_t imu_base;      /* id of IMU_GYRO */
    uint8_t have_time;
    uint64_t last_t_us;     /* unwrapped time of the last emitted sample */
    dbc_slot_t held;        /* a sample outside the window (held.used): stale or a restart */
    uint8_t held_frames;    /* frames in held (late if the stream goes on) */
    dbc_rx_counts_t n;
} dbc_rx_t;

/* imu_base: the id of IMU_GYRO (dbc_imu_base_ok). */
void dbc_rx_init(dbc_rx_t *rx, uint16_t imu_base);

/* 1 if id is one of the IMU frames the assembler takes (any length), else 0. */
int dbc_rx_takes(const dbc_rx_t *rx, uint32_t id);

/* Feeds one IMU frame (dbc_rx_takes). Completed samples queue up for dbc_rx_pop. If the ready
 * queue is full the oldest queued sample is overwritten and counted as discarded (pop after
 * every frame and it never happens). */
void dbc_rx_frame(dbc_rx_t *rx, const hal_frame_t *frame);

/* Takes the oldest completed sample: 1 if *out was filled, 0 if none. */
int dbc_rx_pop(dbc_rx_t *rx, hal_sample_t *out);

/* End of input: emits (or discards) every sample still being assembled; held frames are
 * late. */
void dbc_rx_flush(dbc_rx_t *rx);

/* 1 if base ids put every frame of the protocol inside the 11-bit range without the node's
 * frames overlapping the IMU's: imu_base + 4 <= base or base + 7 <= imu_base. */
int dbc_bases_ok(uint32_t base, uint32_t imu_base);

/* Transmit side. page: the ATT_COUNTERS page sent with the next output; base: id of ATT_EULER. */
typedef struct {
    uint8_t page;
    uint16_t base;
} dbc_tx_t;

void dbc_tx_init(dbc_tx_t *tx, uint16_t base);

/* Encodes an output: ATT_EULER, ATT_RATES, ATT_SIGMA, ATT_STATUS, ATT_COUNTERS for an attitude
 * output, ATT_STATUS and ATT_COUNTERS for a heartbeat. Values outside their wire range are
 * clamped and the status word's OutSaturated bit is set (non-finite values, which the filter
 * never produces, are sent as 0 and flagged the same way). Returns the number of frames
 * written to frames[] (t_us of each = out->rx_us). */
size_t dbc_encode_output(dbc_tx_t *tx, const app_output_t *out, hal_frame_t frames[DBC_MAX_OUT_FRAMES]);

/* Decodes one output frame (of the default base) into *out (fields of that frame only; others
 * untouched). Returns 1 if the id is an output frame of the protocol with the right length,
 * else 0. */
int dbc_decode_output(const hal_frame_t *frame, app_output_t *out);

/* Encodes a sample as the IMU would at the default base (tests, the benchmark sender): one frame
 * per present sensor, then IMU_SYNC. Values outside the wire range are clamped and flagged in
 * the Sat* bits, non-finite sensor vectors are left out. TimeUs = t_us mod 2^32. Returns the
 * number of frames (1..4). */
size_t dbc_encode_sample(const hal_sample_t *s, hal_frame_t frames[DBC_SAMPLE_FRAMES]);

/* ---- parameters (ATT_PARAM_REQ in, ATT_PARAM out) ---- */
typedef enum { DBC_OP_GET = 0, DBC_OP_SET = 1, DBC_OP_SAVE = 2, DBC_OP_ERASE = 3, DBC_OP_RESTART = 4 } dbc_op_t;
typedef enum {
    DBC_RESULT_OK = 0,
    DBC_RESULT_PENDING_RESTART = 1,  /* set: takes effect at the next restart */
    DBC_RESULT_NO_SUCH = 2,
    DBC_RESULT_RANGE = 3,            /* set: refused, the value is unchanged */
    DBC_RESULT_FAILED = 4,           /* save/erase not possible here */
    DBC_RESULT_BAD_REQUEST = 5       /* unknown operation or a value that is not finite */
} dbc_result_t;

typedef struct {
    uint16_t index;
    uint8_t op;      /* dbc_op_t */
    float value;
} dbc_param_req_t;

/* 1 and *req if frame is an ATT_PARAM_REQ of the node at base with 8 bytes; 0 if it is not that
 * id; -1 if it is, but malformed (wrong length). */
int dbc_decode_param_req(const dbc_tx_t *tx, const hal_frame_t *frame, dbc_param_req_t *req);

/* The ATT_PARAM answer. */
void dbc_encode_param(const dbc_tx_t *tx, uint16_t index, uint8_t op, uint8_t result, float value,
                      uint64_t t_us, hal_frame_t *frame);

#ifdef __cplusplus
}
#endif

#endif /* DBC_H */
