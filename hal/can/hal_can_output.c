/*
 * hal_can_output.c - the estimator's output frames (ATT_EULER, ATT_RATES, ATT_SIGMA,
 * ATT_STATUS, ATT_COUNTERS): an output encoded, one frame decoded back.
 *
 * All bit layouts and scalings come from the cantools-generated canmsg_gen.c (from
 * hal/can/attekf.dbc).
 */
#include "hal_can_input.h"

#include <string.h>

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
        e.roll = canmsg_att_euler_roll_encode(hal_can_clamp(out->euler[0], -amax, amax, &sat));
        e.pitch = canmsg_att_euler_pitch_encode(hal_can_clamp(out->euler[1], -amax, amax, &sat));
        e.yaw = canmsg_att_euler_yaw_encode(hal_can_clamp(out->euler[2], -amax, amax, &sat));
        e.seq = out->seq;
        hal_can_put_frame(&frames[n], CANMSG_ATT_EULER_FRAME_ID, t);
        (void)canmsg_att_euler_pack(frames[n++].data, &e, 8u);
        r.rate_p = canmsg_att_rates_rate_p_encode(hal_can_clamp(out->rates[0], -rmax, rmax, &sat));
        r.rate_q = canmsg_att_rates_rate_q_encode(hal_can_clamp(out->rates[1], -rmax, rmax, &sat));
        r.rate_r = canmsg_att_rates_rate_r_encode(hal_can_clamp(out->rates[2], -rmax, rmax, &sat));
        r.seq = out->seq;
        hal_can_put_frame(&frames[n], CANMSG_ATT_RATES_FRAME_ID, t);
        (void)canmsg_att_rates_pack(frames[n++].data, &r, 8u);
        s.sigma_roll = canmsg_att_sigma_sigma_roll_encode(hal_can_clamp(out->sigma[0], 0.0f, smax, &sat));
        s.sigma_pitch = canmsg_att_sigma_sigma_pitch_encode(hal_can_clamp(out->sigma[1], 0.0f, smax, &sat));
        s.sigma_yaw = canmsg_att_sigma_sigma_yaw_encode(hal_can_clamp(out->sigma[2], 0.0f, smax, &sat));
        s.seq = out->seq;
        hal_can_put_frame(&frames[n], CANMSG_ATT_SIGMA_FRAME_ID, t);
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
        hal_can_put_frame(&frames[n], CANMSG_ATT_STATUS_FRAME_ID, t);
        (void)canmsg_att_status_pack(frames[n++].data, &st, 8u);
    }
    {
        struct canmsg_att_counters_t c;
        memset(&c, 0, sizeof(c));
        pack_counter(&c, tx->page, out->counters[tx->page]);
        hal_can_put_frame(&frames[n], CANMSG_ATT_COUNTERS_FRAME_ID, t);
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
