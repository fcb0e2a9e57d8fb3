/*
 * fuzz_can.c - libFuzzer target: the node's CAN receive paths fed arbitrary frames: the DBC
 * sample assembly (firmware/app/dbc/dbc_rx.c over the cantools-generated canmsg_gen.c), and
 * behind it two estimator nodes (firmware/app over the virtual backend), one speaking the DBC,
 * one DroneCAN (dronecan/dcan_transfer.c, the generated dsdl_gen.c, the services).
 *
 * The input is a program of operations: raw frames (any id, any DLC, any payload; DroneCAN ids
 * addressed to the node among them), whole samples encoded as the IMU would and delivered with
 * frames dropped, duplicated or swapped, pops, flushes and output frames to decode. The same
 * frames go to a bare assembler (checked directly) and to both nodes (outputs checked).
 *
 * Invariants: no crash or undefined behaviour (ASan + UBSan); the assembler's counters never
 * decrease and count a frame at most once (bad length / duplicate / late), and only frames of
 * its ids; samples carry only known sensor bits, saturated within valid, finite values within
 * the wire range; the assembler's queues within their sizes; every node output finite with its
 * sigma >= 0, known flag bits, and counters that never decrease; every frame a node receives is
 * counted exactly once in rx_frames.
 */
#include "app.h"
#include "dbc.h"
#include "fuzz_common.h"
#include "hal_virtual.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define MAX_FRAMES 512
#define NODE_ID 100u

/* DBC ids, other 11-bit ids, and DroneCAN ids: requests to the node (GetNodeInfo 1, RestartNode
 * 5, ExecuteOpcode 10, GetSet 11), RawIMU / MagneticFieldStrength2 messages, other traffic. */
static const uint32_t ids[] = {
    0x100u, 0x101u, 0x102u, 0x103u, 0x103u, 0x186u, 0x180u, 0x7FFu,
    0x80000100u,
    HAL_FRAME_EXT | (16u << 24) | (1u << 16) | 0x8000u | (NODE_ID << 8) | 0x80u | 42u,
    HAL_FRAME_EXT | (16u << 24) | (11u << 16) | 0x8000u | (NODE_ID << 8) | 0x80u | 42u,
    HAL_FRAME_EXT | (16u << 24) | (10u << 16) | 0x8000u | (NODE_ID << 8) | 0x80u | 42u,
    HAL_FRAME_EXT | (16u << 24) | (5u << 16) | 0x8000u | (NODE_ID << 8) | 0x80u | 42u,
    HAL_FRAME_EXT | (8u << 24) | (1003u << 8) | 7u,
    HAL_FRAME_EXT | (8u << 24) | (1002u << 8) | 7u,
    HAL_FRAME_EXT | (24u << 24) | (341u << 8) | 9u,
};

typedef struct {
    uint32_t counters[APP_CNT_COUNT];
    uint16_t last_index;
    int have;
    long outputs;
} sink_t;

typedef struct {
    hal_virtual_t v;
    hal_t hal;
    app_t app;
    sink_t sink;
    hal_frame_t buf[MAX_FRAMES];
    uint32_t pushed;
} node_t;

typedef struct {
    dbc_rx_t rx;
    dbc_rx_counts_t prev;
    uint32_t fed;
    node_t node[2]; /* DBC, DroneCAN */
} world_t;

static void check_sample(const hal_sample_t *s)
{
    int i;
    FZ_CHECK((s->valid & ~HAL_HAS_ALL) == 0u, "valid 0x%x", s->valid);
    FZ_CHECK((s->saturated & ~s->valid) == 0u, "saturated 0x%x valid 0x%x", s->saturated, s->valid);
    for (i = 0; i < 3; ++i) {
        FZ_CHECK(isfinite(s->gyro[i]) && fabsf(s->gyro[i]) <= 32.768f, "gyro %g", (double)s->gyro[i]);
        FZ_CHECK(isfinite(s->accel[i]) && fabsf(s->accel[i]) <= 163.84f, "accel %g", (double)s->accel[i]);
        FZ_CHECK(isfinite(s->mag[i]) && fabsf(s->mag[i]) <= 1638.4f, "mag %g", (double)s->mag[i]);
    }
}

