/*
 * test_app.c - the application loop (firmware/app/app*.c) on the virtual backend: output
 * schedule, gaps, long gaps, time errors, stale samples and confirmed sensor restarts,
 * staleness and heartbeats, saturation, rejected input, link loss, foreign frames on a shared
 * bus, and determinism of a replay.
 */
#include <math.h>
#include <string.h>

#include "app.h"
#include "hal.h"
#include "dbc.h"
#include "hal_virtual.h"
#include "unity.h"

#define MAXOUT 600
#define QLEN 2048
#define PERIOD_US 10000u /* samples at 100 Hz */

static hal_virtual_t v;
static hal_t hal;
static app_t app;
static hal_sample_t squeue[QLEN];
static hal_frame_t fqueue[QLEN];
static app_output_t outs[MAXOUT];
static int nout;
static int nframes_out;

static void collect(void *user, const app_output_t *o)
{
    (void)user;
    if (nout < MAXOUT) {
        outs[nout] = *o;
    }
    ++nout;
}

static void count_frames(void *user, const hal_frame_t *f)
{
    (void)user;
    (void)f;
    ++nframes_out;
}

void setUp(void)
{
    nout = 0;
    nframes_out = 0;
    hal_virtual_init(&v, fqueue, QLEN, squeue, QLEN, NULL, 0u);
    hal_virtual_set_sinks(&v, count_frames, NULL, NULL, NULL);
    hal_virtual_bind(&v, &hal);
}
void tearDown(void) {}

/* Level and at rest, heading north-ish: gyro 0, gravity up, field north and down. */
static hal_sample_t level(uint16_t seq, uint64_t t_us)
{
    hal_sample_t s;
    memset(&s, 0, sizeof(s));
    s.seq = seq;
    s.t_us = t_us;
    s.rx_us = t_us;
    s.accel[2] = 9.81f;
    s.mag[1] = 25.0f;
    s.mag[2] = -43.0f;
    s.valid = HAL_HAS_ALL;
    return s;
}

static void push_samples(uint16_t seq0, uint64_t t0, int n)
{
    int k;
    for (k = 0; k < n; ++k) {
        const hal_sample_t s = level((uint16_t)(seq0 + k), t0 + PERIOD_US * (uint64_t)k);
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_sample(&v, &s));
    }
}

static void start(const app_settings_t *settings)
{
    const app_hooks_t hooks = {NULL, NULL, collect, NULL};
    app_config_t cfg;
    app_default_config(&cfg);
    cfg.app = *settings;
    TEST_ASSERT_EQUAL_INT(EKF_OK, app_init(&app, &cfg, &hal));
    app_set_hooks(&app, &hooks);
}

/* Polls until the queued input is consumed (end of input) and returns the polls made. */
static int run_to_end(void)
{
    int polls = 0;
    hal_virtual_end(&v);
    while (app_poll(&app, 10000u) != HAL_END) {
        TEST_ASSERT_TRUE(++polls < 100000);
    }
    return polls;
}

static uint32_t counter(app_counter_id_t id)
{
    uint32_t c[APP_CNT_COUNT];
    app_get_counters(&app, c);
    return c[id];
}

static uint16_t flags_since(int first)
{
    uint16_t f = 0u;
    int i;
    for (i = first; i < nout && i < MAXOUT; ++i) {
        f |= outs[i].flags;
    }
    return f;
}

