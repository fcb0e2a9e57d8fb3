/*
 * test_dbc.c - the node's CAN protocol (firmware/app/dbc/dbc_*.c): sample assembly from frames
 * under every fault the protocol defines (duplicates, reordering, loss, wrong length, other
 * ids, saturation, wraps, stale frames, sender restarts), the output encoding round trip, the
 * base ids, and the parameter frames.
 */
#include <math.h>
#include <string.h>

#include "canmsg_gen.h"
#include "hal.h"
#include "dbc.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static dbc_rx_t rx;

static hal_sample_t make_sample(uint16_t seq, uint64_t t_us)
{
    hal_sample_t s;
    memset(&s, 0, sizeof(s));
    s.seq = seq;
    s.t_us = t_us;
    s.rx_us = t_us + 7u;
    s.gyro[0] = 0.1234f;
    s.gyro[1] = -1.5f;
    s.gyro[2] = 0.0004f * (float)(seq % 100u);
    s.accel[0] = 0.3f;
    s.accel[1] = -0.2f;
    s.accel[2] = 9.81f;
    s.mag[0] = 20.0f;
    s.mag[1] = -3.3f;
    s.mag[2] = -41.7f;
    s.valid = HAL_HAS_ALL;
    return s;
}

/* Encodes sample seq and returns its frames (gyro, accel, mag, sync). */
static size_t frames_of(uint16_t seq, uint64_t t_us, hal_frame_t f[DBC_SAMPLE_FRAMES])
{
    const hal_sample_t s = make_sample(seq, t_us);
    return dbc_encode_sample(&s, f);
}

static void feed_all(const hal_frame_t *f, size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        dbc_rx_frame(&rx, &f[i]);
    }
}

static int pop(hal_sample_t *s) { return dbc_rx_pop(&rx, s); }

static void test_clean_stream_reassembles_within_resolution(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    hal_sample_t s;
    uint16_t k;
    dbc_rx_init(&rx, 0x100u);
    for (k = 0; k < 50u; ++k) {
        const hal_sample_t ref = make_sample(k, 1000u + 5000u * k);
        const size_t n = frames_of(k, ref.t_us, f);
        int i;
        TEST_ASSERT_EQUAL_UINT(4u, n);
        TEST_ASSERT_EQUAL_HEX32(CANMSG_IMU_SYNC_FRAME_ID, f[3].id);
        feed_all(f, n - 1u);
        TEST_ASSERT_FALSE(pop(&s)); /* not complete before IMU_SYNC */
        dbc_rx_frame(&rx, &f[n - 1u]);
        TEST_ASSERT_TRUE(pop(&s));
        TEST_ASSERT_FALSE(pop(&s));
        TEST_ASSERT_EQUAL_UINT16(k, s.seq);
        TEST_ASSERT_EQUAL_UINT64(ref.t_us, s.t_us);
        TEST_ASSERT_EQUAL_UINT64(ref.rx_us, s.rx_us);
        TEST_ASSERT_EQUAL_HEX8(HAL_HAS_ALL, s.valid);
        TEST_ASSERT_EQUAL_HEX8(0u, s.saturated);
        for (i = 0; i < 3; ++i) {
            /* half an LSB of each signal's scaling (docs/can_protocol.md) */
            TEST_ASSERT_FLOAT_WITHIN(0.0005f + 1e-6f, ref.gyro[i], s.gyro[i]);
            TEST_ASSERT_FLOAT_WITHIN(0.0025f + 1e-5f, ref.accel[i], s.accel[i]);
            TEST_ASSERT_FLOAT_WITHIN(0.025f + 1e-4f, ref.mag[i], s.mag[i]);
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0u, rx.n.duplicate + rx.n.late + rx.n.incomplete + rx.n.discarded + rx.n.bad_dlc);
}

static void test_other_ids_are_not_taken_and_bad_length_is_counted(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES], bad;
    hal_sample_t s;
    dbc_rx_init(&rx, 0x100u);
    frames_of(1u, 100u, f);
    bad = f[0];
    bad.id = 0x321u;
    TEST_ASSERT_FALSE(dbc_rx_takes(&rx, bad.id));
    dbc_rx_frame(&rx, &bad); /* not an IMU frame: left alone (the application counts it foreign) */
    bad.id = CANMSG_IMU_GYRO_FRAME_ID | HAL_FRAME_EXT; /* same number, 29-bit id */
    TEST_ASSERT_FALSE(dbc_rx_takes(&rx, bad.id));
    dbc_rx_frame(&rx, &bad);
    TEST_ASSERT_FALSE(dbc_rx_takes(&rx, CANMSG_IMU_GYRO_FRAME_ID - 1u));
    TEST_ASSERT_FALSE(dbc_rx_takes(&rx, CANMSG_IMU_SYNC_FRAME_ID + 1u));
    TEST_ASSERT_TRUE(dbc_rx_takes(&rx, CANMSG_IMU_SYNC_FRAME_ID));
    bad = f[1];
    bad.dlc = 6u;
    dbc_rx_frame(&rx, &bad); /* short accel frame: rejected */
    bad.dlc = 15u;
    dbc_rx_frame(&rx, &bad); /* CAN FD length: rejected */
    TEST_ASSERT_EQUAL_UINT32(2u, rx.n.bad_dlc);
    TEST_ASSERT_FALSE(pop(&s));
    feed_all(f, 4u);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_ALL, s.valid);
    TEST_ASSERT_EQUAL_UINT32(0u, rx.n.duplicate + rx.n.late + rx.n.incomplete + rx.n.discarded);
}

