/*
 * test_att_lowpass.c - the accelerometer low-pass in a frame that turns with the body
 * (firmware/att/att_lowpass.c; docs/derivation.md, "Linear acceleration"): the turn by C^T,
 * the blend's step response in closed form for one and two stages, the restart, and the
 * property the design rests on: gravity, earth-fixed, passes a body turning at a constant
 * rate without lag.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "att_lowpass.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define DT 0.01

static void set_vec(ekf_scalar_t out[3], double x, double y, double z)
{
    out[0] = ekf_from_double(x);
    out[1] = ekf_from_double(y);
    out[2] = ekf_from_double(z);
}

static att_vars_t empty_vars(void)
{
    att_vars_t v;
    memset(&v, 0, sizeof v);
    return v;
}

/* The turn is C^T v for a rotation C about z by 0.3 rad (the new body axes in the old):
 * (c x + s y, -s x + c y, z); the first stage turns only with two stages; an empty low-pass
 * is left alone. */
static void test_turn(void)
{
    const double a = 0.3, c = cos(a), s = sin(a), u[3] = {0.0, 0.0, a};
    double C[9];
    ekf_scalar_t rot[9];
    int order, i;
    af_rotation(u, C);
    for (i = 0; i < 9; ++i) {
        rot[i] = ekf_from_double(C[i]);
    }
    for (order = 1; order <= 2; ++order) {
        att_settings_t st = att_default_settings;
        att_vars_t v = empty_vars();
        st.accel_lpf_order = (uint16_t)order;
        set_vec(v.accel_lp, 1.0, 2.0, 9.0);
        set_vec(v.accel_lp1, -1.0, 0.5, 9.5);
        v.accel_lp_valid = 1u;
        att_lowpass_turn(&v, &st, rot);
        AF_NEAR_S(c * 1.0 + s * 2.0, v.accel_lp[0], 4.0 * af_ulp(10.0));
        AF_NEAR_S(-s * 1.0 + c * 2.0, v.accel_lp[1], 4.0 * af_ulp(10.0));
        AF_NEAR_S(9.0, v.accel_lp[2], 4.0 * af_ulp(10.0));
        if (order == 2) {
            AF_NEAR_S(c * -1.0 + s * 0.5, v.accel_lp1[0], 4.0 * af_ulp(10.0));
            AF_NEAR_S(-s * -1.0 + c * 0.5, v.accel_lp1[1], 4.0 * af_ulp(10.0));
        } else {
            TEST_ASSERT_TRUE(v.accel_lp1[0] == ekf_from_double(-1.0) && v.accel_lp1[1] == ekf_from_double(0.5));
        }
    }
    {
        att_vars_t v = empty_vars();
        set_vec(v.accel_lp, 1.0, 2.0, 9.0);
        att_lowpass_turn(&v, &att_default_settings, rot);
        TEST_ASSERT_TRUE(v.accel_lp[0] == ekf_from_double(1.0) && v.accel_lp[1] == ekf_from_double(2.0));
    }
}

/* Step response from zero with k = dt / (tau + dt), q = 1 - k: one stage a (1 - q^n), two
 * stages a (1 - q^n - n k q^n) (the first stage a (1 - q^n) feeding the second). */