static void test_clean_stream_output_schedule(void)
{
    app_settings_t cfg = app_default_settings;
    int i;
    cfg.output_period_us = 25000u; /* 40 Hz from 100 Hz samples */
    hal_virtual_set_clock(&v, 1000000u); /* no silence before the first sample */
    start(&cfg);
    push_samples(0u, 1000000u, 200);
    run_to_end();
    /* outputs at t0, t0+25ms, ...: samples 0, 3, 5, 8, 10, ... (2.5 samples apart) */
    TEST_ASSERT_EQUAL_INT(80, nout);
    TEST_ASSERT_EQUAL_UINT16(0u, outs[0].seq);
    TEST_ASSERT_EQUAL_UINT16(3u, outs[1].seq);
    TEST_ASSERT_EQUAL_UINT16(5u, outs[2].seq);
    TEST_ASSERT_EQUAL_UINT32(80u, counter(APP_CNT_OUTPUTS));
    TEST_ASSERT_EQUAL_UINT32(200u, counter(APP_CNT_SAMPLES));
    TEST_ASSERT_EQUAL_INT(80 * 5, nframes_out);
    for (i = 0; i < nout; ++i) {
        TEST_ASSERT_EQUAL_UINT16((uint16_t)i, outs[i].index);
        TEST_ASSERT_EQUAL_UINT8(APP_OUT_ATTITUDE, outs[i].kind);
    }
    TEST_ASSERT_EQUAL_HEX16(0u, outs[0].flags); /* first sample: not aligned yet */
    TEST_ASSERT_EQUAL_HEX16(APP_FLAG_ALIGNED, outs[nout - 1].flags);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 0.0f, outs[nout - 1].euler[0]);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 0.0f, outs[nout - 1].euler[1]);
    TEST_ASSERT_FLOAT_WITHIN(0.05f, 0.0f, outs[nout - 1].euler[2]);
    TEST_ASSERT_TRUE(outs[nout - 1].sigma[0] > 0.0f && outs[nout - 1].sigma[0] < 0.1f);
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_GAPS) + counter(APP_CNT_STALE) +
                                     counter(APP_CNT_TIME_ERRORS) + counter(APP_CNT_EKF_REJECTED));
}

static void test_every_sample_with_rate_zero(void)
{
    app_settings_t cfg = app_default_settings;
    cfg.output_period_us = 0u;
    start(&cfg);
    push_samples(0u, 0u, 37);
    run_to_end();
    TEST_ASSERT_EQUAL_INT(37, nout);
}

static void test_gap_is_predicted_across_and_flagged(void)
{
    start(&app_default_settings);
    push_samples(0u, 0u, 50);
    push_samples(55u, 55u * PERIOD_US, 50); /* samples 50..54 missing */
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_GAPS));
    TEST_ASSERT_EQUAL_UINT32(5u, counter(APP_CNT_MISSING));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_REALIGN));
    TEST_ASSERT_EQUAL_UINT16(55u, outs[50].seq); /* the first output after the gap */
    TEST_ASSERT_TRUE((outs[50].flags & APP_FLAG_GAP) != 0u);
    TEST_ASSERT_TRUE((outs[50].flags & APP_FLAG_ALIGNED) != 0u);
    TEST_ASSERT_TRUE((outs[51].flags & APP_FLAG_GAP) == 0u); /* latched for one output */
    TEST_ASSERT_EQUAL_UINT32(100u, counter(APP_CNT_OUTPUTS)); /* 100 Hz: one per sample */
}

static void test_gap_longer_than_dt_max_is_split(void)
{
    /* 1.2 s gap: above the filter's dt_max (0.5 s), below max_gap (2 s) */
    start(&app_default_settings);
    push_samples(0u, 0u, 30);
    push_samples(150u, 149u * PERIOD_US, 30);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_GAPS));
    TEST_ASSERT_EQUAL_UINT32(120u, counter(APP_CNT_MISSING));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_EKF_REJECTED));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_REALIGN));
    TEST_ASSERT_TRUE((app_last_output(&app)->flags & APP_FLAG_ALIGNED) != 0u);
}

static void test_long_gap_restarts_the_filter(void)
{
    int i;
    start(&app_default_settings);
    push_samples(0u, 0u, 30);
    push_samples(30u, 29u * PERIOD_US + 3000000u, 30); /* consecutive seq, 3 s later */
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_REALIGN));
    for (i = 30; i < nout && outs[i].kind == APP_OUT_HEARTBEAT; ++i) {
    } /* heartbeats during the 3 s of silence */
    TEST_ASSERT_TRUE(i > 30);
    TEST_ASSERT_EQUAL_UINT16(30u, outs[i].seq);
    TEST_ASSERT_TRUE((outs[i].flags & APP_FLAG_RESTARTED) != 0u);
    TEST_ASSERT_TRUE((outs[i].flags & APP_FLAG_ALIGNED) == 0u); /* aligning again */
    TEST_ASSERT_TRUE((outs[nout - 1].flags & APP_FLAG_ALIGNED) != 0u);
}