/* Frames shifted from the DBC's ids to other bases: the assembler at its base takes them and
 * only them; the outputs and parameter frames go out at the node's base. */
static void test_base_ids_move_every_frame(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES], out[DBC_MAX_OUT_FRAMES];
    hal_sample_t s;
    dbc_tx_t tx;
    app_output_t o;
    dbc_param_req_t req;
    size_t n, i;
    dbc_rx_init(&rx, 0x300u);
    n = frames_of(7u, 1000u, f);
    feed_all(f, n); /* at the DBC's ids: not this assembler's */
    TEST_ASSERT_FALSE(pop(&s));
    for (i = 0; i < n; ++i) {
        f[i].id = f[i].id - CANMSG_IMU_GYRO_FRAME_ID + 0x300u;
    }
    feed_all(f, n);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(7u, s.seq);
    dbc_tx_init(&tx, 0x400u);
    memset(&o, 0, sizeof(o));
    o.kind = APP_OUT_ATTITUDE;
    n = dbc_encode_output(&tx, &o, out);
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_HEX32(0x400u + i, out[i].id);
    }
    dbc_encode_param(&tx, 3u, DBC_OP_GET, DBC_RESULT_OK, 1.5f, 0u, &out[0]);
    TEST_ASSERT_EQUAL_HEX32(0x405u, out[0].id);
    out[0].id = 0x406u;
    TEST_ASSERT_EQUAL_INT(1, dbc_decode_param_req(&tx, &out[0], &req));
    out[0].id = CANMSG_ATT_PARAM_REQ_FRAME_ID; /* another node's request */
    TEST_ASSERT_EQUAL_INT(0, dbc_decode_param_req(&tx, &out[0], &req));
    /* 11-bit ids only, and the node's frames never on the IMU's */
    TEST_ASSERT_TRUE(dbc_bases_ok(0x180u, 0x100u));
    TEST_ASSERT_TRUE(dbc_bases_ok(0x7F9u, 0x000u));
    TEST_ASSERT_FALSE(dbc_bases_ok(0x7FAu, 0x000u));
    TEST_ASSERT_FALSE(dbc_bases_ok(0x100u, 0x7FDu));
    TEST_ASSERT_FALSE(dbc_bases_ok(0x100u, 0x103u));
    TEST_ASSERT_FALSE(dbc_bases_ok(0x103u, 0x100u));
    TEST_ASSERT_TRUE(dbc_bases_ok(0x104u, 0x100u));
    TEST_ASSERT_TRUE(dbc_bases_ok(0x100u, 0x107u));
    TEST_ASSERT_FALSE(dbc_bases_ok(0x100u, 0x106u));
}