static void on_output(void *user, const app_output_t *o)
{
    sink_t *k = (sink_t *)user;
    int i;
    for (i = 0; i < 3; ++i) {
        FZ_CHECK(isfinite(o->euler[i]) && isfinite(o->rates[i]) && isfinite(o->sigma[i]) && o->sigma[i] >= 0.0f,
                 "output %d: euler %g rates %g sigma %g", i, (double)o->euler[i], (double)o->rates[i],
                 (double)o->sigma[i]);
        FZ_CHECK(fabsf(o->euler[i]) <= 3.1416f, "euler[%d] %g", i, (double)o->euler[i]);
    }
    for (i = 0; i < 4; ++i) {
        FZ_CHECK(isfinite(o->quat[i]), "quat %d", i);
    }
    FZ_CHECK((o->flags & ~0x1FFFu) == 0u, "flags 0x%x", o->flags);
    FZ_CHECK((o->att_flags & ~(uint32_t)((ATT_FLAG_AT_REST << 1) - 1u)) == 0u,
             "att_flags 0x%x: a bit above the last one att.h defines (new flag? update this check)",
             (unsigned)o->att_flags);
    FZ_CHECK(o->kind == APP_OUT_ATTITUDE || o->kind == APP_OUT_HEARTBEAT, "kind %u", o->kind);
    if (k->have) {
        /* consecutive, or 0 after a restart of the node (RestartNode, a restart parameter),
         * which starts the outputs afresh and says so with the latched RESTARTED flag */
        FZ_CHECK(o->index == (uint16_t)(k->last_index + 1u) || (o->index == 0u && (o->flags & APP_FLAG_RESTARTED) != 0u),
                 "index %u after %u (flags 0x%x)", o->index, k->last_index, o->flags);
    }
    for (i = 0; i < APP_CNT_COUNT; ++i) {
        FZ_CHECK(o->counters[i] >= k->counters[i], "counter %s decreased", app_counter_name((app_counter_id_t)i));
        k->counters[i] = o->counters[i];
    }
    k->last_index = o->index;
    k->have = 1;
    ++k->outputs;
}

static void check_rx(world_t *w)
{
    const dbc_rx_t *rx = &w->rx;
    const dbc_rx_counts_t *n = &rx->n, *p = &w->prev;
    int i, used = 0;
    FZ_CHECK(n->bad_dlc >= p->bad_dlc && n->duplicate >= p->duplicate && n->late >= p->late &&
                 n->incomplete >= p->incomplete && n->discarded >= p->discarded,
             "a counter decreased");
    w->prev = *n;
    FZ_CHECK((uint64_t)n->bad_dlc + n->duplicate <= w->fed, "frames counted twice");
    FZ_CHECK(rx->ready_n <= DBC_READY_MAX && rx->ready_head < DBC_READY_MAX, "ready queue");
    FZ_CHECK(rx->hist_n <= DBC_HISTORY && rx->hist_pos < DBC_HISTORY, "history");
    for (i = 0; i < DBC_RX_SLOTS; ++i) {
        used += rx->slot[i].used ? 1 : 0;
    }
    FZ_CHECK(used <= DBC_RX_SLOTS, "slots");
    FZ_CHECK(rx->held_frames <= DBC_SAMPLE_FRAMES && (rx->held.used != 0u) == (rx->held_frames > 0u),
             "held %u frames, used %u", (unsigned)rx->held_frames, (unsigned)rx->held.used);
}

static void pop_all(world_t *w)
{
    hal_sample_t s;
    while (dbc_rx_pop(&w->rx, &s)) {
        check_sample(&s);
    }
}

static void run_node(node_t *nd, uint32_t timeout_us)
{
    uint32_t c[APP_CNT_COUNT];
    int guard = 0;
    hal_status_t st;
    do {
        st = app_poll(&nd->app, timeout_us);
        FZ_CHECK(st == HAL_OK || st == HAL_EMPTY || st == HAL_END || st == HAL_ERR_LINK_DOWN || st == HAL_ERR_IO,
                 "app_poll %d", (int)st);
    } while (st != HAL_EMPTY && st != HAL_END && ++guard < 4 * MAX_FRAMES);
    app_get_counters(&nd->app, c);
    FZ_CHECK(c[APP_CNT_RX_FRAMES] == nd->pushed - (uint32_t)nd->v.frames_n, "rx_frames %u of %u pushed",
             (unsigned)c[APP_CNT_RX_FRAMES], (unsigned)nd->pushed);
}

static void feed(world_t *w, const hal_frame_t *f)
{
    int k;
    if (dbc_rx_takes(&w->rx, f->id)) {
        dbc_rx_frame(&w->rx, f);
        ++w->fed;
    }
    check_rx(w);
    for (k = 0; k < 2; ++k) {
        node_t *nd = &w->node[k];
        if (hal_virtual_frame_space(&nd->v) == 0u) {
            run_node(nd, 1000u);
        }
        if (hal_virtual_push_frame(&nd->v, f) == HAL_OK) {
            ++nd->pushed;
        }
    }
}

