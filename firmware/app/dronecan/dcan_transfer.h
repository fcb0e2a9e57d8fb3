/*
 * dcan_transfer.h - DroneCAN transfers over classic CAN frames (the transport layer of the
 * UAVCAN v0 / DroneCAN specification, as the dronecan Python package implements it):
 *
 *   29-bit id    message:  priority(5) | data type id(16) | 0 | source node(7)
 *                service:  priority(5) | data type id(8) | request(1) | destination(7) | 1 |
 *                          source node(7)
 *   tail byte    the last data byte of every frame: start of transfer(1) | end of transfer(1) |
 *                toggle(1) | transfer id(5)
 *   single frame a payload of up to 7 bytes, no CRC;
 *   multi-frame  the payload preceded by its transfer CRC (CRC-16-CCITT-FALSE, little-endian)
 *                computed over the data type signature (8 bytes, little-endian) and the
 *                payload, cut into 7-byte pieces; the toggle bit starts at 0 and alternates;
 *                every frame but the last carries 8 bytes.
 *
 * The receiver reassembles up to DCAN_RX_SLOTS multi-frame transfers at a time (one per source,
 * data type and kind) and refuses what the rules above do not allow: a continuation without
 * its start, a wrong toggle or transfer id, a short frame before the end, a payload beyond
 * DCAN_RX_PAYLOAD_MAX, a CRC mismatch, a transfer not finished within DCAN_TRANSFER_TIMEOUT_US.
 * No allocation; the caller owns every struct.
 */
#ifndef DCAN_TRANSFER_H
#define DCAN_TRANSFER_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DCAN_FRAME_PAYLOAD 7u          /* payload bytes per frame (the 8th is the tail byte) */
#define DCAN_RX_SLOTS 4u               /* multi-frame transfers reassembled at the same time */
#define DCAN_RX_PAYLOAD_MAX 256u       /* largest payload taken (param.GetSet request: 224) */
#define DCAN_TRANSFER_TIMEOUT_US 2000000u /* a multi-frame transfer must complete within this */
#define DCAN_TX_FRAMES_MAX 64u         /* frames of the longest transfer the node sends */

typedef enum { DCAN_MESSAGE = 0, DCAN_REQUEST = 1, DCAN_RESPONSE = 2 } dcan_kind_t;

/* One transfer: what its CAN id says, and (received or to send) its payload. */
typedef struct {
    uint16_t dtid;          /* data type id (messages 0..65535, services 0..255) */
    uint8_t kind;           /* dcan_kind_t */
    uint8_t source;         /* node id of the sender, 1..127 (0: an anonymous message) */
    uint8_t dest;           /* services: node id it is addressed to, 1..127 */
    uint8_t priority;       /* 0 (highest) .. 31 */
    uint8_t tid;            /* transfer id, 0..31 */
    uint64_t t_us;          /* time of its first frame */
    const uint8_t *payload;
    size_t len;
} dcan_transfer_t;

/* Reads the id of an extended frame into t (dtid, kind, source, dest, priority). 1 if it is a
 * DroneCAN id (an extended frame), 0 if not (an 11-bit frame). Anonymous messages (source 0)
 * have only the low 2 bits of their data type id: dtid holds those. */
int dcan_parse_id(uint32_t frame_id, dcan_transfer_t *t);

/* The extended frame id (with HAL_FRAME_EXT) of a transfer. */
uint32_t dcan_make_id(const dcan_transfer_t *t);

/* CRC-16-CCITT-FALSE (poly 0x1021, no reflection) of n bytes, continuing from crc. */
uint16_t dcan_crc16(uint16_t crc, const uint8_t *data, size_t n);
/* The CRC of the 8 signature bytes from 0xFFFF: where a transfer's CRC starts. */
uint16_t dcan_crc_start(uint64_t signature);

/* Frames of a transfer of len payload bytes. */
size_t dcan_frames_needed(size_t len);

/* Cuts a transfer into frames (t_us of each = t->t_us). Returns the number of frames, or 0 if
 * they do not fit into max_frames. */
size_t dcan_encode(const dcan_transfer_t *t, uint64_t signature, hal_frame_t *frames, size_t max_frames);

/* Reassembly of received transfers. */
typedef struct {
    uint32_t key;           /* dtid, kind, source, dest: one transfer at a time of each */
    uint64_t t_us;          /* first frame */
    uint16_t crc;           /* the CRC the first frame carried */
    uint16_t len;           /* payload bytes so far */
    uint8_t tid;
    uint8_t toggle;         /* toggle bit the next frame must have */
    uint8_t used;
    uint8_t buf[DCAN_RX_PAYLOAD_MAX];
} dcan_rx_slot_t;

typedef struct {
    dcan_rx_slot_t slot[DCAN_RX_SLOTS];
    uint32_t errors;        /* frames or transfers refused (saturating) */
} dcan_rx_t;

void dcan_rx_init(dcan_rx_t *rx);

typedef enum {
    DCAN_RX_MORE = 0,       /* frame taken, the transfer goes on */
    DCAN_RX_DONE = 1,       /* *t is a complete transfer (payload valid until the next call) */
    DCAN_RX_REFUSED = -1    /* frame or transfer refused: counted in errors */
} dcan_rx_result_t;

/* One frame of a transfer the caller wants (its id parsed into *t by dcan_parse_id; signature:
 * its data type's). On DCAN_RX_DONE, t->payload, t->len, t->tid and t->t_us describe it. */
dcan_rx_result_t dcan_rx_frame(dcan_rx_t *rx, const hal_frame_t *frame, uint64_t signature, dcan_transfer_t *t);

#ifdef __cplusplus
}
#endif

#endif /* DCAN_TRANSFER_H */
