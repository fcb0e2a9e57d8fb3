/*
 * test_att_bias.c - the gyroscope offset in motion (att_bias.c) and the considered error
 * sources of the reported covariance (att_consider.c), on simulated data with known truth.
 * Built for float and double.
 */
#include <math.h>
#include <stdio.h>

#include "att.h"
#include "att_bias.h"
#include "att_cov.h"
#include "att_gen.h"
#include "testsim.h"
#include "unity.h"

#define DEG (3.14159265358979323846 / 180.0)

void setUp(void) {}
void tearDown(void) {}

/* A slowly varying rotation that visits every orientation: rad/s at time t (s). */
static void wander(double t, double w[3])
{
    w[0] = 0.5 * sin(0.31 * t);
    w[1] = 0.4 * cos(0.23 * t);
    w[2] = 0.6 * sin(0.17 * t + 1.0);
}

/* Runs `seconds` of wandering motion from the start (no rest before it) with a constant
 * gyroscope offset; returns the largest error of the learned offset per axis (rad/s). */
static double learn_offset_in_motion(uint16_t motion, int use_mag, double seconds, att_ekf_t *f)
{
    static const double bias[3] = {0.5 * DEG, -0.3 * DEG, 0.4 * DEG};
    att_settings_t s = att_default_settings;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_sample_t smp;
    ekf_scalar_t b[3];
    double w[3], worst = 0.0;
    int k, i;
    ts_sim_default(&cfg);
    for (i = 0; i < 3; ++i) {
        cfg.gyro_bias[i] = bias[i];
    }
    ts_sim_init(&sim, &cfg, 11, 0.2, -0.1, 0.5);
    s.rest.bias_tau = EKF_C(0.0); /* no rest learning: a recording that never rests */
    s.bias.motion = motion;
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(f, &s));
    for (k = 0; k < (int)(seconds / cfg.dt); ++k) {
        wander(k * cfg.dt, w);
        ts_sim_step(&sim, w, NULL, &smp);
        if (!use_mag) {
            smp.valid &= (uint8_t)~ATT_HAS_MAG;
        }
        (void)att_step(f, &smp, NULL);
    }
    att_get_gyro_bias(f, b);
    for (i = 0; i < 3; ++i) {
        const double e = fabs(ekf_to_double(b[i]) - bias[i]);
        worst = e > worst ? e : worst;
    }
    return worst;
}

static void test_offset_learned_in_motion_9d(void)
{
    att_ekf_t f;
    const double off = learn_offset_in_motion(0u, 1, 300.0, &f);
    const double on = learn_offset_in_motion(2u, 1, 300.0, &f);
    printf("9D, 300 s of motion, no rest: offset error %.4f deg/s learned, %.4f deg/s not learned\n", on / DEG,
           off / DEG);
    TEST_ASSERT_TRUE(on < 0.05 * DEG);
    TEST_ASSERT_TRUE(off > 0.3 * DEG);
    {
        const ekf_scalar_t *pb = f.vars.bias.Pb; /* packed 00 11 22 01 02 12 */
        const ekf_scalar_t full[9] = {pb[0], pb[3], pb[4], pb[3], pb[1], pb[5], pb[4], pb[5], pb[2]};
        TEST_ASSERT_TRUE(ts_is_positive_definite(full, 3, NULL));
    }
}

static void test_offset_learned_in_motion_6d(void)
{
    /* without a magnetometer the offset is seen through the tilt only; a rotation that
     * turns every body axis through the horizontal still reveals all three components */
    att_ekf_t f;
    const double on = learn_offset_in_motion(1u, 0, 300.0, &f);
    ekf_scalar_t c[6];
    printf("6D, 300 s of motion, no rest: offset error %.4f deg/s\n", on / DEG);
    TEST_ASSERT_TRUE(on < 0.1 * DEG);
    /* the reported yaw variance contains the offset's share V Pb V^T on top of P */
    att_get_angle_covariance(&f, c);
    TEST_ASSERT_TRUE(c[2] >= att_cov_var(&f.vars.cov, ATT_PSI));
}

