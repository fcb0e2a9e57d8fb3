/*
 * test_att_accel.c - the accelerometer stage (firmware/att/att_accel.c; docs/derivation.md,
 * "Accelerometer", "Linear acceleration", "Gyroscope offset in motion"): the two
 * tangent-plane updates against the batch EKF update of the whole unit vector in double
 * (equal because K h = 0 for isotropic noise), the rest weight and the sample fused at rest,
 * the low-passed vector fused in motion, the adaptive and band variances, rejection, gates,
 * the offset learned from the innovations with its gates and the colored residual's excess,
 * the considered error passed on through the gains.
 */
#include <math.h>
#include <string.h>

#include "att.h"
#include "att_accel.h"
#include "att_fixture.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define DT 0.01
#define G 9.81
#define PHI0 0.3
#define THETA0 (-0.5)

static const double k_x[ATT_N] = {0.0, 0.0, 0.0, PHI0, THETA0, 1.0, 0.0, 0.0, 0.0};
static const double k_var[ATT_N] = {0.01, 0.01, 0.01, 1e-3, 1e-3, 1e-2, 0.01, 0.01, 0.01};

/* Every mechanism off but the update itself; accel_noise 0.03 m/s^2 sqrt(s) makes the
 * per-component variance 0.03^2 / (dt g^2) = 9.4e-4, of the size of the tilt variances
 * (rest.accel_noise 0.015: a quarter of it). */
#define NOISE 0.03
#define REST_NOISE 0.015
static att_settings_t plain(void)
{
    att_settings_t s = att_default_settings;
    s.accel_noise = EKF_C(NOISE);
    s.rest.accel_noise = EKF_C(REST_NOISE);
    s.accel_lpf_tau = EKF_C(0);
    s.accel_adapt_tau = EKF_C(0);
    s.accel_band = EKF_C(0);
    s.accel_gate = EKF_C(0);
    return s;
}

static double r_of(double density) { return density * density / (DT * G * G); }

static void x_of(const att_vars_t *v, double x[ATT_N])
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        x[i] = ekf_to_double(v->x[i]);
    }
}

/* The batch EKF update with the direction of a (3 components, h = R^T e_z, H its roll and
 * pitch columns at the prior), isotropic variance r per component. */
static void expect_batch(const att_vars_t *v, const double a[3], double r, double x[ATT_N], double P[ATT_N * ATT_N])
{
    const double n = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    double H[3 * ATT_N], nu[3], rr[3] = {r, r, r}, sp, cp, st, ct;
    x_of(v, x);
    af_cov(v, P);
    sp = sin(x[ATT_PHI]);
    cp = cos(x[ATT_PHI]);
    st = sin(x[ATT_THETA]);
    ct = cos(x[ATT_THETA]);
    nu[0] = a[0] / n + st;
    nu[1] = a[1] / n - sp * ct;
    nu[2] = a[2] / n - cp * ct;
    memset(H, 0, sizeof H);
    H[0 * ATT_N + ATT_THETA] = -ct;
    H[1 * ATT_N + ATT_PHI] = cp * ct;
    H[1 * ATT_N + ATT_THETA] = -sp * st;
    H[2 * ATT_N + ATT_PHI] = -sp * ct;
    H[2 * ATT_N + ATT_THETA] = -cp * st;
    af_batch_update(x, P, H, nu, rr, 3);
}

static void check_result(const att_vars_t *v, const double x[ATT_N], const double P[ATT_N * ATT_N], int line)
{
    int i;
    for (i = 0; i < ATT_N; ++i) {
        af_near(x[i], ekf_to_double(v->x[i]), 64.0 * af_ulp(1.0), "x[i]", line);
    }
    af_cov_near(v, P, 64.0 * af_ulp(0.01), line);
}

/* The specific force of the attitude (phi, theta) with norm `norm`, as doubles and scalars. */
static void force(double norm, double phi, double theta, double a[3], ekf_scalar_t as[3])
{
    int i;
    af_gravity_body(norm, phi, theta, as);
    for (i = 0; i < 3; ++i) {
        a[i] = ekf_to_double(as[i]);
    }
}

