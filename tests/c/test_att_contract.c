/*
 * test_att_contract.c - the contract of every public call of the filter (att.h): a call
 * either succeeds or leaves the whole filter, byte for byte, as it was except its one error
 * counter (diag.rejected for bad input, diag.numeric for EKF_ERR_NUMERIC; att_init and a
 * NULL filter: nothing at all). Drives every error path of every public function and of
 * every stage of att_step from three filter states (fresh, aligning, aligned after motion):
 * NULL pointers, non-finite and out-of-range values in each component of each sensor, bad
 * time steps, calls before the alignment, bad and unrepresentable settings, and numeric
 * failures forced in the middle of a stage (a covariance made indefinite or infinite through
 * att_cov.h, rates so large that the transition overflows). Built for float, double and
 * fixed point.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att.h"
#include "att_cov.h"
#include "att_state.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

typedef enum { CNT_NONE, CNT_REJECTED, CNT_NUMERIC } counter_t;

static att_ekf_t g_before;
static int g_paths;

static void check_refused(const att_ekf_t *f, ekf_status_t got, ekf_status_t want, counter_t c, int line)
{
    static att_ekf_t expect;
    char msg[64];
    snprintf(msg, sizeof msg, "call at line %d", line);
    TEST_ASSERT_EQUAL_INT_MESSAGE(want, got, msg);
    memcpy(&expect, &g_before, sizeof expect);
    if (c == CNT_REJECTED) {
        ++expect.vars.diag.rejected;
    } else if (c == CNT_NUMERIC) {
        ++expect.vars.diag.numeric;
    }
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(&expect, f, sizeof expect, msg);
    ++g_paths;
}

/* call, with f copied just before it, must return want and change nothing but counter c */
#define REFUSED(f, call, want, c)                                                                  \
    do {                                                                                           \
        memcpy(&g_before, (f), sizeof g_before);                                                   \
        check_refused((f), (call), (want), (c), __LINE__);                                         \
    } while (0)

static ekf_scalar_t nan_s(void) { return ekf_from_double((double)NAN); }
static ekf_scalar_t inf_s(double sign) { return ekf_from_double(sign * (double)INFINITY); }

/* ---- filter states ---- */

static void fresh(att_ekf_t *f) { TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(f, &att_default_settings)); }

static void sample_at_rest(ts_sim_t *sim, att_sample_t *smp)
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    ts_sim_step(sim, zero, NULL, smp);
}

/* part of the alignment average collected */
static void aligning(att_ekf_t *f, ts_sim_t *sim)
{
    ts_sim_cfg_t cfg;
    att_sample_t smp;
    int k;
    ts_sim_default(&cfg);
    ts_sim_init(sim, &cfg, 21, 0.2, -0.3, 1.0);
    fresh(f);
    for (k = 0; k < 4; ++k) {
        sample_at_rest(sim, &smp);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_step(f, &smp, NULL));
    }
    TEST_ASSERT_FALSE(att_flags(f) & ATT_FLAG_ALIGNED);
}

/* aligned, 2 s at rest (the rest detector and gyro offset), 1 s of rotation (low-pass,
 * gate clocks, correlations) */
static void aligned(att_ekf_t *f, ts_sim_t *sim)
{
    static const double w[3] = {0.3, -0.2, 0.5};
    att_sample_t smp;
    int k;
    aligning(f, sim);
    for (k = 0; k < 300; ++k) {
        if (k < 200) {
            sample_at_rest(sim, &smp);
        } else {
            ts_sim_step(sim, w, NULL, &smp);
        }
        {
            const ekf_status_t st = att_step(f, &smp, NULL);
            TEST_ASSERT_TRUE(st == EKF_OK || st == EKF_GATED || st == EKF_SKIPPED);
        }
    }
    TEST_ASSERT_TRUE(att_flags(f) & ATT_FLAG_ALIGNED);
}

/* ---- bad vectors ---- */

/* Every bad form of a 3-vector: NULL, NaN / +Inf / -Inf in each component, each component
 * beyond +-range. vec(k) returns the k-th bad vector (NULL for k = 0) and its status. */
