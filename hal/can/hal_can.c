/*
 * hal_can.c - sample assembly and output encoding for the CAN protocol (hal_can.h).
 *
 * All bit layouts and scalings come from the cantools-generated canmsg_gen.c (from
 * hal/can/attekf.dbc); this file only decides what to do with the frames.
 */
#include "hal_can.h"

#include <math.h>
#include <string.h>

#include "canmsg_gen.h"

enum { KIND_GYRO = 0, KIND_ACCEL = 1, KIND_MAG = 2, KIND_SYNC = 3 };

/* a - b in sequence-number arithmetic (RFC 1982 style): in -32768..32767. */
static int32_t seq_diff(uint16_t a, uint16_t b)
{
    int32_t d = (int32_t)(uint16_t)(a - b);
    return (d >= 32768) ? d - 65536 : d;
}

static int frame_kind(uint32_t id)
{
    switch (id) {
    case CANMSG_IMU_GYRO_FRAME_ID: return KIND_GYRO;
    case CANMSG_IMU_ACCEL_FRAME_ID: return KIND_ACCEL;
    case CANMSG_IMU_MAG_FRAME_ID: return KIND_MAG;
    case CANMSG_IMU_SYNC_FRAME_ID: return KIND_SYNC;
    default: return -1;
    }
}

/* A raw 16-bit sensor value at either end of the signed range: the sender clamped it (the
 * DBC range is +-32767 LSB; -32768 is outside it and treated the same). */
static int raw_saturated(int16_t raw) { return raw >= INT16_MAX || raw <= -INT16_MAX; }

void hal_can_rx_init(hal_can_rx_t *rx) { memset(rx, 0, sizeof(*rx)); }

/* ---- history of emitted / discarded samples (duplicate vs late) ---------------------- */
static void history_add(hal_can_rx_t *rx, uint16_t seq, uint8_t have)
{
    rx->hist_seq[rx->hist_pos] = seq;
    rx->hist_have[rx->hist_pos] = have;
    rx->hist_pos = (uint8_t)((rx->hist_pos + 1u) % HAL_CAN_HISTORY);
    if (rx->hist_n < HAL_CAN_HISTORY) {
        ++rx->hist_n;
    }
}

static uint16_t history_newest(const hal_can_rx_t *rx)
{
    return rx->hist_seq[(rx->hist_pos + HAL_CAN_HISTORY - 1u) % HAL_CAN_HISTORY];
}

/* The have-mask of an emitted sample, or -1 if it is not remembered. */
static int history_have(const hal_can_rx_t *rx, uint16_t seq)
{
    uint8_t i;
    for (i = 0; i < rx->hist_n; ++i) {
        const uint8_t k = (uint8_t)((rx->hist_pos + HAL_CAN_HISTORY - 1u - i) % HAL_CAN_HISTORY);
        if (rx->hist_seq[k] == seq) {
            return rx->hist_have[k];
        }
    }
    return -1;
}

/* ---- slots ------------------------------------------------------------------------- */
static hal_can_slot_t *find_slot(hal_can_rx_t *rx, uint16_t seq)
{
    int i;
    for (i = 0; i < HAL_CAN_RX_SLOTS; ++i) {
        if (rx->slot[i].used && rx->slot[i].s.seq == seq) {
            return &rx->slot[i];
        }
    }
    return NULL;
}

/* The used slot with the oldest sequence number (relative to the head), or NULL. */
static hal_can_slot_t *oldest_slot(hal_can_rx_t *rx)
{
    hal_can_slot_t *best = NULL;
    int32_t best_age = -1;
    int i;
    for (i = 0; i < HAL_CAN_RX_SLOTS; ++i) {
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

static int slot_complete(const hal_can_slot_t *sl)
{
    return (sl->have & HAL_CAN_HAVE_SYNC) != 0u &&
           (sl->declared & (uint8_t)~sl->have & HAL_HAS_ALL) == 0u;
}

static void push_ready(hal_can_rx_t *rx, const hal_sample_t *s)
{
    uint8_t tail;
    if (rx->ready_n == HAL_CAN_READY_MAX) {
        /* Nobody popped: drop the oldest so the newest data wins. */
        rx->ready_head = (uint8_t)((rx->ready_head + 1u) % HAL_CAN_READY_MAX);
        --rx->ready_n;
        hal_count(&rx->counters[HAL_CNT_DISCARDED]);
    }
    tail = (uint8_t)((rx->ready_head + rx->ready_n) % HAL_CAN_READY_MAX);
    rx->ready[tail] = *s;
    ++rx->ready_n;
}

/* Emits a slot that has its IMU_SYNC: unwraps the 32-bit time, queues the sample. */
static void emit(hal_can_rx_t *rx, hal_can_slot_t *sl)
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
        hal_count(&rx->counters[HAL_CNT_INCOMPLETE]);
    }
    push_ready(rx, &sl->s);
    history_add(rx, sl->s.seq, sl->have);
    sl->used = 0u;
}