/* ATT_PARAM_REQ in, ATT_PARAM out: every field through the generated code both ways. */
static void test_parameter_frames(void)
{
    dbc_tx_t tx;
    dbc_param_req_t req;
    hal_frame_t f;
    struct canmsg_att_param_req_t m;
    struct canmsg_att_param_t a;
    dbc_tx_init(&tx, 0x180u);
    memset(&f, 0, sizeof(f));
    m.index = 41u;
    m.op = DBC_OP_SET;
    m.value = -0.125f;
    TEST_ASSERT_EQUAL_INT(8, canmsg_att_param_req_pack(f.data, &m, 8u));
    f.id = CANMSG_ATT_PARAM_REQ_FRAME_ID;
    f.dlc = 8u;
    TEST_ASSERT_EQUAL_INT(1, dbc_decode_param_req(&tx, &f, &req));
    TEST_ASSERT_EQUAL_UINT16(41u, req.index);
    TEST_ASSERT_EQUAL_UINT8(DBC_OP_SET, req.op);
    TEST_ASSERT_EQUAL_FLOAT(-0.125f, req.value);
    f.dlc = 7u;
    TEST_ASSERT_EQUAL_INT(-1, dbc_decode_param_req(&tx, &f, &req));
    dbc_encode_param(&tx, 41u, DBC_OP_SET, DBC_RESULT_PENDING_RESTART, 2.5f, 9u, &f);
    TEST_ASSERT_EQUAL_HEX32(CANMSG_ATT_PARAM_FRAME_ID, f.id);
    TEST_ASSERT_EQUAL_UINT8(8u, f.dlc);
    TEST_ASSERT_EQUAL_INT(0, canmsg_att_param_unpack(&a, f.data, 8u));
    TEST_ASSERT_EQUAL_UINT16(41u, a.index);
    TEST_ASSERT_EQUAL_UINT8(DBC_OP_SET, a.op);
    TEST_ASSERT_EQUAL_UINT8(DBC_RESULT_PENDING_RESTART, a.result);
    TEST_ASSERT_EQUAL_FLOAT(2.5f, a.value);
}

static void test_duplicates_and_late_frames_are_dropped(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES], g[DBC_SAMPLE_FRAMES];
    hal_sample_t s;
    dbc_rx_init(&rx, 0x100u);
    frames_of(10u, 1000u, f);
    dbc_rx_frame(&rx, &f[0]);
    dbc_rx_frame(&rx, &f[0]); /* duplicate while assembling */
    feed_all(&f[1], 3u);
    TEST_ASSERT_TRUE(pop(&s));
    dbc_rx_frame(&rx, &f[2]); /* duplicate of an emitted sample */
    dbc_rx_frame(&rx, &f[3]);
    TEST_ASSERT_EQUAL_UINT32(3u, rx.n.duplicate);
    TEST_ASSERT_FALSE(pop(&s));
    /* sample 11 loses its mag frame; it is emitted without mag when 12 completes, and the
     * mag frame arriving afterwards is late */
    frames_of(11u, 2000u, f);
    frames_of(12u, 3000u, g);
    dbc_rx_frame(&rx, &f[0]);
    dbc_rx_frame(&rx, &f[1]);
    dbc_rx_frame(&rx, &f[3]);
    TEST_ASSERT_FALSE(pop(&s)); /* still waiting for the declared mag frame */
    feed_all(g, 4u);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(11u, s.seq);
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_GYRO | HAL_HAS_ACCEL, s.valid);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(12u, s.seq);
    TEST_ASSERT_EQUAL_UINT32(1u, rx.n.incomplete);
    dbc_rx_frame(&rx, &f[2]);
    TEST_ASSERT_EQUAL_UINT32(1u, rx.n.late);
    TEST_ASSERT_FALSE(pop(&s));
}