static void test_time_errors_then_resync(void)
{
    hal_sample_t s;
    start(&app_default_settings);
    push_samples(0u, 1000000u, 20);
    s = level(20u, 1000000u + 19u * PERIOD_US); /* same time as sample 19 */
    hal_virtual_push_sample(&v, &s);
    push_samples(21u, 1000000u + 21u * PERIOD_US, 5);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_TIME_ERRORS));
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_GAPS)); /* the dropped one is missing */
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_RESYNC));
    TEST_ASSERT_TRUE((flags_since(0) & APP_FLAG_TIME_ERROR) != 0u);

    /* the sender's clock restarts (time back to 0, sequence continues): the node follows it
     * on the APP_RESTART_CONFIRM-th sample of the new clock; the ones before are dropped */
    setUp();
    start(&app_default_settings);
    push_samples(0u, 5000000u, 20);
    push_samples(20u, 0u, 20);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(APP_RESTART_CONFIRM - 1u, counter(APP_CNT_TIME_ERRORS));
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_RESYNC));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_LATE) + counter(APP_CNT_REALIGN));
    TEST_ASSERT_TRUE((app_last_output(&app)->flags & APP_FLAG_ALIGNED) != 0u);
}

static void test_sequence_restart_resyncs(void)
{
    start(&app_default_settings);
    push_samples(40000u, 0u, 20);
    push_samples(0u, 20u * PERIOD_US, 20); /* counter restarted, time continues */
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_RESYNC));
    TEST_ASSERT_EQUAL_UINT32(APP_RESTART_CONFIRM - 1u, counter(APP_CNT_TIME_ERRORS));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_GAPS));
    TEST_ASSERT_EQUAL_UINT32(40u, counter(APP_CNT_SAMPLES));
}

/* Frames of sample (seq, t) onto the virtual bus; sync_only: its IMU_SYNC frame alone. */
static void push_sample_frames(uint16_t seq, uint64_t t_us, int sync_only)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES];
    const hal_sample_t s = level(seq, t_us);
    const size_t n = dbc_encode_sample(&s, f);
    size_t i;
    TEST_ASSERT_EQUAL_HEX32(0x103u, f[n - 1u].id); /* IMU_SYNC comes last */
    for (i = sync_only ? n - 1u : 0u; i < n; ++i) {
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f[i]));
    }
}

/* One stale IMU_SYNC (sample 99, 3 s old) between samples 399 and 400 of a 100 Hz stream:
 * the CAN assembly drops it as late (more than 64 samples away, not continued); no resync,
 * no re-alignment, no sample missing, the filter stays aligned. */
static void test_one_stale_frame_is_late_not_a_restart(void)
{
    int i;
    uint16_t k;
    start(&app_default_settings);
    for (k = 0; k < 500u; ++k) {
        push_sample_frames(k, PERIOD_US * k, 0);
        if (k == 399u) {
            push_sample_frames(99u, 99u * PERIOD_US, 1);
        }
    }
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_LATE));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_RESYNC) + counter(APP_CNT_REALIGN) + counter(APP_CNT_GAPS) +
                                     counter(APP_CNT_MISSING) + counter(APP_CNT_TIME_ERRORS));
    TEST_ASSERT_EQUAL_UINT32(500u, counter(APP_CNT_SAMPLES));
    TEST_ASSERT_EQUAL_INT(500, nout); /* 100 Hz: one output per stream sample */
    for (i = 20; i < nout; ++i) {
        TEST_ASSERT_EQUAL_UINT16((uint16_t)i, outs[i].seq);
        TEST_ASSERT_TRUE((outs[i].flags & APP_FLAG_ALIGNED) != 0u);
        TEST_ASSERT_TRUE((outs[i].flags & APP_FLAG_RESTARTED) == 0u);
        /* the late frame is flagged on the next output only */
        TEST_ASSERT_EQUAL_INT(i == 400, (outs[i].flags & APP_FLAG_FRAME_ERROR) != 0u);
    }
    TEST_ASSERT_EQUAL_UINT32(1u, app_last_output(&app)->counters[APP_CNT_LATE]);
}

/* A burst of stale samples shorter than APP_RESTART_CONFIRM (consecutive among themselves) is
 * dropped as late too; the stream goes on without a restart. */
