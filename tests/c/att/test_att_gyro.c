/*
 * test_att_gyro.c - the gyroscope stage (firmware/att/att_gyro.c; docs/derivation.md,
 * "Gyroscope", "Gyroscope saturation", "Innovation gate", "Gate timeouts"): the three scalar
 * updates against the batch Kalman update in double (H = [I 0 0], R = gyro_noise^2 / dt,
 * the offsets subtracted and clamped together within bias_max), the gate and its bypass, a
 * pitch pushed over +-90 deg by the update, and the saturated sample's P + G diag(e) G^T.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_fixture.h"
#include "att_gyro.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define DT 0.01

static const double k_x[ATT_N] = {0.1, -0.2, 0.3, 0.2, 0.3, 0.4, 0.05, -0.1, 0.2};
static const double k_var[ATT_N] = {0.01, 0.02, 0.005, 1e-3, 2e-3, 5e-3, 0.03, 0.01, 0.02};

/* gyro_noise 0.01 rad/sqrt(s): R = 0.01 (rad/s)^2 at 10 ms, of the size of the rate variances */
static att_settings_t settings(void)
{
    att_settings_t s = att_default_settings;
    s.gyro_noise = EKF_C(0.01);
    return s;
}

static void x_of(const att_vars_t *v, double x[ATT_N])
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        x[i] = ekf_to_double(v->x[i]);
    }
}

static void state_near(const att_vars_t *v, const double want[ATT_N], double tol)
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        AF_NEAR_S(want[i], v->x[i], tol);
    }
}

/* The expected result of fusing z (rad/s, net of the offsets) with H = [I 0 0]. */
static void expect_fused(const att_vars_t *v, const att_settings_t *s, const double z[3], double x[ATT_N],
                         double P[ATT_N * ATT_N])
{
    double H[3 * ATT_N], nu[3], r[3];
    const double R = ekf_to_double(ekf_sq(s->gyro_noise)) / DT;
    int i;
    x_of(v, x);
    af_cov(v, P);
    memset(H, 0, sizeof H);
    for (i = 0; i < 3; ++i) {
        H[i * ATT_N + ATT_P + i] = 1.0;
        nu[i] = z[i] - x[ATT_P + i];
        r[i] = R;
    }
    af_batch_update(x, P, H, nu, r, 3);
}

static void set_gyro(const double g[3], ekf_scalar_t out[3])
{
    int i;
    for (i = 0; i < 3; ++i) {
        out[i] = ekf_from_double(g[i]);
    }
}

/* The sequential updates equal the batch update of the rate vector, the rest offset and the
 * offset learned in motion subtracted from the sample; the angles and Euler rates move
 * through their correlation with the rates. */
static void test_update_equals_batch(void)
{
    const att_settings_t s = settings();
    const double g[3] = {0.15, -0.1, 0.2}, rest[3] = {0.01, 0.0, -0.01}, b[3] = {0.002, 0.001, 0.0};
    double P0[ATT_N * ATT_N], x[ATT_N], P[ATT_N * ATT_N], z[3];
    att_vars_t v;
    ekf_scalar_t gs[3];
    int i;
    af_random_cov(1, k_var, P0);
    af_vars_full(&v, &s, k_x, P0);
    for (i = 0; i < 3; ++i) {
        v.rest.bias[i] = ekf_from_double(rest[i]);
        v.bias.b[i] = ekf_from_double(b[i]);
        z[i] = g[i] - rest[i] - b[i];
    }
    expect_fused(&v, &s, z, x, P);
    set_gyro(g, gs);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    state_near(&v, x, 32.0 * af_ulp(0.5));
    af_cov_near(&v, P, 32.0 * af_ulp(0.03), __LINE__);
    TEST_ASSERT_EQUAL_UINT32(3u, v.diag.gyro_fused);
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GYRO_GATED);
}

/* The offset learned in motion is clamped so that it and the rest offset together stay
 * within +-bias_max, before it is subtracted. */
static void test_offsets_clamped_together(void)
{
    const att_settings_t s = settings();
    const double m = ekf_to_double(s.rest.bias_max);
    const double g[3] = {0.15, -0.1, 0.2};
    double x[ATT_N], P[ATT_N * ATT_N], z[3];
    att_vars_t v;
    ekf_scalar_t gs[3];
    af_vars(&v, &s, k_x, k_var);
    v.rest.bias[0] = ekf_from_double(m - 0.005);
    v.bias.b[0] = EKF_C(0.01);  /* together 0.005 beyond: clamped to 0.005 */
    v.bias.b[1] = EKF_C(-0.05); /* clamped to -bias_max */
    v.bias.b[2] = EKF_C(0.001); /* within */
    z[0] = g[0] - m;
    z[1] = g[1] + m;
    z[2] = g[2] - 0.001;
    expect_fused(&v, &s, z, x, P);
    set_gyro(g, gs);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    AF_NEAR_S(0.005, v.bias.b[0], af_ulp(0.04));
    AF_NEAR_S(-m, v.bias.b[1], af_ulp(0.04));
    AF_NEAR_S(0.001, v.bias.b[2], af_ulp(0.001));
    state_near(&v, x, 32.0 * af_ulp(0.5));
}

