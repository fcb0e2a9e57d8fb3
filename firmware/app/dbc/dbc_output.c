/*
 * dbc_output.c - the estimator's output frames (ATT_EULER, ATT_RATES, ATT_SIGMA, ATT_STATUS,
 * ATT_COUNTERS): an output encoded, one frame decoded back; the parameter frames (ATT_PARAM_REQ
 * in, ATT_PARAM out).
 *
 * All bit layouts and scalings come from the cantools-generated canmsg_gen.c (from
 * firmware/app/dbc/attekf.dbc); the ids are the DBC's moved to the node's base.
 */
#include "dbc_input.h"

#include <string.h>

/* The node's frames are consecutive from ATT_EULER: the base moves them together. */
typedef char dbc_output_ids_are_consecutive[(CANMSG_ATT_RATES_FRAME_ID == CANMSG_ATT_EULER_FRAME_ID + 1 &&
                                             CANMSG_ATT_SIGMA_FRAME_ID == CANMSG_ATT_EULER_FRAME_ID + 2 &&
                                             CANMSG_ATT_STATUS_FRAME_ID == CANMSG_ATT_EULER_FRAME_ID + 3 &&
                                             CANMSG_ATT_COUNTERS_FRAME_ID == CANMSG_ATT_EULER_FRAME_ID + 4 &&
                                             CANMSG_ATT_PARAM_FRAME_ID == CANMSG_ATT_EULER_FRAME_ID + 5 &&
                                             CANMSG_ATT_PARAM_REQ_FRAME_ID == CANMSG_ATT_EULER_FRAME_ID + 6 &&
                                             DBC_NODE_FRAMES == 7)
                                                ? 1
                                                : -1];

/* The id of a node frame (its DBC id) at the node's base. */
static uint32_t node_id(const dbc_tx_t *tx, uint32_t dbc_id)
{
    return dbc_id - CANMSG_ATT_EULER_FRAME_ID + tx->base;
}

void dbc_tx_init(dbc_tx_t *tx, uint16_t base)
{
    tx->page = 0u;
    tx->base = base;
}

static void pack_counter(struct canmsg_att_counters_t *m, uint8_t page, uint32_t v)
{
    m->page = page;
    switch (page) {
    case APP_CNT_RX_FRAMES: m->rx_frames = v; break;
    case APP_CNT_FOREIGN: m->foreign = v; break;
    case APP_CNT_BAD_DLC: m->bad_dlc = v; break;
    case APP_CNT_DUPLICATE: m->duplicate = v; break;
    case APP_CNT_LATE: m->late = v; break;
    case APP_CNT_INCOMPLETE: m->incomplete = v; break;
    case APP_CNT_DISCARDED: m->discarded = v; break;
    case APP_CNT_RX_OVERFLOW: m->rx_overflow = v; break;
    case APP_CNT_LINK_DOWN: m->link_down = v; break;
    case APP_CNT_TX_FRAMES: m->tx_frames = v; break;
    case APP_CNT_TX_ERRORS: m->tx_errors = v; break;
    case APP_CNT_SAMPLES: m->samples = v; break;
    case APP_CNT_GAPS: m->gaps = v; break;
    case APP_CNT_MISSING: m->missing = v; break;
    case APP_CNT_STALE: m->stale_count = v; break;
    case APP_CNT_TIME_ERRORS: m->time_errors = v; break;
    case APP_CNT_RESYNC: m->resync = v; break;
    case APP_CNT_SATURATED: m->saturated = v; break;
    case APP_CNT_EKF_REJECTED: m->ekf_rejected = v; break;
    case APP_CNT_REALIGN: m->realign = v; break;
    case APP_CNT_OUTPUTS: m->outputs = v; break;
    case APP_CNT_TRANSFER_ERRORS: m->transfer_errors = v; break;
    case APP_CNT_REQUESTS: m->requests = v; break;
    case APP_CNT_REFUSED: m->refused = v; break;
    default: break;
    }
}

