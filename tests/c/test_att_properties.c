/*
 * test_att_properties.c - properties of the estimator that follow from its mathematics
 * (docs/derivation.md), each checked against a computation of its own here in double:
 *
 *   - the accelerometer stage's two scalar updates in the tangent plane, the second
 *     relinearised about the prior, equal the batch EKF update of the two components
 *     ("Accelerometer": noise isotropic across the components);
 *   - the pitch remap (phi, theta, psi) -> (phi + pi, pi - theta, psi + pi) is the same
 *     rotation, and the angle errors map as (d phi, -d theta, d psi): the reported angle
 *     covariance, the offset's share included, transforms with J = diag(1, -1, 1), and all
 *     of P with -1 at the pitch and the pitch rate;
 *   - a gap (a step over 1.5 sample intervals) adds the integrated rate walk
 *     rate_walk^2 e^3 / 3 to the angle variances, a shorter step nothing of the kind;
 *   - the gyroscope noise is a density: R = gyro_noise^2 / dt;
 *   - a saturated gyroscope sample raises each body-rate variance to the square of its
 *     largest component, each by its own deficit;
 *   - the heading's noise: a density, widened by tan^2(dip) times the tilt variance of the
 *     linear acceleration and by the field's norm and dip errors;
 *   - the heading innovation is wrapped: held at a heading of 180 deg no sample is gated;
 *   - a turned field is gated, then after mag_reset_time the heading reset to it, counted once.
 *
 * Built for float, double and fixed point. Found missing by scripts/mutate.py
 * (docs/reliability.md, "Mutation testing").
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att.h"
#include "att_state.h"
#include "testsim.h"
#include "unity.h"

#define DEG (3.14159265358979323846 / 180.0)

/* The filter's update against the batch update computed here, relative to the update's own
 * size: about three times the rounding measured in each build (docs/reliability.md,
 * "Mutation testing"). */
#if defined(EKF_SCALAR_FLOAT)
#define REL_TOL 4e-6
#elif defined(EKF_SCALAR_DOUBLE)
#define REL_TOL 1.5e-14
#else
#define REL_TOL 2e-8
#endif

void setUp(void) {}
void tearDown(void) {}

/* A slowly varying rotation (rad/s at time t, s). */
static void wander(double t, double w[3])
{
    w[0] = 0.5 * sin(0.31 * t);
    w[1] = 0.4 * cos(0.23 * t);
    w[2] = 0.6 * sin(0.17 * t + 1.0);
}

/* A filter after `seconds` of wandering motion at 100 Hz, with every sensor, or (gyro_only)
 * with the gyroscope alone once aligned. */
