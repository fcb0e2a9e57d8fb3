/*
 * test_att_filter.c - the attitude estimator end to end on simulated data with known
 * truth, and every bad-input class. Built for float and double.
 *
 * Errors are rotation angles between estimate and truth (meaningful at any attitude).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att.h"
#include "att_model.h"
#include "testsim.h"
#include "unity.h"

#define DEG (3.14159265358979323846 / 180.0)

void setUp(void) {}
void tearDown(void) {}

static double est_error(const att_ekf_t *f, const ts_sim_t *s)
{
    ekf_scalar_t e[3];
    double ed[3], et[3];
    att_get_euler(f, e);
    ed[0] = (double)e[0];
    ed[1] = (double)e[1];
    ed[2] = (double)e[2];
    ts_sim_euler(s, et);
    return ts_euler_angle_between(ed, et);
}

static void init_default(att_ekf_t *f)
{
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(f, &att_default_settings));
}

/* Aligns on the first align_samples samples of the simulator at rest. */
static void align_on(att_ekf_t *f, ts_sim_t *s)
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    unsigned k;
    for (k = 0; k < f->settings.align_samples; ++k) {
        att_sample_t smp;
        ts_sim_step(s, zero, NULL, &smp);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_step(f, &smp, NULL));
    }
    TEST_ASSERT_TRUE((att_flags(f) & ATT_FLAG_ALIGNED) != 0u);
}

/* ----- convergence ----- */

/* Static body, filter aligned 20 deg away from the truth: converges within 0.4 deg (measured
 * 0.027-0.135 deg over the five attitudes, float and double). */
static void test_static_convergence_from_wrong_start(void)
{
    static const double attitudes[][3] = {
        {0.0, 0.0, 0.0}, {0.5, -0.3, 2.0}, {-1.2, 0.8, -2.5}, {2.9, 0.2, 1.0}, {0.1, -1.3, 0.4},
    };
    size_t a;
    for (a = 0; a < sizeof attitudes / sizeof attitudes[0]; ++a) {
        ts_sim_cfg_t cfg;
        ts_sim_t sim;
        att_ekf_t f;
        att_sample_t smp;
        double R[9], acc[3], mag[3], err = 0.0, err0;
        ekf_scalar_t acc_s[3], mag_s[3];
        static const double zero[3] = {0.0, 0.0, 0.0};
        int k;
        ts_sim_default(&cfg);
        ts_sim_init(&sim, &cfg, 100 + a, attitudes[a][0], attitudes[a][1], attitudes[a][2]);
        {
            att_settings_t st = att_default_settings;
            st.mag_heading_noise = EKF_C(0.01);
            TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &st));
        }
        /* align on a wrong attitude: roll +12, pitch -10, yaw +12 deg off */
        ts_euler_to_R(attitudes[a][0] + 12 * DEG, attitudes[a][1] - 10 * DEG, attitudes[a][2] + 12 * DEG, R);
        for (k = 0; k < 3; ++k) {
            acc[k] = R[6 + k] * cfg.gravity;
            mag[k] = R[3 + k] * cfg.mag_h - R[6 + k] * cfg.mag_v;
            acc_s[k] = (ekf_scalar_t)acc[k];
            mag_s[k] = (ekf_scalar_t)mag[k];
        }
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_align(&f, acc_s, mag_s));
        err0 = est_error(&f, &sim);
        TEST_ASSERT_TRUE(err0 > 10 * DEG);
        /* 60 s at 100 Hz. The default magnetometer noise density is set for disturbed real
         * recordings; this clean simulation uses a smaller one, as a user with a clean field
         * would (docs/derivation.md, "Magnetometer") */
        for (k = 0; k < 6000; ++k) {
            ts_sim_step(&sim, zero, NULL, &smp);
            (void)att_step(&f, &smp, NULL);
        }
        err = est_error(&f, &sim);
        printf("static attitude (%.1f, %.1f, %.1f) deg, start %.1f deg off: final error %.3f deg\n",
               attitudes[a][0] / DEG, attitudes[a][1] / DEG, attitudes[a][2] / DEG, err0 / DEG, err / DEG);
        TEST_ASSERT_TRUE_MESSAGE(err < 0.4 * DEG, "static attitude did not converge within 0.4 deg");
    }
}

typedef struct {
    const char *name;
    double w[3];         /* rad/s, body */
    double start[3];     /* initial Euler angles, rad */
    double measured_deg; /* RMS error measured with the default settings (float and double alike), deg */
} rate_case_t;