/* The two tangent-plane components, fused in turn (the second relinearised about the prior),
 * equal the batch update of the 3-vector: the component along h carries no attitude. With
 * correlations in P, so that every state moves. The norm (off g by 2 %) only sets the norm
 * error. */
static void test_tangent_plane_updates_equal_batch(void)
{
    const att_settings_t s = plain();
    double P0[ATT_N * ATT_N], x[ATT_N], P[ATT_N * ATT_N], a[3];
    att_vars_t v;
    ekf_scalar_t as[3];
    af_random_cov(3, k_var, P0);
    af_vars_full(&v, &s, k_x, P0);
    v.heading_ref = 1u; /* (else "no turn about the vertical" below) */
    force(1.02 * G, PHI0 + 0.03, THETA0 + 0.03, a, as);
    expect_batch(&v, a, r_of(NOISE), x, P);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
    check_result(&v, x, P, __LINE__);
    TEST_ASSERT_EQUAL_UINT32(2u, v.diag.accel_fused);
    AF_NEAR_S(0.02 * G, v.diag.accel_norm_error, 4.0 * af_ulp(G));
    TEST_ASSERT_EQUAL_UINT8(1u, v.tilt_ok);
    TEST_ASSERT_EQUAL_UINT32(0u,
                             v.flags & (ATT_FLAG_ACCEL_DEWEIGHTED | ATT_FLAG_ACCEL_REJECTED | ATT_FLAG_ACCEL_GATED));
}

/* The two components fused in turn as accel_fuse does (u and the second's relinearisation
 * as above), each with the gain K = P h / S except on psi, K_psi = sin(theta) K_phi at the
 * pitch both are linearised about (the prior's), and P by Joseph's form for that gain: written out in double, with
 * no use of the update's closed form (Kalman P plus delta^2 / S on psi). */
static void expect_held(const att_vars_t *v, const double a[3], double r, double x[ATT_N], double P[ATT_N * ATT_N])
{
    const double n = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    double u[2][3], th0, A[ATT_N * ATT_N], T[ATT_N * ATT_N];
    int c, i, j, k;
    x_of(v, x);
    af_cov(v, P);
    th0 = x[ATT_THETA];
    u[0][0] = 0.0, u[0][1] = cos(x[ATT_PHI]), u[0][2] = -sin(x[ATT_PHI]);
    u[1][0] = -cos(th0), u[1][1] = -sin(x[ATT_PHI]) * sin(th0), u[1][2] = -cos(x[ATT_PHI]) * sin(th0);
    for (c = 0; c < 2; ++c) {
        double h[ATT_N] = {0}, K[ATT_N], S = r;
        double nu = (u[c][0] * a[0] + u[c][1] * a[1] + u[c][2] * a[2]) / n - ((c == 1) ? x[ATT_THETA] - th0 : 0.0);
        h[(c == 0) ? ATT_PHI : ATT_THETA] = (c == 0) ? cos(th0) : 1.0;
        for (i = 0; i < ATT_N; ++i) {
            K[i] = 0.0;
            for (j = 0; j < ATT_N; ++j) {
                K[i] += P[i * ATT_N + j] * h[j];
            }
        }
        for (i = 0; i < ATT_N; ++i) {
            S += h[i] * K[i];
        }
        for (i = 0; i < ATT_N; ++i) {
            K[i] /= S;
        }
        K[ATT_PSI] = sin(th0) * K[ATT_PHI];
        for (i = 0; i < ATT_N; ++i) {
            x[i] += K[i] * nu;
            for (j = 0; j < ATT_N; ++j) {
                A[i * ATT_N + j] = ((i == j) ? 1.0 : 0.0) - K[i] * h[j];
            }
        }
        for (i = 0; i < ATT_N; ++i) { /* T = A P */
            for (j = 0; j < ATT_N; ++j) {
                T[i * ATT_N + j] = 0.0;
                for (k = 0; k < ATT_N; ++k) {
                    T[i * ATT_N + j] += A[i * ATT_N + k] * P[k * ATT_N + j];
                }
            }
        }
        for (i = 0; i < ATT_N; ++i) { /* P = T A^T + r K K^T */
            for (j = 0; j < ATT_N; ++j) {
                double sum = r * K[i] * K[j];
                for (k = 0; k < ATT_N; ++k) {
                    sum += T[i * ATT_N + k] * A[j * ATT_N + k];
                }
                P[i * ATT_N + j] = sum;
            }
        }
    }
}