static void run_motion(att_ekf_t *f, const att_settings_t *s, double seconds, int gyro_only, ts_sim_t *sim)
{
    ts_sim_cfg_t cfg;
    att_sample_t smp;
    double w[3];
    int k;
    ts_sim_default(&cfg);
    cfg.gyro_bias[0] = 0.3 * DEG;
    cfg.gyro_bias[2] = -0.2 * DEG;
    ts_sim_init(sim, &cfg, 21, 0.3, -0.2, 0.7);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(f, s));
    for (k = 0; k < (int)(seconds / cfg.dt); ++k) {
        wander(k * cfg.dt, w);
        ts_sim_step(sim, w, NULL, &smp);
        if (gyro_only && (att_flags(f) & ATT_FLAG_ALIGNED) != 0u) {
            smp.valid = ATT_HAS_GYRO;
        }
        TEST_ASSERT_FALSE(ekf_status_is_error(att_step(f, &smp, NULL)));
    }
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* The batch update of the accelerometer's two tangent-plane components at the prior (x, P):
 * the sample turned to the end of its interval by the rate state (second order, "Sample
 * timing"), its direction e, z = (u_phi . e, u_theta . e) with u_phi = (0, c_phi, -s_phi),
 * u_theta = (-c_th, -s_phi s_th, -c_phi s_th), H = [c_th e_phi; e_theta], R = r I. */
static void batch_accel_update(const double x0[ATT_N], const double P0[ATT_N * ATT_N], const double a_in[3], double dt,
                               double r, double x[ATT_N], double P[ATT_N * ATT_N], double z[2])
{
    const double sp = sin(x0[ATT_PHI]), cp = cos(x0[ATT_PHI]), st = sin(x0[ATT_THETA]), ct = cos(x0[ATT_THETA]);
    const double u[2][3] = {{0.0, cp, -sp}, {-ct, -sp * st, -cp * st}};
    double th[3], c1[3], c2[3], a[3], n, PH[ATT_N][2], S[2][2], Si[2][2], det, K[ATT_N][2];
    int i, j;
    for (i = 0; i < 3; ++i) {
        th[i] = x0[ATT_P + i] * 0.5 * dt;
    }
    cross3(th, a_in, c1);
    cross3(th, c1, c2);
    for (i = 0; i < 3; ++i) {
        a[i] = a_in[i] - c1[i] + 0.5 * c2[i];
    }
    n = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    for (i = 0; i < 2; ++i) {
        z[i] = (u[i][0] * a[0] + u[i][1] * a[1] + u[i][2] * a[2]) / n;
    }
    for (i = 0; i < ATT_N; ++i) { /* P H^T */
        PH[i][0] = P0[i * ATT_N + ATT_PHI] * ct;
        PH[i][1] = P0[i * ATT_N + ATT_THETA];
    }
    S[0][0] = ct * PH[ATT_PHI][0] + r;
    S[0][1] = ct * PH[ATT_PHI][1];
    S[1][0] = PH[ATT_THETA][0];
    S[1][1] = PH[ATT_THETA][1] + r;
    det = S[0][0] * S[1][1] - S[0][1] * S[1][0];
    Si[0][0] = S[1][1] / det;
    Si[1][1] = S[0][0] / det;
    Si[0][1] = -S[0][1] / det;
    Si[1][0] = -S[1][0] / det;
    for (i = 0; i < ATT_N; ++i) {
        K[i][0] = PH[i][0] * Si[0][0] + PH[i][1] * Si[1][0];
        K[i][1] = PH[i][0] * Si[0][1] + PH[i][1] * Si[1][1];
        x[i] = x0[i] + K[i][0] * z[0] + K[i][1] * z[1];
    }
    for (i = 0; i < ATT_N; ++i) { /* P - K (P H^T)^T */
        for (j = 0; j < ATT_N; ++j) {
            P[i * ATT_N + j] = P0[i * ATT_N + j] - K[i][0] * PH[j][0] - K[i][1] * PH[j][1];
        }
    }
}

/* The same as two scalar updates, the second's innovation relinearised about the prior with
 * the first's correction (relin = 1) or not (relin = 0). */
static void sequential_accel_update(const double x0[ATT_N], const double P0[ATT_N * ATT_N], const double z[2], double ct,
                                    double r, int relin, double x[ATT_N], double P[ATT_N * ATT_N])
{
    static const int col[2] = {ATT_PHI, ATT_THETA};
    const double h[2] = {ct, 1.0};
    double b[ATT_N], nu, S;
    int c, i, j;
    memcpy(x, x0, sizeof(double) * ATT_N);
    memcpy(P, P0, sizeof(double) * ATT_N * ATT_N);
    for (c = 0; c < 2; ++c) {
        for (i = 0; i < ATT_N; ++i) {
            b[i] = P[i * ATT_N + col[c]] * h[c];
        }
        S = h[c] * b[col[c]] + r;
        nu = z[c] - (relin ? h[c] * (x[col[c]] - x0[col[c]]) : 0.0);
        for (i = 0; i < ATT_N; ++i) {
            x[i] += b[i] / S * nu;
        }
        for (i = 0; i < ATT_N; ++i) {
            for (j = 0; j < ATT_N; ++j) {
                P[i * ATT_N + j] -= b[i] * b[j] / S;
            }
        }
    }
}

static double max_diff(const double *a, const double *b, int n)
{
    double m = 0.0;
    int i;
    for (i = 0; i < n; ++i) {
        m = fmax(m, fabs(a[i] - b[i]));
    }
    return m;
}

static void test_accel_stage_is_the_batch_update(void)
{
    /* the stage without what is not the update: no low-pass, no adaptive noise, no offset
     * learning (it moves the angles too), no rest detection, no gate */
    att_settings_t s = att_default_settings;
    static att_ekf_t f;
    ts_sim_t sim;
    ekf_scalar_t Ps[ATT_N * ATT_N], a[3];
    double x0[ATT_N], P0[ATT_N * ATT_N], xb[ATT_N], Pb[ATT_N * ATT_N], a_d[3], R[9], up[3] = {0.0, 0.0, 0.0};
    double xs[ATT_N], Pseq[ATT_N * ATT_N], xf[ATT_N], Pf[ATT_N * ATT_N], z[2];
    double dx_max, dP_max, ex, eP, corr, r, wrong;
    const double dt = 0.01, g = 9.81;
    int i;
    s.accel_lpf_tau = EKF_C(0);
    s.accel_adapt_tau = EKF_C(0);
    s.bias.motion = 0u;
    s.rest.bias_tau = EKF_C(0);
    s.accel_gate = EKF_C(0);
    /* a tilt uncertainty the update can reduce (its variance well above the sample's) and
     * roll and pitch errors the rotation has correlated: seconds of gyroscope alone after the
     * alignment */
    s.init_tilt_sigma = EKF_C(0.2);
    run_motion(&f, &s, 4.0, 1, &sim);
    att_get_covariance(&f, Ps);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        P0[i] = ekf_to_double(Ps[i]);
    }
    for (i = 0; i < ATT_N; ++i) {
        x0[i] = ekf_to_double(att_state(&f)[i]);
    }
    /* the roll-pitch correlation that makes the relinearisation matter (and the test able
     * to see it) */
    corr = P0[ATT_PHI * ATT_N + ATT_THETA] / sqrt(P0[ATT_PHI * ATT_N + ATT_PHI] * P0[ATT_THETA * ATT_N + ATT_THETA]);
    /* a sample of gravity seen 2 deg off in roll and 3 deg off in pitch from the estimate */
    ts_euler_to_R(x0[ATT_PHI] + 2.0 * DEG, x0[ATT_THETA] - 3.0 * DEG, x0[ATT_PSI], R);
    up[2] = g;
    for (i = 0; i < 3; ++i) { /* R^T (0, 0, g): the body's reading of gravity */
        a_d[i] = R[3 * 2 + i] * up[2];
        a[i] = ekf_from_double(a_d[i]);
        a_d[i] = ekf_to_double(a[i]);
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_update_accel(&f, a, ekf_from_double(dt)));
    r = ekf_to_double(ekf_div(ekf_sq(s.accel_noise), ekf_from_double(dt))) / (g * g);
    batch_accel_update(x0, P0, a_d, dt, r, xb, Pb, z);
    att_get_covariance(&f, Ps);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        Pf[i] = ekf_to_double(Ps[i]);
    }
    for (i = 0; i < ATT_N; ++i) {
        xf[i] = ekf_to_double(att_state(&f)[i]);
    }
    dx_max = max_diff(xb, x0, ATT_N);
    dP_max = max_diff(Pb, P0, ATT_N * ATT_N);
    ex = max_diff(xf, xb, ATT_N);
    eP = max_diff(Pf, Pb, ATT_N * ATT_N);
    /* this test's own maths: two scalar updates, the second relinearised, are the batch
     * update; without the relinearisation they are not, by far more than the tolerance */
    sequential_accel_update(x0, P0, z, cos(x0[ATT_THETA]), r, 1, xs, Pseq);
    TEST_ASSERT_TRUE(max_diff(xs, xb, ATT_N) <= 1e-12 && max_diff(Pseq, Pb, ATT_N * ATT_N) <= 1e-12);
    sequential_accel_update(x0, P0, z, cos(x0[ATT_THETA]), r, 0, xs, Pseq);
    wrong = max_diff(xs, xb, ATT_N);
    printf("accelerometer stage vs batch update (%s): roll-pitch correlation %.3f; state change %.3g, differs by "
           "%.3g (without relinearisation: %.3g); covariance change %.3g, differs by %.3g\n",
           EKF_SCALAR_NAME, corr, dx_max, ex, wrong, dP_max, eP);
    TEST_ASSERT_TRUE(dx_max > 1.0 * DEG); /* a real correction */
    TEST_ASSERT_TRUE(wrong > 100.0 * REL_TOL * dx_max);
    TEST_ASSERT_TRUE(ex <= REL_TOL * dx_max);
    TEST_ASSERT_TRUE(eP <= REL_TOL * dP_max);
}