static double run_constant_rate(const rate_case_t *c, int use_mag, double *max_err)
{
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_ekf_t f;
    att_sample_t smp;
    double sum = 0.0;
    int k, n = 0;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 7, c->start[0], c->start[1], c->start[2]);
    init_default(&f);
    align_on(&f, &sim);
    *max_err = 0.0;
    for (k = 0; k < 6000; ++k) { /* 60 s at 100 Hz */
        ts_sim_step(&sim, c->w, NULL, &smp);
        if (!use_mag) {
            smp.valid &= (uint8_t)~ATT_HAS_MAG;
        }
        (void)att_step(&f, &smp, NULL);
        if (k >= 100) { /* score after the first second */
            double e = est_error(&f, &sim);
            if (!use_mag) {
                /* 6D: heading is unobservable; score inclination only */
                ekf_scalar_t eu[3];
                double ed[3], et[3];
                att_get_euler(&f, eu);
                ts_sim_euler(&sim, et);
                ed[0] = (double)eu[0];
                ed[1] = (double)eu[1];
                ed[2] = et[2];
                e = ts_euler_angle_between(ed, et);
            }
            sum += e * e;
            ++n;
            if (e > *max_err) {
                *max_err = e;
            }
        }
    }
    printf("  (covariance repairs: %u)\n", (unsigned)att_diag(&f)->cov_repairs);
    TEST_ASSERT_EQUAL_UINT32(0u, att_diag(&f)->cov_repairs);
    return sqrt(sum / n);
}

static void test_constant_rate_rotations_tracked(void)
{
    static const rate_case_t cases[] = {
        {"yaw spin 1 rad/s, tilted 20 deg", {0.0, 0.342, 0.940}, {0.349, 0.0, 0.0}, 0.206},
        {"roll spin 0.5 rad/s (roll wraps)", {0.5, 0.0, 0.0}, {0.0, 0.1, 0.5}, 0.125},
        {"axis (1,1,1)/sqrt3 at 0.3 rad/s", {0.1732, 0.1732, 0.1732}, {0.0, 0.0, 0.0}, 0.235},
        {"pitch-yaw 0.2/0.6 rad/s", {0.0, 0.2, 0.6}, {0.2, -0.2, 1.0}, 0.467},
    };
    size_t i;
    for (i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        double max_err;
        const double rms = run_constant_rate(&cases[i], 1, &max_err);
        printf("constant rate, %s: RMS error %.3f deg (max %.3f; bound 3 x %.3f)\n", cases[i].name, rms / DEG,
               max_err / DEG, cases[i].measured_deg);
        TEST_ASSERT_TRUE_MESSAGE(rms < 3.0 * cases[i].measured_deg * DEG,
                                 "constant-rate rotation: RMS error above 3 x the measured one");
    }
}

static void test_constant_rate_without_magnetometer(void)
{
    static const rate_case_t c = {"6D yaw spin", {0.0, 0.342, 0.940}, {0.349, 0.0, 0.0}, 0.103};
    double max_err;
    const double rms = run_constant_rate(&c, 0, &max_err);
    printf("constant rate 6D (inclination only): RMS %.3f deg (bound 3 x %.3f)\n", rms / DEG, c.measured_deg);
    TEST_ASSERT_TRUE(rms < 3.0 * c.measured_deg * DEG);
}

/* Pitch up through +90 deg (the body goes over the top) and come back to rest: the filter
 * stays finite, flags gimbal lock while near it, remaps the Euler triple, and recovers. */