/* Gives up a slot: emitted without its missing sensors if it has a time, else discarded. */
static void finish(hal_can_rx_t *rx, hal_can_slot_t *sl)
{
    if ((sl->have & HAL_CAN_HAVE_SYNC) != 0u) {
        emit(rx, sl);
    } else {
        hal_count(&rx->counters[HAL_CNT_DISCARDED]);
        history_add(rx, sl->s.seq, sl->have);
        sl->used = 0u;
    }
}

/* Emits whatever can go out, in sequence order. */
static void advance(hal_can_rx_t *rx)
{
    for (;;) {
        hal_can_slot_t *old = oldest_slot(rx);
        int i;
        int newer_complete = 0;
        if (old == NULL) {
            return;
        }
        if (slot_complete(old)) {
            emit(rx, old);
            continue;
        }
        for (i = 0; i < HAL_CAN_RX_SLOTS; ++i) {
            if (&rx->slot[i] != old && rx->slot[i].used && slot_complete(&rx->slot[i])) {
                newer_complete = 1;
            }
        }
        /* A newer sample is complete: the sensor frame the old one waits for would have come
         * before it. Without its IMU_SYNC the old one may still complete (reordering). */
        if (newer_complete && (old->have & HAL_CAN_HAVE_SYNC) != 0u) {
            emit(rx, old);
            continue;
        }
        return;
    }
}

static void flush_slots(hal_can_rx_t *rx)
{
    hal_can_slot_t *old;
    while ((old = oldest_slot(rx)) != NULL) {
        finish(rx, old);
    }
}

void hal_can_rx_flush(hal_can_rx_t *rx) { flush_slots(rx); }