static void test_remap_transforms_the_reported_covariance(void)
{
    att_settings_t s = att_default_settings;
    static att_ekf_t f;
    ts_sim_t sim;
    ekf_scalar_t before[6], after[6], v_max = EKF_C(0), P0[ATT_N * ATT_N], P1[ATT_N * ATT_N];
    double worst_p = 0.0, scale_p = 0.0;
    /* (phi theta), (theta psi) change sign with d theta; the rest keep theirs */
    static const double sign[6] = {1.0, 1.0, 1.0, -1.0, 1.0, -1.0};
    double worst = 0.0, scale = 0.0;
    int i;
    s.bias.motion = 2u;
    s.rest.bias_tau = EKF_C(0);
    run_motion(&f, &s, 60.0, 0, &sim);
    for (i = 0; i < 9; ++i) {
        v_max = ekf_max(v_max, ekf_abs(f.vars.bias.V[i]));
    }
    TEST_ASSERT_TRUE(ekf_to_double(v_max) > 0.1); /* the offset's share is in the covariance */
    /* the same rotation written beyond the top: theta -> pi - theta, phi and psi + pi */
    f.vars.x[ATT_THETA] = ekf_sub(EKF_PI, f.vars.x[ATT_THETA]);
    f.vars.x[ATT_PHI] = ekf_wrap_pi(ekf_add(f.vars.x[ATT_PHI], EKF_PI));
    f.vars.x[ATT_PSI] = ekf_wrap_pi(ekf_add(f.vars.x[ATT_PSI], EKF_PI));
    f.vars.x[ATT_THETAD] = ekf_neg(f.vars.x[ATT_THETAD]);
    att_get_angle_covariance(&f, before);
    att_get_covariance(&f, P0);
    TEST_ASSERT_EQUAL_INT(1, att_normalise(&f.vars));
    att_get_angle_covariance(&f, after);
    att_get_covariance(&f, P1);
    /* and all of P with diag(1, .., -1 at theta and theta-dot, .., 1): the pitch rate's
     * correlations change sign with the pitch's */
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        const int r = i / ATT_N, c = i % ATT_N;
        const double sr = (r == ATT_THETA || r == ATT_THETAD) ? -1.0 : 1.0;
        const double sc = (c == ATT_THETA || c == ATT_THETAD) ? -1.0 : 1.0;
        scale_p = fmax(scale_p, fabs(ekf_to_double(P0[i])));
        worst_p = fmax(worst_p, fabs(ekf_to_double(P1[i]) - sr * sc * ekf_to_double(P0[i])));
    }
    for (i = 0; i < 6; ++i) {
        scale = fmax(scale, fabs(ekf_to_double(before[i])));
        worst = fmax(worst, fabs(ekf_to_double(after[i]) - sign[i] * ekf_to_double(before[i])));
    }
    printf("reported angle covariance through the pitch remap (%s): largest entry %.3g, off J c J by %.3g; "
           "all of P: largest %.3g, off by %.3g\n", EKF_SCALAR_NAME, scale, worst, scale_p, worst_p);
    TEST_ASSERT_TRUE(fabs(ekf_to_double(before[5])) > 1e-3 * scale); /* the sign change is visible */
    TEST_ASSERT_TRUE(worst <= 1e-6 * scale);
    TEST_ASSERT_TRUE(worst_p <= 1e-6 * scale_p);
}

