/*
 * fuzz_hal_can.c - libFuzzer target: the CAN protocol receive path (hal/can/hal_can_rx.c over
 * the cantools-generated canmsg_gen.c) and, behind it, the estimator node (firmware/app over
 * the virtual backend) fed arbitrary frames.
 *
 * The input is a program of operations: raw frames (any id, any DLC, any payload), whole
 * samples encoded as the IMU would and delivered with frames dropped, duplicated or
 * swapped, pops, flushes and output frames to decode. The same frames go to a bare
 * assembler (checked directly) and to an app_t on the virtual backend (outputs checked).
 *
 * Invariants: no crash or undefined behaviour (ASan + UBSan); every frame counted in
 * rx_frames and at most once as unknown id / bad DLC / duplicate / late; counters never
 * decrease; samples carry only known sensor bits, saturated within valid, finite values
 * within the wire range; the assembler's queues within their sizes; every node output
 * finite with its sigma >= 0, known flag bits, and counters that never decrease.
 */
#include "app.h"
#include "fuzz_common.h"
#include "hal_can.h"
#include "hal_virtual.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define MAX_FRAMES 512

static const uint32_t ids[] = {
    0x100u, 0x101u, 0x102u, 0x103u, 0x103u, 0x100u, 0x180u, 0x181u,
    0x182u, 0x183u, 0x184u, 0x000u, 0x7FFu, 0x104u, 0x80000100u, 0x80000103u,
};

typedef struct {
    uint32_t counters[HAL_CNT_COUNT];
    uint16_t last_index;
    int have;
    long outputs;
} sink_t;

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

static void on_output(void *user, const hal_output_t *o)
{
    sink_t *k = (sink_t *)user;
    int i;
    for (i = 0; i < 3; ++i) {
        FZ_CHECK(isfinite(o->euler[i]) && isfinite(o->rates[i]) && isfinite(o->sigma[i]) && o->sigma[i] >= 0.0f,
                 "output %d: euler %g rates %g sigma %g", i, (double)o->euler[i], (double)o->rates[i],
                 (double)o->sigma[i]);
        FZ_CHECK(fabsf(o->euler[i]) <= 3.1416f, "euler[%d] %g", i, (double)o->euler[i]);
    }
    FZ_CHECK((o->flags & ~0x0FFFu) == 0u, "flags 0x%x", o->flags);
    FZ_CHECK((o->att_flags & ~(uint32_t)((ATT_FLAG_AT_REST << 1) - 1u)) == 0u,
             "att_flags 0x%x: a bit above the last one att.h defines (new flag? update this check)",
             (unsigned)o->att_flags);
    FZ_CHECK(o->kind == HAL_OUT_ATTITUDE || o->kind == HAL_OUT_HEARTBEAT, "kind %u", o->kind);
    if (k->have) {
        FZ_CHECK(o->index == (uint16_t)(k->last_index + 1u), "index %u after %u", o->index, k->last_index);
    }
    for (i = 0; i < HAL_CNT_COUNT; ++i) {
        FZ_CHECK(o->counters[i] >= k->counters[i], "counter %s decreased", hal_counter_name((hal_counter_id_t)i));
        k->counters[i] = o->counters[i];
    }
    k->last_index = o->index;
    k->have = 1;
    ++k->outputs;
}

typedef struct {
    hal_can_rx_t rx;
    uint32_t prev[HAL_CNT_COUNT];
    uint32_t fed;
    hal_virtual_t v;
    hal_t hal;
    app_t app;
    sink_t sink;
    hal_can_frame_t vbuf[MAX_FRAMES];
} world_t;

static void check_rx(world_t *w)
{
    const hal_can_rx_t *rx = &w->rx;
    uint32_t c[HAL_CNT_COUNT] = {0};
    int i, used = 0;
    hal_can_rx_add_counters(rx, c);
    for (i = 0; i < HAL_CNT_COUNT; ++i) {
        FZ_CHECK(c[i] >= w->prev[i], "counter %s decreased", hal_counter_name((hal_counter_id_t)i));
        w->prev[i] = c[i];
    }
    FZ_CHECK(c[HAL_CNT_RX_FRAMES] == w->fed, "rx_frames %u fed %u", (unsigned)c[HAL_CNT_RX_FRAMES], (unsigned)w->fed);
    FZ_CHECK((uint64_t)c[HAL_CNT_UNKNOWN_ID] + c[HAL_CNT_BAD_DLC] + c[HAL_CNT_DUPLICATE] + c[HAL_CNT_LATE] <= w->fed,
             "frames counted twice");
    FZ_CHECK(rx->ready_n <= HAL_CAN_READY_MAX && rx->ready_head < HAL_CAN_READY_MAX, "ready queue");
    FZ_CHECK(rx->hist_n <= HAL_CAN_HISTORY && rx->hist_pos < HAL_CAN_HISTORY, "history");
    for (i = 0; i < HAL_CAN_RX_SLOTS; ++i) {
        used += rx->slot[i].used ? 1 : 0;
    }
    FZ_CHECK(used <= HAL_CAN_RX_SLOTS, "slots");
    FZ_CHECK(rx->held_frames <= HAL_CAN_SAMPLE_FRAMES && (rx->held.used != 0u) == (rx->held_frames > 0u),
             "held %u frames, used %u", (unsigned)rx->held_frames, (unsigned)rx->held.used);
}