#define N_BAD_VEC (1 + 3 * 3 + 3 * 2)
static const ekf_scalar_t *bad_vec(int k, const ekf_scalar_t good[3], ekf_scalar_t range, ekf_scalar_t out[3],
                                   ekf_status_t *st)
{
    int c;
    if (k == 0) {
        *st = EKF_ERR_NULL;
        return NULL;
    }
    memcpy(out, good, 3 * sizeof out[0]);
    --k;
    if (k < 9) {
        c = k / 3;
        out[c] = (k % 3 == 0) ? nan_s() : (k % 3 == 1) ? inf_s(1.0) : inf_s(-1.0);
        *st = EKF_ERR_NOT_FINITE;
        return out;
    }
    k -= 9;
    c = k / 2;
    out[c] = (k % 2 == 0) ? ekf_mul(range, EKF_C(1.01)) : ekf_neg(ekf_mul(range, EKF_C(1.01)));
    *st = EKF_ERR_RANGE;
    return out;
}

static void expect_report(const att_step_report_t *rep, ekf_status_t predict, ekf_status_t gyro, ekf_status_t accel,
                          ekf_status_t mag)
{
    TEST_ASSERT_EQUAL_INT(predict, rep->predict);
    TEST_ASSERT_EQUAL_INT(gyro, rep->gyro);
    TEST_ASSERT_EQUAL_INT(accel, rep->accel);
    TEST_ASSERT_EQUAL_INT(mag, rep->mag);
}

/* ---- the error paths of each public function, from one filter state ---- */

static void align_errors(att_ekf_t *f, const att_sample_t *good)
{
    const att_settings_t *s = &f->settings;
    const ekf_scalar_t zero[3] = {EKF_C(0), EKF_C(0), EKF_C(0)};
    ekf_scalar_t buf[3];
    ekf_status_t want;
    int k;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_align(NULL, good->accel, good->mag));
    for (k = 0; k < N_BAD_VEC; ++k) {
        const ekf_scalar_t *v = bad_vec(k, good->accel, s->accel_range, buf, &want);
        REFUSED(f, att_align(f, v, good->mag), want, CNT_REJECTED);
        if (k > 0) {
            v = bad_vec(k, good->mag, s->mag_range, buf, &want);
            REFUSED(f, att_align(f, good->accel, v), want, CNT_REJECTED);
        }
    }
    /* free fall: no gravity direction */
    REFUSED(f, att_align(f, zero, NULL), EKF_ERR_RANGE, CNT_REJECTED);
}