static void test_gimbal_lock_pass_and_recovery(void)
{
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_ekf_t f;
    att_sample_t smp;
    static const double pitch_rate[3] = {0.0, 0.5, 0.0};
    static const double zero[3] = {0.0, 0.0, 0.0};
    ekf_scalar_t P[ATT_N * ATT_N];
    int k, saw_lock = 0;
    double err;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 9, 0.0, 0.0, 0.3);
    init_default(&f);
    align_on(&f, &sim);
    for (k = 0; k < 500; ++k) { /* 5 s at 0.5 rad/s: 143 deg of pitch rotation */
        ts_sim_step(&sim, pitch_rate, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
        TEST_ASSERT_TRUE(ekf_all_finite(att_state(&f), ATT_N));
        att_get_covariance(&f, P);
        TEST_ASSERT_TRUE(ekf_all_finite(P, ATT_N * ATT_N));
        if (att_flags(&f) & ATT_FLAG_GIMBAL_LOCK) {
            saw_lock = 1;
        }
    }
    for (k = 0; k < 3000; ++k) { /* 30 s at rest */
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    err = est_error(&f, &sim);
    printf("over the top in pitch and back to rest: lock flagged %d, remaps %u, covariance repairs %u, final error "
           "%.3f deg\n", saw_lock, (unsigned)att_diag(&f)->remaps, (unsigned)att_diag(&f)->cov_repairs, err / DEG);
    TEST_ASSERT_TRUE(saw_lock);
    TEST_ASSERT_TRUE(att_diag(&f)->remaps >= 1u);
    TEST_ASSERT_FALSE(att_flags(&f) & ATT_FLAG_GIMBAL_LOCK);
    TEST_ASSERT_TRUE(err < 0.25 * DEG); /* measured 0.077 deg */
}

/* The remap (phi+pi, pi-theta, psi+pi) is the same rotation. */
static void test_remap_is_same_rotation(void)
{
    ekf_scalar_t x[ATT_N] = {0};
    double before[3], after[3];
    x[ATT_PHI] = EKF_C(0.4);
    x[ATT_THETA] = EKF_C(1.9); /* beyond +90 deg */
    x[ATT_PSI] = EKF_C(-0.7);
    x[ATT_THETAD] = EKF_C(0.3);
    before[0] = (double)x[ATT_PHI];
    before[1] = (double)x[ATT_THETA];
    before[2] = (double)x[ATT_PSI];
    TEST_ASSERT_EQUAL_INT(1, att_model_normalise(x));
    after[0] = (double)x[ATT_PHI];
    after[1] = (double)x[ATT_THETA];
    after[2] = (double)x[ATT_PSI];
    TEST_ASSERT_TRUE(after[1] <= 1.5707964 && after[1] >= -1.5707964);
    TEST_ASSERT_TRUE(ts_euler_angle_between(before, after) < 1e-5);
    TEST_ASSERT_TRUE(x[ATT_THETAD] < EKF_C(0));
}

static void test_heading_capped_without_magnetometer(void)
{
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_ekf_t f;
    att_sample_t smp;
    static const double zero[3] = {0.0, 0.0, 0.0};
    ekf_scalar_t var[ATT_N], P[ATT_N * ATT_N];
    int k;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 5, 0.1, 0.1, 0.1);
    init_default(&f);
    for (k = 0; k < 20000; ++k) {
        ts_sim_step(&sim, zero, NULL, &smp);
        smp.valid = ATT_HAS_GYRO | ATT_HAS_ACCEL;
        (void)att_step(&f, &smp, NULL);
    }
    att_get_variances(&f, var);
    TEST_ASSERT_TRUE(var[ATT_PSI] <= f.settings.heading_var_max * EKF_C(1.0001));
    TEST_ASSERT_TRUE(att_flags(&f) & ATT_FLAG_HEADING_LIMITED);
    att_get_covariance(&f, P);
    TEST_ASSERT_TRUE(ts_is_positive_definite(P, ATT_N, NULL));
    /* a magnetometer arriving later sets the heading */
    for (k = 0; k < 2000; ++k) {
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    printf("heading capped without magnetometer, then 20 s with it: error %.3f deg\n", est_error(&f, &sim) / DEG);
    TEST_ASSERT_TRUE(est_error(&f, &sim) < 0.25 * DEG); /* measured 0.070 deg */
}

/* An accelerometer at its range (within ATT_ACCEL_CLIP_MARGIN of accel_range, or beyond it)
 * is clipped: the step goes on with every sensor, nothing is refused; a reading beyond the
 * range is taken at the range; the clipped sample is de-weighted (ATT_FLAG_ACCEL_DEWEIGHTED,
 * variance doubled: a smaller correction than the same reading unclipped), holds the offset
 * learning and ends a rest; a reading just inside the margin is an ordinary one. While
 * aligning, a clipped sample is skipped. A turn of clipped samples keeps the attitude. */
static void angles(const att_ekf_t *f, double out[3])
{
    int i;
    for (i = 0; i < 3; ++i) {
        out[i] = ekf_to_double(att_state(f)[ATT_PHI + i]);
    }
}

static void test_clipped_accelerometer(void)
{
    static const double zero[3] = {0.0, 0.0, 0.0}, turn[3] = {0.0, 0.0, 1.0};
    const double range = 2.0 * 9.81;
    att_settings_t s = att_default_settings, wide;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    static att_ekf_t f, g, h;
    att_sample_t smp, at_range;
    att_step_report_t rep;
    double a0[3], af[3], ag[3], ah[3];
    int k;
    s.accel_range = ekf_from_double(range);
    wide = s;
    wide.accel_range = EKF_C(160);
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 9, 0.2, -0.1, 0.5);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &s));
    /* aligning: a clipped sample is skipped, not refused and not averaged */
    ts_sim_step(&sim, zero, NULL, &smp);
    smp.accel[0] = ekf_from_double(-range);
    TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_step(&f, &smp, &rep));
    TEST_ASSERT_EQUAL_UINT32(0u, att_diag(&f)->rejected);
    TEST_ASSERT_EQUAL_UINT32(1u, att_diag(&f)->accel_skipped);
    TEST_ASSERT_EQUAL_UINT16(0u, f.vars.align_count);
    for (k = 0; k < 300; ++k) { /* 3 s at rest: aligned and at rest */
        ts_sim_step(&sim, zero, NULL, &smp);
        TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, NULL)));
    }
    TEST_ASSERT_TRUE((att_flags(&f) & (ATT_FLAG_ALIGNED | ATT_FLAG_AT_REST)) == (ATT_FLAG_ALIGNED | ATT_FLAG_AT_REST));
    TEST_ASSERT_TRUE(f.vars.bias.hold == EKF_C(0));
    /* within the margin: clipped, against the same reading with a wide range */
    ts_sim_step(&sim, zero, NULL, &smp);
    smp.accel[1] = ekf_from_double(-range * (1.0 - 0.1 * ATT_ACCEL_CLIP_MARGIN));
    g = f;
    h = f;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_set_settings(&g, &wide));
    at_range = smp; /* (h: the prediction alone, no accelerometer) */
    at_range.valid = (uint8_t)(at_range.valid & ~ATT_HAS_ACCEL);
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&h, &at_range, NULL)));
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, &rep)));
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&g, &smp, NULL)));
    angles(&h, a0);
    angles(&f, af);
    angles(&g, ag);
    TEST_ASSERT_TRUE(rep.predict == EKF_OK && rep.gyro == EKF_OK && !ekf_status_is_error(rep.accel));
    TEST_ASSERT_TRUE((att_flags(&f) & (ATT_FLAG_ACCEL_DEWEIGHTED | ATT_FLAG_AT_REST)) == ATT_FLAG_ACCEL_DEWEIGHTED);
    TEST_ASSERT_TRUE(f.vars.bias.hold > EKF_C(0) && g.vars.bias.hold == EKF_C(0));
    TEST_ASSERT_TRUE(fabs(af[0] - a0[0]) < 0.8 * fabs(ag[0] - a0[0]));
    TEST_ASSERT_EQUAL_UINT32(0u, att_diag(&f)->rejected);
    /* beyond the range: the same as at the range */
    ts_sim_step(&sim, zero, NULL, &at_range);
    at_range.accel[2] = ekf_from_double(range);
    smp = at_range;
    smp.accel[2] = ekf_from_double(range * 1.5);
    g = f;
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, NULL)));
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&g, &at_range, NULL)));
    angles(&f, af);
    angles(&g, ag);
    TEST_ASSERT_TRUE(af[0] == ag[0] && af[1] == ag[1] && af[2] == ag[2]);
    TEST_ASSERT_TRUE(f.vars.accel_lp1[2] == g.vars.accel_lp1[2]); /* (what the low-pass took) */
    /* just inside the margin: an ordinary reading, as with a wide range */
    ts_sim_step(&sim, zero, NULL, &smp);
    smp.accel[0] = ekf_from_double(range * (1.0 - 2.0 * ATT_ACCEL_CLIP_MARGIN));
    g = f;
    h = f;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_set_settings(&h, &wide));
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&g, &smp, NULL)));
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&h, &smp, NULL)));
    angles(&g, ag);
    angles(&h, ah);
    TEST_ASSERT_TRUE(ag[0] == ah[0] && ag[1] == ah[1] && ag[2] == ah[2]);
    /* a second of turning at 1 rad/s with every accelerometer sample beyond the range: the
     * gyroscope carries the attitude, nothing refused */
    for (k = 0; k < 100; ++k) {
        ts_sim_step(&sim, turn, NULL, &smp);
        smp.accel[2] = ekf_from_double(range * 1.5);
        TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, NULL)));
    }
    printf("one second of turning with the accelerometer clipped: error %.3f deg\n", est_error(&f, &sim) / DEG);
    TEST_ASSERT_TRUE(est_error(&f, &sim) < 0.5 * DEG);
    smp.accel[2] = ekf_from_double(-range * 3.0); /* the single-sensor call too */
    TEST_ASSERT_FALSE(ekf_status_is_error(att_update_accel(&f, smp.accel, EKF_C(0.01))));
    TEST_ASSERT_EQUAL_UINT32(0u, att_diag(&f)->rejected);
}