static void pop_all(world_t *w)
{
    hal_sample_t s;
    while (hal_can_rx_pop(&w->rx, &s)) {
        check_sample(&s);
    }
}

static void run_app(world_t *w, uint32_t timeout_us)
{
    int guard = 0;
    hal_status_t st;
    do {
        st = app_poll(&w->app, timeout_us);
        FZ_CHECK(st == HAL_OK || st == HAL_EMPTY || st == HAL_END || st == HAL_ERR_LINK_DOWN || st == HAL_ERR_IO,
                 "app_poll %d", (int)st);
    } while (st != HAL_EMPTY && st != HAL_END && ++guard < 4 * MAX_FRAMES);
}

static void feed(world_t *w, const hal_can_frame_t *f)
{
    hal_can_rx_frame(&w->rx, f);
    ++w->fed;
    check_rx(w);
    if (hal_virtual_frame_space(&w->v) == 0u) {
        run_app(w, 1000u);
    }
    (void)hal_virtual_push_frame(&w->v, f);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static world_t w;
    fz_t z = {data, size};
    uint64_t t_us = 1000u;
    uint16_t seq = 0u;
    int ops = 0;

    memset(&w, 0, sizeof(w));
    hal_can_rx_init(&w.rx);
    hal_virtual_init(&w.v, w.vbuf, MAX_FRAMES, NULL, 0);
    hal_virtual_bind(&w.v, &w.hal);
    hal_virtual_set_sinks(&w.v, on_output, NULL, NULL, &w.sink);
    FZ_CHECK(app_init(&w.app, &app_default_settings, &att_default_settings, &w.hal) == EKF_OK, "app_init");

    while (fz_more(&z) && ops++ < 2000) {
        const uint8_t op = fz_u8(&z);
        t_us += (uint64_t)fz_u8(&z) * 50u;
        switch (op % 8u) {
        case 0:
        case 1: { /* a raw frame */
            hal_can_frame_t f;
            const uint8_t dl = fz_u8(&z);
            memset(&f, 0, sizeof(f));
            f.t_us = t_us;
            f.id = (op & 0x80u) ? fz_u32(&z) : ids[(op >> 3) & 15u];
            f.dlc = (dl & 0xF0u) ? 8u : (uint8_t)(dl & 0x0Fu);
            fz_bytes(&z, f.data, 8u);
            feed(&w, &f);
            break;
        }
        case 2:
        case 3:
        case 4: { /* a sample as the IMU encodes it, frames dropped / repeated / reordered */
            hal_sample_t s;
            hal_can_frame_t fr[HAL_CAN_SAMPLE_FRAMES];
            const uint8_t mode = fz_u8(&z);
            size_t n, i;
            int k;
            memset(&s, 0, sizeof(s));
            seq = (uint16_t)(seq + ((mode & 0x80u) ? (uint16_t)fz_u16(&z) : (uint16_t)(1u + (mode & 1u))));
            s.seq = seq;
            s.t_us = t_us;
            s.rx_us = t_us;
            s.valid = (uint8_t)(fz_u8(&z) & HAL_HAS_ALL);
            for (k = 0; k < 3; ++k) {
                s.gyro[k] = (float)fz_real(&z, 10.0);
                s.accel[k] = (float)fz_real(&z, 20.0);
                s.mag[k] = (float)fz_real(&z, 50.0);
            }
            n = hal_can_encode_sample(&s, fr);
            FZ_CHECK(n >= 1u && n <= HAL_CAN_SAMPLE_FRAMES, "encode_sample %zu", n);
            if ((mode & 0x06u) == 0x02u && n > 1u) { /* swap two frames */
                const size_t a = fz_u8(&z) % n, b = fz_u8(&z) % n;
                const hal_can_frame_t tmp = fr[a];
                fr[a] = fr[b];
                fr[b] = tmp;
            }
            for (i = 0; i < n; ++i) {
                fr[i].t_us = t_us;
                if ((mode & 0x18u) == 0x08u && (fz_u8(&z) & 3u) == 0u) {
                    continue; /* dropped */
                }
                feed(&w, &fr[i]);
                if ((mode & 0x60u) == 0x20u && (fz_u8(&z) & 3u) == 0u) {
                    feed(&w, &fr[i]); /* duplicated */
                }
            }
            break;
        }
        case 5:
            pop_all(&w);
            run_app(&w, 1000u);
            break;
        case 6:
            hal_can_rx_flush(&w.rx);
            check_rx(&w);
            break;
        default: { /* output frames: decode arbitrary payloads */
            hal_can_frame_t f;
            hal_output_t o;
            memset(&f, 0, sizeof(f));
            memset(&o, 0, sizeof(o));
            f.id = 0x180u + (uint32_t)(fz_u8(&z) % 6u);
            f.dlc = (uint8_t)(fz_u8(&z) % 10u);
            fz_bytes(&z, f.data, 8u);
            if (hal_can_decode_output(&f, &o)) {
                int k;
                for (k = 0; k < 3; ++k) {
                    FZ_CHECK(isfinite(o.euler[k]) && isfinite(o.rates[k]) && isfinite(o.sigma[k]), "decoded output");
                }
            }
            break;
        }
        }
        pop_all(&w);
    }
    hal_can_rx_flush(&w.rx);
    check_rx(&w);
    pop_all(&w);
    hal_virtual_end(&w.v);
    run_app(&w, 100000u);
    return 0;
}