static void stage_errors(att_ekf_t *f, const att_sample_t *good)
{
    const att_settings_t *s = &f->settings;
    const int is_aligned = (att_flags(f) & ATT_FLAG_ALIGNED) != 0u;
    const ekf_scalar_t dts[6] = {EKF_C(0), EKF_C(-0.01), nan_s(), inf_s(1.0), inf_s(-1.0), ekf_mul(s->dt_max, EKF_C(1.01))};
    const ekf_status_t dt_st[6] = {EKF_ERR_DT_NONPOSITIVE, EKF_ERR_DT_NONPOSITIVE, EKF_ERR_NOT_FINITE,
                                   EKF_ERR_NOT_FINITE, EKF_ERR_NOT_FINITE, EKF_ERR_DT_TOO_LARGE};
    ekf_scalar_t buf[3];
    ekf_status_t want;
    int k;

    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_predict(NULL, good->dt));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_update_gyro(NULL, good->gyro, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_update_accel(NULL, good->accel, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_update_mag(NULL, good->mag, EKF_C(0.01)));
    if (!is_aligned) {
        REFUSED(f, att_predict(f, good->dt), EKF_ERR_NOT_INITIALISED, CNT_REJECTED);
        REFUSED(f, att_update_gyro(f, good->gyro, EKF_C(0.01)), EKF_ERR_NOT_INITIALISED, CNT_REJECTED);
        REFUSED(f, att_update_accel(f, good->accel, EKF_C(0.01)), EKF_ERR_NOT_INITIALISED, CNT_REJECTED);
        REFUSED(f, att_update_mag(f, good->mag, EKF_C(0.01)), EKF_ERR_NOT_INITIALISED, CNT_REJECTED);
        REFUSED(f, att_update_mag(f, NULL, EKF_C(0.01)), EKF_ERR_NOT_INITIALISED, CNT_REJECTED);
        return;
    }
    for (k = 0; k < 6; ++k) {
        REFUSED(f, att_predict(f, dts[k]), dt_st[k], CNT_REJECTED);
    }
    for (k = 0; k < N_BAD_VEC; ++k) {
        const ekf_scalar_t *v = bad_vec(k, good->gyro, s->gyro_range, buf, &want);
        REFUSED(f, att_update_gyro(f, v, EKF_C(0.01)), want, CNT_REJECTED);
        v = bad_vec(k, good->accel, s->accel_range, buf, &want);
        if (want != EKF_ERR_RANGE) { /* (beyond the range: clipped, not refused; test_att_filter) */
            REFUSED(f, att_update_accel(f, v, EKF_C(0.01)), want, CNT_REJECTED);
        }
        v = bad_vec(k, good->mag, s->mag_range, buf, &want);
        REFUSED(f, att_update_mag(f, v, EKF_C(0.01)), want, CNT_REJECTED);
    }
}

/* att_step with one bad input in an otherwise good sample: refused whole, the report names
 * the input at fault and skips every stage */
static void step_errors(att_ekf_t *f, const att_sample_t *good)
{
    const att_settings_t *s = &f->settings;
    const int is_aligned = (att_flags(f) & ATT_FLAG_ALIGNED) != 0u;
    const ekf_status_t SK = EKF_SKIPPED;
    att_step_report_t rep;
    att_sample_t smp;
    ekf_status_t want;
    int k, sensor;

    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_step(NULL, good, &rep));
    expect_report(&rep, EKF_ERR_NULL, EKF_ERR_NULL, EKF_ERR_NULL, EKF_ERR_NULL);
    REFUSED(f, att_step(f, NULL, &rep), EKF_ERR_NULL, CNT_REJECTED);
    REFUSED(f, att_step(f, NULL, NULL), EKF_ERR_NULL, CNT_REJECTED);
    if (is_aligned) {
        const ekf_scalar_t dts[5] = {EKF_C(0), EKF_C(-1), nan_s(), inf_s(1.0), ekf_mul(s->dt_max, EKF_C(2))};
        const ekf_status_t dt_st[5] = {EKF_ERR_DT_NONPOSITIVE, EKF_ERR_DT_NONPOSITIVE, EKF_ERR_NOT_FINITE,
                                       EKF_ERR_NOT_FINITE, EKF_ERR_DT_TOO_LARGE};
        for (k = 0; k < 5; ++k) {
            smp = *good;
            smp.dt = dts[k];
            REFUSED(f, att_step(f, &smp, &rep), dt_st[k], CNT_REJECTED);
            expect_report(&rep, dt_st[k], SK, SK, SK);
        }
    } else {
        /* nothing to align on */
        smp = *good;
        smp.valid = ATT_HAS_GYRO | ATT_HAS_MAG;
        REFUSED(f, att_step(f, &smp, &rep), EKF_ERR_NOT_INITIALISED, CNT_REJECTED);
        expect_report(&rep, SK, SK, EKF_ERR_NOT_INITIALISED, SK);
    }
    /* each sensor (NULL is not possible in a sample: its vectors are arrays) */
    for (sensor = 0; sensor < 3; ++sensor) {
        for (k = 1; k < N_BAD_VEC; ++k) {
            ekf_scalar_t buf[3];
            smp = *good;
            if (sensor == 0) {
                memcpy(smp.gyro, bad_vec(k, good->gyro, s->gyro_range, buf, &want), sizeof buf);
            } else if (sensor == 1) {
                memcpy(smp.accel, bad_vec(k, good->accel, s->accel_range, buf, &want), sizeof buf);
                if (want == EKF_ERR_RANGE) {
                    continue; /* clipped, not refused: test_att_filter */
                }
            } else {
                memcpy(smp.mag, bad_vec(k, good->mag, s->mag_range, buf, &want), sizeof buf);
            }
            REFUSED(f, att_step(f, &smp, &rep), want, CNT_REJECTED);
            expect_report(&rep, SK, sensor == 0 ? want : SK, sensor == 1 ? want : SK, sensor == 2 ? want : SK);
            /* a saturated gyro's vector is checked too */
            if (sensor == 0) {
                smp.valid = (uint8_t)((smp.valid & ~ATT_HAS_GYRO) | ATT_GYRO_SATURATED);
                REFUSED(f, att_step(f, &smp, &rep), want, CNT_REJECTED);
                expect_report(&rep, SK, want, SK, SK);
            }
        }
    }
    /* two bad inputs: the first in the order predict, gyro, accel, mag is returned, both named */
    smp = *good;
    smp.accel[0] = nan_s();
    smp.mag[2] = ekf_mul(s->mag_range, EKF_C(2));
    REFUSED(f, att_step(f, &smp, &rep), EKF_ERR_NOT_FINITE, CNT_REJECTED);
    expect_report(&rep, SK, SK, EKF_ERR_NOT_FINITE, EKF_ERR_RANGE);
}