/* A step longer than 1.5 sample intervals is a gap: rate_walk^2 e^3 / 3 (e the excess over
 * the interval) integrates into the angles, times sec^2 theta for roll and heading
 * (docs/derivation.md, "Gaps"); a shorter step adds nothing of the kind. Seen as the
 * difference between two copies of one filter that differ only in rate_walk, predicted over
 * the same step (the rest of the prediction adds the same to both). The secant is the one of
 * the pitch the prediction uses, which here differs from the prior's by under 2 %. */
static void test_gap_adds_the_integrated_rate_walk(void)
{
    att_settings_t s = att_default_settings;
    static att_ekf_t f, f1, f2;
    ts_sim_t sim;
    const double w1 = 2.0, w2 = 6.0;
    double dt_nom, k;
    int i;
    s.rate_walk = ekf_from_double(w1);
    run_motion(&f, &s, 4.0, 0, &sim);
    dt_nom = ekf_to_double(f.vars.dt_nom);
    for (k = 1.3; k < 4.0; k += 1.7) { /* 1.3 intervals: not a gap; 3 intervals: a gap */
        const double dt = k * dt_nom, e = (k > 1.5) ? dt - dt_nom : 0.0;
        const double q = (w2 * w2 - w1 * w1) * e * e * e / 3.0;
        const double sec2 = 1.0 / (cos(ekf_to_double(att_state(&f)[ATT_THETA])) *
                                   cos(ekf_to_double(att_state(&f)[ATT_THETA])));
        const double want[3] = {q * sec2, q, q * sec2};
        ekf_scalar_t P1[ATT_N * ATT_N], P2[ATT_N * ATT_N];
        f1 = f;
        f2 = f;
        f2.settings.rate_walk = ekf_from_double(w2);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_predict(&f1, ekf_from_double(dt)));
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_predict(&f2, ekf_from_double(dt)));
        att_get_covariance(&f1, P1);
        att_get_covariance(&f2, P2);
        for (i = 0; i < 3; ++i) {
            const int a = ATT_PHI + i;
            const double got = ekf_to_double(P2[a * ATT_N + a]) - ekf_to_double(P1[a * ATT_N + a]);
            printf("step of %.1f intervals (%s): angle %d variance grows by %.4g more at the larger rate_walk, "
                   "the integrated walk %.4g\n", k, EKF_SCALAR_NAME, i, got, want[i]);
            if (k > 1.5) {
                TEST_ASSERT_TRUE(fabs(got - want[i]) <= 0.05 * want[i]);
            } else {
                TEST_ASSERT_TRUE(fabs(got) <= 1e-3 * ekf_to_double(P1[a * ATT_N + a]));
            }
        }
    }
}