/* gyro_gate 3: an axis whose innovation is beyond 3 sqrt(S) is not fused (the others are),
 * its test ratio nu^2 / (9 S), the flag and the gate clock set; a consistent sample clears
 * both. P diagonal: the axes are independent. */
static void test_gate(void)
{
    att_settings_t s = settings();
    const double S = k_var[ATT_P] + 0.01, nu[3] = {0.5, 0.1, -0.05};
    double g[3];
    att_vars_t v;
    ekf_scalar_t gs[3];
    int i;
    s.gyro_gate = EKF_C(3);
    af_vars(&v, &s, k_x, k_var);
    for (i = 0; i < 3; ++i) {
        g[i] = k_x[ATT_P + i] + nu[i];
    }
    set_gyro(g, gs);
    TEST_ASSERT_EQUAL_INT(EKF_GATED, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    TEST_ASSERT_TRUE(v.x[ATT_P] == ekf_from_double(k_x[ATT_P]));
    AF_NEAR_S(k_x[ATT_Q] + k_var[ATT_Q] / (k_var[ATT_Q] + 0.01) * nu[1], v.x[ATT_Q], 8.0 * af_ulp(0.5));
    AF_NEAR_S(nu[0] * nu[0] / (9.0 * S), v.diag.gyro_ratio[0], 8.0 * af_ulp(2.0));
    TEST_ASSERT_EQUAL_UINT32(1u, v.diag.gyro_gated);
    TEST_ASSERT_EQUAL_UINT32(2u, v.diag.gyro_fused);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_GYRO_GATED, v.flags & ATT_FLAG_GYRO_GATED);
    TEST_ASSERT_TRUE(v.gated_time[0] > EKF_C(0));
    set_gyro(k_x, gs);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GYRO_GATED);
    TEST_ASSERT_TRUE(v.gated_time[0] == EKF_C(0));
}

/* Gated for longer than gate_timeout: the gate is bypassed (the innovation fused, the
 * bypass flagged, the offset's learning held) and stays so, the clock running, until the
 * innovations pass the configured gate again. */
static void test_gate_bypass_after_timeout(void)
{
    att_settings_t s = settings();
    const double nu = 0.5;
    double g[3];
    att_vars_t v;
    ekf_scalar_t gs[3];
    s.gyro_gate = EKF_C(3);
    af_vars(&v, &s, k_x, k_var);
    v.gated_time[0] = ekf_add(s.gate_timeout, EKF_C(0.5));
    memcpy(g, k_x, sizeof g);
    g[0] += nu;
    set_gyro(g, gs);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    AF_NEAR_S(k_x[ATT_P] + k_var[ATT_P] / (k_var[ATT_P] + 0.01) * nu, v.x[ATT_P], 8.0 * af_ulp(0.5));
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_GATE_BYPASS, v.flags & ATT_FLAG_GATE_BYPASS);
    TEST_ASSERT_TRUE(v.bias.hold == s.bias.hold_time);
    TEST_ASSERT_TRUE(v.gated_time[0] > s.gate_timeout);
    set_gyro(k_x, gs); /* within the gate of the updated state */
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    TEST_ASSERT_EQUAL_UINT32(0u, v.flags & ATT_FLAG_GATE_BYPASS);
    TEST_ASSERT_TRUE(v.gated_time[0] == EKF_C(0));
}

/* An update that moves the pitch over +90 deg (a rate correlated with it at 0.9) remaps the
 * angles to the same rotation (phi + pi, pi - theta, psi + pi), negates the pitch and pitch
 * rate rows of P, counts the remap, and sets the gimbal flag from the new pitch. */