static void test_reordering_within_and_across_samples(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES], g[DBC_SAMPLE_FRAMES];
    hal_sample_t s;
    dbc_rx_init(&rx, 0x100u);
    /* IMU_SYNC first: the sample completes with its last declared sensor frame */
    frames_of(5u, 500u, f);
    dbc_rx_frame(&rx, &f[3]);
    dbc_rx_frame(&rx, &f[2]);
    dbc_rx_frame(&rx, &f[0]);
    TEST_ASSERT_FALSE(pop(&s));
    dbc_rx_frame(&rx, &f[1]);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_ALL, s.valid);
    /* priority order of a CAN controller: IMU_GYRO of 7 before IMU_SYNC of 6 */
    frames_of(6u, 600u, f);
    frames_of(7u, 700u, g);
    feed_all(f, 3u);
    dbc_rx_frame(&rx, &g[0]);
    dbc_rx_frame(&rx, &f[3]);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(6u, s.seq);
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_ALL, s.valid);
    feed_all(&g[1], 3u);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(7u, s.seq);
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_ALL, s.valid);
    TEST_ASSERT_EQUAL_UINT32(0u, rx.n.late + rx.n.discarded +
                                     rx.n.incomplete);
}

static void test_lost_sync_discards_the_sample(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    hal_sample_t s;
    uint16_t k;
    dbc_rx_init(&rx, 0x100u);
    frames_of(20u, 2000u, f);
    feed_all(f, 3u); /* IMU_SYNC of 20 lost */
    for (k = 21u; k <= 22u; ++k) {
        frames_of(k, 2000u + 10u * (k - 20u), f);
        feed_all(f, 4u);
    }
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(21u, s.seq);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(22u, s.seq);
    TEST_ASSERT_FALSE(pop(&s));
    TEST_ASSERT_EQUAL_UINT32(1u, rx.n.discarded);
    /* end of input with a sample that has no IMU_SYNC: discarded by the flush too */
    frames_of(23u, 2100u, f);
    dbc_rx_frame(&rx, &f[0]);
    dbc_rx_flush(&rx);
    TEST_ASSERT_FALSE(pop(&s));
    TEST_ASSERT_EQUAL_UINT32(2u, rx.n.discarded);
}

static void test_optional_sensors_and_non_finite_values(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    hal_sample_t in = make_sample(3u, 300u), s;
    size_t n;
    dbc_rx_init(&rx, 0x100u);
    in.valid = HAL_HAS_GYRO | HAL_HAS_ACCEL; /* no magnetometer in this sample */
    in.accel[1] = NAN;                      /* and a broken accelerometer reading */
    n = dbc_encode_sample(&in, f);
    TEST_ASSERT_EQUAL_UINT(2u, n); /* gyro + sync */
    feed_all(f, n);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_GYRO, s.valid);
}

static void test_saturation_is_clamped_and_flagged(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    hal_sample_t in = make_sample(4u, 400u), s;
    dbc_rx_init(&rx, 0x100u);
    in.gyro[1] = 50.0f;     /* beyond +-32.767 rad/s */
    in.accel[2] = -1000.0f; /* beyond +-163.835 m/s^2 */
    feed_all(f, dbc_encode_sample(&in, f));
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_ALL, s.valid);
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_GYRO | HAL_HAS_ACCEL, s.saturated);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 32.767f, s.gyro[1]);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, -163.835f, s.accel[2]);
    /* a sender that clamps without setting the Sat bit: the extreme raw value says it */
    in = make_sample(5u, 500u);
    TEST_ASSERT_EQUAL_UINT(4u, dbc_encode_sample(&in, f));
    {
        struct canmsg_imu_mag_t m;
        TEST_ASSERT_EQUAL_INT(0, canmsg_imu_mag_unpack(&m, f[2].data, 8u));
        m.mag_x = INT16_MAX;
        TEST_ASSERT_EQUAL_INT(8, canmsg_imu_mag_pack(f[2].data, &m, 8u));
    }
    feed_all(f, 4u);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_HEX8(HAL_HAS_MAG, s.saturated);
}