static void test_linear_acceleration_and_mag_disturbance_flags(void)
{
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_ekf_t f;
    att_sample_t smp;
    static const double zero[3] = {0.0, 0.0, 0.0};
    /* vertical, so that |a| changes by the full amount: 60 m/s^2 is beyond accel_reject
     * (50 m/s^2); two seconds of 2 m/s^2 move the low-passed force (accel_lpf_tau 1 s) by
     * 1.7 m/s^2 and its running variance (accel_adapt_tau 0.5 s) far above
     * accel_noise^2 (0.25 (m/s^2)^2): de-weighted */
    static const double push[3] = {0.0, 0.0, 60.0};
    static const double nudge[3] = {0.0, 0.0, 2.0};
    int k;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 6, 0.0, 0.0, 0.0);
    init_default(&f);
    align_on(&f, &sim);
    ts_sim_step(&sim, zero, push, &smp);
    TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_step(&f, &smp, NULL));
    TEST_ASSERT_TRUE(att_flags(&f) & ATT_FLAG_ACCEL_REJECTED);
    TEST_ASSERT_FALSE(att_flags(&f) & ATT_FLAG_ACCEL_DEWEIGHTED);
    /* forget the push: five seconds (ten time constants) at rest */
    for (k = 0; k < 500; ++k) {
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    TEST_ASSERT_FALSE(att_flags(&f) & ATT_FLAG_ACCEL_DEWEIGHTED);
    for (k = 0; k < 200; ++k) {
        ts_sim_step(&sim, zero, nudge, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    TEST_ASSERT_TRUE(att_flags(&f) & ATT_FLAG_ACCEL_DEWEIGHTED);
    TEST_ASSERT_FALSE(att_flags(&f) & ATT_FLAG_ACCEL_REJECTED);
    /* a field 50 % stronger than the reference is a disturbance */
    ts_sim_step(&sim, zero, NULL, &smp);
    smp.mag[0] = smp.mag[0] * EKF_C(1.5);
    smp.mag[1] = smp.mag[1] * EKF_C(1.5);
    smp.mag[2] = smp.mag[2] * EKF_C(1.5);
    TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_step(&f, &smp, NULL));
    TEST_ASSERT_TRUE(att_flags(&f) & ATT_FLAG_MAG_DISTURBED);
    TEST_ASSERT_TRUE(att_diag(&f)->mag_skipped >= 1u);
}

/* Upside down, atan2(+0, -g) is +pi itself: the alignment must still put roll in
 * [-pi, pi) like every other stage (a fuzzing finding). */
static void test_align_upside_down_roll_in_range(void)
{
    static const ekf_scalar_t acc[3] = {EKF_C(0), EKF_C(0), EKF_C(-9.81)};
    static const ekf_scalar_t mag[3] = {EKF_C(0), EKF_C(-20), EKF_C(40)};
    att_ekf_t f;
    ekf_scalar_t e[3];
    init_default(&f);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_align(&f, acc, mag));
    att_get_euler(&f, e);
    TEST_ASSERT_TRUE(e[0] >= -EKF_PI && e[0] < EKF_PI);
    TEST_ASSERT_TRUE(ekf_abs(ekf_abs(e[0]) - EKF_PI) < EKF_C(1e-6)); /* still upside down */
    TEST_ASSERT_TRUE(e[2] >= -EKF_PI && e[2] < EKF_PI);
}