static void test_stale_burst_is_late_not_a_restart(void)
{
    start(&app_default_settings);
    push_samples(0u, 0u, 300);
    push_samples(100u, 100u * PERIOD_US, (int)APP_RESTART_CONFIRM - 1); /* 2 s old */
    push_samples(300u, 300u * PERIOD_US, 100);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(APP_RESTART_CONFIRM - 1u, counter(APP_CNT_LATE));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_RESYNC) + counter(APP_CNT_REALIGN) + counter(APP_CNT_MISSING));
    TEST_ASSERT_TRUE((flags_since(0) & APP_FLAG_FRAME_ERROR) != 0u);
    TEST_ASSERT_TRUE((flags_since(0) & APP_FLAG_RESTARTED) == 0u);
}

/* A sensor that really restarts (sequence and clock from 0) is followed after
 * APP_RESTART_CONFIRM samples: the first ones look like stale samples and are dropped. */
static void test_sensor_restart_is_followed_after_confirmation(void)
{
    int i, k, restarted = -1;
    hal_virtual_set_clock(&v, 60000000u); /* no silence before the first sample */
    start(&app_default_settings);
    push_samples(5000u, 60000000u, 100);
    for (k = 0; k < 100; ++k) { /* the sensor's clock restarts, the receiver's goes on */
        hal_sample_t smp = level((uint16_t)k, PERIOD_US * (uint64_t)k);
        smp.rx_us = 61000000u + PERIOD_US * (uint64_t)k;
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_sample(&v, &smp));
    }
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(APP_RESTART_CONFIRM - 1u, counter(APP_CNT_LATE));
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_RESYNC));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_REALIGN) + counter(APP_CNT_TIME_ERRORS));
    for (i = 0; i < nout; ++i) {
        if ((outs[i].flags & APP_FLAG_RESTARTED) != 0u) {
            restarted = i;
            break;
        }
    }
    TEST_ASSERT_TRUE(restarted >= 0);
    /* the first output of the new stream, on the sample that confirmed it */
    TEST_ASSERT_EQUAL_UINT8(APP_OUT_ATTITUDE, outs[restarted].kind);
    TEST_ASSERT_EQUAL_UINT16((uint16_t)(APP_RESTART_CONFIRM - 1u), outs[restarted].seq);
    TEST_ASSERT_EQUAL_INT(100, restarted);
    TEST_ASSERT_EQUAL_UINT16(5099u, outs[restarted - 1].seq);
    TEST_ASSERT_TRUE((outs[restarted].flags & APP_FLAG_ALIGNED) == 0u); /* aligning again */
    TEST_ASSERT_TRUE((outs[nout - 1].flags & APP_FLAG_ALIGNED) != 0u);

    /* two off-stream samples that do not continue each other do not add up to a restart */
    setUp();
    start(&app_default_settings);
    push_samples(5000u, 60000000u, 50);
    push_samples(0u, 0u, 1);
    push_samples(900u, 9000000u, 1);
    push_samples(0u, 1000000u, 1);
    push_samples(5050u, 60000000u + 50u * PERIOD_US, 50);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(3u, counter(APP_CNT_LATE));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_RESYNC) + counter(APP_CNT_MISSING));
}

static void test_stale_input_heartbeats_and_resume(void)
{
    app_settings_t cfg = app_default_settings;
    int i, hb = 0, first_after;
    cfg.stale_timeout_us = 50000u;
    cfg.heartbeat_period_us = 100000u;
    start(&cfg);
    push_samples(0u, 0u, 20);
    /* 1 s of silence, then the stream resumes */
    push_samples(20u, 1190000u, 20);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_STALE));
    for (i = 0; i < nout; ++i) {
        if (outs[i].kind == APP_OUT_HEARTBEAT) {
            ++hb;
            TEST_ASSERT_EQUAL_HEX16(APP_FLAG_HEARTBEAT | APP_FLAG_STALE,
                                    outs[i].flags & (APP_FLAG_HEARTBEAT | APP_FLAG_STALE));
            TEST_ASSERT_EQUAL_UINT16(19u, outs[i].seq); /* the last estimate, repeated */
        }
    }
    /* stale from 0.24 s (0.19 + 0.05) to 1.19 s: heartbeats at 0.24, 0.34, ... 1.14 */
    TEST_ASSERT_EQUAL_INT(10, hb);
    /* heartbeats are not attitude outputs; every sample still gives one (100 Hz) */
    TEST_ASSERT_EQUAL_UINT32(40u, counter(APP_CNT_OUTPUTS));
    TEST_ASSERT_EQUAL_INT(50, nout);
    first_after = 20 + hb;
    TEST_ASSERT_EQUAL_UINT16(20u, outs[first_after].seq);
    TEST_ASSERT_EQUAL_UINT8(APP_OUT_ATTITUDE, outs[first_after].kind);
    TEST_ASSERT_TRUE((outs[first_after].flags & APP_FLAG_STALE) == 0u);
    /* the sequence continued through the silence: no gap, the 1 s was predicted across */
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_GAPS));
    TEST_ASSERT_TRUE((outs[nout - 1].flags & APP_FLAG_ALIGNED) != 0u);
}

