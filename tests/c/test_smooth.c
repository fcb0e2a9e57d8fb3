/*
 * test_smooth.c - the attitude smoother of the host tools (host_tools/native/smooth_att.c) on
 * simulated recordings with known truth, for the float, double and fixed-point filters:
 *   - memory: any segment length gives the same outputs, bit for bit (the recomputed
 *     segments retrace the forward pass exactly);
 *   - the smoothed attitude is closer to the truth than the filter's (white sensor noise,
 *     where the smoother's model holds);
 *   - a heading reset is not smoothed across: the heading before it stays the filter's;
 *   - a refused sample belongs to the epoch before it; no estimate before alignment;
 *   - a saturated gyroscope cuts the rates; the progress callback can stop the run.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core_io.h"
#include "smooth_att.h"
#include "testsim.h"
#include "unity.h"

#define RATE_HZ 100.0
#define NMAX 6000
#define DEG (3.14159265358979323846 / 180.0)

void setUp(void) {}
void tearDown(void) {}

/* A recording and the outputs of one run over it. */
typedef struct {
    size_t n;
    double dt[NMAX], gyr[3 * NMAX], acc[3 * NMAX], mag[3 * NMAX];
    double truth[3 * NMAX]; /* true Euler angles, rad */
    uint8_t saturated[NMAX];
} rec_t;

typedef struct {
    double state[9 * NMAX], var[9 * NMAX], quat[4 * NMAX], euler[3 * NMAX], cov[6 * NMAX], bias[3 * NMAX],
        bias_sigma[3 * NMAX];
    uint32_t flags[NMAX];
    uint8_t status[CORE_STATUS_COLS * NMAX];
    smooth_report_t rep;
    att_diag_t diag;
} out_t;

static rec_t g_rec;
static out_t g_a, g_b;
static att_trace_t g_trace[NMAX];
static size_t g_trace_sample[NMAX];
static uint8_t g_trace_event[NMAX];
static att_ekf_t g_ckpt[NMAX];

/* The benchmark's tumble after 3 s at rest, white noise; from rot_at on the earth's field is
 * turned by rot_deg about the vertical (an undisturbed field in another direction: the filter
 * gates it, then resets its heading). */
static void make_recording(rec_t *r, size_t n, double rot_at, double rot_deg)
{
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    size_t i, k;
    ts_sim_default(&cfg);
    cfg.dt = 1.0 / RATE_HZ;
    ts_sim_init(&sim, &cfg, 7u, TS_BENCH_PHI, TS_BENCH_THETA, TS_BENCH_PSI);
    r->n = n;
    for (i = 0; i < n; ++i) {
        att_sample_t s;
        double w[3] = {0.0, 0.0, 0.0}, e[3];
        const double t = (double)i / RATE_HZ;
        if (t > 3.0) {
            ts_bench_motion(t - 3.0, w);
        }
        ts_sim_step(&sim, w, NULL, &s);
        r->dt[i] = 1.0 / RATE_HZ;
        for (k = 0; k < 3; ++k) {
            r->gyr[3 * i + k] = ekf_to_double(s.gyro[k]);
            r->acc[3 * i + k] = ekf_to_double(s.accel[k]);
            r->mag[3 * i + k] = ekf_to_double(s.mag[k]);
        }
        if (t >= rot_at) {
            /* body = R^T Rz(a) m_earth */
            const double a = rot_deg * DEG, me[3] = {-sin(a) * cfg.mag_h, cos(a) * cfg.mag_h, -cfg.mag_v};
            for (k = 0; k < 3; ++k) {
                r->mag[3 * i + k] = sim.R[0 * 3 + k] * me[0] + sim.R[1 * 3 + k] * me[1] + sim.R[2 * 3 + k] * me[2];
            }
        }
        ts_sim_euler(&sim, e);
        memcpy(&r->truth[3 * i], e, sizeof e);
        r->saturated[i] = 0;
    }
}

static core_run_io_t io_of(const rec_t *r, out_t *o)
{
    core_run_io_t io;
    io.dt = r->dt;
    io.gyr = r->gyr;
    io.acc = r->acc;
    io.mag = r->mag;
    io.state = o->state;
    io.var = o->var;
    io.quat = o->quat;
    io.euler = o->euler;
    io.cov = o->cov;
    io.bias = o->bias;
    io.bias_sigma = o->bias_sigma;
    io.flags = o->flags;
    io.status = o->status;
    return io;
}

typedef struct {
    size_t calls, done, stop_after;
} progress_t;

static int on_progress(void *ctx, size_t done)
{
    progress_t *p = (progress_t *)ctx;
    p->calls++;
    p->done += done;
    return p->stop_after > 0 && p->done >= p->stop_after;
}