/* Initial sigmas below the variance floor: the alignment raises them to the floor, and a
 * heading cap below the floor is refused (fuzzing findings: P[0][0] and P[5][5] started
 * below the floor the rest of the filter guarantees). */
static void test_align_respects_variance_floor(void)
{
    static const ekf_scalar_t acc[3] = {EKF_C(0), EKF_C(0), EKF_C(9.81)};
    static const ekf_scalar_t mag[3] = {EKF_C(20), EKF_C(0), EKF_C(40)};
    att_ekf_t f;
    att_settings_t s = att_default_settings;
    ekf_scalar_t P[ATT_N * ATT_N];
    int i;
    s.var_floor = EKF_C(1e-6);
    s.init_rate_sigma = EKF_C(1e-5);    /* 1e-10 rad^2/s^2 < floor */
    s.init_heading_sigma = EKF_C(1e-4); /* 1e-8 rad^2 < floor */
    s.init_tilt_sigma = EKF_C(1e-5);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &s));
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_align(&f, acc, mag));
    att_get_covariance(&f, P);
    for (i = 0; i < ATT_N; ++i) {
        TEST_ASSERT_TRUE(P[i * ATT_N + i] >= s.var_floor);
    }
    s.heading_var_max = EKF_C(1e-7); /* a ceiling under the floor */
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_settings_check(&s));
}