/* A slot for a sequence number not being assembled, or NULL (frame is late: counted). */
static hal_can_slot_t *open_slot(hal_can_rx_t *rx, uint16_t seq)
{
    int i;
    for (;;) {
        hal_can_slot_t *old;
        for (i = 0; i < HAL_CAN_RX_SLOTS; ++i) {
            if (!rx->slot[i].used) {
                hal_can_slot_t *sl = &rx->slot[i];
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
            hal_count(&rx->counters[HAL_CNT_LATE]); /* older than everything pending */
            return NULL;
        }
        finish(rx, old);
        advance(rx);
    }
}

/* ---- decoding ------------------------------------------------------------------------ */
typedef struct {
    uint16_t seq;
    float v[3];
    int16_t raw[3];
    struct canmsg_imu_sync_t sync;
} decoded_t;

static int decode_input(int kind, const uint8_t *data, decoded_t *d)
{
    int i;
    switch (kind) {
    case KIND_GYRO: {
        struct canmsg_imu_gyro_t m;
        if (canmsg_imu_gyro_unpack(&m, data, 8u) != 0) {
            return 0;
        }
        d->raw[0] = m.gyro_x;
        d->raw[1] = m.gyro_y;
        d->raw[2] = m.gyro_z;
        d->v[0] = canmsg_imu_gyro_gyro_x_decode(m.gyro_x);
        d->v[1] = canmsg_imu_gyro_gyro_y_decode(m.gyro_y);
        d->v[2] = canmsg_imu_gyro_gyro_z_decode(m.gyro_z);
        d->seq = m.seq;
        return 1;
    }
    case KIND_ACCEL: {
        struct canmsg_imu_accel_t m;
        if (canmsg_imu_accel_unpack(&m, data, 8u) != 0) {
            return 0;
        }
        d->raw[0] = m.accel_x;
        d->raw[1] = m.accel_y;
        d->raw[2] = m.accel_z;
        d->v[0] = canmsg_imu_accel_accel_x_decode(m.accel_x);
        d->v[1] = canmsg_imu_accel_accel_y_decode(m.accel_y);
        d->v[2] = canmsg_imu_accel_accel_z_decode(m.accel_z);
        d->seq = m.seq;
        return 1;
    }
    case KIND_MAG: {
        struct canmsg_imu_mag_t m;
        if (canmsg_imu_mag_unpack(&m, data, 8u) != 0) {
            return 0;
        }
        d->raw[0] = m.mag_x;
        d->raw[1] = m.mag_y;
        d->raw[2] = m.mag_z;
        d->v[0] = canmsg_imu_mag_mag_x_decode(m.mag_x);
        d->v[1] = canmsg_imu_mag_mag_y_decode(m.mag_y);
        d->v[2] = canmsg_imu_mag_mag_z_decode(m.mag_z);
        d->seq = m.seq;
        return 1;
    }
    case KIND_SYNC:
        if (canmsg_imu_sync_unpack(&d->sync, data, 8u) != 0) {
            return 0;
        }
        d->seq = d->sync.seq;
        for (i = 0; i < 3; ++i) {
            d->raw[i] = 0;
        }
        return 1;
    default:
        return 0;
    }
}

static void add_to_slot(hal_can_slot_t *sl, int kind, const decoded_t *d, uint64_t rx_us)
{
    int i;
    float *dst = NULL;
    if (kind == KIND_SYNC) {
        sl->time_raw = d->sync.time_us;
        sl->declared = (uint8_t)((d->sync.has_gyro ? HAL_HAS_GYRO : 0u) |
                                 (d->sync.has_accel ? HAL_HAS_ACCEL : 0u) |
                                 (d->sync.has_mag ? HAL_HAS_MAG : 0u));
        sl->s.saturated |= (uint8_t)((d->sync.sat_gyro ? HAL_HAS_GYRO : 0u) |
                                     (d->sync.sat_accel ? HAL_HAS_ACCEL : 0u) |
                                     (d->sync.sat_mag ? HAL_HAS_MAG : 0u));
        sl->have |= HAL_CAN_HAVE_SYNC;
    } else {
        const uint8_t bit = (uint8_t)(1u << kind);
        dst = (kind == KIND_GYRO) ? sl->s.gyro : (kind == KIND_ACCEL) ? sl->s.accel : sl->s.mag;
        for (i = 0; i < 3; ++i) {
            dst[i] = d->v[i];
            if (raw_saturated(d->raw[i])) {
                sl->s.saturated |= bit;
            }
        }
        sl->have |= bit;
    }
    /* The sample is available when its last frame arrives. */
    if (rx_us > sl->s.rx_us) {
        sl->s.rx_us = rx_us;
    }
}

void hal_can_rx_frame(hal_can_rx_t *rx, const hal_can_frame_t *frame)
{
    decoded_t d;
    hal_can_slot_t *sl;
    uint8_t bit;
    int kind;

    hal_count(&rx->counters[HAL_CNT_RX_FRAMES]);
    kind = frame_kind(frame->id);
    if (kind < 0) {
        hal_count(&rx->counters[HAL_CNT_UNKNOWN_ID]);
        return;
    }
    if (frame->dlc != 8u || !decode_input(kind, frame->data, &d)) {
        hal_count(&rx->counters[HAL_CNT_BAD_DLC]);
        return;
    }
    bit = (uint8_t)((kind == KIND_SYNC) ? HAL_CAN_HAVE_SYNC : (1u << kind)); /* one cast: gcc -fsanitize */

    sl = find_slot(rx, d.seq);
    if (sl == NULL) {
        if (rx->hist_n > 0u) {
            const int32_t dh = seq_diff(d.seq, history_newest(rx));
            if (dh <= 0 && dh >= -HAL_CAN_LATE_WINDOW) {
                const int have = history_have(rx, d.seq);
                hal_count(&rx->counters[(have >= 0 && ((unsigned)have & bit) != 0u) ? HAL_CNT_DUPLICATE
                                                                                     : HAL_CNT_LATE]);
                return;
            }
        }
        if (rx->have_head && seq_diff(d.seq, rx->head_seq) < -HAL_CAN_LATE_WINDOW) {
            /* Far behind everything: the sender restarted its counter. Start over. */
            flush_slots(rx);
            rx->hist_n = 0u;
            rx->have_head = 0u;
        }
        sl = open_slot(rx, d.seq);
        if (sl == NULL) {
            return;
        }
    } else if ((sl->have & bit) != 0u) {
        hal_count(&rx->counters[HAL_CNT_DUPLICATE]);
        return;
    }
    add_to_slot(sl, kind, &d, frame->t_us);
    advance(rx);
}

int hal_can_rx_pop(hal_can_rx_t *rx, hal_sample_t *out)
{
    if (rx->ready_n == 0u) {
        return 0;
    }
    *out = rx->ready[rx->ready_head];
    rx->ready_head = (uint8_t)((rx->ready_head + 1u) % HAL_CAN_READY_MAX);
    --rx->ready_n;
    return 1;
}

void hal_can_rx_add_counters(const hal_can_rx_t *rx, uint32_t counters[HAL_CNT_COUNT])
{
    int i;
    for (i = HAL_CNT_LINK_FIRST; i < HAL_CNT_LINK_END; ++i) {
        hal_count_n(&counters[i], rx->counters[i]);
    }
}

/* ---- encoding ------------------------------------------------------------------------- */
/* v clamped to [lo, hi]; *sat set if it had to be (non-finite: 0). */
static float clamp_flag(float v, float lo, float hi, int *sat)
{
    if (!isfinite(v)) {
        *sat = 1;
        return 0.0f;
    }
    if (v > hi) {
        *sat = 1;
        return hi;
    }
    if (v < lo) {
        *sat = 1;
        return lo;
    }
    return v;
}

static void put_frame(hal_can_frame_t *f, uint32_t id, uint64_t t_us)
{
    f->id = id;
    f->dlc = 8u;
    f->t_us = t_us;
}

void hal_can_tx_init(hal_can_tx_t *tx) { tx->page = 0u; }

static void pack_counter(struct canmsg_att_counters_t *m, uint8_t page, uint32_t v)
{
    m->page = page;
    switch (page) {
    case HAL_CNT_RX_FRAMES: m->rx_frames = v; break;
    case HAL_CNT_UNKNOWN_ID: m->unknown_id = v; break;
    case HAL_CNT_BAD_DLC: m->bad_dlc = v; break;
    case HAL_CNT_DUPLICATE: m->duplicate = v; break;
    case HAL_CNT_LATE: m->late = v; break;
    case HAL_CNT_INCOMPLETE: m->incomplete = v; break;
    case HAL_CNT_DISCARDED: m->discarded = v; break;
    case HAL_CNT_RX_OVERFLOW: m->rx_overflow = v; break;
    case HAL_CNT_LINK_DOWN: m->link_down = v; break;
    case HAL_CNT_TX_FRAMES: m->tx_frames = v; break;
    case HAL_CNT_TX_ERRORS: m->tx_errors = v; break;
    case HAL_CNT_SAMPLES: m->samples = v; break;
    case HAL_CNT_GAPS: m->gaps = v; break;
    case HAL_CNT_MISSING: m->missing = v; break;
    case HAL_CNT_STALE: m->stale_count = v; break;
    case HAL_CNT_TIME_ERRORS: m->time_errors = v; break;
    case HAL_CNT_RESYNC: m->resync = v; break;
    case HAL_CNT_SATURATED: m->saturated = v; break;
    case HAL_CNT_EKF_REJECTED: m->ekf_rejected = v; break;
    case HAL_CNT_REALIGN: m->realign = v; break;
    case HAL_CNT_OUTPUTS: m->outputs = v; break;
    default: break;
    }
}

static uint32_t unpack_counter(const struct canmsg_att_counters_t *m)
{
    switch (m->page) {
    case HAL_CNT_RX_FRAMES: return m->rx_frames;
    case HAL_CNT_UNKNOWN_ID: return m->unknown_id;
    case HAL_CNT_BAD_DLC: return m->bad_dlc;
    case HAL_CNT_DUPLICATE: return m->duplicate;
    case HAL_CNT_LATE: return m->late;
    case HAL_CNT_INCOMPLETE: return m->incomplete;
    case HAL_CNT_DISCARDED: return m->discarded;
    case HAL_CNT_RX_OVERFLOW: return m->rx_overflow;
    case HAL_CNT_LINK_DOWN: return m->link_down;
    case HAL_CNT_TX_FRAMES: return m->tx_frames;
    case HAL_CNT_TX_ERRORS: return m->tx_errors;
    case HAL_CNT_SAMPLES: return m->samples;
    case HAL_CNT_GAPS: return m->gaps;
    case HAL_CNT_MISSING: return m->missing;
    case HAL_CNT_STALE: return m->stale_count;
    case HAL_CNT_TIME_ERRORS: return m->time_errors;
    case HAL_CNT_RESYNC: return m->resync;
    case HAL_CNT_SATURATED: return m->saturated;
    case HAL_CNT_EKF_REJECTED: return m->ekf_rejected;
    case HAL_CNT_REALIGN: return m->realign;
    case HAL_CNT_OUTPUTS: return m->outputs;
    default: return 0u;
    }
}

size_t hal_can_encode_output(hal_can_tx_t *tx, const hal_output_t *out,
                             hal_can_frame_t frames[HAL_CAN_MAX_OUT_FRAMES])
{
    size_t n = 0;
    int sat = 0;
    uint16_t flags = out->flags;
    const uint64_t t = out->rx_us;

    if (out->kind == HAL_OUT_ATTITUDE) {
        /* Wire ranges from the generated decoders: the largest raw values of the signals. */
        const float amax = canmsg_att_euler_roll_decode(INT16_MAX);
        const float rmax = canmsg_att_rates_rate_p_decode(INT16_MAX);
        const float smax = canmsg_att_sigma_sigma_roll_decode(UINT16_MAX);
        struct canmsg_att_euler_t e;
        struct canmsg_att_rates_t r;
        struct canmsg_att_sigma_t s;
        e.roll = canmsg_att_euler_roll_encode(clamp_flag(out->euler[0], -amax, amax, &sat));
        e.pitch = canmsg_att_euler_pitch_encode(clamp_flag(out->euler[1], -amax, amax, &sat));
        e.yaw = canmsg_att_euler_yaw_encode(clamp_flag(out->euler[2], -amax, amax, &sat));
        e.seq = out->seq;
        put_frame(&frames[n], CANMSG_ATT_EULER_FRAME_ID, t);
        (void)canmsg_att_euler_pack(frames[n++].data, &e, 8u);
        r.rate_p = canmsg_att_rates_rate_p_encode(clamp_flag(out->rates[0], -rmax, rmax, &sat));
        r.rate_q = canmsg_att_rates_rate_q_encode(clamp_flag(out->rates[1], -rmax, rmax, &sat));
        r.rate_r = canmsg_att_rates_rate_r_encode(clamp_flag(out->rates[2], -rmax, rmax, &sat));
        r.seq = out->seq;
        put_frame(&frames[n], CANMSG_ATT_RATES_FRAME_ID, t);
        (void)canmsg_att_rates_pack(frames[n++].data, &r, 8u);
        s.sigma_roll = canmsg_att_sigma_sigma_roll_encode(clamp_flag(out->sigma[0], 0.0f, smax, &sat));
        s.sigma_pitch = canmsg_att_sigma_sigma_pitch_encode(clamp_flag(out->sigma[1], 0.0f, smax, &sat));
        s.sigma_yaw = canmsg_att_sigma_sigma_yaw_encode(clamp_flag(out->sigma[2], 0.0f, smax, &sat));
        s.seq = out->seq;
        put_frame(&frames[n], CANMSG_ATT_SIGMA_FRAME_ID, t);
        (void)canmsg_att_sigma_pack(frames[n++].data, &s, 8u);
        if (sat) {
            flags |= HAL_FLAG_OUT_SATURATED;
        }
    }
    {
        struct canmsg_att_status_t st;
        st.aligned = (flags & HAL_FLAG_ALIGNED) ? 1u : 0u;
        st.stale = (flags & HAL_FLAG_STALE) ? 1u : 0u;
        st.gap = (flags & HAL_FLAG_GAP) ? 1u : 0u;
        st.in_saturated = (flags & HAL_FLAG_IN_SATURATED) ? 1u : 0u;
        st.out_saturated = (flags & HAL_FLAG_OUT_SATURATED) ? 1u : 0u;
        st.link_error = (flags & HAL_FLAG_LINK_ERROR) ? 1u : 0u;
        st.frame_error = (flags & HAL_FLAG_FRAME_ERROR) ? 1u : 0u;
        st.incomplete = (flags & HAL_FLAG_INCOMPLETE) ? 1u : 0u;
        st.ekf_reject = (flags & HAL_FLAG_EKF_REJECT) ? 1u : 0u;
        st.time_error = (flags & HAL_FLAG_TIME_ERROR) ? 1u : 0u;
        st.restarted = (flags & HAL_FLAG_RESTARTED) ? 1u : 0u;
        st.heartbeat = (flags & HAL_FLAG_HEARTBEAT) ? 1u : 0u;
        st.att_flags = (uint16_t)(out->att_flags & 0xFFFFu);
        st.seq = out->seq;
        st.out_index = out->index;
        put_frame(&frames[n], CANMSG_ATT_STATUS_FRAME_ID, t);
        (void)canmsg_att_status_pack(frames[n++].data, &st, 8u);
    }
    {
        struct canmsg_att_counters_t c;
        memset(&c, 0, sizeof(c));
        pack_counter(&c, tx->page, out->counters[tx->page]);
        put_frame(&frames[n], CANMSG_ATT_COUNTERS_FRAME_ID, t);
        (void)canmsg_att_counters_pack(frames[n++].data, &c, 8u);
        tx->page = (uint8_t)((tx->page + 1u) % HAL_CNT_COUNT);
    }
    return n;
}

int hal_can_decode_output(const hal_can_frame_t *frame, hal_output_t *out)
{
    if (frame->dlc != 8u) {
        return 0;
    }
    switch (frame->id) {
    case CANMSG_ATT_EULER_FRAME_ID: {
        struct canmsg_att_euler_t m;
        (void)canmsg_att_euler_unpack(&m, frame->data, 8u);
        out->euler[0] = canmsg_att_euler_roll_decode(m.roll);
        out->euler[1] = canmsg_att_euler_pitch_decode(m.pitch);
        out->euler[2] = canmsg_att_euler_yaw_decode(m.yaw);
        out->seq = m.seq;
        return 1;
    }
    case CANMSG_ATT_RATES_FRAME_ID: {
        struct canmsg_att_rates_t m;
        (void)canmsg_att_rates_unpack(&m, frame->data, 8u);
        out->rates[0] = canmsg_att_rates_rate_p_decode(m.rate_p);
        out->rates[1] = canmsg_att_rates_rate_q_decode(m.rate_q);
        out->rates[2] = canmsg_att_rates_rate_r_decode(m.rate_r);
        out->seq = m.seq;
        return 1;
    }
    case CANMSG_ATT_SIGMA_FRAME_ID: {
        struct canmsg_att_sigma_t m;
        (void)canmsg_att_sigma_unpack(&m, frame->data, 8u);
        out->sigma[0] = canmsg_att_sigma_sigma_roll_decode(m.sigma_roll);
        out->sigma[1] = canmsg_att_sigma_sigma_pitch_decode(m.sigma_pitch);
        out->sigma[2] = canmsg_att_sigma_sigma_yaw_decode(m.sigma_yaw);
        out->seq = m.seq;
        return 1;
    }
    case CANMSG_ATT_STATUS_FRAME_ID: {
        struct canmsg_att_status_t m;
        (void)canmsg_att_status_unpack(&m, frame->data, 8u);
        out->flags = (uint16_t)((m.aligned ? HAL_FLAG_ALIGNED : 0u) | (m.stale ? HAL_FLAG_STALE : 0u) |
                                (m.gap ? HAL_FLAG_GAP : 0u) | (m.in_saturated ? HAL_FLAG_IN_SATURATED : 0u) |
                                (m.out_saturated ? HAL_FLAG_OUT_SATURATED : 0u) |
                                (m.link_error ? HAL_FLAG_LINK_ERROR : 0u) |
                                (m.frame_error ? HAL_FLAG_FRAME_ERROR : 0u) |
                                (m.incomplete ? HAL_FLAG_INCOMPLETE : 0u) |
                                (m.ekf_reject ? HAL_FLAG_EKF_REJECT : 0u) |
                                (m.time_error ? HAL_FLAG_TIME_ERROR : 0u) |
                                (m.restarted ? HAL_FLAG_RESTARTED : 0u) |
                                (m.heartbeat ? HAL_FLAG_HEARTBEAT : 0u));
        out->kind = m.heartbeat ? (uint8_t)HAL_OUT_HEARTBEAT : (uint8_t)HAL_OUT_ATTITUDE;
        out->att_flags = m.att_flags;
        out->seq = m.seq;
        out->index = m.out_index;
        return 1;
    }
    case CANMSG_ATT_COUNTERS_FRAME_ID: {
        struct canmsg_att_counters_t m;
        (void)canmsg_att_counters_unpack(&m, frame->data, 8u);
        if (m.page >= HAL_CNT_COUNT) {
            return 0;
        }
        out->counters[m.page] = unpack_counter(&m);
        return 1;
    }
    default:
        return 0;
    }
}

size_t hal_can_encode_sample(const hal_sample_t *s, hal_can_frame_t frames[HAL_CAN_SAMPLE_FRAMES])
{
    size_t n = 0;
    uint8_t valid = 0u;
    uint8_t satbits = 0u;
    int k;
    for (k = KIND_GYRO; k <= KIND_MAG; ++k) {
        const uint8_t bit = (uint8_t)(1u << k);
        const float *v = (k == KIND_GYRO) ? s->gyro : (k == KIND_ACCEL) ? s->accel : s->mag;
        int sat = 0;
        float c[3];
        int i;
        if ((s->valid & bit) == 0u || !isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2])) {
            continue;
        }
        if (k == KIND_GYRO) {
            struct canmsg_imu_gyro_t m;
            const float lim = canmsg_imu_gyro_gyro_x_decode(INT16_MAX);
            for (i = 0; i < 3; ++i) {
                c[i] = clamp_flag(v[i], -lim, lim, &sat);
            }
            m.gyro_x = canmsg_imu_gyro_gyro_x_encode(c[0]);
            m.gyro_y = canmsg_imu_gyro_gyro_y_encode(c[1]);
            m.gyro_z = canmsg_imu_gyro_gyro_z_encode(c[2]);
            m.seq = s->seq;
            (void)canmsg_imu_gyro_pack(frames[n].data, &m, 8u);
            put_frame(&frames[n++], CANMSG_IMU_GYRO_FRAME_ID, s->rx_us);
        } else if (k == KIND_ACCEL) {
            struct canmsg_imu_accel_t m;
            const float lim = canmsg_imu_accel_accel_x_decode(INT16_MAX);
            for (i = 0; i < 3; ++i) {
                c[i] = clamp_flag(v[i], -lim, lim, &sat);
            }
            m.accel_x = canmsg_imu_accel_accel_x_encode(c[0]);
            m.accel_y = canmsg_imu_accel_accel_y_encode(c[1]);
            m.accel_z = canmsg_imu_accel_accel_z_encode(c[2]);
            m.seq = s->seq;
            (void)canmsg_imu_accel_pack(frames[n].data, &m, 8u);
            put_frame(&frames[n++], CANMSG_IMU_ACCEL_FRAME_ID, s->rx_us);
        } else {
            struct canmsg_imu_mag_t m;
            const float lim = canmsg_imu_mag_mag_x_decode(INT16_MAX);
            for (i = 0; i < 3; ++i) {
                c[i] = clamp_flag(v[i], -lim, lim, &sat);
            }
            m.mag_x = canmsg_imu_mag_mag_x_encode(c[0]);
            m.mag_y = canmsg_imu_mag_mag_y_encode(c[1]);
            m.mag_z = canmsg_imu_mag_mag_z_encode(c[2]);
            m.seq = s->seq;
            (void)canmsg_imu_mag_pack(frames[n].data, &m, 8u);
            put_frame(&frames[n++], CANMSG_IMU_MAG_FRAME_ID, s->rx_us);
        }
        valid |= bit;
        if (sat || (s->saturated & bit) != 0u) {
            satbits |= bit;
        }
    }
    {
        struct canmsg_imu_sync_t m;
        m.time_us = (uint32_t)(s->t_us & 0xFFFFFFFFu);
        m.seq = s->seq;
        m.has_gyro = (valid & HAL_HAS_GYRO) ? 1u : 0u;
        m.has_accel = (valid & HAL_HAS_ACCEL) ? 1u : 0u;
        m.has_mag = (valid & HAL_HAS_MAG) ? 1u : 0u;
        m.sat_gyro = (satbits & HAL_HAS_GYRO) ? 1u : 0u;
        m.sat_accel = (satbits & HAL_HAS_ACCEL) ? 1u : 0u;
        m.sat_mag = (satbits & HAL_HAS_MAG) ? 1u : 0u;
        (void)canmsg_imu_sync_pack(frames[n].data, &m, 8u);
        put_frame(&frames[n++], CANMSG_IMU_SYNC_FRAME_ID, s->rx_us);
    }
    return n;
}