static void start_node(node_t *nd, uint8_t protocol)
{
    const app_hooks_t hooks = {NULL, NULL, on_output, &nd->sink};
    app_config_t cfg;
    app_default_config(&cfg);
    cfg.node.protocol = protocol;
    cfg.node.input = protocol;
    cfg.node.node_id = NODE_ID;
    hal_virtual_init(&nd->v, nd->buf, MAX_FRAMES, NULL, 0, NULL, 0);
    hal_virtual_bind(&nd->v, &nd->hal);
    FZ_CHECK(app_init(&nd->app, &cfg, &nd->hal) == EKF_OK, "app_init");
    app_set_hooks(&nd->app, &hooks);
}

/* One sample as the IMU encodes it, frames dropped / repeated / reordered. */
static void sample_op(world_t *w, fz_t *z, uint64_t t_us, uint16_t *seq)
{
    hal_sample_t s;
    hal_frame_t fr[DBC_SAMPLE_FRAMES];
    const uint8_t mode = fz_u8(z);
    size_t n, i;
    int k;
    memset(&s, 0, sizeof(s));
    *seq = (uint16_t)(*seq + ((mode & 0x80u) ? (uint16_t)fz_u16(z) : (uint16_t)(1u + (mode & 1u))));
    s.seq = *seq;
    s.t_us = t_us;
    s.rx_us = t_us;
    s.valid = (uint8_t)(fz_u8(z) & HAL_HAS_ALL);
    for (k = 0; k < 3; ++k) {
        s.gyro[k] = (float)fz_real(z, 10.0);
        s.accel[k] = (float)fz_real(z, 20.0);
        s.mag[k] = (float)fz_real(z, 50.0);
    }
    n = dbc_encode_sample(&s, fr);
    FZ_CHECK(n >= 1u && n <= DBC_SAMPLE_FRAMES, "encode_sample %zu", n);
    if ((mode & 0x06u) == 0x02u && n > 1u) { /* swap two frames */
        const size_t a = fz_u8(z) % n, b = fz_u8(z) % n;
        const hal_frame_t tmp = fr[a];
        fr[a] = fr[b];
        fr[b] = tmp;
    }
    for (i = 0; i < n; ++i) {
        fr[i].t_us = t_us;
        if ((mode & 0x18u) == 0x08u && (fz_u8(z) & 3u) == 0u) {
            continue; /* dropped */
        }
        feed(w, &fr[i]);
        if ((mode & 0x60u) == 0x20u && (fz_u8(z) & 3u) == 0u) {
            feed(w, &fr[i]); /* duplicated */
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static world_t w;
    fz_t z = {data, size};
    uint64_t t_us = 1000u;
    uint16_t seq = 0u;
    int ops = 0, k;

    memset(&w, 0, sizeof(w));
    dbc_rx_init(&w.rx, 0x100u);
    start_node(&w.node[0], APP_PROTO_DBC);
    start_node(&w.node[1], APP_PROTO_DRONECAN);

    while (fz_more(&z) && ops++ < 2000) {
        const uint8_t op = fz_u8(&z);
        t_us += (uint64_t)fz_u8(&z) * 50u;
        switch (op % 8u) {
        case 0:
        case 1: { /* a raw frame */
            hal_frame_t f;
            const uint8_t dl = fz_u8(&z);
            memset(&f, 0, sizeof(f));
            f.t_us = t_us;
            f.id = (op & 0x80u) ? fz_u32(&z) : ids[(op >> 3) % (sizeof(ids) / sizeof(ids[0]))];
            f.dlc = (dl & 0xF0u) ? 8u : (uint8_t)(dl & 0x0Fu);
            fz_bytes(&z, f.data, 8u);
            feed(&w, &f);
            break;
        }
        case 2:
        case 3:
        case 4:
            sample_op(&w, &z, t_us, &seq);
            break;
        case 5:
            pop_all(&w);
            run_node(&w.node[0], 1000u);
            run_node(&w.node[1], 1000u);
            break;
        case 6:
            dbc_rx_flush(&w.rx);
            check_rx(&w);
            break;
        default: { /* output frames: decode arbitrary payloads */
            hal_frame_t f;
            app_output_t o;
            memset(&f, 0, sizeof(f));
            memset(&o, 0, sizeof(o));
            f.id = 0x180u + (uint32_t)(fz_u8(&z) % 6u);
            f.dlc = (uint8_t)(fz_u8(&z) % 10u);
            fz_bytes(&z, f.data, 8u);
            if (dbc_decode_output(&f, &o)) {
                for (k = 0; k < 3; ++k) {
                    FZ_CHECK(isfinite(o.euler[k]) && isfinite(o.rates[k]) && isfinite(o.sigma[k]), "decoded output");
                }
            }
            break;
        }
        }
        pop_all(&w);
    }
    dbc_rx_flush(&w.rx);
    check_rx(&w);
    pop_all(&w);
    for (k = 0; k < 2; ++k) {
        hal_virtual_end(&w.node[k].v);
        run_node(&w.node[k], 100000u);
    }
    return 0;
}