static void test_rest_takes_over(void)
{
    /* a residual learned in motion moves into the rest offset once the sensor rests */
    static const double zero[3] = {0.0, 0.0, 0.0};
    att_ekf_t f;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_sample_t smp;
    ekf_scalar_t b[3];
    int k, i;
    ts_sim_default(&cfg);
    cfg.gyro_bias[0] = 0.3 * DEG;
    ts_sim_init(&sim, &cfg, 5, 0.0, 0.0, 0.0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    f.vars.bias.b[0] = EKF_C(0.2 * DEG); /* as if learned in motion */
    for (k = 0; k < 6000; ++k) {     /* 60 s at rest */
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    att_get_gyro_bias(&f, b);
    printf("after 60 s at rest: residual %.4f deg/s, total %.4f deg/s (true 0.3)\n", ekf_to_double(f.vars.bias.b[0]) / DEG,
           ekf_to_double(b[0]) / DEG);
    TEST_ASSERT_TRUE(fabs(ekf_to_double(f.vars.bias.b[0])) < 0.01 * DEG);
    TEST_ASSERT_TRUE(fabs(ekf_to_double(b[0]) - 0.3 * DEG) < 0.02 * DEG);
    for (i = 0; i < 3; ++i) {
        /* below (0.03 deg/s)^2 after the rest (Pb in ATT_BIAS_UNIT^2) */
        TEST_ASSERT_TRUE(ekf_to_double(f.vars.bias.Pb[i]) * 1e-6 < (0.03 * DEG) * (0.03 * DEG));
    }
}

static void test_saturated_gyro_forgets_sensitivity(void)
{
    static const double spin[3] = {0.0, 0.0, 2.0};
    att_ekf_t f;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_sample_t smp;
    int k, i;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 9, 0.1, 0.1, 0.0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &att_default_settings));
    for (k = 0; k < 500; ++k) {
        ts_sim_step(&sim, spin, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    TEST_ASSERT_TRUE(fabs(ekf_to_double(f.vars.bias.V[8])) > 0.1); /* yaw depends on the z offset */
    smp.valid |= ATT_GYRO_SATURATED;
    (void)att_step(&f, &smp, NULL);
    for (i = 0; i < 9; ++i) {
        /* only this step's own prediction is left */
        TEST_ASSERT_TRUE(fabs(ekf_to_double(f.vars.bias.V[i])) <= 2.0 * cfg.dt);
    }
}

/* The consider recursion against a Monte Carlo of what it describes: an error corrected
 * with gain k per step towards a measurement whose error is AR(1) (correlation rho). */
static void test_consider_colored_error_matches_simulation(void)
{
    const double k = 0.01, rho = 0.995, n_var = 1.0;
    const ekf_scalar_t kf[2] = {EKF_C(0.01), EKF_C(0.01)};
    att_consider_t c;
    ts_rng_t rng;
    double e = 0.0, n = 0.0, sum2 = 0.0, white;
    int i, count = 0;
    att_consider_reset(&c);
    for (i = 0; i < 20000; ++i) {
        att_consider_accel(&c, kf, EKF_C(1.0), EKF_C(0.995));
    }
    ts_rng_seed(&rng, 3);
    for (i = 0; i < 2000000; ++i) {
        n = rho * n + sqrt(1.0 - rho * rho) * sqrt(n_var) * ts_gauss(&rng);
        e = (1.0 - k) * e + k * n;
        if (i > 10000) {
            sum2 += e * e;
            ++count;
        }
    }
    white = k * n_var / (2.0 - k); /* what the filter would claim for white noise */
    printf("colored error: considered variance %.5f, simulated %.5f, white-noise value %.5f\n", ekf_to_double(c.tilt[0]),
           sum2 / count, white);
    TEST_ASSERT_TRUE(fabs(ekf_to_double(c.tilt[0]) / (sum2 / count) - 1.0) < 0.05);
    TEST_ASSERT_TRUE(ekf_to_double(c.tilt[0]) > 10.0 * white);
}

static void test_reported_covariance_contains_references(void)
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    att_settings_t s = att_default_settings;
    att_ekf_t f;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    att_sample_t smp;
    ekf_scalar_t c[6], var[ATT_N];
    int k;
    s.accel_ref_sigma = EKF_C(0.01);
    s.mag_ref_sigma = EKF_C(0.05);
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 2, 0.0, 0.0, 0.0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &s));
    for (k = 0; k < 200; ++k) {
        ts_sim_step(&sim, zero, NULL, &smp);
        (void)att_step(&f, &smp, NULL);
    }
    att_get_angle_covariance(&f, c);
    att_get_variances(&f, var);
    TEST_ASSERT_TRUE(ekf_to_double(c[0]) >= ekf_to_double(att_cov_var(&f.vars.cov, ATT_PHI)) + 0.99e-4);
    TEST_ASSERT_TRUE(ekf_to_double(c[2]) >= ekf_to_double(att_cov_var(&f.vars.cov, ATT_PSI)) + 0.99 * 0.0025);
    TEST_ASSERT_TRUE(var[ATT_PHI] == c[0] && var[ATT_THETA] == c[1] && var[ATT_PSI] == c[2]);
    TEST_ASSERT_TRUE(var[ATT_P] == att_cov_var(&f.vars.cov, ATT_P));
}

/* att_bias_predict reads D1's entries by their place in att_gen_f1_pattern: angle row a,
 * column j of the body rates and angles at 6 a + j. */
static void test_f1_pattern_as_the_bias_filter_reads_it(void)
{
    int a, j;
    TEST_ASSERT_EQUAL_INT(18, ATT_GEN_F1_NNZ);
    for (a = 0; a < 3; ++a) {
        for (j = 0; j < 6; ++j) {
            TEST_ASSERT_EQUAL_INT(ATT_PHI + a, att_gen_f1_pattern[6 * a + j].row);
            TEST_ASSERT_EQUAL_INT(j, att_gen_f1_pattern[6 * a + j].col);
        }
    }
}

