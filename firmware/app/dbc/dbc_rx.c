/*
 * dbc_rx.c - the sample assembly of the node's CAN protocol (dbc.h, docs/can_protocol.md):
 * input frames -> samples, in sequence order, with every fault counted.
 */
#include "dbc_input.h"

#include <string.h>

/* a - b in sequence-number arithmetic (RFC 1982 style): in -32768..32767. */
static int32_t seq_diff(uint16_t a, uint16_t b)
{
    int32_t d = (int32_t)(uint16_t)(a - b);
    return (d >= 32768) ? d - 65536 : d;
}

void dbc_rx_init(dbc_rx_t *rx, uint16_t imu_base)
{
    memset(rx, 0, sizeof(*rx));
    rx->imu_base = imu_base;
}

int dbc_rx_takes(const dbc_rx_t *rx, uint32_t id)
{
    return id >= rx->imu_base && id < (uint32_t)rx->imu_base + DBC_IMU_FRAMES;
}

int dbc_bases_ok(uint32_t base, uint32_t imu_base)
{
    return base + DBC_NODE_FRAMES - 1u <= DBC_ID_MAX && imu_base + DBC_IMU_FRAMES - 1u <= DBC_ID_MAX &&
           (imu_base + DBC_IMU_FRAMES <= base || base + DBC_NODE_FRAMES <= imu_base);
}

/* ---- history of emitted / discarded samples (duplicate vs late) ---------------------- */
static void history_add(dbc_rx_t *rx, const dbc_slot_t *sl)
{
    rx->hist_seq[rx->hist_pos] = sl->s.seq;
    rx->hist_have[rx->hist_pos] = sl->have;
    rx->hist_sync[rx->hist_pos] = sl->have_sync;
    rx->hist_pos = (uint8_t)((rx->hist_pos + 1u) % DBC_HISTORY);
    if (rx->hist_n < DBC_HISTORY) {
        ++rx->hist_n;
    }
}

static uint16_t history_newest(const dbc_rx_t *rx)
{
    return rx->hist_seq[(rx->hist_pos + DBC_HISTORY - 1u) % DBC_HISTORY];
}

/* 1 if the frame of that kind was received for an emitted sample, 0 if not (or the sample is
 * not remembered). */
static int history_had(const dbc_rx_t *rx, uint16_t seq, int kind)
{
    uint8_t i;
    for (i = 0; i < rx->hist_n; ++i) {
        const uint8_t k = (uint8_t)((rx->hist_pos + DBC_HISTORY - 1u - i) % DBC_HISTORY);
        if (rx->hist_seq[k] == seq) {
            return (kind == DBC_KIND_SYNC) ? rx->hist_sync[k] != 0u
                                           : (rx->hist_have[k] & (1u << kind)) != 0u;
        }
    }
    return 0;
}

/* ---- slots ------------------------------------------------------------------------- */
static dbc_slot_t *find_slot(dbc_rx_t *rx, uint16_t seq)
{
    int i;
    for (i = 0; i < DBC_RX_SLOTS; ++i) {
        if (rx->slot[i].used && rx->slot[i].s.seq == seq) {
            return &rx->slot[i];
        }
    }
    return NULL;
}

/* The used slot with the oldest sequence number (relative to the head), or NULL. */
static dbc_slot_t *oldest_slot(dbc_rx_t *rx)
{
    dbc_slot_t *best = NULL;
    int32_t best_age = -1;
    int i;
    for (i = 0; i < DBC_RX_SLOTS; ++i) {
        if (rx->slot[i].used) {
            const int32_t age = seq_diff(rx->head_seq, rx->slot[i].s.seq);
            if (age > best_age) {
                best_age = age;
                best = &rx->slot[i];
            }
        }
    }
    return best;
}

static int slot_complete(const dbc_slot_t *sl)
{
    return sl->have_sync && (sl->declared & (uint8_t)~sl->have & HAL_HAS_ALL) == 0u;
}

static void push_ready(dbc_rx_t *rx, const hal_sample_t *s)
{
    uint8_t tail;
    if (rx->ready_n == DBC_READY_MAX) {
        /* Nobody popped: drop the oldest so the newest data wins. */
        rx->ready_head = (uint8_t)((rx->ready_head + 1u) % DBC_READY_MAX);
        --rx->ready_n;
        hal_count(&rx->n.discarded);
    }
    tail = (uint8_t)((rx->ready_head + rx->ready_n) % DBC_READY_MAX);
    rx->ready[tail] = *s;
    ++rx->ready_n;
}