/* The gyroscope's noise is a density: a sample over dt measures the rate with variance
 * gyro_noise^2 / dt (docs/derivation.md, "Noise densities"). Read back from the update of
 * each rate's variance, 1 / P+ = 1 / P + 1 / R (a unit row), whatever the innovation. */
static void test_gyro_noise_is_a_density(void)
{
    att_settings_t s = att_default_settings;
    static att_ekf_t f;
    ts_sim_t sim;
    const double dt = 0.01, want = ekf_to_double(s.gyro_noise) * ekf_to_double(s.gyro_noise) / dt;
    ekf_scalar_t P0[ATT_N * ATT_N], P1[ATT_N * ATT_N], g[3];
    int i;
    run_motion(&f, &s, 4.0, 0, &sim);
    for (i = 0; i < 3; ++i) { /* the rate the filter expects: no innovation, never gated */
        g[i] = ekf_add(att_state(&f)[ATT_P + i], ekf_add(f.vars.rest.bias[i], f.vars.bias.b[i]));
    }
    att_get_covariance(&f, P0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_update_gyro(&f, g, ekf_from_double(dt)));
    att_get_covariance(&f, P1);
    for (i = 0; i < 3; ++i) {
        const int a = ATT_P + i;
        const double r = 1.0 / (1.0 / ekf_to_double(P1[a * ATT_N + a]) - 1.0 / ekf_to_double(P0[a * ATT_N + a]));
        printf("gyroscope noise (%s), axis %d: rate variance %.4g -> %.4g, R %.5g, gyro_noise^2 / dt %.5g\n",
               EKF_SCALAR_NAME, i, ekf_to_double(P0[a * ATT_N + a]), ekf_to_double(P1[a * ATT_N + a]), r, want);
        TEST_ASSERT_TRUE(fabs(r - want) <= 1e-3 * want);
    }
}

/* A saturated gyroscope sample raises each body-rate variance to at least the square of its
 * largest component (att.h, ATT_GYRO_SATURATED), each by its own deficit: checked with the
 * roll rate's variance made larger than the others' first. */