/* Without a heading reference the update turns nothing about the vertical (first order:
 * dpsi = sin(theta) dphi per component) and P is Joseph's for that gain; the heading's
 * variance is then larger than the Kalman update's. */
static void test_no_turn_about_the_vertical(void)
{
    const att_settings_t s = plain();
    double P0[ATT_N * ATT_N], x[ATT_N], P[ATT_N * ATT_N], xk[ATT_N], Pk[ATT_N * ATT_N], a[3];
    att_vars_t v;
    ekf_scalar_t as[3];
    af_random_cov(3, k_var, P0);
    af_vars_full(&v, &s, k_x, P0);
    force(1.02 * G, PHI0 + 0.03, THETA0 + 0.03, a, as);
    expect_held(&v, a, r_of(NOISE), x, P);
    expect_batch(&v, a, r_of(NOISE), xk, Pk);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
    check_result(&v, x, P, __LINE__);
    /* and it is not the Kalman update (the case is not one where the two agree) */
    TEST_ASSERT_TRUE(fabs(x[ATT_PSI] - xk[ATT_PSI]) > 1e-3);
    TEST_ASSERT_TRUE(P[ATT_PSI * ATT_N + ATT_PSI] > Pk[ATT_PSI * ATT_N + ATT_PSI] + 1e-5);
}

/* In motion with the low-pass on, the vector fused is the low-passed force after this
 * sample's blend (two stages, k = dt / (tau + dt)); at rest (ATT_FLAG_AT_REST) the sample
 * itself with the density rest.accel_noise; at rest with rest.accel_noise 0, as in motion. */
static void test_vector_and_weight_at_rest_and_in_motion(void)
{
    int mode;
    for (mode = 0; mode < 3; ++mode) {
        att_settings_t s = plain();
        const double k = DT / (1.0 + DT);
        double x[ATT_N], P[ATT_N * ATT_N], a[3], lp1[3], lp[3], fused[3];
        att_vars_t v;
        ekf_scalar_t as[3];
        int i;
        s.accel_lpf_tau = EKF_C(1.0);
        s.accel_lpf_order = 2u;
        s.rest.accel_noise = (mode == 2) ? EKF_C(0) : EKF_C(REST_NOISE);
        af_vars(&v, &s, k_x, k_var);
        v.heading_ref = 1u; /* a heading reference: the Kalman update of expect_batch */
        if (mode > 0) {
            v.flags |= ATT_FLAG_AT_REST;
        }
        force(G, 0.1, -0.2, lp, v.accel_lp);   /* the low-pass holds another direction */
        force(G, 0.2, -0.3, lp1, v.accel_lp1);
        v.accel_lp_valid = 1u;
        force(G, PHI0 + 0.02, THETA0 - 0.01, a, as);
        for (i = 0; i < 3; ++i) {
            lp1[i] += k * (a[i] - lp1[i]);
            lp[i] += k * (lp1[i] - lp[i]);
            fused[i] = (mode == 1) ? a[i] : lp[i];
        }
        expect_batch(&v, fused, r_of((mode == 1) ? REST_NOISE : NOISE), x, P);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
        check_result(&v, x, P, __LINE__);
        for (i = 0; i < 3; ++i) {
            AF_NEAR_S(lp[i], v.accel_lp[i], 16.0 * af_ulp(G));
            AF_NEAR_S(lp1[i], v.accel_lp1[i], 16.0 * af_ulp(G));
        }
    }
}

/* The gate, per component (P diagonal: independent): a 0.5 rad roll error is beyond 3 sigma
 * of the roll component, whose innovation is cos(theta) sin(0.5), and not fused; the pitch
 * component (innovation sin(theta) cos(theta) (1 - cos 0.5)) is. A 0.2 rad error within a
 * gate of 10 is fused, but beyond 3 sigma the tilt is not confirmed (tilt_ok). */