static uint32_t unpack_counter(const struct canmsg_att_counters_t *m)
{
    switch (m->page) {
    case APP_CNT_RX_FRAMES: return m->rx_frames;
    case APP_CNT_FOREIGN: return m->foreign;
    case APP_CNT_BAD_DLC: return m->bad_dlc;
    case APP_CNT_DUPLICATE: return m->duplicate;
    case APP_CNT_LATE: return m->late;
    case APP_CNT_INCOMPLETE: return m->incomplete;
    case APP_CNT_DISCARDED: return m->discarded;
    case APP_CNT_RX_OVERFLOW: return m->rx_overflow;
    case APP_CNT_LINK_DOWN: return m->link_down;
    case APP_CNT_TX_FRAMES: return m->tx_frames;
    case APP_CNT_TX_ERRORS: return m->tx_errors;
    case APP_CNT_SAMPLES: return m->samples;
    case APP_CNT_GAPS: return m->gaps;
    case APP_CNT_MISSING: return m->missing;
    case APP_CNT_STALE: return m->stale_count;
    case APP_CNT_TIME_ERRORS: return m->time_errors;
    case APP_CNT_RESYNC: return m->resync;
    case APP_CNT_SATURATED: return m->saturated;
    case APP_CNT_EKF_REJECTED: return m->ekf_rejected;
    case APP_CNT_REALIGN: return m->realign;
    case APP_CNT_OUTPUTS: return m->outputs;
    case APP_CNT_TRANSFER_ERRORS: return m->transfer_errors;
    case APP_CNT_REQUESTS: return m->requests;
    case APP_CNT_REFUSED: return m->refused;
    default: return 0u;
    }
}

/* ATT_EULER, ATT_RATES, ATT_SIGMA of an attitude output; returns 1 if a value was clamped. */
static int encode_attitude(const dbc_tx_t *tx, const app_output_t *out, hal_frame_t frames[3])
{
    /* Wire ranges from the generated decoders: the largest raw values of the signals. */
    const float amax = canmsg_att_euler_roll_decode(INT16_MAX);
    const float rmax = canmsg_att_rates_rate_p_decode(INT16_MAX);
    const float smax = canmsg_att_sigma_sigma_roll_decode(UINT16_MAX);
    const uint64_t t = out->rx_us;
    int sat = 0;
    struct canmsg_att_euler_t e;
    struct canmsg_att_rates_t r;
    struct canmsg_att_sigma_t s;
    e.roll = canmsg_att_euler_roll_encode(dbc_clamp(out->euler[0], -amax, amax, &sat));
    e.pitch = canmsg_att_euler_pitch_encode(dbc_clamp(out->euler[1], -amax, amax, &sat));
    e.yaw = canmsg_att_euler_yaw_encode(dbc_clamp(out->euler[2], -amax, amax, &sat));
    e.seq = out->seq;
    dbc_put_frame(&frames[0], node_id(tx, CANMSG_ATT_EULER_FRAME_ID), t);
    (void)canmsg_att_euler_pack(frames[0].data, &e, 8u);
    r.rate_p = canmsg_att_rates_rate_p_encode(dbc_clamp(out->rates[0], -rmax, rmax, &sat));
    r.rate_q = canmsg_att_rates_rate_q_encode(dbc_clamp(out->rates[1], -rmax, rmax, &sat));
    r.rate_r = canmsg_att_rates_rate_r_encode(dbc_clamp(out->rates[2], -rmax, rmax, &sat));
    r.seq = out->seq;
    dbc_put_frame(&frames[1], node_id(tx, CANMSG_ATT_RATES_FRAME_ID), t);
    (void)canmsg_att_rates_pack(frames[1].data, &r, 8u);
    s.sigma_roll = canmsg_att_sigma_sigma_roll_encode(dbc_clamp(out->sigma[0], 0.0f, smax, &sat));
    s.sigma_pitch = canmsg_att_sigma_sigma_pitch_encode(dbc_clamp(out->sigma[1], 0.0f, smax, &sat));
    s.sigma_yaw = canmsg_att_sigma_sigma_yaw_encode(dbc_clamp(out->sigma[2], 0.0f, smax, &sat));
    s.seq = out->seq;
    dbc_put_frame(&frames[2], node_id(tx, CANMSG_ATT_SIGMA_FRAME_ID), t);
    (void)canmsg_att_sigma_pack(frames[2].data, &s, 8u);
    return sat;
}

static void encode_status(const dbc_tx_t *tx, const app_output_t *out, uint16_t flags, hal_frame_t *frame)
{
    struct canmsg_att_status_t st;
    st.aligned = (flags & APP_FLAG_ALIGNED) ? 1u : 0u;
    st.stale = (flags & APP_FLAG_STALE) ? 1u : 0u;
    st.gap = (flags & APP_FLAG_GAP) ? 1u : 0u;
    st.in_saturated = (flags & APP_FLAG_IN_SATURATED) ? 1u : 0u;
    st.out_saturated = (flags & APP_FLAG_OUT_SATURATED) ? 1u : 0u;
    st.link_error = (flags & APP_FLAG_LINK_ERROR) ? 1u : 0u;
    st.frame_error = (flags & APP_FLAG_FRAME_ERROR) ? 1u : 0u;
    st.incomplete = (flags & APP_FLAG_INCOMPLETE) ? 1u : 0u;
    st.ekf_reject = (flags & APP_FLAG_EKF_REJECT) ? 1u : 0u;
    st.time_error = (flags & APP_FLAG_TIME_ERROR) ? 1u : 0u;
    st.restarted = (flags & APP_FLAG_RESTARTED) ? 1u : 0u;
    st.heartbeat = (flags & APP_FLAG_HEARTBEAT) ? 1u : 0u;
    st.config_pending = (flags & APP_FLAG_CONFIG_PENDING) ? 1u : 0u;
    st.att_flags = (uint16_t)(out->att_flags & 0xFFFFu);
    st.seq = out->seq;
    st.out_index = out->index;
    dbc_put_frame(frame, node_id(tx, CANMSG_ATT_STATUS_FRAME_ID), out->rx_us);
    (void)canmsg_att_status_pack(frame->data, &st, 8u);
}