static void test_saturated_gyro_raises_every_rate_variance(void)
{
    att_settings_t s = att_default_settings;
    static att_ekf_t f;
    ts_sim_t sim;
    att_sample_t smp;
    const double full = 10.0; /* rad/s */
    const double walk = ekf_to_double(s.rate_walk) * ekf_to_double(s.rate_walk) * 0.01;
    ekf_scalar_t P[ATT_N * ATT_N];
    int i;
    run_motion(&f, &s, 4.0, 0, &sim);
    att_cov_add_var(&f.vars.cov, ATT_P, ekf_from_double(0.5 * full * full));
    memset(&smp, 0, sizeof smp);
    smp.dt = EKF_C(0.01);
    smp.gyro[1] = ekf_from_double(-full);
    smp.valid = ATT_HAS_GYRO | ATT_GYRO_SATURATED;
    TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, NULL)));
    att_get_covariance(&f, P);
    for (i = 0; i < 3; ++i) {
        const double v = ekf_to_double(P[(ATT_P + i) * ATT_N + ATT_P + i]);
        printf("saturated gyroscope (%s): rate %d variance %.8g, at least %.4g\n", EKF_SCALAR_NAME, i, v, full * full);
        /* every variance was below full^2: raised to it, not beyond (but for the step's own
         * rate walk, rate_walk^2 dt) */
        TEST_ASSERT_TRUE(v >= (1.0 - 1e-4) * full * full && v <= (1.0 + 1e-4) * full * full + walk);
    }
}

/* The heading's noise (docs/derivation.md, "Magnetometer"): a density, widened by the tilt
 * error linear acceleration causes, which moves the levelled heading by about tan(dip) times
 * it, and by the field's norm and dip errors:
 *   R = (mag_heading_noise^2 + tan^2(dip) accel_dev_var accel_adapt_weight / g^2) / dt
 *       (1 + (norm error / mag_norm_band)^2 + (dip error / mag_dip_band)^2).
 * Read back from the heading variance's update (a unit row), with a linear-acceleration
 * variance set that makes the dip term several times the plain noise. */
static void test_heading_noise(void)
{
    att_settings_t s = att_default_settings;
    static att_ekf_t f;
    ts_sim_t sim;
    att_sample_t smp;
    const double dt = 0.01, dev_var = 10.0; /* (m/s^2)^2 */
    ekf_scalar_t P0[ATT_N * ATT_N], P1[ATT_N * ATT_N];
    double w[3], hn, tan2, g, kn, kd, want, r;
    run_motion(&f, &s, 4.0, 0, &sim);
    wander(4.0, w);
    ts_sim_step(&sim, w, NULL, &smp);
    f.vars.accel_dev_var = ekf_from_double(dev_var);
    att_get_covariance(&f, P0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_update_mag(&f, smp.mag, ekf_from_double(dt)));
    att_get_covariance(&f, P1);
    hn = ekf_to_double(s.mag_heading_noise);
    tan2 = tan(ekf_to_double(f.vars.mag_ref_dip)) * tan(ekf_to_double(f.vars.mag_ref_dip));
    g = ekf_to_double(s.gravity);
    kn = ekf_to_double(att_diag(&f)->mag_norm_error) / ekf_to_double(s.mag_norm_band);
    kd = ekf_to_double(att_diag(&f)->mag_dip_error) / ekf_to_double(s.mag_dip_band);
    want = (hn * hn + tan2 * dev_var * ekf_to_double(s.accel_adapt_weight) / (g * g)) / dt * (1.0 + kn * kn + kd * kd);
    r = 1.0 / (1.0 / ekf_to_double(P1[ATT_PSI * ATT_N + ATT_PSI]) - 1.0 / ekf_to_double(P0[ATT_PSI * ATT_N + ATT_PSI]));
    printf("heading noise (%s): dip %.1f deg, R %.5g, expected %.5g (plain noise alone %.5g)\n", EKF_SCALAR_NAME,
           ekf_to_double(f.vars.mag_ref_dip) / DEG, r, want, hn * hn / dt);
    TEST_ASSERT_TRUE(tan2 > 1.0);                       /* tan^2 and tan differ */
    TEST_ASSERT_TRUE(want > 3.0 * hn * hn / dt);       /* the dip term matters */
    TEST_ASSERT_TRUE(fabs(r - want) <= 6e-4 * want);
}