/* Emits a slot that has its IMU_SYNC: unwraps the 32-bit time, queues the sample. */
static void emit(dbc_rx_t *rx, dbc_slot_t *sl)
{
    uint64_t t;
    if (!rx->have_time) {
        t = sl->time_raw;
    } else {
        /* Signed 32-bit difference to the previous sample: correct across the 2^32 us
         * wrap as long as consecutive samples are less than 35 min apart. */
        const uint32_t u = sl->time_raw - (uint32_t)rx->last_t_us;
        const int64_t d = (u >= 0x80000000u) ? (int64_t)u - (int64_t)0x100000000 : (int64_t)u;
        if (d < 0 && (uint64_t)(-d) > rx->last_t_us) {
            t = sl->time_raw; /* before the start of the unwrapped clock: take it as is */
        } else {
            t = (uint64_t)((int64_t)rx->last_t_us + d);
        }
    }
    rx->last_t_us = t;
    rx->have_time = 1u;
    sl->s.t_us = t;
    sl->s.valid = (uint8_t)(sl->have & HAL_HAS_ALL);
    sl->s.saturated = (uint8_t)(sl->s.saturated & sl->s.valid);
    if ((sl->declared & (uint8_t)~sl->have & HAL_HAS_ALL) != 0u) {
        hal_count(&rx->n.incomplete);
    }
    push_ready(rx, &sl->s);
    history_add(rx, sl);
    sl->used = 0u;
}

/* Gives up a slot: emitted without its missing sensors if it has a time, else discarded. */
static void finish(dbc_rx_t *rx, dbc_slot_t *sl)
{
    if (sl->have_sync) {
        emit(rx, sl);
    } else {
        hal_count(&rx->n.discarded);
        history_add(rx, sl);
        sl->used = 0u;
    }
}

/* Emits whatever can go out, in sequence order. */
static void advance(dbc_rx_t *rx)
{
    for (;;) {
        dbc_slot_t *old = oldest_slot(rx);
        int i;
        int newer_complete = 0;
        if (old == NULL) {
            return;
        }
        if (slot_complete(old)) {
            emit(rx, old);
            continue;
        }
        for (i = 0; i < DBC_RX_SLOTS; ++i) {
            if (&rx->slot[i] != old && rx->slot[i].used && slot_complete(&rx->slot[i])) {
                newer_complete = 1;
            }
        }
        /* A newer sample is complete: the sensor frame the old one waits for would have come
         * before it. Without its IMU_SYNC the old one may still complete (reordering). */
        if (newer_complete && old->have_sync) {
            emit(rx, old);
            continue;
        }
        return;
    }
}

static void flush_slots(dbc_rx_t *rx)
{
    dbc_slot_t *old;
    while ((old = oldest_slot(rx)) != NULL) {
        finish(rx, old);
    }
}

/* A slot for a sequence number not being assembled, or NULL (frame is late: counted). */
static dbc_slot_t *open_slot(dbc_rx_t *rx, uint16_t seq)
{
    int i;
    for (;;) {
        dbc_slot_t *old;
        for (i = 0; i < DBC_RX_SLOTS; ++i) {
            if (!rx->slot[i].used) {
                dbc_slot_t *sl = &rx->slot[i];
                memset(sl, 0, sizeof(*sl));
                sl->used = 1u;
                sl->s.seq = seq;
                if (!rx->have_head || seq_diff(seq, rx->head_seq) > 0) {
                    rx->head_seq = seq;
                    rx->have_head = 1u;
                }
                return sl;
            }
        }
        old = oldest_slot(rx);
        if (seq_diff(seq, old->s.seq) < 0) {
            hal_count(&rx->n.late); /* older than everything pending */
            return NULL;
        }
        finish(rx, old);
        advance(rx);
    }
}

static void add_to_slot(dbc_slot_t *sl, int kind, const dbc_input_t *d, uint64_t rx_us)
{
    int i;
    float *dst = NULL;
    if (kind == DBC_KIND_SYNC) {
        sl->time_raw = d->sync.time_us;
        sl->declared = (uint8_t)((d->sync.has_gyro ? HAL_HAS_GYRO : 0u) |
                                 (d->sync.has_accel ? HAL_HAS_ACCEL : 0u) |
                                 (d->sync.has_mag ? HAL_HAS_MAG : 0u));
        sl->s.saturated |= (uint8_t)((d->sync.sat_gyro ? HAL_HAS_GYRO : 0u) |
                                     (d->sync.sat_accel ? HAL_HAS_ACCEL : 0u) |
                                     (d->sync.sat_mag ? HAL_HAS_MAG : 0u));
        sl->have_sync = 1u;
    } else {
        const uint8_t bit = (uint8_t)(1u << kind);
        dst = (kind == DBC_KIND_GYRO) ? sl->s.gyro : (kind == DBC_KIND_ACCEL) ? sl->s.accel : sl->s.mag;
        for (i = 0; i < 3; ++i) {
            dst[i] = d->v[i];
        }
        if (d->saturated) {
            sl->s.saturated |= bit;
        }
        sl->have |= bit;
    }
    /* The sample is available when its last frame arrives. */
    if (rx_us > sl->s.rx_us) {
        sl->s.rx_us = rx_us;
    }
}

