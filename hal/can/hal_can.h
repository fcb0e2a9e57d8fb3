/*
 * hal_can.h - the CAN protocol of hal/can/attekf.dbc on top of the cantools-generated
 * pack/unpack code (canmsg_gen.c): IMU frames -> samples (hal_can_rx.c), outputs -> frames
 * (hal_can_output.c); the IMU frames one at a time in hal_can_input.c.
 *
 * Independent of any CAN driver: the SocketCAN backend, the virtual backend and a bare-metal
 * CAN driver all feed received frames to hal_can_rx_frame() and send what
 * hal_can_encode_output() produces. docs/can_protocol.md describes the protocol; the
 * assembly rules, in short:
 *   - the frames of one sample (IMU_GYRO, IMU_ACCEL, IMU_MAG, IMU_SYNC) share Seq;
 *   - a sample is complete when its IMU_SYNC has arrived together with every sensor frame
 *     IMU_SYNC declares (Has* bits), in any order: it is emitted at once;
 *   - up to HAL_CAN_RX_SLOTS samples are assembled at the same time, so frames of
 *     consecutive samples may interleave (CAN controllers send queued frames by id
 *     priority, which can put IMU_GYRO of k+1 before IMU_SYNC of k);
 *   - samples are emitted in sequence order. When a newer sample completes, older ones that
 *     already have their IMU_SYNC are emitted without the missing sensor (HAL_CNT_INCOMPLETE);
 *     when a frame needs a slot and none is free, the oldest sample is emitted the same way,
 *     or, without its IMU_SYNC (no time), discarded (HAL_CNT_DISCARDED);
 *   - a frame repeating one already received for its sample is a duplicate; a frame for a
 *     sample already emitted or discarded (within HAL_CAN_SEQ_WINDOW) is late; both dropped
 *     and counted;
 *   - a frame more than HAL_CAN_SEQ_WINDOW away from the newest sample (either way) is held
 *     aside, the samples being assembled untouched: the next frame of the stream drops it
 *     as late (a stale frame). A frame of a newer sample continuing the held one (within the
 *     window) before that means the sender restarted: the samples being assembled are
 *     emitted or discarded as above and the assembly goes on from the held sample;
 *   - wrong length: rejected (HAL_CNT_BAD_DLC); other ids: ignored (HAL_CNT_UNKNOWN_ID).
 */
#ifndef HAL_CAN_H
#define HAL_CAN_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_CAN_RX_SLOTS 2        /* samples assembled concurrently */
#define HAL_CAN_SEQ_WINDOW 64     /* sequence numbers either side of the newest sample that
                                     belong to the stream (late, duplicate or new samples) */
#define HAL_CAN_READY_MAX 4       /* completed samples waiting for hal_can_rx_pop */
#define HAL_CAN_HISTORY 4         /* emitted samples remembered to tell duplicates from late */
#define HAL_CAN_MAX_OUT_FRAMES 5  /* frames per output (hal_can_encode_output) */
#define HAL_CAN_SAMPLE_FRAMES 4   /* frames per input sample (hal_can_encode_sample) */

/* One classic CAN frame (11-bit id, no RTR / error frames reach this layer). */
typedef struct {
    uint64_t t_us;     /* receive (or send) time, us, on the HAL clock */
    uint32_t id;       /* 11-bit id; a 29-bit (extended) id has bit 31 set */
    uint8_t dlc;       /* 0..8 (a larger value is reported as a wrong length) */
    uint8_t data[8];
} hal_can_frame_t;

/* A sample being assembled. */
typedef struct {
    hal_sample_t s;
    uint32_t time_raw;   /* IMU_SYNC.TimeUs as received */
    uint8_t have;        /* HAL_HAS_* of sensor frames received, HAL_CAN_HAVE_SYNC */
    uint8_t declared;    /* HAL_HAS_* declared by IMU_SYNC */
    uint8_t used;
} hal_can_slot_t;

#define HAL_CAN_HAVE_SYNC (1u << 3)

/* Receive side: the sample assembler. Memory owned by the caller; hal_can_rx_init first. */
typedef struct {
    hal_can_slot_t slot[HAL_CAN_RX_SLOTS];
    hal_sample_t ready[HAL_CAN_READY_MAX];
    uint16_t hist_seq[HAL_CAN_HISTORY]; /* emitted or discarded samples, newest at hist_pos-1 */
    uint8_t hist_have[HAL_CAN_HISTORY];
    uint8_t hist_n;
    uint8_t hist_pos;
    uint8_t ready_head;
    uint8_t ready_n;
    uint8_t have_head;      /* head_seq valid */
    uint16_t head_seq;      /* newest sequence number seen */
    uint8_t have_time;
    uint64_t last_t_us;     /* unwrapped time of the last emitted sample */
    hal_can_slot_t held;    /* a sample outside the window (held.used): stale or a restart */
    uint8_t held_frames;    /* frames in held (late if the stream goes on) */
    uint32_t counters[HAL_CNT_COUNT]; /* RX_FRAMES, UNKNOWN_ID, BAD_DLC, DUPLICATE, LATE,
                                         INCOMPLETE, DISCARDED */
} hal_can_rx_t;

void hal_can_rx_init(hal_can_rx_t *rx);

/* Feeds one received frame (any id). Completed samples queue up for hal_can_rx_pop. If the
 * ready queue is full the oldest queued sample is overwritten and counted as discarded
 * (pop after every frame and it never happens). */
void hal_can_rx_frame(hal_can_rx_t *rx, const hal_can_frame_t *frame);

/* Takes the oldest completed sample: 1 if *out was filled, 0 if none. */
int hal_can_rx_pop(hal_can_rx_t *rx, hal_sample_t *out);

/* End of input: emits (or discards) every sample still being assembled; held frames are
 * late. */
void hal_can_rx_flush(hal_can_rx_t *rx);

/* Adds the assembler's counters into counters[] (link-level entries only). */
void hal_can_rx_add_counters(const hal_can_rx_t *rx, uint32_t counters[HAL_CNT_COUNT]);

/* Transmit side. page: the ATT_COUNTERS page sent with the next output. */
typedef struct {
    uint8_t page;
} hal_can_tx_t;

void hal_can_tx_init(hal_can_tx_t *tx);

/* Encodes an output: ATT_EULER, ATT_RATES, ATT_SIGMA, ATT_STATUS, ATT_COUNTERS for an
 * attitude output, ATT_STATUS and ATT_COUNTERS for a heartbeat. Values outside their wire
 * range are clamped and the status word's OutSaturated bit is set (non-finite values, which
 * the filter never produces, are sent as 0 and flagged the same way). Returns the number
 * of frames written to frames[] (t_us of each = out->rx_us). */
size_t hal_can_encode_output(hal_can_tx_t *tx, const hal_output_t *out,
                             hal_can_frame_t frames[HAL_CAN_MAX_OUT_FRAMES]);

/* Encodes a sample as the IMU would (tests, the benchmark sender): one frame per present
 * sensor, then IMU_SYNC. Values outside the wire range are clamped and flagged in the
 * Sat* bits, non-finite sensor vectors are left out. TimeUs = t_us mod 2^32. Returns the
 * number of frames (1..4). */
size_t hal_can_encode_sample(const hal_sample_t *s, hal_can_frame_t frames[HAL_CAN_SAMPLE_FRAMES]);

/* Decodes one output frame into *out (fields of that frame only; others untouched).
 * Returns 1 if the id is an output frame of the protocol with the right length, else 0. */
int hal_can_decode_output(const hal_can_frame_t *frame, hal_output_t *out);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CAN_H */
