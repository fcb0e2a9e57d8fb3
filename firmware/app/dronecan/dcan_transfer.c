/*
 * dcan_transfer.c - DroneCAN frames <-> transfers (dcan_transfer.h).
 */
#include "dcan_transfer.h"

#include <string.h>

#define TAIL_SOT 0x80u
#define TAIL_EOT 0x40u
#define TAIL_TOGGLE 0x20u
#define TAIL_TID 0x1Fu

int dcan_parse_id(uint32_t frame_id, dcan_transfer_t *t)
{
    const uint32_t id = frame_id & 0x1FFFFFFFu;
    if ((frame_id & HAL_FRAME_EXT) == 0u) {
        return 0;
    }
    t->priority = (uint8_t)((id >> 24) & 0x1Fu);
    t->source = (uint8_t)(id & 0x7Fu);
    if ((id & 0x80u) != 0u) {
        t->kind = ((id & 0x8000u) != 0u) ? (uint8_t)DCAN_REQUEST : (uint8_t)DCAN_RESPONSE;
        t->dtid = (uint16_t)((id >> 16) & 0xFFu);
        t->dest = (uint8_t)((id >> 8) & 0x7Fu);
    } else {
        t->kind = DCAN_MESSAGE;
        t->dest = 0u;
        /* anonymous messages carry only 2 bits of their type id (and a discriminator) */
        t->dtid = (uint16_t)((t->source == 0u) ? (id >> 8) & 0x3u : (id >> 8) & 0xFFFFu);
    }
    return 1;
}

uint32_t dcan_make_id(const dcan_transfer_t *t)
{
    uint32_t id = ((uint32_t)(t->priority & 0x1Fu) << 24) | (uint32_t)(t->source & 0x7Fu);
    if (t->kind == DCAN_MESSAGE) {
        id |= (uint32_t)t->dtid << 8;
    } else {
        id |= 0x80u | ((uint32_t)(t->dtid & 0xFFu) << 16) | ((uint32_t)(t->dest & 0x7Fu) << 8);
        if (t->kind == DCAN_REQUEST) {
            id |= 0x8000u;
        }
    }
    return id | HAL_FRAME_EXT;
}

uint16_t dcan_crc16(uint16_t crc, const uint8_t *data, size_t n)
{
    size_t i;
    int b;
    for (i = 0; i < n; ++i) {
        crc = (uint16_t)(crc ^ ((uint16_t)data[i] << 8));
        for (b = 0; b < 8; ++b) {
            crc = (uint16_t)(((crc & 0x8000u) != 0u) ? ((uint32_t)crc << 1) ^ 0x1021u : (uint32_t)crc << 1);
        }
    }
    return crc;
}

uint16_t dcan_crc_start(uint64_t signature)
{
    uint8_t b[8];
    int i;
    for (i = 0; i < 8; ++i) {
        b[i] = (uint8_t)(signature >> (8 * i));
    }
    return dcan_crc16(0xFFFFu, b, 8u);
}

size_t dcan_frames_needed(size_t len)
{
    return (len <= DCAN_FRAME_PAYLOAD) ? 1u : (len + 2u + DCAN_FRAME_PAYLOAD - 1u) / DCAN_FRAME_PAYLOAD;
}

size_t dcan_encode(const dcan_transfer_t *t, uint64_t signature, hal_frame_t *frames, size_t max_frames)
{
    const size_t n = dcan_frames_needed(t->len);
    const uint32_t id = dcan_make_id(t);
    const size_t total = (n == 1u) ? t->len : t->len + 2u; /* bytes before the tail bytes */
    size_t k, pos = 0;
    uint16_t crc = 0u;
    if (n > max_frames) {
        return 0;
    }
    if (n > 1u) {
        crc = dcan_crc16(dcan_crc_start(signature), t->payload, t->len);
    }
    for (k = 0; k < n; ++k) {
        hal_frame_t *f = &frames[k];
        uint8_t m = 0u;
        memset(f->data, 0, sizeof(f->data));
        while (m < DCAN_FRAME_PAYLOAD && pos < total) {
            /* byte pos of CRC + payload (multi-frame) or of the payload */
            if (n > 1u && pos < 2u) {
                f->data[m] = (uint8_t)(crc >> (8u * pos));
            } else {
                f->data[m] = t->payload[(n > 1u) ? pos - 2u : pos];
            }
            ++m;
            ++pos;
        }
        f->data[m] = (uint8_t)((k == 0u ? TAIL_SOT : 0u) | (k + 1u == n ? TAIL_EOT : 0u) |
                               ((k % 2u) != 0u ? TAIL_TOGGLE : 0u) | (t->tid & TAIL_TID));
        f->dlc = (uint8_t)(m + 1u);
        f->id = id;
        f->t_us = t->t_us;
    }
    return n;
}