static void all_input_errors(att_ekf_t *f, const att_sample_t *good)
{
    align_errors(f, good);
    stage_errors(f, good);
    step_errors(f, good);
}

static void test_input_errors_change_nothing(void)
{
    static att_ekf_t f;
    ts_sim_t sim;
    att_sample_t good;
    int before;

    fresh(&f);
    {
        ts_sim_cfg_t cfg;
        ts_sim_default(&cfg);
        ts_sim_init(&sim, &cfg, 5, 0.1, 0.2, -0.5);
        sample_at_rest(&sim, &good);
    }
    before = g_paths;
    all_input_errors(&f, &good);
    printf("fresh filter: %d refused calls checked\n", g_paths - before);

    aligning(&f, &sim);
    sample_at_rest(&sim, &good);
    before = g_paths;
    all_input_errors(&f, &good);
    printf("aligning filter: %d refused calls checked\n", g_paths - before);
    /* while aligning dt is not an input: a sample with a bad one is applied (and the rest
     * detector skips it) */
    {
        att_sample_t smp = good;
        smp.dt = nan_s();
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_step(&f, &smp, NULL));
    }

    aligned(&f, &sim);
    sample_at_rest(&sim, &good);
    before = g_paths;
    all_input_errors(&f, &good);
    printf("aligned filter: %d refused calls checked\n", g_paths - before);
    /* at rest (ATT_FLAG_AT_REST, the offset being learned): a bad dt neither clears the flag
     * nor feeds the rest detector */
    {
        att_sample_t smp;
        att_step_report_t rep;
        int k;
        for (k = 0; k < 300 && (att_flags(&f) & ATT_FLAG_AT_REST) == 0u; ++k) {
            sample_at_rest(&sim, &smp);
            (void)att_step(&f, &smp, NULL);
        }
        TEST_ASSERT_TRUE(att_flags(&f) & ATT_FLAG_AT_REST);
        sample_at_rest(&sim, &smp);
        smp.dt = EKF_C(0);
        REFUSED(&f, att_step(&f, &smp, &rep), EKF_ERR_DT_NONPOSITIVE, CNT_REJECTED);
        smp.dt = nan_s();
        REFUSED(&f, att_step(&f, &smp, &rep), EKF_ERR_NOT_FINITE, CNT_REJECTED);
        TEST_ASSERT_TRUE(att_flags(&f) & ATT_FLAG_AT_REST);
        sample_at_rest(&sim, &good);
    }
    /* a bad vector of an absent sensor is not an input */
    {
        att_sample_t smp = good;
        ekf_status_t st;
        smp.mag[0] = nan_s();
        smp.valid &= (uint8_t)~ATT_HAS_MAG;
        st = att_step(&f, &smp, NULL);
        TEST_ASSERT_TRUE(st == EKF_OK || st == EKF_GATED);
    }
}