static void test_gate_per_component(void)
{
    const double ct = cos(THETA0), st = sin(THETA0), r = r_of(NOISE), Pt = k_var[ATT_PHI];
    int big;
    for (big = 0; big < 2; ++big) {
        att_settings_t s = plain();
        const double d = big ? 0.5 : 0.2;
        const double nu0 = ct * sin(d), nu1 = st * ct * (1.0 - cos(d)), S0 = ct * ct * Pt + r;
        double a[3];
        att_vars_t v;
        ekf_scalar_t as[3];
        s.accel_gate = big ? EKF_C(3) : EKF_C(10);
        af_vars(&v, &s, k_x, k_var);
        force(G, PHI0 + d, THETA0, a, as);
        TEST_ASSERT_EQUAL_INT(big ? EKF_GATED : EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
        TEST_ASSERT_EQUAL_UINT8(0u, v.tilt_ok);
        {
            const double ratio = nu0 * nu0 / (ekf_to_double(ekf_sq(s.accel_gate)) * S0);
            AF_NEAR_S(ratio, v.diag.accel_ratio[0], 64.0 * af_ulp(ratio));
        }
        AF_NEAR_S(THETA0 + Pt / (Pt + r) * nu1, v.x[ATT_THETA], 16.0 * af_ulp(1.0));
        if (big) {
            TEST_ASSERT_TRUE(v.x[ATT_PHI] == ekf_from_double(PHI0));
            TEST_ASSERT_EQUAL_UINT32(1u, v.diag.accel_gated);
            TEST_ASSERT_EQUAL_UINT32(1u, v.diag.accel_fused);
            TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ACCEL_GATED, v.flags & ATT_FLAG_ACCEL_GATED);
            TEST_ASSERT_TRUE(v.gated_time[1] > EKF_C(0));
        } else {
            AF_NEAR_S(PHI0 + ct * Pt / S0 * nu0, v.x[ATT_PHI], 16.0 * af_ulp(1.0));
            TEST_ASSERT_EQUAL_UINT32(2u, v.diag.accel_fused);
            TEST_ASSERT_TRUE(v.gated_time[1] == EKF_C(0));
        }
    }
}

/* | |a| - g | beyond accel_reject, or no force at all: not fused, flagged, counted, the state
 * and covariance untouched; just within accel_reject: fused. */
static void test_rejection(void)
{
    const att_settings_t s = plain();
    const double rej = ekf_to_double(s.accel_reject);
    const double norms[3] = {G + rej + 1.0, 0.0, G + rej - 1.0};
    int c;
    for (c = 0; c < 3; ++c) {
        att_vars_t v, before;
        double a[3];
        ekf_scalar_t as[3];
        af_vars(&v, &s, k_x, k_var);
        before = v;
        force(norms[c], PHI0 + 0.01, THETA0, a, as);
        if (c < 2) {
            TEST_ASSERT_EQUAL_INT(EKF_SKIPPED, att_stage_accel(&v, &s, as, EKF_C(DT)));
            TEST_ASSERT_EQUAL_MEMORY(before.x, v.x, sizeof v.x);
            TEST_ASSERT_EQUAL_MEMORY(&before.cov, &v.cov, sizeof v.cov);
            TEST_ASSERT_EQUAL_UINT32(ATT_FLAG_ACCEL_REJECTED, v.flags & ATT_FLAG_ACCEL_REJECTED);
            TEST_ASSERT_EQUAL_UINT32(1u, v.diag.accel_skipped);
            TEST_ASSERT_EQUAL_UINT8(0u, v.tilt_ok);
        } else {
            TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
            TEST_ASSERT_EQUAL_UINT32(0u, v.diag.accel_skipped);
        }
        AF_NEAR_S(fabs(norms[c] - G), v.diag.accel_norm_error, 4.0 * af_ulp(100.0));
    }
}

/* accel_band: the variance times 1 + (err / band)^2 for this sample, flagged as de-weighted
 * (and the tilt not confirmed) when err > band. */