/* Headings either side of +-180 deg are 2 deg apart, not 358: held still at a heading of
 * 180 deg, the estimate and the measured heading fall either side of it from sample to
 * sample, and the heading innovation must stay small (wrapped into [-pi, pi)), so almost no
 * sample is gated and the heading stays right. */
static void test_heading_across_180_deg(void)
{
    att_settings_t s = att_default_settings;
    static att_ekf_t f;
    ts_sim_t sim;
    ts_sim_cfg_t cfg;
    att_sample_t smp;
    const double w[3] = {0.0, 0.0, 0.0};
    double e[3], err;
    uint32_t fused, gated;
    int k;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 5, 0.1, -0.05, 3.14159265358979323846);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &s));
    for (k = 0; k < (int)(20.0 / cfg.dt); ++k) {
        ts_sim_step(&sim, w, NULL, &smp);
        TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, NULL)));
    }
    ts_sim_euler(&sim, e);
    err = fabs(remainder(ekf_to_double(att_state(&f)[ATT_PSI]) - e[2], 2.0 * 3.14159265358979323846));
    fused = att_diag(&f)->mag_fused;
    gated = att_diag(&f)->mag_gated;
    printf("heading at 180 deg (%s): %u headings fused, %u gated, heading error %.3f deg\n", EKF_SCALAR_NAME,
           (unsigned)fused, (unsigned)gated, err / DEG);
    TEST_ASSERT_TRUE(fused > 1000u);
    TEST_ASSERT_TRUE(gated <= fused / 100u);
    TEST_ASSERT_TRUE(err < 0.03 * DEG);
}

/* A field turned 60 deg (as by a magnet that keeps its norm and dip) gates every heading;
 * after mag_reset_time gated (the tilt confirmed by the accelerometer, held still), the
 * heading is reset to the magnetic one and the reset counted, once. */
static void test_heading_reset(void)
{
    att_settings_t s = att_default_settings;
    static att_ekf_t f;
    ts_sim_t sim;
    ts_sim_cfg_t cfg;
    att_sample_t smp;
    const double w[3] = {0.0, 0.0, 0.0}, turn = 60.0 * DEG;
    double e[3], off;
    uint32_t before, resets;
    int k;
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, 9, 0.1, -0.05, 0.7);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &s));
    for (k = 0; k < (int)(10.0 / cfg.dt); ++k) {
        ts_sim_step(&sim, w, NULL, &smp);
        TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, NULL)));
    }
    before = att_diag(&f)->heading_resets;
    f.settings.mag_declination = ekf_from_double(turn); /* the same as the field turned by -turn */
    for (k = 0; k < (int)((ekf_to_double(s.mag_reset_time) + 2.0) / cfg.dt); ++k) {
        ts_sim_step(&sim, w, NULL, &smp);
        TEST_ASSERT_FALSE(ekf_status_is_error(att_step(&f, &smp, NULL)));
    }
    ts_sim_euler(&sim, e);
    off = fabs(remainder(ekf_to_double(att_state(&f)[ATT_PSI]) - (e[2] - turn), 2.0 * 3.14159265358979323846));
    resets = att_diag(&f)->heading_resets - before;
    printf("field turned 60 deg (%s): %u heading reset(s), heading then %.2f deg from the field's\n", EKF_SCALAR_NAME,
           (unsigned)resets, off / DEG);
    TEST_ASSERT_EQUAL_UINT32(1u, resets);
    TEST_ASSERT_TRUE(off < 0.75 * DEG);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_accel_stage_is_the_batch_update);
    RUN_TEST(test_remap_transforms_the_reported_covariance);
    RUN_TEST(test_gap_adds_the_integrated_rate_walk);
    RUN_TEST(test_gyro_noise_is_a_density);
    RUN_TEST(test_saturated_gyro_raises_every_rate_variance);
    RUN_TEST(test_heading_noise);
    RUN_TEST(test_heading_across_180_deg);
    RUN_TEST(test_heading_reset);
    return UNITY_END();
}