/* The accelerometer's update moves the offset only at right angles to gravity (up): an
 * offset along up turns the heading alone, which the tilt cannot see. */
static void test_accelerometer_learns_only_horizontal_offset(void)
{
    static const ekf_scalar_t up[3] = {EKF_C(0), EKF_C(0), EKF_C(1)};
    static const ekf_scalar_t h[3] = {EKF_C(1), EKF_C(0), EKF_C(0)};
    static const ekf_scalar_t pht[3] = {EKF_C(1e-4), EKF_C(0), EKF_C(0)};
    int with_up;
    for (with_up = 0; with_up < 2; ++with_up) {
        att_bias_t bf;
        ekf_scalar_t x_ang[3] = {EKF_C(0), EKF_C(0), EKF_C(0)};
        double pb_up0, pb_up1, c0, c2, expect02;
        att_bias_reset(&bf, &att_default_settings.bias);
        /* the x-z covariance after the update, from the gain's p = Pb u, u = -h V unit */
        c0 = ekf_to_double(bf.Pb[0]) * 1e-3;
        c2 = ekf_to_double(bf.Pb[2]) * 1e-3;
        expect02 = -c0 * c2 / (1e-4 + (c0 + c2) * 1e-3);
        /* the roll error depends on the offset's x and z components (s) */
        bf.V[0] = EKF_C(1);
        bf.V[2] = EKF_C(1);
        pb_up0 = ekf_to_double(bf.Pb[2]);
        TEST_ASSERT_EQUAL_INT(1, att_bias_update(&bf, 1, h, pht, EKF_C(0.005), EKF_C(1e-4), EKF_C(1),
                                                 with_up ? up : NULL, x_ang));
        pb_up1 = ekf_to_double(bf.Pb[2]);
        TEST_ASSERT_TRUE(fabs(ekf_to_double(bf.b[0])) > 1e-6);
        /* Joseph's form for the projected gain keeps the cross term of the full update */
        TEST_ASSERT_TRUE(fabs(ekf_to_double(bf.Pb[4]) - expect02) <= 1e-2 * fabs(expect02));
        if (with_up) {
            /* nothing moves along up: neither the offset nor its variance */
            TEST_ASSERT_TRUE(bf.b[2] == EKF_C(0));
            TEST_ASSERT_TRUE(fabs(pb_up1 - pb_up0) <= 1e-6 * pb_up0);
        } else {
            TEST_ASSERT_TRUE(fabs(ekf_to_double(bf.b[2])) > 1e-6);
            TEST_ASSERT_TRUE(pb_up1 < 0.9 * pb_up0);
        }
        {
            const ekf_scalar_t *pb = bf.Pb;
            const ekf_scalar_t full[9] = {pb[0], pb[3], pb[4], pb[3], pb[1], pb[5], pb[4], pb[5], pb[2]};
            TEST_ASSERT_TRUE(ts_is_positive_definite(full, 3, NULL));
        }
    }
}

/* The offset's update refuses an innovation beyond 3 sigma of its variance s_b (not the
 * offset's doing) and takes one within. */
static void test_offset_update_gate_is_three_sigma(void)
{
    static const ekf_scalar_t h[3] = {EKF_C(1), EKF_C(0), EKF_C(0)};
    static const ekf_scalar_t pht[3] = {EKF_C(1e-4), EKF_C(0), EKF_C(0)};
    int k;
    for (k = 0; k < 2; ++k) {
        const double n_sigma = (k == 0) ? 2.5 : 3.2;
        att_bias_t bf;
        ekf_scalar_t x_ang[3] = {EKF_C(0), EKF_C(0), EKF_C(0)};
        double c0, sb;
        att_bias_reset(&bf, &att_default_settings.bias);
        bf.V[0] = EKF_C(1);
        c0 = ekf_to_double(bf.Pb[0]) * 1e-3;
        sb = 1e-4 + c0 * 1e-3; /* S + u Pb u^T with u = -h V unit */
        TEST_ASSERT_EQUAL_INT(k == 0 ? 1 : 0, att_bias_update(&bf, 1, h, pht, ekf_from_double(n_sigma * sqrt(sb)),
                                                              EKF_C(1e-4), EKF_C(1), NULL, x_ang));
        TEST_ASSERT_TRUE((bf.b[0] != EKF_C(0)) == (k == 0));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_f1_pattern_as_the_bias_filter_reads_it);
    RUN_TEST(test_offset_learned_in_motion_9d);
    RUN_TEST(test_offset_learned_in_motion_6d);
    RUN_TEST(test_rest_takes_over);
    RUN_TEST(test_accelerometer_learns_only_horizontal_offset);
    RUN_TEST(test_offset_update_gate_is_three_sigma);
    RUN_TEST(test_saturated_gyro_forgets_sensitivity);
    RUN_TEST(test_consider_colored_error_matches_simulation);
    RUN_TEST(test_reported_covariance_contains_references);
    return UNITY_END();
}