size_t dbc_encode_output(dbc_tx_t *tx, const app_output_t *out, hal_frame_t frames[DBC_MAX_OUT_FRAMES])
{
    size_t n = 0;
    uint16_t flags = out->flags;
    struct canmsg_att_counters_t c;

    if (out->kind == APP_OUT_ATTITUDE) {
        if (encode_attitude(tx, out, frames)) {
            flags |= APP_FLAG_OUT_SATURATED;
        }
        n = 3;
    }
    encode_status(tx, out, flags, &frames[n++]);
    memset(&c, 0, sizeof(c));
    pack_counter(&c, tx->page, out->counters[tx->page]);
    dbc_put_frame(&frames[n], node_id(tx, CANMSG_ATT_COUNTERS_FRAME_ID), out->rx_us);
    (void)canmsg_att_counters_pack(frames[n++].data, &c, 8u);
    tx->page = (uint8_t)((tx->page + 1u) % APP_CNT_COUNT);
    return n;
}

/* The output flags of an ATT_STATUS frame. */
static uint16_t status_flags(const struct canmsg_att_status_t *m)
{
    return (uint16_t)((m->aligned ? APP_FLAG_ALIGNED : 0u) | (m->stale ? APP_FLAG_STALE : 0u) |
                      (m->gap ? APP_FLAG_GAP : 0u) | (m->in_saturated ? APP_FLAG_IN_SATURATED : 0u) |
                      (m->out_saturated ? APP_FLAG_OUT_SATURATED : 0u) |
                      (m->link_error ? APP_FLAG_LINK_ERROR : 0u) |
                      (m->frame_error ? APP_FLAG_FRAME_ERROR : 0u) |
                      (m->incomplete ? APP_FLAG_INCOMPLETE : 0u) |
                      (m->ekf_reject ? APP_FLAG_EKF_REJECT : 0u) |
                      (m->time_error ? APP_FLAG_TIME_ERROR : 0u) |
                      (m->restarted ? APP_FLAG_RESTARTED : 0u) |
                      (m->heartbeat ? APP_FLAG_HEARTBEAT : 0u) |
                      (m->config_pending ? APP_FLAG_CONFIG_PENDING : 0u));
}

int dbc_decode_output(const hal_frame_t *frame, app_output_t *out)
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
        out->flags = status_flags(&m);
        out->kind = m.heartbeat ? (uint8_t)APP_OUT_HEARTBEAT : (uint8_t)APP_OUT_ATTITUDE;
        out->att_flags = m.att_flags;
        out->seq = m.seq;
        out->index = m.out_index;
        return 1;
    }
    case CANMSG_ATT_COUNTERS_FRAME_ID: {
        struct canmsg_att_counters_t m;
        (void)canmsg_att_counters_unpack(&m, frame->data, 8u);
        if (m.page >= APP_CNT_COUNT) {
            return 0;
        }
        out->counters[m.page] = unpack_counter(&m);
        return 1;
    }
    default:
        return 0;
    }
}

int dbc_decode_param_req(const dbc_tx_t *tx, const hal_frame_t *frame, dbc_param_req_t *req)
{
    struct canmsg_att_param_req_t m;
    if (frame->id != node_id(tx, CANMSG_ATT_PARAM_REQ_FRAME_ID)) {
        return 0;
    }
    if (frame->dlc != 8u || canmsg_att_param_req_unpack(&m, frame->data, 8u) != 0) {
        return -1;
    }
    req->index = m.index;
    req->op = m.op;
    req->value = m.value;
    return 1;
}

void dbc_encode_param(const dbc_tx_t *tx, uint16_t index, uint8_t op, uint8_t result, float value,
                      uint64_t t_us, hal_frame_t *frame)
{
    struct canmsg_att_param_t m;
    memset(&m, 0, sizeof(m));
    m.index = index;
    m.op = op;
    m.result = result;
    m.value = value;
    dbc_put_frame(frame, node_id(tx, CANMSG_ATT_PARAM_FRAME_ID), t_us);
    (void)canmsg_att_param_pack(frame->data, &m, 8u);
}