static void test_band(void)
{
    int big;
    for (big = 0; big < 2; ++big) {
        att_settings_t s = plain();
        const double err = big ? 2.0 : 0.5;
        double x[ATT_N], P[ATT_N * ATT_N], a[3];
        att_vars_t v;
        ekf_scalar_t as[3];
        s.accel_band = EKF_C(1.0);
        af_vars(&v, &s, k_x, k_var);
        v.heading_ref = 1u; /* a heading reference: the Kalman update of expect_batch */
        force(G + err, PHI0 + 0.02, THETA0 + 0.01, a, as);
        expect_batch(&v, a, r_of(NOISE) * (1.0 + err * err), x, P);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
        check_result(&v, x, P, __LINE__);
        TEST_ASSERT_EQUAL_UINT32(big ? ATT_FLAG_ACCEL_DEWEIGHTED : 0u, v.flags & ATT_FLAG_ACCEL_DEWEIGHTED);
        TEST_ASSERT_EQUAL_UINT8(big ? 0u : 1u, v.tilt_ok);
    }
}

/* Adaptive noise: the running variance v <- v + k (e^2 - v), k = dt / (accel_adapt_tau + dt),
 * enters the density^2 as v accel_adapt_weight; de-weighted when that exceeds accel_noise^2. */
static void test_adaptive_variance(void)
{
    int big;
    for (big = 0; big < 2; ++big) {
        att_settings_t s = plain();
        const double e = 0.3, noise = 0.05, w = 0.0035, k = DT / (0.5 + DT), v0 = big ? 1.0 : 0.5;
        const double v1 = v0 + k * (e * e - v0);
        double x[ATT_N], P[ATT_N * ATT_N], a[3];
        att_vars_t v;
        ekf_scalar_t as[3];
        s.accel_noise = ekf_from_double(noise);
        s.accel_adapt_tau = EKF_C(0.5);
        s.accel_adapt_weight = ekf_from_double(w);
        af_vars(&v, &s, k_x, k_var);
        v.heading_ref = 1u; /* a heading reference: the Kalman update of expect_batch */
        v.accel_dev_var = ekf_from_double(v0);
        force(G + e, PHI0 + 0.002, THETA0 - 0.001, a, as);
        expect_batch(&v, a, (noise * noise + v1 * w) / (DT * G * G), x, P);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
        AF_NEAR_S(v1, v.accel_dev_var, 16.0 * af_ulp(1.0));
        check_result(&v, x, P, __LINE__);
        TEST_ASSERT_EQUAL_UINT32(big ? ATT_FLAG_ACCEL_DEWEIGHTED : 0u, v.flags & ATT_FLAG_ACCEL_DEWEIGHTED);
    }
}

/* The offset learned in motion from the roll component, with V = diag(0.5 s, 0, 0) so that
 * only that component sees it (g = -h V = (-cos(theta) 0.5, 0, 0)): the Kalman update of a
 * constant through g with variance S + excess + g Pb g^T, excess = 2 (v / g^2) T / dt the
 * colored residual of the low-pass (T = accel_lpf_order accel_lpf_tau), 0 at rest, its gain
 * Pb g^T / (that variance) projected at right angles to the predicted gravity direction up
 * (the offset along up turns only the heading, which the tilt cannot see): db = (I - up up^T)
 * Pb g^T nu / (S + excess + g Pb g^T). Nothing is learned with bias.motion 0, at the gimbal
 * lock, or while the short-term deviation exceeds quiet_accel. */