static void test_saturated_sensor_is_not_fused(void)
{
    hal_sample_t s;
    start(&app_default_settings);
    push_samples(0u, 0u, 20);
    s = level(20u, 20u * PERIOD_US);
    s.saturated = HAL_HAS_GYRO;
    s.gyro[0] = 32.767f;
    hal_virtual_push_sample(&v, &s);
    push_samples(21u, 21u * PERIOD_US, 5);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_SATURATED));
    TEST_ASSERT_TRUE((flags_since(0) & APP_FLAG_IN_SATURATED) != 0u);
    /* the clamped 32.767 rad/s was not fused: the rate estimate stays near zero */
    TEST_ASSERT_FLOAT_WITHIN(0.05f, 0.0f, app_last_output(&app)->rates[0]);
    /* but the estimator was told, and widened its rate uncertainty for that sample */
    TEST_ASSERT_EQUAL_UINT32(1u, att_diag(&app.ekf)->gyro_saturated);
}

static void test_bad_values_are_rejected_and_counted(void)
{
    hal_sample_t s;
    start(&app_default_settings);
    push_samples(0u, 0u, 20);
    s = level(20u, 20u * PERIOD_US);
    s.accel[1] = NAN;
    hal_virtual_push_sample(&v, &s);
    s = level(21u, 21u * PERIOD_US);
    s.gyro[2] = 1e6f; /* beyond gyro_range */
    hal_virtual_push_sample(&v, &s);
    push_samples(22u, 22u * PERIOD_US, 5);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(2u, counter(APP_CNT_EKF_REJECTED));
    TEST_ASSERT_TRUE((flags_since(0) & APP_FLAG_EKF_REJECT) != 0u);
    /* the filter refused those two samples whole, the node fused them without the bad
     * sensor: a prediction for every sample after the alignment on samples 0-9 */
    TEST_ASSERT_EQUAL_UINT32(2u, att_diag(app_filter(&app))->rejected);
    TEST_ASSERT_EQUAL_UINT32(17u, att_diag(app_filter(&app))->steps);
    TEST_ASSERT_TRUE(isfinite(app_last_output(&app)->euler[0]));
    TEST_ASSERT_TRUE((app_last_output(&app)->flags & APP_FLAG_ALIGNED) != 0u);
}

static void test_link_down_is_counted_and_flagged(void)
{
    int before;
    start(&app_default_settings);
    push_samples(0u, 0u, 10);
    while (v.samples_n > 0u) {
        (void)app_poll(&app, 10000u);
    }
    before = nout;
    hal_virtual_set_link(&v, 0);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_LINK_DOWN, app_poll(&app, 10000u));
    TEST_ASSERT_EQUAL_INT(HAL_EMPTY, app_poll(&app, 10000u));
    hal_virtual_set_link(&v, 1);
    push_samples(10u, 10u * PERIOD_US + 20000u, 10);
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_LINK_DOWN));
    TEST_ASSERT_TRUE(nout > before);
    TEST_ASSERT_TRUE((outs[before].flags & APP_FLAG_LINK_ERROR) != 0u);

    /* a failed publish (bus off, queue full) is counted; its events go with the next one */
    setUp();
    start(&app_default_settings);
    push_samples(0u, 0u, 1);
    (void)app_poll(&app, 10000u);
    TEST_ASSERT_EQUAL_INT(1, nout);
    hal_virtual_set_tx_fail(&v, 1);
    push_samples(2u, 20000u, 1); /* sample 1 missing: the failed output carries GAP */
    TEST_ASSERT_EQUAL_INT(HAL_OK, app_poll(&app, 30000u));
    TEST_ASSERT_EQUAL_INT(1, nout);
    TEST_ASSERT_EQUAL_UINT32(5u, counter(APP_CNT_TX_ERRORS));
    hal_virtual_set_tx_fail(&v, 0);
    push_samples(3u, 30000u, 1);
    run_to_end();
    TEST_ASSERT_EQUAL_INT(2, nout);
    TEST_ASSERT_EQUAL_UINT16(3u, outs[1].seq);
    TEST_ASSERT_TRUE((outs[1].flags & APP_FLAG_LINK_ERROR) != 0u);
    TEST_ASSERT_TRUE((outs[1].flags & APP_FLAG_GAP) != 0u);
    TEST_ASSERT_EQUAL_UINT16(2u, outs[1].index); /* index 1 was the failed one */
}