/* The smoother over r in segments of seg_len (ned: NED outputs); returns smooth_run's value. */
static int smooth(const rec_t *r, out_t *o, size_t seg_len, int ned, progress_t *p)
{
    att_ekf_t f;
    core_frame_t fr;
    smooth_buffers_t b;
    core_run_io_t io = io_of(r, o);
    int st;
    memset(&fr, 0, sizeof fr);
    fr.ned = ned;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    TEST_ASSERT_TRUE(smooth_checkpoints(r->n, seg_len) <= NMAX);
    b.seg_len = seg_len;
    b.trace = g_trace;
    b.trace_sample = g_trace_sample;
    b.trace_event = g_trace_event;
    b.ckpt = g_ckpt;
    st = smooth_run(&f, &fr, r->n, &io, &b, (p != NULL) ? on_progress : NULL, p, &o->rep);
    o->diag = *att_diag(&f);
    return st;
}

/* The filter alone over r: its Euler angles (ENU) into euler. */
static void filter_only(const rec_t *r, double *euler, uint32_t *flags)
{
    att_ekf_t f;
    core_frame_t fr;
    size_t i;
    memset(&fr, 0, sizeof fr);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    for (i = 0; i < r->n; ++i) {
        att_sample_t s;
        double q[4];
        core_sample(&fr, r->dt[i], &r->gyr[3 * i], &r->acc[3 * i], &r->mag[3 * i], &s);
        (void)att_step(&f, &s, NULL);
        core_attitude(&fr, &f, q, &euler[3 * i]);
        flags[i] = att_flags(&f);
    }
}

static double wrap(double a) { return atan2(sin(a), cos(a)); }

/* RMS over samples [i0, i1) of the angle k's error (rad). */
static double rms_error(const rec_t *r, const double *euler, size_t i0, size_t i1, size_t k)
{
    double s = 0.0;
    size_t i;
    for (i = i0; i < i1; ++i) {
        const double d = wrap(euler[3 * i + k] - r->truth[3 * i + k]);
        s += d * d;
    }
    return sqrt(s / (double)(i1 - i0));
}

static void test_segments_give_the_same_outputs(void)
{
    make_recording(&g_rec, 3000, 1e9, 0.0);
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_a, g_rec.n, 0, NULL));
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_b, 97, 0, NULL));
    TEST_ASSERT_EQUAL_UINT32(0, g_a.rep.recomputed);
    TEST_ASSERT_EQUAL_UINT32(97 * (3000 / 97), g_b.rep.recomputed);
    TEST_ASSERT_EQUAL_MEMORY(g_a.quat, g_b.quat, sizeof(double) * 4 * g_rec.n);
    TEST_ASSERT_EQUAL_MEMORY(g_a.cov, g_b.cov, sizeof(double) * 6 * g_rec.n);
    TEST_ASSERT_EQUAL_MEMORY(g_a.state, g_b.state, sizeof(double) * 9 * g_rec.n);
    TEST_ASSERT_EQUAL_MEMORY(g_a.flags, g_b.flags, sizeof(uint32_t) * g_rec.n);
    TEST_ASSERT_EQUAL_UINT32(g_a.rep.epochs, g_b.rep.epochs);
    TEST_ASSERT_EQUAL_UINT32(g_a.diag.steps, g_a.rep.epochs);
}

static void test_smoothed_attitude_closer_to_the_truth(void)
{
    static double fe[3 * NMAX];
    static uint32_t ff[NMAX];
    double ef[3], es[3];
    size_t k;
    make_recording(&g_rec, 6000, 1e9, 0.0);
    filter_only(&g_rec, fe, ff);
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_a, g_rec.n, 0, NULL));
    TEST_ASSERT_EQUAL_MEMORY(ff, g_a.flags, sizeof(uint32_t) * g_rec.n); /* the same filter forward */
    for (k = 0; k < 3; ++k) {
        ef[k] = rms_error(&g_rec, fe, 500, g_rec.n - 100, k);
        es[k] = rms_error(&g_rec, g_a.euler, 500, g_rec.n - 100, k);
    }
    printf("RMS error roll/pitch/yaw, deg: filter %.4f/%.4f/%.4f, smoothed %.4f/%.4f/%.4f\n", ef[0] / DEG,
           ef[1] / DEG, ef[2] / DEG, es[0] / DEG, es[1] / DEG, es[2] / DEG);
    for (k = 0; k < 3; ++k) {
        TEST_ASSERT_TRUE(es[k] < 0.9 * ef[k]);
    }
    TEST_ASSERT_EQUAL_UINT32(0, g_a.rep.heading_cuts);
    TEST_ASSERT_EQUAL_UINT32(0, g_a.rep.not_pd);
}

/* The field turns by 120 deg at 20 s: the filter gates it, then resets its heading to it; the
 * smoothed heading before the reset is the filter's, not shifted by the jump. */