static void test_time_and_sequence_wrap(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    hal_sample_t s;
    const uint64_t t0 = 0xFFFFFF00u; /* 256 us before the 32-bit wrap */
    uint16_t seq = 65534u;
    int k;
    dbc_rx_init(&rx, 0x100u);
    for (k = 0; k < 4; ++k, ++seq) {
        feed_all(f, frames_of(seq, t0 + 100u * (uint64_t)k, f));
        TEST_ASSERT_TRUE(pop(&s));
        TEST_ASSERT_EQUAL_UINT16(seq, s.seq);
        TEST_ASSERT_EQUAL_UINT64(t0 + 100u * (uint64_t)k, s.t_us); /* unwrapped past 2^32 */
    }
    TEST_ASSERT_EQUAL_UINT32(0u, rx.n.late + rx.n.duplicate);
}

/* ---- frames outside the stream's window ----------------------------------------------- */
#define STREAM_T0_US 5000000u
#define STREAM_DT_US 10000u /* 100 Hz */

static uint64_t stream_t(uint16_t seq) { return STREAM_T0_US + STREAM_DT_US * (uint64_t)seq; }

/* Pops everything ready and checks it is samples *next, *next + 1, ... in order, each
 * complete with its own time. */
static void pop_in_order(uint16_t *next)
{
    hal_sample_t s;
    while (pop(&s)) {
        TEST_ASSERT_EQUAL_UINT16(*next, s.seq);
        TEST_ASSERT_EQUAL_HEX8(HAL_HAS_ALL, s.valid);
        TEST_ASSERT_EQUAL_UINT64(stream_t(*next), s.t_us);
        ++*next;
    }
}

/* Samples 0..39 of a stream, frames in the order a CAN controller may send them (IMU_GYRO of
 * k+1 before IMU_SYNC of k when interleave is set), with `extra` fed just before frame
 * number `at` of the whole stream. Every sample must come out complete and in order. */
static void stream_with_extra(const hal_frame_t *extra, size_t n_extra, size_t at, int interleave)
{
    hal_frame_t all[40u * DBC_SAMPLE_FRAMES];
    size_t n = 0, i;
    uint16_t k, next = 0u;
    for (k = 0; k < 40u; ++k) {
        n += frames_of(k, stream_t(k), &all[n]);
    }
    if (interleave) {
        for (i = 3u; i + 1u < n; i += 4u) { /* swap IMU_SYNC of k and IMU_GYRO of k+1 */
            const hal_frame_t t = all[i];
            all[i] = all[i + 1u];
            all[i + 1u] = t;
        }
    }
    dbc_rx_init(&rx, 0x100u);
    for (i = 0; i < n; ++i) {
        if (i == at) {
            feed_all(extra, n_extra);
        }
        dbc_rx_frame(&rx, &all[i]);
        pop_in_order(&next);
    }
    dbc_rx_flush(&rx);
    pop_in_order(&next);
    TEST_ASSERT_EQUAL_UINT16(40u, next);
    TEST_ASSERT_EQUAL_UINT32(0u, rx.n.incomplete + rx.n.discarded +
                                     rx.n.duplicate);
}

/* One stale frame (any id, from far behind or beyond the window ahead) at every position
 * inside and between the samples of a stream: dropped as late, and every sample of the
 * stream still comes out complete. The frame is inserted while samples 20 to 22 are being
 * assembled: its distance from them is just outside the window or further. */