static void test_frame_errors_reach_the_status(void)
{
    hal_frame_t f[DBC_SAMPLE_FRAMES], junk;
    uint16_t k;
    start(&app_default_settings);
    for (k = 0; k < 20u; ++k) {
        const hal_sample_t s = level(k, 1000u + PERIOD_US * k);
        const size_t n = dbc_encode_sample(&s, f);
        size_t i;
        for (i = 0; i < n; ++i) {
            hal_virtual_push_frame(&v, &f[i]);
        }
        if (k == 10u) {
            junk = f[0];
            junk.dlc = 6u; /* a gyro frame cut short */
            hal_virtual_push_frame(&v, &junk);
        }
    }
    run_to_end();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_BAD_DLC));
    TEST_ASSERT_EQUAL_UINT32(81u, counter(APP_CNT_RX_FRAMES));
    TEST_ASSERT_TRUE((outs[10].flags & APP_FLAG_FRAME_ERROR) == 0u);
    TEST_ASSERT_TRUE((outs[11].flags & APP_FLAG_FRAME_ERROR) != 0u);
    TEST_ASSERT_TRUE((outs[12].flags & APP_FLAG_FRAME_ERROR) == 0u);
}

/* A shared bus: frames of other protocols and nodes (11-bit ids that are not the IMU's, 29-bit
 * DroneCAN frames, the node's own output ids from someone else) between the IMU's are counted
 * as foreign and change nothing: every sample, every output, no status flag, the same attitude
 * as without them. */
static void test_foreign_frames_are_no_errors(void)
{
    static app_output_t clean[MAXOUT];
    static const uint32_t foreign_ids[] = {0x555u, 0x7FFu, 0x180u, 0x104u, 0x0FFu, HAL_FRAME_EXT | 0x18155501u,
                                           HAL_FRAME_EXT | 0x0103E801u, HAL_FRAME_EXT | 0x100u};
    int round, n_clean = 0, i;
    for (round = 0; round < 2; ++round) {
        hal_frame_t f[DBC_SAMPLE_FRAMES];
        uint16_t k;
        setUp();
        start(&app_default_settings);
        for (k = 0; k < 100u; ++k) {
            const hal_sample_t s = level(k, 1000u + PERIOD_US * k);
            const size_t n = dbc_encode_sample(&s, f);
            size_t j;
            for (j = 0; j < n; ++j) {
                TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f[j]));
                if (round == 1) {
                    hal_frame_t x = f[j];
                    x.id = foreign_ids[(k + j) % (sizeof(foreign_ids) / sizeof(foreign_ids[0]))];
                    x.dlc = (uint8_t)((k + j) % 9u);
                    TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &x));
                }
            }
        }
        run_to_end();
        if (round == 0) {
            memcpy(clean, outs, sizeof(clean));
            n_clean = nout;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(400u, counter(APP_CNT_FOREIGN));
    TEST_ASSERT_EQUAL_UINT32(800u, counter(APP_CNT_RX_FRAMES));
    TEST_ASSERT_EQUAL_UINT32(100u, counter(APP_CNT_SAMPLES));
    TEST_ASSERT_EQUAL_INT(n_clean, nout);
    for (i = 0; i < nout; ++i) {
        TEST_ASSERT_EQUAL_HEX16(clean[i].flags, outs[i].flags);
        TEST_ASSERT_EQUAL_MEMORY(clean[i].euler, outs[i].euler, sizeof(outs[i].euler));
        TEST_ASSERT_TRUE((outs[i].flags & APP_FLAG_FRAME_ERROR) == 0u);
    }
}

