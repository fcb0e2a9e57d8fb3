/*
 * test_att_sensor.c - what the measurement stages share (firmware/att/att_sensor.h, inline;
 * docs/derivation.md, "Innovation gate", "Gate timeouts", "Sample timing"): the
 * measurement trigonometry and the reuse of the prediction's, the gate and its time-out,
 * the gate clock and the bypass flag, the turn of a vector sample to its interval's end
 * (against the exact rotation, with the bound of the series' first omitted term), the gate
 * test and the variance reduction.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "att_sensor.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const double k_x[ATT_N] = {0.5, -1.0, 2.0, 0.3, -0.4, 1.0, 0.0, 0.0, 0.0};
static const double k_var[ATT_N] = {0.01, 0.01, 0.01, 1e-3, 1e-3, 1e-2, 0.01, 0.01, 0.01};

/* The prediction's trigonometry is taken when it is of these very angles (and valid,
 * cos(theta) > 0), else sin and cos are computed; sec(theta) is never used (0). */
static void test_trig_reuse(void)
{
    const att_settings_t *s = &att_default_settings;
    int c;
    for (c = 0; c < 3; ++c) {
        att_vars_t v;
        att_trig_t t;
        af_vars(&v, s, k_x, k_var);
        v.trig.sphi = EKF_C(0.125); /* marks: not the sines of these angles */
        v.trig.cphi = EKF_C(0.25);
        v.trig.sth = EKF_C(0.375);
        v.trig.cth = (c == 2) ? EKF_C(0) : EKF_C(0.5);
        v.trig.secth = EKF_C(2);
        v.trig_at[0] = v.x[ATT_PHI];
        v.trig_at[1] = (c == 1) ? ekf_add(v.x[ATT_THETA], EKF_C(1e-3)) : v.x[ATT_THETA];
        att_sensor_trig(&v, &t);
        if (c == 0) {
            TEST_ASSERT_TRUE(t.sphi == v.trig.sphi && t.cphi == v.trig.cphi && t.sth == v.trig.sth &&
                             t.cth == v.trig.cth);
        } else {
            AF_NEAR_S(sin(k_x[ATT_PHI]), t.sphi, 4.0 * af_ulp(1.0));
            AF_NEAR_S(cos(k_x[ATT_PHI]), t.cphi, 4.0 * af_ulp(1.0));
            AF_NEAR_S(sin(k_x[ATT_THETA]), t.sth, 4.0 * af_ulp(1.0));
            AF_NEAR_S(cos(k_x[ATT_THETA]), t.cth, 4.0 * af_ulp(1.0));
        }
        TEST_ASSERT_TRUE(t.secth == EKF_C(0));
    }
}

/* The gate is the setting until the sensor has gated for longer than gate_timeout (strictly);
 * then 0 (off), the bypass flagged and the offset's learning held for bias.hold_time.
 * gate_timeout 0: never bypassed; a gate of 0 stays off without a bypass. */
static void test_gate_timeout(void)
{
    att_settings_t s = att_default_settings;
    att_vars_t v;
    af_vars(&v, &s, k_x, k_var);
    v.gated_time[ATT_SENSOR_ACCEL] = s.gate_timeout;
    TEST_ASSERT_TRUE(att_sensor_gate(&v, &s, ATT_SENSOR_ACCEL, EKF_C(3)) == EKF_C(3));
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GATE_BYPASS);
    v.gated_time[ATT_SENSOR_ACCEL] = ekf_add(s.gate_timeout, EKF_C(0.01));
    TEST_ASSERT_TRUE(att_sensor_gate(&v, &s, ATT_SENSOR_GYRO, EKF_C(3)) == EKF_C(3)); /* its own clock */
    TEST_ASSERT_TRUE(v.bias.hold == EKF_C(0));
    TEST_ASSERT_TRUE(att_sensor_gate(&v, &s, ATT_SENSOR_ACCEL, EKF_C(3)) == EKF_C(0));
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_GATE_BYPASS, v.flags & ATT_FLAG_GATE_BYPASS);
    TEST_ASSERT_TRUE(v.bias.hold == s.bias.hold_time);
    af_vars(&v, &s, k_x, k_var);
    v.gated_time[ATT_SENSOR_ACCEL] = EKF_C(100);
    TEST_ASSERT_TRUE(att_sensor_gate(&v, &s, ATT_SENSOR_ACCEL, EKF_C(0)) == EKF_C(0));
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GATE_BYPASS);
    s.gate_timeout = EKF_C(0);
    TEST_ASSERT_TRUE(att_sensor_gate(&v, &s, ATT_SENSOR_ACCEL, EKF_C(3)) == EKF_C(3));
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GATE_BYPASS);
}

/* The clock: a gated update starts it (running, the smallest positive step: the prediction
 * adds dt) and leaves a running one alone; a passed update stops it. The bypass flag clears
 * only when neither the gyroscope's nor the accelerometer's clock is past gate_timeout. */