/* A tumble beyond the gyro's full scale (8.7 rad/s, 500 deg/s), 1.5 s at 12.4 rad/s: with
 * the clamped readings flagged ATT_GYRO_SATURATED the rate variances are raised, the
 * attitude uncertainty grows with the unmeasured rotation, and the accelerometer and
 * magnetometer take the attitude back within seconds afterwards. (With the gyro merely
 * left out, this test measures 11.1 deg 3 s after and 5.3 deg 5 s after, and fails: the
 * attitude then drifts with an uncertainty that does not grow, so the sensors are gated
 * out; the soak's tumbles end 100-180 deg off that way, docs/reliability.md, Finding 6.) */
static void test_gyro_saturation_tumble_recovers(void)
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    static const double tumble[3] = {10.0, 4.0, 6.0};
    const double fs = 8.7; /* rad/s */
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_ekf_t f;
    att_sample_t smp;
    ekf_scalar_t P[ATT_N * ATT_N];
    double err = 0.0;
    int k, i, n_sat = 0;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 77, 0.3, -0.2, 1.0);
    init_default(&f);
    align_on(&f, &sim);
    for (k = 0; k < 200; ++k) {
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    for (k = 0; k < 150; ++k) {
        ts_sim_step(&sim, tumble, NULL, &smp);
        for (i = 0; i < 3; ++i) {
            if (fabs((double)smp.gyro[i]) > fs) {
                smp.gyro[i] = (ekf_scalar_t)(smp.gyro[i] > 0 ? fs : -fs);
                smp.valid |= ATT_GYRO_SATURATED;
            }
        }
        n_sat += (smp.valid & ATT_GYRO_SATURATED) != 0u;
        {
            const ekf_status_t st = att_step(&f, &smp, NULL);
            TEST_ASSERT_TRUE(st == EKF_OK || st == EKF_GATED || st == EKF_SKIPPED);
        }
        att_get_covariance(&f, P);
        TEST_ASSERT_TRUE(ts_is_positive_definite(P, ATT_N, NULL));
        if ((smp.valid & ATT_GYRO_SATURATED) != 0u) {
            for (i = 0; i < 3; ++i) { /* raised to fs^2, then reduced by this step's updates */
                TEST_ASSERT_TRUE((double)P[(ATT_P + i) * ATT_N + ATT_P + i] >= 1.0);
            }
        }
    }
    TEST_ASSERT_EQUAL_INT(n_sat, (int)att_diag(&f)->gyro_saturated);
    TEST_ASSERT_TRUE(n_sat > 100);
    for (k = 0; k < 500; ++k) { /* 5 s at rest, every sensor */
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
        if (k == 299) {
            err = est_error(&f, &sim);
        }
    }
    printf("saturated tumble: error %.2f deg 3 s after, %.2f deg 5 s after (flags 0x%x, heading resets %u)\n",
           err / DEG, est_error(&f, &sim) / DEG, (unsigned)att_flags(&f), (unsigned)att_diag(&f)->heading_resets);
    TEST_ASSERT_TRUE(err < 2.5 * DEG);
    TEST_ASSERT_TRUE(est_error(&f, &sim) < 1.0 * DEG);
}

/* ----- bad input ----- */