void dcan_rx_init(dcan_rx_t *rx) { memset(rx, 0, sizeof(*rx)); }

static uint32_t key_of(const dcan_transfer_t *t)
{
    return ((uint32_t)t->dtid << 16) | ((uint32_t)(t->kind & 3u) << 14) | ((uint32_t)(t->source & 0x7Fu) << 7) |
           (uint32_t)(t->dest & 0x7Fu);
}

static dcan_rx_result_t refuse(dcan_rx_t *rx, dcan_rx_slot_t *sl)
{
    hal_count(&rx->errors);
    if (sl != NULL) {
        sl->used = 0u;
    }
    return DCAN_RX_REFUSED;
}

/* The slot of a key, or NULL. Slots whose transfer timed out are freed (and counted) on the
 * way. */
static dcan_rx_slot_t *find(dcan_rx_t *rx, uint32_t key, uint64_t now)
{
    dcan_rx_slot_t *hit = NULL;
    size_t i;
    for (i = 0; i < DCAN_RX_SLOTS; ++i) {
        dcan_rx_slot_t *sl = &rx->slot[i];
        if (!sl->used) {
            continue;
        }
        if (now > sl->t_us && now - sl->t_us > DCAN_TRANSFER_TIMEOUT_US) {
            (void)refuse(rx, sl); /* never finished */
            continue;
        }
        if (sl->key == key) {
            hit = sl;
        }
    }
    return hit;
}

static dcan_rx_slot_t *free_slot(dcan_rx_t *rx)
{
    size_t i;
    for (i = 0; i < DCAN_RX_SLOTS; ++i) {
        if (!rx->slot[i].used) {
            return &rx->slot[i];
        }
    }
    return NULL;
}

/* The first frame of a multi-frame transfer. */
static dcan_rx_result_t start(dcan_rx_t *rx, dcan_rx_slot_t *sl, const hal_frame_t *f, uint32_t key)
{
    if (sl != NULL) {
        (void)refuse(rx, sl); /* a new start while one was in progress: the old one is lost */
    }
    sl = free_slot(rx);
    if (sl == NULL || f->dlc != 8u) {
        return refuse(rx, NULL); /* no room, or a first frame that is not full */
    }
    sl->used = 1u;
    sl->key = key;
    sl->t_us = f->t_us;
    sl->tid = (uint8_t)(f->data[7] & TAIL_TID);
    sl->toggle = TAIL_TOGGLE;
    sl->crc = (uint16_t)(f->data[0] | (f->data[1] << 8));
    sl->len = 5u;
    memcpy(sl->buf, &f->data[2], 5u);
    return DCAN_RX_MORE;
}

dcan_rx_result_t dcan_rx_frame(dcan_rx_t *rx, const hal_frame_t *f, uint64_t signature, dcan_transfer_t *t)
{
    const uint32_t key = key_of(t);
    dcan_rx_slot_t *sl = find(rx, key, f->t_us);
    uint8_t tail;
    size_t n;
    if (f->dlc < 1u || f->dlc > 8u) {
        return refuse(rx, NULL);
    }
    tail = f->data[f->dlc - 1u];
    n = (size_t)f->dlc - 1u;
    if ((tail & TAIL_SOT) != 0u) {
        if ((tail & TAIL_TOGGLE) != 0u) {
            return refuse(rx, sl); /* a transfer starts with the toggle bit clear */
        }
        if ((tail & TAIL_EOT) != 0u) {
            if (sl != NULL) {
                (void)refuse(rx, sl);
            }
            t->payload = f->data;
            t->len = n;
            t->tid = (uint8_t)(tail & TAIL_TID);
            t->t_us = f->t_us;
            return DCAN_RX_DONE;
        }
        return start(rx, sl, f, key);
    }
    if (sl == NULL) {
        return refuse(rx, NULL); /* a continuation whose start we did not see */
    }
    if ((tail & TAIL_TID) != sl->tid || (tail & TAIL_TOGGLE) != sl->toggle ||
        ((tail & TAIL_EOT) == 0u && f->dlc != 8u) || sl->len + n > DCAN_RX_PAYLOAD_MAX) {
        return refuse(rx, sl);
    }
    memcpy(&sl->buf[sl->len], f->data, n);
    sl->len = (uint16_t)(sl->len + n);
    sl->toggle ^= TAIL_TOGGLE;
    if ((tail & TAIL_EOT) == 0u) {
        return DCAN_RX_MORE;
    }
    sl->used = 0u;
    if (dcan_crc16(dcan_crc_start(signature), sl->buf, sl->len) != sl->crc) {
        return refuse(rx, NULL);
    }
    t->payload = sl->buf;
    t->len = sl->len;
    t->tid = sl->tid;
    t->t_us = sl->t_us;
    return DCAN_RX_DONE;
}