static void test_replay_is_deterministic(void)
{
    static app_output_t first[MAXOUT];
    int n1, i, round;
    for (round = 0; round < 2; ++round) {
        hal_frame_t f[DBC_SAMPLE_FRAMES];
        uint16_t k;
        setUp();
        start(&app_default_settings);
        for (k = 0; k < 300u; ++k) {
            hal_sample_t s = level(k, 5000u * k);
            size_t n, j;
            s.gyro[0] = 0.3f * sinf(0.05f * (float)k);
            s.accel[1] = 0.5f * cosf(0.03f * (float)k);
            n = dbc_encode_sample(&s, f);
            for (j = 0; j < n; ++j) {
                f[j].t_us = s.t_us;
                TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f[j]));
            }
        }
        run_to_end();
        if (round == 0) {
            memcpy(first, outs, sizeof(first));
            n1 = nout;
        }
    }
    TEST_ASSERT_EQUAL_INT(n1, nout);
    for (i = 0; i < nout; ++i) {
        TEST_ASSERT_EQUAL_MEMORY(first[i].euler, outs[i].euler, sizeof(outs[i].euler));
        TEST_ASSERT_EQUAL_MEMORY(first[i].sigma, outs[i].sigma, sizeof(outs[i].sigma));
        TEST_ASSERT_EQUAL_UINT16(first[i].flags, outs[i].flags);
    }
}

static void test_init_refuses_bad_settings(void)
{
    app_config_t cfg;
    hal_t broken = {NULL, NULL};
    app_default_config(&cfg);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, app_init(&app, &cfg, &broken));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, app_init(NULL, &cfg, &hal));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, app_init(&app, NULL, &hal));
    cfg.app.stale_timeout_us = 0u;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, app_init(&app, &cfg, &hal));
    app_default_config(&cfg);
    cfg.app.seq_window = 40000u;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, app_init(&app, &cfg, &hal));
    app_default_config(&cfg);
    cfg.app.max_gap_us = 60000000u;
    cfg.att.dt_max = EKF_C(0.01); /* 6000 prediction steps for the longest gap: refused */
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, app_init(&app, &cfg, &hal));
    app_default_config(&cfg);
    cfg.att.gyro_noise = EKF_C(-1.0);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, app_init(&app, &cfg, &hal));
    app_default_config(&cfg);
    cfg.node.node_id = 0u;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, app_init(&app, &cfg, &hal));
    app_default_config(&cfg);
    cfg.node.dbc_base = 0x102u; /* on the IMU's ids */
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, app_init(&app, &cfg, &hal));
    app_default_config(&cfg);
    cfg.node.protocol = 3u;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, app_init(&app, &cfg, &hal));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_ARG, app_poll(NULL, 0u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_clean_stream_output_schedule);
    RUN_TEST(test_every_sample_with_rate_zero);
    RUN_TEST(test_gap_is_predicted_across_and_flagged);
    RUN_TEST(test_gap_longer_than_dt_max_is_split);
    RUN_TEST(test_long_gap_restarts_the_filter);
    RUN_TEST(test_time_errors_then_resync);
    RUN_TEST(test_sequence_restart_resyncs);
    RUN_TEST(test_one_stale_frame_is_late_not_a_restart);
    RUN_TEST(test_stale_burst_is_late_not_a_restart);
    RUN_TEST(test_sensor_restart_is_followed_after_confirmation);
    RUN_TEST(test_stale_input_heartbeats_and_resume);
    RUN_TEST(test_saturated_sensor_is_not_fused);
    RUN_TEST(test_bad_values_are_rejected_and_counted);
    RUN_TEST(test_link_down_is_counted_and_flagged);
    RUN_TEST(test_frame_errors_reach_the_status);
    RUN_TEST(test_foreign_frames_are_no_errors);
    RUN_TEST(test_replay_is_deterministic);
    RUN_TEST(test_init_refuses_bad_settings);
    return UNITY_END();
}