static void test_offset_learning_and_its_gates(void)
{
    enum { MOTION, REST, NO_MOTION, GIMBAL, SHAKING, QUIET };
    int c;
    for (c = MOTION; c <= QUIET; ++c) {
        att_settings_t s = plain();
        const double ct = cos(THETA0), d = 0.01, Pt = k_var[ATT_PHI], vv = 0.5, dev = 5e-4;
        const double r = (c == REST) ? r_of(REST_NOISE) : r_of(NOISE), S = ct * ct * Pt + r;
        const double excess = (c == REST) ? 0.0 : 2.0 * dev / (G * G) * 2.0 / DT;
        const double pb = pow(ekf_to_double(s.bias.sigma_init) * 1e3, 2.0), u = -ct * vv * 1e-3;
        const double nu = ct * sin(d), sb = S + excess + u * pb * u;
        /* up at the prior attitude, body frame; Pb g^T = pb (u, 0, 0) */
        const double up[3] = {-sin(THETA0), sin(PHI0) * ct, cos(PHI0) * ct};
        const double q = ekf_to_double(s.bias.quiet_accel);
        double a[3];
        int i;
        att_vars_t v;
        ekf_scalar_t as[3];
        s.accel_lpf_tau = EKF_C(1.0); /* restarted below: the sample is fused */
        s.accel_lpf_order = 2u;
        s.accel_adapt_weight = EKF_C(0); /* the running variance sets the excess only */
        s.bias.motion = (uint16_t)((c == NO_MOTION) ? 0u : 1u);
        af_vars(&v, &s, k_x, k_var);
        v.accel_dev_var = ekf_from_double(dev);
        v.accel_lp_valid = 0u;
        v.bias.V[0] = ekf_from_double(vv);
        v.accel_hf_var = ekf_from_double((c == SHAKING) ? 1.1 * q * q : (c == QUIET) ? 0.9 * q * q : 0.0);
        if (c == REST) {
            v.flags |= ATT_FLAG_AT_REST;
        }
        if (c == GIMBAL) {
            v.flags |= ATT_FLAG_GIMBAL_LOCK;
        }
        force(G, PHI0 + d, THETA0, a, as);
        TEST_ASSERT_TRUE(nu * nu < 9.0 * sb);
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
        for (i = 0; i < 3; ++i) {
            if (c == NO_MOTION || c == GIMBAL || c == SHAKING) {
                TEST_ASSERT_TRUE(v.bias.b[i] == EKF_C(0));
            } else {
                const double proj = ((i == 0) ? 1.0 : 0.0) - up[i] * up[0];
                AF_NEAR_S(pb * u * proj * nu / sb * 1e-3, v.bias.b[i], 64.0 * af_ulp(1e-3));
            }
        }
    }
}

/* The considered error of the low-passed force goes through the gains just applied: from
 * zero, tilt = K^2 N and cross = K N per axis (N = v / g^2, K the fraction by which the
 * update reduced that angle's variance), and the rate-proportional term shrinks by (1 - K)^2. */
static void test_considered_error_through_gains(void)
{
    att_settings_t s = plain();
    const double dev = 0.01, N = dev / (G * G);
    double a[3], K[2];
    att_vars_t v;
    ekf_scalar_t as[3];
    int i;
    s.accel_adapt_weight = EKF_C(0);
    af_vars(&v, &s, k_x, k_var);
    v.accel_dev_var = ekf_from_double(dev);
    v.consider.rate[0] = v.consider.rate[1] = EKF_C(0.01);
    v.consider.rate[2] = EKF_C(0.02);
    force(G, PHI0 + 0.01, THETA0 + 0.01, a, as);
    TEST_ASSERT_EQUAL_INT(EKF_OK, att_stage_accel(&v, &s, as, EKF_C(DT)));
    for (i = 0; i < 2; ++i) {
        K[i] = 1.0 - ekf_to_double(att_cov_var(&v.cov, ATT_PHI + i)) / k_var[ATT_PHI + i];
        TEST_ASSERT_TRUE(K[i] > 0.2 && K[i] < 0.8);
        AF_NEAR_S(K[i] * K[i] * N, v.consider.tilt[i], 64.0 * af_ulp(N));
        AF_NEAR_S(K[i] * N, v.consider.cross[i], 64.0 * af_ulp(N));
        AF_NEAR_S((1.0 - K[i]) * (1.0 - K[i]) * 0.01, v.consider.rate[i], 64.0 * af_ulp(0.01));
    }
    TEST_ASSERT_TRUE(v.consider.rate[2] == EKF_C(0.02));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_tangent_plane_updates_equal_batch);
    RUN_TEST(test_no_turn_about_the_vertical);
    RUN_TEST(test_vector_and_weight_at_rest_and_in_motion);
    RUN_TEST(test_gate_per_component);
    RUN_TEST(test_rejection);
    RUN_TEST(test_band);
    RUN_TEST(test_adaptive_variance);
    RUN_TEST(test_offset_learning_and_its_gates);
    RUN_TEST(test_considered_error_through_gains);
    af_print_worst();
    return UNITY_END();
}