/* ---- frames outside the stream's window ------------------------------------------- */
/* 1 if seq is of a sample emitted or discarded not long ago (a duplicate or late frame). */
static int recent(const dbc_rx_t *rx, uint16_t seq)
{
    int32_t dh;
    if (rx->hist_n == 0u) {
        return 0;
    }
    dh = seq_diff(seq, history_newest(rx));
    return dh <= 0 && dh >= -DBC_SEQ_WINDOW;
}

/* 1 if seq is more than DBC_SEQ_WINDOW away from the newest sample, either way. */
static int off_stream(const dbc_rx_t *rx, uint16_t seq)
{
    int32_t d;
    if (!rx->have_head) {
        return 0;
    }
    d = seq_diff(seq, rx->head_seq);
    return d < -DBC_SEQ_WINDOW || d > DBC_SEQ_WINDOW;
}

/* The stream went on: the held frames were stale (or stray), each one late. */
static void drop_held(dbc_rx_t *rx)
{
    hal_count_n(&rx->n.late, rx->held_frames);
    rx->held.used = 0u;
    rx->held_frames = 0u;
}

/* 1 if the slot already has the frame of that kind. */
static int slot_has(const dbc_slot_t *sl, int kind)
{
    return (kind == DBC_KIND_SYNC) ? sl->have_sync != 0u : (sl->have & (1u << kind)) != 0u;
}

/* An off-stream frame: held with the frames of its sample. Returns 1 if it continues the
 * held sample with a newer sequence number (within the window): the sender restarted. */
static int hold(dbc_rx_t *rx, int kind, const dbc_input_t *d, uint64_t rx_us)
{
    dbc_slot_t *h = &rx->held;
    if (h->used) {
        const int32_t dc = seq_diff(d->seq, h->s.seq);
        if (dc > 0 && dc <= DBC_SEQ_WINDOW) {
            return 1;
        }
        if (dc == 0) {
            if (slot_has(h, kind)) {
                hal_count(&rx->n.duplicate);
            } else {
                add_to_slot(h, kind, d, rx_us);
                ++rx->held_frames;
            }
            return 0;
        }
        drop_held(rx); /* a stray frame of its own */
    }
    memset(h, 0, sizeof(*h));
    h->used = 1u;
    h->s.seq = d->seq;
    add_to_slot(h, kind, d, rx_us);
    rx->held_frames = 1u;
    return 0;
}

/* The sender restarted: the old stream's samples are given up (emitted without what is
 * missing, or discarded) and the held sample starts the new one. */
static void restart_with_held(dbc_rx_t *rx)
{
    flush_slots(rx);
    rx->hist_n = 0u;
    rx->slot[0] = rx->held;
    rx->head_seq = rx->held.s.seq;
    rx->have_head = 1u;
    rx->held.used = 0u;
    rx->held_frames = 0u;
    advance(rx);
}

void dbc_rx_flush(dbc_rx_t *rx)
{
    if (rx->held.used) {
        drop_held(rx); /* one sample of a sequence of its own is no stream */
    }
    flush_slots(rx);
}

void dbc_rx_frame(dbc_rx_t *rx, const hal_frame_t *frame)
{
    dbc_input_t d;
    dbc_slot_t *sl;
    int kind;

    if (!dbc_rx_takes(rx, frame->id)) {
        return; /* not an IMU frame: the caller's business */
    }
    kind = (int)(frame->id - rx->imu_base);
    if (frame->dlc != 8u || !dbc_decode_input(kind, frame->data, &d)) {
        hal_count(&rx->n.bad_dlc);
        return;
    }

    sl = find_slot(rx, d.seq);
    if (sl == NULL && !recent(rx, d.seq) && off_stream(rx, d.seq)) {
        /* A stale frame or the start of a restarted sender: only a second sample continuing
         * it tells, so it touches nothing being assembled until then. */
        if (!hold(rx, kind, &d, frame->t_us)) {
            return;
        }
        restart_with_held(rx);
    } else if (rx->held.used) {
        drop_held(rx);
    }
    if (sl == NULL) {
        if (recent(rx, d.seq)) {
            hal_count(history_had(rx, d.seq, kind) ? &rx->n.duplicate : &rx->n.late);
            return;
        }
        sl = open_slot(rx, d.seq);
        if (sl == NULL) {
            return;
        }
    } else if (slot_has(sl, kind)) {
        hal_count(&rx->n.duplicate);
        return;
    }
    add_to_slot(sl, kind, &d, frame->t_us);
    advance(rx);
}

int dbc_rx_pop(dbc_rx_t *rx, hal_sample_t *out)
{
    if (rx->ready_n == 0u) {
        return 0;
    }
    *out = rx->ready[rx->ready_head];
    rx->ready_head = (uint8_t)((rx->ready_head + 1u) % DBC_READY_MAX);
    --rx->ready_n;
    return 1;
}