/* ---- numeric failures forced in the middle of a stage ---- */

static void test_numeric_failures_discard_the_whole_call(void)
{
    static att_ekf_t f;
    ts_sim_t sim;
    att_sample_t good, smp;
    att_step_report_t rep;
    const ekf_status_t SK = EKF_SKIPPED, NU = EKF_ERR_NUMERIC;
    int before;

    aligned(&f, &sim);
    sample_at_rest(&sim, &good);
    before = g_paths;

    /* (a) a heading variance of -1 (P indefinite), set through the covariance interface:
     * every update refuses (no floor hides it), and so does the guard after a prediction */
    att_cov_reset_state(&f.vars.cov, ATT_PSI, EKF_C(-1));
    REFUSED(&f, att_update_gyro(&f, good.gyro, EKF_C(0.01)), NU, CNT_NUMERIC);
    REFUSED(&f, att_update_accel(&f, good.accel, EKF_C(0.01)), NU, CNT_NUMERIC);
    REFUSED(&f, att_update_mag(&f, good.mag, EKF_C(0.01)), NU, CNT_NUMERIC);
    REFUSED(&f, att_predict(&f, good.dt), NU, CNT_NUMERIC);
    /* att_step: at the first stage (gyro), in the middle of the step (the accelerometer,
     * after the prediction ran on the working copy), at the last one (the magnetometer), and
     * at the guard (prediction only) */
    REFUSED(&f, att_step(&f, &good, &rep), NU, CNT_NUMERIC);
    expect_report(&rep, SK, NU, SK, SK);
    smp = good;
    smp.valid = ATT_HAS_ACCEL | ATT_HAS_MAG;
    REFUSED(&f, att_step(&f, &smp, &rep), NU, CNT_NUMERIC);
    expect_report(&rep, SK, SK, NU, SK);
    smp.valid = ATT_HAS_MAG;
    REFUSED(&f, att_step(&f, &smp, &rep), NU, CNT_NUMERIC);
    expect_report(&rep, SK, SK, SK, NU);
    smp.valid = 0u;
    REFUSED(&f, att_step(&f, &smp, &rep), NU, CNT_NUMERIC);
    expect_report(&rep, NU, SK, SK, SK);
    /* a saturated gyro (no update) does not see it; the guard does */
    smp = good;
    smp.valid = ATT_GYRO_SATURATED;
    REFUSED(&f, att_step(&f, &smp, &rep), NU, CNT_NUMERIC);
    expect_report(&rep, NU, SK, SK, SK);

    /* (b) an infinite roll variance: the updates' new variances are not finite, the
     * prediction's P is not finite for the guard (an Euler rate's would not do: the
     * prediction replaces those rows without reading them) */
    aligned(&f, &sim);
    sample_at_rest(&sim, &good);
    att_cov_reset_state(&f.vars.cov, ATT_PHI, inf_s(1.0));
    REFUSED(&f, att_update_mag(&f, good.mag, EKF_C(0.01)), NU, CNT_NUMERIC);
    REFUSED(&f, att_update_gyro(&f, good.gyro, EKF_C(0.01)), NU, CNT_NUMERIC);
    REFUSED(&f, att_predict(&f, good.dt), NU, CNT_NUMERIC);
    REFUSED(&f, att_step(&f, &good, &rep), NU, CNT_NUMERIC);
    expect_report(&rep, SK, NU, SK, SK);

    /* (c) body rates so large that the transition overflows (finite state, finite dt): the
     * prediction stage refuses */
    aligned(&f, &sim);
    sample_at_rest(&sim, &good);
    {
#if defined(EKF_SCALAR_FIXED)
        const ekf_scalar_t big = ekf_from_double(5e8);
#elif defined(EKF_SCALAR_FLOAT)
        const ekf_scalar_t big = ekf_from_double(1e38);
#else
        const ekf_scalar_t big = ekf_from_double(1e307);
#endif
        f.vars.x[ATT_Q] = big;
        f.vars.x[ATT_R] = big;
        f.vars.x[ATT_THETAD] = big; /* midpoint pitch beyond the gimbal limit: sec(theta) large */
        REFUSED(&f, att_predict(&f, f.settings.dt_max), NU, CNT_NUMERIC);
        smp = good;
        smp.dt = f.settings.dt_max;
        smp.valid = ATT_HAS_ACCEL;
        REFUSED(&f, att_step(&f, &smp, &rep), NU, CNT_NUMERIC);
        expect_report(&rep, NU, SK, SK, SK);
    }
    /* (d) a correlation beyond 1, 1.01 between roll and pitch or 1.05 between heading and
     * yaw rate: every variance positive, P indefinite by far more than rounding. No call
     * repairs it (a repair would hide what made it); every one is refused, the filter
     * unchanged, until att_reset starts it afresh (att.h, "Contract") */
    {
        static const int pairs[2][2] = {{ATT_PHI, ATT_THETA}, {ATT_PSI, ATT_R}};
        static const double rho[2] = {1.01, 1.05};
        int k;
        for (k = 0; k < 2; ++k) {
            ekf_scalar_t P[ATT_N * ATT_N];
            const int i = pairs[k][0], j = pairs[k][1];
            aligned(&f, &sim);
            sample_at_rest(&sim, &good);
            att_get_covariance(&f, P);
            {
                const double pij = rho[k] * sqrt(ekf_to_double(P[i * ATT_N + i]) * ekf_to_double(P[j * ATT_N + j]));
                int m;
                for (m = 0; m < ATT_N; ++m) { /* the pair alone correlated */
                    if (m != i && m != j) {
                        P[i * ATT_N + m] = P[m * ATT_N + i] = EKF_C(0);
                        P[j * ATT_N + m] = P[m * ATT_N + j] = EKF_C(0);
                    }
                }
                P[i * ATT_N + j] = P[j * ATT_N + i] = ekf_from_double(pij);
            }
            att_cov_from_full(&f.vars.cov, P);
            REFUSED(&f, att_update_accel(&f, good.accel, good.dt), NU, CNT_NUMERIC);
            REFUSED(&f, att_step(&f, &good, &rep), NU, CNT_NUMERIC);
            /* (a prediction alone may be accepted: its rate noise, added between the steps'
             * gyro updates, can outweigh the defect; P is then positive definite on its own,
             * and nothing was repaired) */
            {
                const ekf_status_t st = att_predict(&f, good.dt);
                ekf_scalar_t Pn[ATT_N * ATT_N];
                att_get_covariance(&f, Pn);
                TEST_ASSERT_TRUE(st == EKF_ERR_NUMERIC ||
                                 (st == EKF_OK && (att_flags(&f) & ATT_FLAG_COV_REPAIRED) == 0u &&
                                  ts_is_positive_definite(Pn, ATT_N, NULL)));
            }
            TEST_ASSERT_EQUAL_INT(EKF_OK, att_reset(&f));
            TEST_ASSERT_EQUAL_INT(0, (int)(att_flags(&f) & ATT_FLAG_ALIGNED));
            TEST_ASSERT_EQUAL_INT(0, (int)att_diag(&f)->numeric);
        }
    }
    printf("forced numeric failures: %d refused calls checked\n", g_paths - before);
}