typedef struct {
    ekf_scalar_t x[ATT_N];
    ekf_scalar_t P[ATT_N * ATT_N];
    uint32_t flags;
} snapshot_t;

static void snap(const att_ekf_t *f, snapshot_t *s)
{
    memcpy(s->x, att_state(f), sizeof s->x);
    att_get_covariance(f, s->P);
    s->flags = att_flags(f);
}

static void assert_unchanged(const att_ekf_t *f, const snapshot_t *s)
{
    snapshot_t now;
    snap(f, &now);
    TEST_ASSERT_EQUAL_MEMORY(s->x, now.x, sizeof s->x);
    TEST_ASSERT_EQUAL_MEMORY(s->P, now.P, sizeof s->P);
    TEST_ASSERT_EQUAL_UINT32(s->flags, now.flags);
}

static void aligned_filter(att_ekf_t *f, ts_sim_t *sim)
{
    ts_sim_cfg_t cfg;
    att_sample_t smp;
    static const double w[3] = {0.1, -0.2, 0.3};
    int k;
    ts_sim_default(&cfg);
    ts_sim_init(sim, &cfg, 3, 0.2, -0.1, 0.5);
    init_default(f);
    align_on(f, sim);
    for (k = 0; k < 50; ++k) {
        ts_sim_step(sim, w, NULL, &smp);
        (void)att_step(f, &smp, NULL);
    }
}

static void test_bad_settings_rejected(void)
{
    att_ekf_t f;
    att_settings_t s = att_default_settings;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_settings_check(&s));
    s.gyro_noise = EKF_C(-1);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_init(&f, &s));
    s = att_default_settings;
    s.accel_noise = (ekf_scalar_t)NAN;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_init(&f, &s));
    s = att_default_settings;
    s.gimbal_limit = EKF_HALF_PI;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_init(&f, &s));
    s = att_default_settings;
    s.align_samples = 0u;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_init(&f, &s));
    s = att_default_settings;
    s.dt_max = (ekf_scalar_t)INFINITY;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, att_init(&f, &s));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_init(NULL, &att_default_settings));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_init(&f, NULL));
}