static void test_one_stale_frame_leaves_the_assembly_alone(void)
{
    static const int32_t away[] = {-300, -DBC_SEQ_WINDOW - 1, DBC_SEQ_WINDOW + 3, 300, 30000};
    size_t a, at;
    int kind, interleave;
    for (a = 0; a < sizeof(away) / sizeof(away[0]); ++a) {
        for (kind = 0; kind < 4; ++kind) {
            for (interleave = 0; interleave < 2; ++interleave) {
                for (at = 4u * 20u; at < 4u * 20u + 8u; ++at) { /* around samples 20 and 21 */
                    hal_frame_t f[DBC_SAMPLE_FRAMES];
                    const uint16_t seq = (uint16_t)(20 + away[a]);
                    frames_of(seq, stream_t(seq), f);
                    stream_with_extra(&f[kind], 1u, at, interleave);
                    TEST_ASSERT_EQUAL_UINT32(1u, rx.n.late);
                }
            }
        }
    }
}

/* A whole stale sample re-sent (all four frames, one sequence number) is no restart: late. */
static void test_stale_sample_is_late_not_a_restart(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    size_t at;
    frames_of(10u, stream_t(10u), f);
    for (at = 4u * 30u; at < 4u * 30u + 4u; ++at) {
        stream_with_extra(f, 4u, at, 0);
        TEST_ASSERT_EQUAL_UINT32(4u, rx.n.late);
    }
    /* two stray frames that do not continue each other: both late */
    {
        hal_frame_t two[2];
        frames_of(500u, stream_t(500u), f);
        two[0] = f[3];
        frames_of(700u, stream_t(700u), f);
        two[1] = f[0];
        stream_with_extra(two, 2u, 4u * 30u + 2u, 0);
        TEST_ASSERT_EQUAL_UINT32(2u, rx.n.late);
    }
    /* held at the end of the input: late too, never a sample */
    {
        hal_sample_t s;
        uint16_t next = 0u, k;
        dbc_rx_init(&rx, 0x100u);
        for (k = 0; k < 5u; ++k) {
            feed_all(f, frames_of(k, stream_t(k), f));
            pop_in_order(&next);
        }
        feed_all(f, frames_of(9000u, stream_t(9000u), f));
        dbc_rx_flush(&rx);
        TEST_ASSERT_FALSE(pop(&s));
        TEST_ASSERT_EQUAL_UINT32(4u, rx.n.late);
    }
}

/* The sender restarts in the middle of a sample (its IMU_SYNC never sent): the new stream is
 * followed from its first sample, handed on as soon as a frame of the second one arrives;
 * the cut sample is discarded, nothing is late. */
static void test_sender_restart_is_followed(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES], g[DBC_SAMPLE_FRAMES];
    hal_sample_t s;
    uint16_t k, next = 30000u;
    int prio;
    for (prio = 0; prio < 2; ++prio) {
        dbc_rx_init(&rx, 0x100u);
        next = 30000u;
        for (k = 30000u; k < 30050u; ++k) {
            feed_all(f, frames_of(k, stream_t(k), f));
            pop_in_order(&next);
        }
        frames_of(30050u, stream_t(30050u), f);
        feed_all(f, 2u); /* gyro and accel of 30050, then the sender resets */
        next = 0u;
        frames_of(0u, stream_t(0u), f);
        frames_of(1u, stream_t(1u), g);
        if (prio) { /* priority order: IMU_GYRO of 1 before IMU_SYNC of 0 */
            feed_all(f, 3u);
            TEST_ASSERT_FALSE(pop(&s));
            dbc_rx_frame(&rx, &g[0]);
            TEST_ASSERT_FALSE(pop(&s)); /* the restart is followed, sample 0 still waits */
            dbc_rx_frame(&rx, &f[3]);
        } else {
            feed_all(f, 4u);
            TEST_ASSERT_FALSE(pop(&s)); /* one sample of a new sequence: held */
            dbc_rx_frame(&rx, &g[0]);
        }
        pop_in_order(&next);
        TEST_ASSERT_EQUAL_UINT16(1u, next); /* sample 0 handed on */
        feed_all(&g[1], 3u);
        pop_in_order(&next);
        for (k = 2u; k < 20u; ++k) {
            feed_all(f, frames_of(k, stream_t(k), f));
            pop_in_order(&next);
        }
        TEST_ASSERT_EQUAL_UINT16(20u, next);
        TEST_ASSERT_EQUAL_UINT32(1u, rx.n.discarded); /* 30050 */
        TEST_ASSERT_EQUAL_UINT32(0u, rx.n.late + rx.n.incomplete +
                                         rx.n.duplicate);
    }
    /* within the window behind the new stream: late */
    feed_all(f, frames_of(65530u, stream_t(65530u), f));
    TEST_ASSERT_EQUAL_UINT32(4u, rx.n.late);
    TEST_ASSERT_FALSE(pop(&s));
}