static void test_heading_reset_is_not_smoothed_across(void)
{
    static double fe[3 * NMAX];
    static uint32_t ff[NMAX];
    size_t i, reset = 0;
    double worst = 0.0;
    make_recording(&g_rec, 4000, 20.0, 120.0);
    filter_only(&g_rec, fe, ff);
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_a, g_rec.n, 0, NULL));
    TEST_ASSERT_TRUE(g_a.diag.heading_resets >= 1u);
    TEST_ASSERT_TRUE(g_a.rep.heading_cuts >= g_a.diag.heading_resets);
    for (i = 2000; i < g_rec.n && reset == 0; ++i) {
        if (fabs(wrap(fe[3 * i + 2] - fe[3 * (i - 1) + 2])) > 30.0 * DEG) {
            reset = i;
        }
    }
    TEST_ASSERT_TRUE(reset > 2000);
    for (i = 500; i + 10 < reset; ++i) {
        worst = fmax(worst, fabs(wrap(g_a.euler[3 * i + 2] - fe[3 * i + 2])));
    }
    printf("heading reset at %.2f s; smoothed heading before it within %.3f deg of the filter's\n",
           (double)reset / RATE_HZ, worst / DEG);
    TEST_ASSERT_TRUE(worst < 1.0 * DEG);
    /* after it, the heading is the new field's */
    TEST_ASSERT_TRUE(fabs(wrap(g_a.euler[3 * (g_rec.n - 1) + 2] - fe[3 * (g_rec.n - 1) + 2])) < 5.0 * DEG);
}

static void test_refused_sample_and_alignment(void)
{
    size_t i;
    int k;
    make_recording(&g_rec, 1500, 1e9, 0.0);
    g_rec.gyr[3 * 800] = (double)NAN; /* refused by the filter */
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_a, g_rec.n, 0, NULL));
    TEST_ASSERT_TRUE(g_a.status[CORE_STATUS_COLS * 800 + CORE_STATUS_STEP] != EKF_OK);
    for (k = 0; k < 4; ++k) {
        TEST_ASSERT_EQUAL_DOUBLE(g_a.quat[4 * 799 + k], g_a.quat[4 * 800 + k]);
    }
    for (k = 0; k < 6; ++k) {
        TEST_ASSERT_EQUAL_DOUBLE(g_a.cov[6 * 799 + k], g_a.cov[6 * 800 + k]);
    }
    for (i = 0; i < g_rec.n; ++i) {
        if ((g_a.flags[i] & ATT_FLAG_ALIGNED) == 0u) {
            TEST_ASSERT_TRUE(isnan(g_a.quat[4 * i]));
            TEST_ASSERT_TRUE(isinf(g_a.cov[6 * i]));
        } else {
            TEST_ASSERT_TRUE(g_a.cov[6 * i] > 0.0 && isfinite(g_a.cov[6 * i + 2]));
        }
    }
    TEST_ASSERT_FALSE((g_a.flags[0] & ATT_FLAG_ALIGNED) != 0u);
}

static void test_ned_outputs_are_the_enu_ones_turned(void)
{
    size_t i;
    make_recording(&g_rec, 1500, 1e9, 0.0);
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_a, g_rec.n, 0, NULL));
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_b, g_rec.n, 1, NULL));
    for (i = 20; i < g_rec.n; ++i) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, -g_a.euler[3 * i + 1], g_b.euler[3 * i + 1]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, wrap(g_b.euler[3 * i + 2] - (0.5 * 3.14159265358979323846 - g_a.euler[3 * i + 2])));
        TEST_ASSERT_DOUBLE_WITHIN(1e-18, -g_a.cov[6 * i + 3], g_b.cov[6 * i + 3]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-18, g_a.cov[6 * i + 5], g_b.cov[6 * i + 5]);
    }
}

static void test_progress_counts_and_stops(void)
{
    progress_t p = {0, 0, 0};
    make_recording(&g_rec, 3000, 1e9, 0.0);
    TEST_ASSERT_EQUAL_INT(0, smooth(&g_rec, &g_a, 500, 0, &p));
    TEST_ASSERT_EQUAL_size_t(2 * g_rec.n, p.done);
    p.calls = p.done = 0;
    p.stop_after = 1;
    TEST_ASSERT_EQUAL_INT(1, smooth(&g_rec, &g_a, 500, 0, &p));
    TEST_ASSERT_EQUAL_size_t(1, p.calls);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_segments_give_the_same_outputs);
    RUN_TEST(test_smoothed_attitude_closer_to_the_truth);
    RUN_TEST(test_heading_reset_is_not_smoothed_across);
    RUN_TEST(test_refused_sample_and_alignment);
    RUN_TEST(test_ned_outputs_are_the_enu_ones_turned);
    RUN_TEST(test_progress_counts_and_stops);
    return UNITY_END();
}