/* ---- settings ---- */

static void test_bad_settings_change_nothing(void)
{
    static att_ekf_t f;
    att_settings_t s;
    ekf_scalar_t *fields[] = {
        &s.rate_walk, &s.angle_walk, &s.euler_rate_rel, &s.gyro_noise, &s.gyro_gate, &s.gyro_range,
        &s.rest.rest_gyro, &s.rest.rest_accel, &s.rest.rest_time, &s.rest.rest_tau, &s.rest.bias_tau,
        &s.rest.bias_max, &s.gravity, &s.accel_noise, &s.accel_band, &s.accel_reject, &s.accel_adapt_tau,
        &s.accel_lpf_tau, &s.accel_gate, &s.accel_range, &s.mag_heading_noise, &s.mag_gate, &s.mag_norm_tol,
        &s.mag_dip_tol, &s.mag_reset_time, &s.mag_ref_norm, &s.mag_ref_dip, &s.mag_declination, &s.mag_range,
        &s.gate_timeout, &s.gimbal_limit, &s.dt_max, &s.heading_var_max, &s.var_floor, &s.init_tilt_sigma,
        &s.init_heading_sigma, &s.init_rate_sigma,
    };
    const size_t n = sizeof fields / sizeof fields[0];
    size_t i;
    int before = g_paths;
    ts_sim_t sim;
    aligned(&f, &sim);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_init(NULL, &att_default_settings));
    REFUSED(&f, att_init(&f, NULL), EKF_ERR_NULL, CNT_NONE);
    for (i = 0; i < n; ++i) {
        /* non-finite, and far out of any range (negative or huge) */
        s = att_default_settings;
        *fields[i] = nan_s();
        REFUSED(&f, att_init(&f, &s), EKF_ERR_SETTINGS, CNT_NONE);
        s = att_default_settings;
        *fields[i] = ekf_from_double(-1e3);
        REFUSED(&f, att_init(&f, &s), EKF_ERR_SETTINGS, CNT_NONE);
    }
    s = att_default_settings;
    s.align_samples = 0u;
    REFUSED(&f, att_init(&f, &s), EKF_ERR_SETTINGS, CNT_NONE);
    /* settings whose variance is not representable in this build's scalar: a gyro noise whose
     * square is below one LSB of Q29.34, a variance floor that rounds to zero; fine in float
     * and double */
    s = att_default_settings;
    s.gyro_noise = ekf_from_double(1e-6);
    TEST_ASSERT_TRUE(s.gyro_noise > EKF_C(0));