/* Frames lost for longer than the window: the first sample after the jump is handed on
 * with the first frame of the next one; nothing is lost or counted. */
static void test_jump_beyond_the_window_is_followed(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    uint16_t k, next = 0u;
    dbc_rx_init(&rx, 0x100u);
    for (k = 0; k < 20u; ++k) {
        feed_all(f, frames_of(k, stream_t(k), f));
        pop_in_order(&next);
    }
    next = 220u;
    for (k = 220u; k < 240u; ++k) {
        feed_all(f, frames_of(k, stream_t(k), f));
        pop_in_order(&next);
        if (k == 220u) {
            TEST_ASSERT_EQUAL_UINT16(220u, next); /* held */
        }
    }
    TEST_ASSERT_EQUAL_UINT16(240u, next);
    TEST_ASSERT_EQUAL_UINT32(0u, rx.n.late + rx.n.incomplete +
                                     rx.n.discarded + rx.n.duplicate);
}

static void test_ready_queue_overflow_drops_oldest(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    hal_sample_t s;
    uint16_t k;
    dbc_rx_init(&rx, 0x100u);
    for (k = 0; k < DBC_READY_MAX + 2u; ++k) {
        feed_all(f, frames_of(k, 100u * k, f));
    }
    TEST_ASSERT_EQUAL_UINT32(2u, rx.n.discarded);
    TEST_ASSERT_TRUE(pop(&s));
    TEST_ASSERT_EQUAL_UINT16(2u, s.seq);
}

static void test_output_round_trip_and_clamping(void)
{
    dbc_tx_t tx;
    app_output_t out, back;
    hal_frame_t f[DBC_MAX_OUT_FRAMES];
    size_t n, i;
    int page;
    memset(&out, 0, sizeof(out));
    dbc_tx_init(&tx, 0x180u);
    out.kind = APP_OUT_ATTITUDE;
    out.euler[0] = 0.12345f;
    out.euler[1] = -1.5f;
    out.euler[2] = 3.14159f;
    out.rates[0] = -0.5f;
    out.rates[1] = 40.0f; /* beyond the wire range: clamped, OutSaturated */
    out.rates[2] = 0.001f;
    out.sigma[0] = 0.01f;
    out.sigma[1] = 0.02f;
    out.sigma[2] = 0.5f;
    out.flags = APP_FLAG_ALIGNED | APP_FLAG_GAP;
    out.att_flags = 0x0A01u;
    out.seq = 4321u;
    out.index = 77u;
    for (i = 0; i < APP_CNT_COUNT; ++i) {
        out.counters[i] = 1000u * (uint32_t)i + 7u;
    }
    out.counters[APP_CNT_RX_FRAMES] = UINT32_MAX;
    n = dbc_encode_output(&tx, &out, f);
    TEST_ASSERT_EQUAL_UINT(5u, n);
    memset(&back, 0, sizeof(back));
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_TRUE(dbc_decode_output(&f[i], &back));
    }
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_FLOAT_WITHIN(0.00005f + 1e-6f, out.euler[i], back.euler[i]);
        TEST_ASSERT_FLOAT_WITHIN(0.00005f + 1e-6f, out.sigma[i], back.sigma[i]);
    }
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 32.767f, back.rates[1]);
    TEST_ASSERT_FLOAT_WITHIN(0.0005f, -0.5f, back.rates[0]);
    TEST_ASSERT_EQUAL_HEX16(APP_FLAG_ALIGNED | APP_FLAG_GAP | APP_FLAG_OUT_SATURATED, back.flags);
    TEST_ASSERT_EQUAL_HEX32(0x0A01u, back.att_flags);
    TEST_ASSERT_EQUAL_UINT16(4321u, back.seq);
    TEST_ASSERT_EQUAL_UINT16(77u, back.index);
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, back.counters[APP_CNT_RX_FRAMES]);
    /* the counter pages cycle through every counter */
    for (page = 1; page < APP_CNT_COUNT; ++page) {
        n = dbc_encode_output(&tx, &out, f);
        TEST_ASSERT_TRUE(dbc_decode_output(&f[n - 1u], &back));
    }
    for (i = 0; i < APP_CNT_COUNT; ++i) {
        TEST_ASSERT_EQUAL_UINT32(out.counters[i], back.counters[i]);
    }
    /* a heartbeat is status + counters only */
    out.kind = APP_OUT_HEARTBEAT;
    out.flags = APP_FLAG_STALE | APP_FLAG_HEARTBEAT;
    n = dbc_encode_output(&tx, &out, f);
    TEST_ASSERT_EQUAL_UINT(2u, n);
    TEST_ASSERT_EQUAL_HEX32(CANMSG_ATT_STATUS_FRAME_ID, f[0].id);
    TEST_ASSERT_TRUE(dbc_decode_output(&f[0], &back));
    TEST_ASSERT_EQUAL_UINT8(APP_OUT_HEARTBEAT, back.kind);
    /* non-finite values (which the filter never produces) go out as 0, flagged */
    out.kind = APP_OUT_ATTITUDE;
    out.flags = 0u;
    out.rates[1] = 0.0f;
    out.euler[2] = NAN;
    n = dbc_encode_output(&tx, &out, f);
    TEST_ASSERT_TRUE(dbc_decode_output(&f[0], &back));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, back.euler[2]);
    TEST_ASSERT_TRUE(dbc_decode_output(&f[3], &back));
    TEST_ASSERT_EQUAL_HEX16(APP_FLAG_OUT_SATURATED, back.flags);
}