static void test_not_initialised(void)
{
    att_ekf_t f;
    snapshot_t s;
    const ekf_scalar_t v[3] = {EKF_C(0), EKF_C(0), EKF_C(9.81)};
    att_sample_t smp;
    memset(&smp, 0, sizeof smp);
    init_default(&f);
    snap(&f, &s);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_INITIALISED, att_predict(&f, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_INITIALISED, att_update_gyro(&f, v, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_INITIALISED, att_update_accel(&f, v, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_INITIALISED, att_update_mag(&f, v, EKF_C(0.01)));
    smp.valid = ATT_HAS_GYRO; /* no accelerometer: nothing to align on */
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_INITIALISED, att_step(&f, &smp, NULL));
    assert_unchanged(&f, &s);
    TEST_ASSERT_EQUAL_UINT32(5u, att_diag(&f)->rejected);
}

static void test_every_bad_input_class_leaves_state_unchanged(void)
{
    att_ekf_t f;
    ts_sim_t sim;
    snapshot_t s;
    const ekf_scalar_t nan_v = (ekf_scalar_t)NAN, inf_v = (ekf_scalar_t)INFINITY;
    ekf_scalar_t good[3] = {EKF_C(0.1), EKF_C(0.2), EKF_C(9.7)};
    ekf_scalar_t bad[3];
    uint32_t rejected;
    int k;
    aligned_filter(&f, &sim);
    snap(&f, &s);
    rejected = att_diag(&f)->rejected;

    /* time step */
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, att_predict(&f, EKF_C(0)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, att_predict(&f, EKF_C(-0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_predict(&f, nan_v));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_predict(&f, inf_v));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_TOO_LARGE, att_predict(&f, EKF_C(0.51)));
    assert_unchanged(&f, &s);

    /* each sensor: NaN, +Inf, -Inf in each component; out of range (gyro, mag; an accelerometer
     * beyond its range is clipped, not refused: test_clipped_accelerometer); NULL */
    for (k = 0; k < 3; ++k) {
        memcpy(bad, good, sizeof bad);
        bad[k] = nan_v;
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_update_gyro(&f, bad, EKF_C(0.01)));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_update_accel(&f, bad, EKF_C(0.01)));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_update_mag(&f, bad, EKF_C(0.01)));
        bad[k] = inf_v;
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_update_gyro(&f, bad, EKF_C(0.01)));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_update_accel(&f, bad, EKF_C(0.01)));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_update_mag(&f, bad, EKF_C(0.01)));
        bad[k] = -inf_v;
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_update_accel(&f, bad, EKF_C(0.01)));
        memcpy(bad, good, sizeof bad);
        bad[k] = EKF_C(41); /* gyro_range 40 rad/s */
        TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, att_update_gyro(&f, bad, EKF_C(0.01)));
        bad[k] = EKF_C(5001); /* mag_range 5000 */
        TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, att_update_mag(&f, bad, EKF_C(0.01)));
    }
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_update_gyro(&f, NULL, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_update_accel(&f, NULL, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_update_mag(&f, NULL, EKF_C(0.01)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_step(&f, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, att_step(NULL, NULL, NULL));
    assert_unchanged(&f, &s);
    /* 5 dt + 3*(3+3+1+2) + 3 NULL sensor calls + the NULL sample; att_step(NULL...)
     * cannot count */
    TEST_ASSERT_EQUAL_UINT32(rejected + 5u + 27u + 3u + 1u, att_diag(&f)->rejected);

    /* a bad dt refuses the whole sample, state unchanged */
    {
        att_sample_t smp;
        att_step_report_t rep;
        static const double w[3] = {0.1, 0.0, 0.0};
        ts_sim_step(&sim, w, NULL, &smp);
        smp.dt = EKF_C(-1);
        TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, att_step(&f, &smp, &rep));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, rep.predict);
        assert_unchanged(&f, &s);
        TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, rep.gyro);
        TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, rep.accel);
        TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, rep.mag);
        /* a bad magnetometer alone refuses the whole sample too: the report names it, the
         * filter (every byte but diag.rejected) is as it was */
        smp.dt = EKF_C(0.01);
        smp.mag[1] = nan_v;
        {
            att_ekf_t before;
            memcpy(&before, &f, sizeof f);
            TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_step(&f, &smp, &rep));
            TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, rep.gyro);
            TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, rep.predict);
            TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, rep.accel);
            TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, rep.mag);
            ++before.vars.diag.rejected;
            TEST_ASSERT_EQUAL_MEMORY(&before, &f, sizeof f);
        }
        /* the caller clears the bad sensor's bit and calls again: the rest of the sample
         * is applied */
        smp.valid &= (uint8_t)~ATT_HAS_MAG;
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_step(&f, &smp, &rep));
        TEST_ASSERT_EQUAL_INT(EKF_OK, rep.gyro);
        TEST_ASSERT_EQUAL_INT(EKF_OK, rep.predict);
        TEST_ASSERT_EQUAL_INT(EKF_OK, rep.accel);
        TEST_ASSERT_EQUAL_INT(EKF_OK, rep.mag);
        TEST_ASSERT_TRUE(ekf_all_finite(att_state(&f), ATT_N));
        att_get_covariance(&f, s.P);
        TEST_ASSERT_TRUE(ts_is_positive_definite(s.P, ATT_N, NULL));
    }
    /* alignment input errors */
    {
        att_ekf_t g;
        const ekf_scalar_t zero_acc[3] = {EKF_C(0), EKF_C(0), EKF_C(0)};
        init_default(&g);
        TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, att_align(&g, zero_acc, NULL));
        bad[0] = nan_v;
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_align(&g, bad, NULL));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, att_align(&g, good, bad));
        TEST_ASSERT_FALSE(att_flags(&g) & ATT_FLAG_ALIGNED);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_static_convergence_from_wrong_start);
    RUN_TEST(test_constant_rate_rotations_tracked);
    RUN_TEST(test_constant_rate_without_magnetometer);
    RUN_TEST(test_gimbal_lock_pass_and_recovery);
    RUN_TEST(test_remap_is_same_rotation);
    RUN_TEST(test_heading_capped_without_magnetometer);
    RUN_TEST(test_clipped_accelerometer);
    RUN_TEST(test_linear_acceleration_and_mag_disturbance_flags);
    RUN_TEST(test_align_upside_down_roll_in_range);
    RUN_TEST(test_align_respects_variance_floor);
    RUN_TEST(test_gyro_saturation_tumble_recovers);
    RUN_TEST(test_bad_settings_rejected);
    RUN_TEST(test_not_initialised);
    RUN_TEST(test_every_bad_input_class_leaves_state_unchanged);
    return UNITY_END();
}