static void test_update_over_the_top(void)
{
    att_settings_t s = settings();
    double x0[ATT_N], var[ATT_N], P0[ATT_N * ATT_N], x[ATT_N], P[ATT_N * ATT_N], z[3];
    att_vars_t v;
    ekf_scalar_t gs[3];
    int i, j;
    s.gimbal_limit = EKF_C(1.5);
    memcpy(x0, k_x, sizeof x0);
    x0[ATT_THETA] = 1.55;
    for (i = 0; i < ATT_N; ++i) {
        var[i] = (i == ATT_Q) ? 1.0 : 0.01;
    }
    memset(P0, 0, sizeof P0);
    for (i = 0; i < ATT_N; ++i) {
        P0[i * ATT_N + i] = var[i];
    }
    P0[ATT_Q * ATT_N + ATT_THETA] = P0[ATT_THETA * ATT_N + ATT_Q] = 0.09;
    af_vars_full(&v, &s, x0, P0);
    for (i = 0; i < 3; ++i) {
        z[i] = x0[ATT_P + i] + ((i == 1) ? 0.5 : 0.0);
    }
    expect_fused(&v, &s, z, x, P);
    TEST_ASSERT_TRUE(x[ATT_THETA] > 1.5707963267948966 + 0.02);
    /* the remap, in double */
    x[ATT_THETA] = 3.141592653589793 - x[ATT_THETA];
    x[ATT_PHI] -= 3.141592653589793; /* 0.2 + pi and 0.4 + pi wrapped into [-pi, pi) */
    x[ATT_PSI] -= 3.141592653589793;
    x[ATT_THETAD] = -x[ATT_THETAD];
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            if ((i == ATT_THETA || i == ATT_THETAD) != (j == ATT_THETA || j == ATT_THETAD)) {
                P[i * ATT_N + j] = -P[i * ATT_N + j];
            }
        }
    }
    for (i = 0; i < 3; ++i) {
        gs[i] = ekf_from_double(z[i]);
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    state_near(&v, x, 32.0 * af_ulp(4.0));
    af_cov_near(&v, P, 32.0 * af_ulp(1.0), __LINE__);
    TEST_ASSERT_EQUAL_UINT32(1u, v.diag.remaps);
    TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_GIMBAL_LOCK, v.flags & ATT_FLAG_GIMBAL_LOCK);
}

/* A saturated sample: not fused; each body-rate variance raised to at least w_sat^2 (w_sat
 * the largest component), P += G diag(e) G^T with e_i = max(0, w_sat^2 - P_ii) and
 * G = [I; 0; W(phi, theta)]; the offset's sensitivity forgotten, its learning held, the
 * low-pass restarted, the rate state marked as a guess until the next measured sample. */
static void test_saturated_sample(void)
{
    const att_settings_t s = settings();
    const double g[3] = {8.7, -1.0, 0.3}, w2 = 8.7 * 8.7;
    const double phi = k_x[ATT_PHI], th = k_x[ATT_THETA];
    const double sp = sin(phi), cp = cos(phi), t = tan(th), sec = 1.0 / cos(th);
    const double W[9] = {1.0, sp * t, cp * t, 0.0, cp, -sp, 0.0, sp * sec, cp * sec};
    double var[ATT_N], P0[ATT_N * ATT_N], P[ATT_N * ATT_N], Gm[ATT_N * 3], e[3];
    att_vars_t v;
    ekf_scalar_t gs[3];
    int i, j, k;
    memcpy(var, k_var, sizeof var);
    var[ATT_Q] = 80.0; /* already above w_sat^2: not raised */
    af_random_cov(2, var, P0);
    af_vars_full(&v, &s, k_x, P0);
    for (i = 0; i < 9; ++i) {
        v.bias.V[i] = EKF_C(0.3);
    }
    v.accel_lp_valid = 1u;
    af_cov(&v, P);
    memset(Gm, 0, sizeof Gm);
    for (k = 0; k < 3; ++k) {
        e[k] = fmax(0.0, w2 - P[(ATT_P + k) * (ATT_N + 1)]);
        Gm[(ATT_P + k) * 3 + k] = 1.0;
        for (i = 0; i < 3; ++i) {
            Gm[(ATT_PHID + i) * 3 + k] = W[3 * i + k];
        }
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            for (k = 0; k < 3; ++k) {
                P[i * ATT_N + j] += Gm[i * 3 + k] * e[k] * Gm[j * 3 + k];
            }
        }
    }
    set_gyro(g, gs);
    TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_stage_gyro_saturated(&v, &s, gs));
    af_cov_near(&v, P, 16.0 * af_ulp(300.0), __LINE__);
    AF_NEAR_S(w2, att_cov_var(&v.cov, ATT_P), 4.0 * af_ulp(w2));
    AF_NEAR_S(var[ATT_Q], att_cov_var(&v.cov, ATT_Q), 4.0 * af_ulp(80.0));
    state_near(&v, k_x, af_ulp(0.5));
    for (i = 0; i < 9; ++i) {
        TEST_ASSERT_TRUE(v.bias.V[i] == EKF_C(0));
    }
    TEST_ASSERT_TRUE(v.bias.hold == s.bias.hold_time);
    TEST_ASSERT_EQUAL_UINT8(0u, v.accel_lp_valid);
    TEST_ASSERT_EQUAL_UINT8(1u, v.rate_unmeasured);
    TEST_ASSERT_EQUAL_UINT32(1u, v.diag.gyro_saturated);
    TEST_ASSERT_EQUAL_UINT32(0u, v.diag.gyro_fused);
    set_gyro(k_x, gs);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_gyro(&v, &s, gs, EKF_C(DT)));
    TEST_ASSERT_EQUAL_UINT8(0u, v.rate_unmeasured);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_update_equals_batch);
    RUN_TEST(test_offsets_clamped_together);
    RUN_TEST(test_gate);
    RUN_TEST(test_gate_bypass_after_timeout);
    RUN_TEST(test_update_over_the_top);
    RUN_TEST(test_saturated_sample);
    af_print_worst();
    return UNITY_END();
}