static void test_names(void)
{
    TEST_ASSERT_EQUAL_STRING("foreign", app_counter_name(APP_CNT_FOREIGN));
    TEST_ASSERT_EQUAL_STRING("outputs", app_counter_name(APP_CNT_OUTPUTS));
    TEST_ASSERT_EQUAL_STRING("refused", app_counter_name(APP_CNT_REFUSED));
    TEST_ASSERT_EQUAL_STRING("unknown_counter", app_counter_name(APP_CNT_COUNT));
    TEST_ASSERT_EQUAL_STRING("HAL_ERR_LINK_DOWN", hal_status_name(HAL_ERR_LINK_DOWN));
    {
        uint32_t c = UINT32_MAX - 1u;
        hal_count(&c);
        hal_count(&c);
        TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, c);
        c = 5u;
        hal_count_n(&c, UINT32_MAX);
        TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, c);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_clean_stream_reassembles_within_resolution);
    RUN_TEST(test_other_ids_are_not_taken_and_bad_length_is_counted);
    RUN_TEST(test_base_ids_move_every_frame);
    RUN_TEST(test_parameter_frames);
    RUN_TEST(test_duplicates_and_late_frames_are_dropped);
    RUN_TEST(test_reordering_within_and_across_samples);
    RUN_TEST(test_lost_sync_discards_the_sample);
    RUN_TEST(test_optional_sensors_and_non_finite_values);
    RUN_TEST(test_saturation_is_clamped_and_flagged);
    RUN_TEST(test_time_and_sequence_wrap);
    RUN_TEST(test_one_stale_frame_leaves_the_assembly_alone);
    RUN_TEST(test_stale_sample_is_late_not_a_restart);
    RUN_TEST(test_sender_restart_is_followed);
    RUN_TEST(test_jump_beyond_the_window_is_followed);
    RUN_TEST(test_ready_queue_overflow_drops_oldest);
    RUN_TEST(test_output_round_trip_and_clamping);
    RUN_TEST(test_names);
    return UNITY_END();
}