static void test_step_response(void)
{
    const double tau = 0.1, k = DT / (tau + DT), q = 1.0 - k, a = 5.0;
    int order;
    for (order = 1; order <= 2; ++order) {
        att_settings_t st = att_default_settings;
        att_vars_t v = empty_vars();
        ekf_scalar_t in[3];
        int n;
        st.accel_lpf_tau = ekf_from_double(tau);
        st.accel_lpf_order = (uint16_t)order;
        v.accel_lp_valid = 1u; /* holding zero */
        set_vec(in, a, -a, 2.0 * a);
        for (n = 1; n <= 25; ++n) {
            const double qn = pow(q, (double)n);
            const double y = (order == 1) ? 1.0 - qn : 1.0 - qn - n * k * qn;
            att_lowpass_blend(&v, &st, in, ekf_from_double(DT));
            AF_NEAR_S(a * y, v.accel_lp[0], 32.0 * af_ulp(2.0 * a));
            AF_NEAR_S(-a * y, v.accel_lp[1], 32.0 * af_ulp(2.0 * a));
            AF_NEAR_S(2.0 * a * y, v.accel_lp[2], 32.0 * af_ulp(2.0 * a));
            if (order == 2) {
                AF_NEAR_S(a * (1.0 - qn), v.accel_lp1[0], 32.0 * af_ulp(2.0 * a));
            }
        }
    }
}

/* A restarted (empty) low-pass takes the sample in every stage. */
static void test_restart_takes_the_sample(void)
{
    att_settings_t st = att_default_settings;
    att_vars_t v = empty_vars();
    ekf_scalar_t in[3];
    int i;
    st.accel_lpf_order = 2u;
    set_vec(v.accel_lp, 100.0, 100.0, 100.0);
    set_vec(v.accel_lp1, -100.0, 100.0, -100.0);
    set_vec(in, 0.5, -0.25, 9.75);
    att_lowpass_blend(&v, &st, in, ekf_from_double(DT));
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(v.accel_lp[i] == in[i] && v.accel_lp1[i] == in[i]);
    }
    TEST_ASSERT_EQUAL_UINT8(1u, v.accel_lp_valid);
}

/* Gravity is earth-fixed: a body turning at 1 rad/s about a tilted axis sees it as
 * R(t)^T g; turned with each step's rotation and blended with that sample, the low-pass
 * stays on it (no lag) for both orders, to rounding. Turned the wrong way (C instead of C^T)
 * it would lag by about 2 |w| tau = 0.2 rad. */
static void test_gravity_passes_without_lag(void)
{
    const double w[3] = {0.6, -0.5, 0.62}, g[3] = {0.0, 0.0, 9.81};
    double C[9], R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, u[3];
    ekf_scalar_t rot[9];
    int order, n, i, j, k;
    for (i = 0; i < 3; ++i) {
        u[i] = w[i] * DT;
    }
    af_rotation(u, C);
    for (i = 0; i < 9; ++i) {
        rot[i] = ekf_from_double(C[i]);
    }
    for (order = 1; order <= 2; ++order) {
        att_settings_t st = att_default_settings;
        att_vars_t v = empty_vars();
        st.accel_lpf_order = (uint16_t)order;
        memcpy(R, (const double[9]){1, 0, 0, 0, 1, 0, 0, 0, 1}, sizeof R);
        for (n = 0; n < 300; ++n) {
            double Rn[9], gb[3];
            ekf_scalar_t in[3];
            if (n > 0) {
                att_lowpass_turn(&v, &st, rot);
                for (i = 0; i < 3; ++i) {
                    for (j = 0; j < 3; ++j) {
                        Rn[3 * i + j] = 0.0;
                        for (k = 0; k < 3; ++k) {
                            Rn[3 * i + j] += R[3 * i + k] * C[3 * k + j];
                        }
                    }
                }
                memcpy(R, Rn, sizeof R);
            }
            for (i = 0; i < 3; ++i) {
                gb[i] = R[i] * g[0] + R[3 + i] * g[1] + R[6 + i] * g[2];
                in[i] = ekf_from_double(gb[i]);
            }
            att_lowpass_blend(&v, &st, in, ekf_from_double(DT));
            for (i = 0; i < 3; ++i) {
                AF_NEAR_S(gb[i], v.accel_lp[i], 256.0 * af_ulp(9.81));
            }
        }
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_turn);
    RUN_TEST(test_step_response);
    RUN_TEST(test_restart_takes_the_sample);
    RUN_TEST(test_gravity_passes_without_lag);
    af_print_worst();
    return UNITY_END();
}