#if defined(EKF_SCALAR_FIXED)
    REFUSED(&f, att_init(&f, &s), EKF_ERR_SETTINGS, CNT_NONE);
#else
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&s));
#endif
    s = att_default_settings;
    s.var_floor = ekf_from_double(1e-12);
#if defined(EKF_SCALAR_FIXED)
    TEST_ASSERT_TRUE(s.var_floor == EKF_C(0));
    REFUSED(&f, att_init(&f, &s), EKF_ERR_SETTINGS, CNT_NONE);
#else
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&s));
#endif
    /* a gyro range beyond its bound (whose Euler-rate variance bound would also saturate the
     * fixed-point format) */
    s = att_default_settings;
    s.gyro_range = ekf_from_double(5000.0);
    s.rest.bias_max = EKF_C(0.01);
    REFUSED(&f, att_init(&f, &s), EKF_ERR_SETTINGS, CNT_NONE);
    printf("settings: %d refused calls checked\n", g_paths - before);
}

/* The end-of-call check of the state (att_state_finite) sees a non-finite value in every
 * state, the last included. */
static void test_state_finiteness_sees_every_state(void)
{
    ekf_scalar_t x[ATT_N];
    int i;
    memset(x, 0, sizeof x);
    TEST_ASSERT_EQUAL_INT(1, att_state_finite(x));
    for (i = 0; i < ATT_N; ++i) {
        memset(x, 0, sizeof x);
        x[i] = ekf_from_double(INFINITY);
        TEST_ASSERT_EQUAL_INT_MESSAGE(0, att_state_finite(x), "an infinite state missed");
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_input_errors_change_nothing);
    RUN_TEST(test_state_finiteness_sees_every_state);
    RUN_TEST(test_numeric_failures_discard_the_whole_call);
    RUN_TEST(test_bad_settings_change_nothing);
    printf("%d refused calls in all (%s)\n", g_paths, EKF_SCALAR_NAME);
    return UNITY_END();
}