static void test_gate_result(void)
{
    const att_settings_t *s = &att_default_settings;
    att_vars_t v;
    af_vars(&v, s, k_x, k_var);
    att_sensor_gate_result(&v, s, ATT_SENSOR_MAG, 1);
    TEST_ASSERT_TRUE(v.gated_time[ATT_SENSOR_MAG] > EKF_C(0));
    TEST_ASSERT_TRUE(v.gated_time[ATT_SENSOR_MAG] <= EKF_SCALAR_EPS);
    v.gated_time[ATT_SENSOR_MAG] = EKF_C(0.5);
    att_sensor_gate_result(&v, s, ATT_SENSOR_MAG, 1);
    TEST_ASSERT_TRUE(v.gated_time[ATT_SENSOR_MAG] == EKF_C(0.5));
    /* bypassed accelerometer: another sensor passing does not clear the flag */
    v.flags |= ATT_FLAG_GATE_BYPASS;
    v.gated_time[ATT_SENSOR_ACCEL] = ekf_add(s->gate_timeout, EKF_C(0.5));
    att_sensor_gate_result(&v, s, ATT_SENSOR_MAG, 0);
    TEST_ASSERT_TRUE(v.gated_time[ATT_SENSOR_MAG] == EKF_C(0));
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_GATE_BYPASS, v.flags & ATT_FLAG_GATE_BYPASS);
    v.gated_time[ATT_SENSOR_GYRO] = ekf_add(s->gate_timeout, EKF_C(0.5));
    att_sensor_gate_result(&v, s, ATT_SENSOR_ACCEL, 0);
    TEST_ASSERT_TRUE(v.gated_time[ATT_SENSOR_ACCEL] == EKF_C(0));
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_GATE_BYPASS, v.flags & ATT_FLAG_GATE_BYPASS);
    att_sensor_gate_result(&v, s, ATT_SENSOR_GYRO, 0);
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GATE_BYPASS);
}

/* The exact turn: Exp(-[w h]x) vec, h the half interval. */
static void exact_turn(const double w[3], double h, const ekf_scalar_t vec[3], double out[3])
{
    double u[3], C[9];
    int i;
    for (i = 0; i < 3; ++i) {
        u[i] = -w[i] * h;
    }
    af_rotation(u, C);
    for (i = 0; i < 3; ++i) {
        out[i] = C[3 * i] * ekf_to_double(vec[0]) + C[3 * i + 1] * ekf_to_double(vec[1]) +
                 C[3 * i + 2] * ekf_to_double(vec[2]);
    }
}

/* A vector sample is turned to its interval's end by the body's rotation over half its own
 * interval (the step, or after a gap dt_nom), to second order: against the exact rotation
 * within the first omitted term, |th|^3 |v| / 6 (th = |w| h); not at all when the rate state
 * is a guess. */
static void test_to_interval_end(void)
{
    static const double cases[4][2] = {/* dt, dt_nom */ {0.01, 0.0}, {0.05, 0.01}, {0.01, 0.02}, {0.004, 0.004}};
    const att_settings_t *s = &att_default_settings;
    const double nw = sqrt(k_x[0] * k_x[0] + k_x[1] * k_x[1] + k_x[2] * k_x[2]);
    ekf_scalar_t vec[3], out[3];
    att_vars_t v;
    int c, i;
    af_gravity_body(9.81, 0.3, -0.4, vec);
    for (c = 0; c < 4; ++c) {
        const double own = (cases[c][1] > 0.0) ? fmin(cases[c][0], cases[c][1]) : cases[c][0];
        const double th = nw * own / 2.0;
        double want[3];
        af_vars(&v, s, k_x, k_var);
        v.dt_nom = ekf_from_double(cases[c][1]);
        att_sensor_to_interval_end(&v, vec, ekf_from_double(cases[c][0]), out);
        exact_turn(k_x, own / 2.0, vec, want);
        for (i = 0; i < 3; ++i) {
            AF_NEAR_S(want[i], out[i], th * th * th / 6.0 * 9.81 + 16.0 * af_ulp(9.81));
        }
    }
    v.rate_unmeasured = 1u;
    att_sensor_to_interval_end(&v, vec, EKF_C(0.01), out);
    TEST_ASSERT_EQUAL_MEMORY(vec, out, sizeof out);
}

/* An innovation fails a gate of g sigmas when nu^2 > g^2 S (strictly); a gate of 0 is off.
 * The reduction of a variance is 1 - after / before, 0 for a variance of 0. */
static void test_gate_test_and_reduction(void)
{
    ekf_innov_t info;
    memset(&info, 0, sizeof info);
    info.variance = EKF_C(0.25);
    info.innovation = EKF_C(1.5);
    TEST_ASSERT_EQUAL_INT(0, att_sensor_fails_gate(&info, EKF_C(3)));
    info.innovation = EKF_C(-1.5);
    TEST_ASSERT_EQUAL_INT(0, att_sensor_fails_gate(&info, EKF_C(3)));
    info.innovation = EKF_C(1.51);
    TEST_ASSERT_EQUAL_INT(1, att_sensor_fails_gate(&info, EKF_C(3)));
    info.innovation = EKF_C(-1.51);
    TEST_ASSERT_EQUAL_INT(1, att_sensor_fails_gate(&info, EKF_C(3)));
    TEST_ASSERT_EQUAL_INT(0, att_sensor_fails_gate(&info, EKF_C(0)));
    AF_NEAR_S(0.75, att_sensor_reduction(EKF_C(0.04), EKF_C(0.01)), 2.0 * af_ulp(1.0));
    TEST_ASSERT_TRUE(att_sensor_reduction(EKF_C(0), EKF_C(0.01)) == EKF_C(0));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_trig_reuse);
    RUN_TEST(test_gate_timeout);
    RUN_TEST(test_gate_result);
    RUN_TEST(test_to_interval_end);
    RUN_TEST(test_gate_test_and_reduction);
    af_print_worst();
    return UNITY_END();
}
