/*
 * test_jacobians.c - every Jacobian of the attitude model against central finite
 * differences (double build).
 *
 * Finite differences: Richardson-extrapolated central differences,
 *   D(h) = (f(x+h) - f(x-h)) / 2h,  J_fd = (4 D(h/2) - D(h)) / 3   (error O(h^4)),
 * with a step scaled to the distance from the singularity, so that the comparison stays
 * meaningful where sec(theta) is in the thousands.
 *
 * Error measure per entry: |J - J_fd| / max(1, |J|), i.e. relative for entries of
 * magnitude >= 1 and absolute below. Required: max <= 1e-6 over >= 1000 random states,
 * the state at rest (all rates zero) and states within 0.06 deg .. 0.6 deg of +-90 deg.
 */
#include <math.h>
#include <stdio.h>

#include "att.h"
#include "att_gen.h"
#include "att_model.h"
#include "testsim.h"
#include "unity.h"

#define N_RANDOM 1500
#define N_SINGULAR 1000
#define TOL 1e-6

/* Gimbal clamp effectively off: the raw derivative is what is being checked. */
static const double NO_CLAMP = 1.5707963267948966 - 1e-12;

static double worst_F, worst_G, worst_H, worst_Hmag;
static double worst_F_rest;

void setUp(void) {}
void tearDown(void) {}

static double entry_error(double a, double b)
{
    const double scale = fabs(a) > 1.0 ? fabs(a) : 1.0;
    return fabs(a - b) / scale;
}

/* Analytic F = I + D from the generated code. */
static void analytic_F(const double x[ATT_N], double dt, double F[ATT_N * ATT_N])
{
    double xn[ATT_N], d[ATT_GEN_F_NNZ];
    att_trig_t tm, tn;
    int i;
    att_model_transition(x, NULL, dt, NO_CLAMP, xn, &tm, &tn);
    att_gen_transition_jacobian(&tm, &tn, x, dt, d);
    for (i = 0; i < ATT_N * ATT_N; ++i) {
        F[i] = 0.0;
    }
    for (i = 0; i < ATT_N; ++i) {
        F[i * ATT_N + i] = 1.0;
    }
    for (i = 0; i < ATT_GEN_F_NNZ; ++i) {
        F[att_gen_f_pattern[i].row * ATT_N + att_gen_f_pattern[i].col] += d[i];
    }
}

static void central(const double x[ATT_N], const double w[3], double dt, int wrt_noise, int j, double h,
                    double out[ATT_N])
{
    double xp[ATT_N], xm[ATT_N], wp[3], wm[3], fp[ATT_N], fm[ATT_N];
    int i;
    for (i = 0; i < ATT_N; ++i) {
        xp[i] = xm[i] = x[i];
    }
    for (i = 0; i < 3; ++i) {
        wp[i] = wm[i] = w[i];
    }
    if (wrt_noise) {
        wp[j] += h;
        wm[j] -= h;
    } else {
        xp[j] += h;
        xm[j] -= h;
    }
    att_model_transition(xp, wp, dt, NO_CLAMP, fp, NULL, NULL);
    att_model_transition(xm, wm, dt, NO_CLAMP, fm, NULL, NULL);
    for (i = 0; i < ATT_N; ++i) {
        out[i] = (fp[i] - fm[i]) / (2.0 * h);
    }
}

static void richardson(const double x[ATT_N], double dt, int wrt_noise, int j, double h, double out[ATT_N])
{
    static const double zero_w[3] = {0.0, 0.0, 0.0};
    double d1[ATT_N], d2[ATT_N];
    int i;
    central(x, zero_w, dt, wrt_noise, j, h, d1);
    central(x, zero_w, dt, wrt_noise, j, h / 2.0, d2);
    for (i = 0; i < ATT_N; ++i) {
        out[i] = (4.0 * d2[i] - d1[i]) / 3.0;
    }
}

/* Finite-difference step for state j. W is singular at theta = +-90 deg and is evaluated at
 * the midpoint pitch (distance margin_m from 90 deg) and at the advanced angles (margin_n):
 * the step must move each pitch by a small fraction of its margin and each roll by a small
 * fraction of a radian. F's angle rows give the advanced angles' sensitivity. */
static double step_for(int j, const double F[ATT_N * ATT_N], double dt, double margin_m, double margin_n)
{
    const double c = 1.0 / 200.0;
    double h = 1e-3;
    double d_phim = (j == ATT_PHI) ? 1.0 : (j == ATT_PHID) ? 0.5 * dt : 0.0;
    double d_thm = (j == ATT_THETA) ? 1.0 : (j == ATT_THETAD) ? 0.5 * dt : 0.0;
    double d_phin = fabs(F[ATT_PHI * ATT_N + j]);
    double d_thn = fabs(F[ATT_THETA * ATT_N + j]);
    if (d_phim > 0.0) h = fmin(h, c / d_phim);
    if (d_thm > 0.0) h = fmin(h, c * margin_m / d_thm);
    if (d_phin > 0.0) h = fmin(h, c / d_phin);
    if (d_thn > 0.0) h = fmin(h, c * margin_n / d_thn);
    return h;
}

static double check_transition(const double x[ATT_N], double dt, double margin_m, double margin_n)
{
    double F[ATT_N * ATT_N], col[ATT_N], G[ATT_N * 3], g[9];
    double worst = 0.0;
    att_trig_t tn;
    double xn[ATT_N];
    int i, j;
    analytic_F(x, dt, F);
    for (j = 0; j < ATT_N; ++j) {
        richardson(x, dt, 0, j, step_for(j, F, dt, margin_m, margin_n), col);
        for (i = 0; i < ATT_N; ++i) {
            const double e = entry_error(F[i * ATT_N + j], col[i]);
            if (e > worst) {
                worst = e;
            }
        }
    }
    /* noise Jacobian G = [I; 0; g] */
    att_model_transition(x, NULL, dt, NO_CLAMP, xn, NULL, &tn);
    att_gen_noise_jacobian(&tn, g);
    for (i = 0; i < ATT_N * 3; ++i) {
        G[i] = 0.0;
    }
    for (i = 0; i < 3; ++i) {
        G[(ATT_P + i) * 3 + i] = 1.0;
        for (j = 0; j < 3; ++j) {
            G[(ATT_PHID + i) * 3 + j] = g[i * 3 + j];
        }
    }
    for (j = 0; j < 3; ++j) {
        /* w enters only omega+, and Thetadot+ = W(Theta+) omega+ is linear in it */
        richardson(x, dt, 1, j, 1e-3, col);
        for (i = 0; i < ATT_N; ++i) {
            const double e = entry_error(G[i * 3 + j], col[i]);
            if (e > worst_G) {
                worst_G = e;
            }
        }
    }
    return worst;
}

static void accel_h_of(const double x[ATT_N], double h[3])
{
    att_trig_t t;
    t.sphi = sin(x[ATT_PHI]);
    t.cphi = cos(x[ATT_PHI]);
    t.sth = sin(x[ATT_THETA]);
    t.cth = cos(x[ATT_THETA]);
    t.secth = 0.0;
    att_gen_accel_h(&t, h);
}

static void check_accel(const double x[ATT_N])
{
    double hj[6], xp[ATT_N], xm[ATT_N], hp[3], hm[3], hp2[3], hm2[3];
    att_trig_t t;
    int i, j, k;
    t.sphi = sin(x[ATT_PHI]);
    t.cphi = cos(x[ATT_PHI]);
    t.sth = sin(x[ATT_THETA]);
    t.cth = cos(x[ATT_THETA]);
    t.secth = 0.0;
    att_gen_accel_jacobian(&t, hj);
    for (j = 0; j < ATT_N; ++j) {
        const double h = 1e-3;
        for (i = 0; i < ATT_N; ++i) {
            xp[i] = xm[i] = x[i];
        }
        xp[j] += h;
        xm[j] -= h;
        accel_h_of(xp, hp);
        accel_h_of(xm, hm);
        xp[j] = x[j] + h / 2.0;
        xm[j] = x[j] - h / 2.0;
        accel_h_of(xp, hp2);
        accel_h_of(xm, hm2);
        for (k = 0; k < 3; ++k) {
            const double fd = (4.0 * (hp2[k] - hm2[k]) / h - (hp[k] - hm[k]) / (2.0 * h)) / 3.0;
            const double an = (j == ATT_PHI) ? hj[2 * k] : (j == ATT_THETA) ? hj[2 * k + 1] : 0.0;
            const double e = entry_error(an, fd);
            if (e > worst_H) {
                worst_H = e;
            }
        }
    }
}

/* Magnetometer: heading measurement h(x) = psi, H = e_psi (the tilt-compensated heading
 * is formed from the field and the current roll/pitch outside the state function). */
static void check_mag(const double x[ATT_N])
{
    int j;
    for (j = 0; j < ATT_N; ++j) {
        const double h = 1e-3;
        double xp = x[ATT_PSI], xm = x[ATT_PSI];
        if (j == ATT_PSI) {
            xp += h;
            xm -= h;
        }
        {
            const double fd = (xp - xm) / (2.0 * h);
            const double an = (j == ATT_PSI) ? 1.0 : 0.0;
            const double e = entry_error(an, fd);
            if (e > worst_Hmag) {
                worst_Hmag = e;
            }
        }
    }
}

/* Random state whose advanced pitch (at_mid = 0) or midpoint pitch (at_mid = 1), where W is
 * evaluated, is theta_target. margin_m, margin_n: distances of the midpoint and the
 * advanced pitch from +-90 deg (rad). */
static void random_state(ts_rng_t *r, double x[ATT_N], double dt, double theta_target, int at_mid,
                         double *margin_m, double *margin_n)
{
    const double half_pi = 1.5707963267948966;
    double phim, thm, thn;
    int i;
    for (i = 0; i < 3; ++i) {
        x[ATT_P + i] = ts_uniform_in(r, -10.0, 10.0);
        x[ATT_PHID + i] = ts_uniform_in(r, -10.0, 10.0);
    }
    x[ATT_PHI] = ts_uniform_in(r, -3.14159, 3.14159);
    x[ATT_PSI] = ts_uniform_in(r, -3.14159, 3.14159);
    /* theta+ = theta + dt (cos(phi_m) q - sin(phi_m) r), phi_m = phi + dt/2 phid */
    phim = x[ATT_PHI] + 0.5 * dt * x[ATT_PHID];
    if (at_mid) {
        x[ATT_THETA] = theta_target - 0.5 * dt * x[ATT_THETAD];
    } else {
        x[ATT_THETA] = theta_target - dt * (cos(phim) * x[ATT_Q] - sin(phim) * x[ATT_R]);
    }
    thm = x[ATT_THETA] + 0.5 * dt * x[ATT_THETAD];
    thn = x[ATT_THETA] + dt * (cos(phim) * x[ATT_Q] - sin(phim) * x[ATT_R]);
    *margin_m = half_pi - fabs(thm);
    *margin_n = half_pi - fabs(thn);
}

static void test_transition_jacobian_random_states(void)
{
    ts_rng_t r;
    int n;
    ts_rng_seed(&r, 1);
    for (n = 0; n < N_RANDOM; ++n) {
        double x[ATT_N];
        const double dt = ts_uniform_in(&r, 1e-3, 0.05);
        double mm, mn;
        random_state(&r, x, dt, ts_uniform_in(&r, -1.4, 1.4), n % 2, &mm, &mn);
        if (mm < 0.05 || mn < 0.05) {
            continue; /* the other pitch came close to 90 deg: the next test covers that */
        }
        {
            const double e = check_transition(x, dt, mm, mn);
            if (e > worst_F) {
                worst_F = e;
            }
        }
        check_accel(x);
        check_mag(x);
    }
    printf("F (transition) max error over %d random states: %.3e\n", N_RANDOM, worst_F);
    TEST_ASSERT_TRUE_MESSAGE(worst_F <= TOL, "transition Jacobian differs from finite differences");
}

static void test_transition_jacobian_at_rest(void)
{
    ts_rng_t r;
    int n;
    ts_rng_seed(&r, 2);
    for (n = 0; n < 200; ++n) {
        double x[ATT_N] = {0};
        const double dt = ts_uniform_in(&r, 1e-3, 0.05);
        x[ATT_PHI] = ts_uniform_in(&r, -3.14159, 3.14159);
        x[ATT_THETA] = ts_uniform_in(&r, -1.5, 1.5);
        x[ATT_PSI] = ts_uniform_in(&r, -3.14159, 3.14159);
        {
            const double margin = 1.5707963267948966 - fabs(x[ATT_THETA]);
            const double e = check_transition(x, dt, margin, margin); /* at rest theta+ = theta */
            if (e > worst_F_rest) {
                worst_F_rest = e;
            }
        }
        check_accel(x);
    }
    printf("F at rest (all rates zero), 200 states: max error %.3e\n", worst_F_rest);
    TEST_ASSERT_TRUE_MESSAGE(worst_F_rest <= TOL, "transition Jacobian at rest");
}

static void test_transition_jacobian_near_singularity(void)
{
    ts_rng_t r;
    double worst = 0.0;
    int n;
    ts_rng_seed(&r, 3);
    for (n = 0; n < N_SINGULAR; ++n) {
        double x[ATT_N];
        const double dt = ts_uniform_in(&r, 1e-3, 0.05);
        const double target = ts_uniform_in(&r, 1e-3, 1e-2); /* 0.06 .. 0.6 deg from 90 deg */
        const double sign = (n % 2) ? 1.0 : -1.0;
        /* alternately the midpoint and the advanced pitch next to the singularity */
        double mm, mn, e;
        random_state(&r, x, dt, sign * (1.5707963267948966 - target), (n / 2) % 2, &mm, &mn);
        if (!(mm > 1e-4 && mn > 1e-4)) {
            continue; /* the other pitch landed on (or past) the singularity itself */
        }
        e = check_transition(x, dt, mm, mn);
        if (e > worst) {
            worst = e;
        }
    }
    printf("F near theta = +-90 deg (margin 1e-3..1e-2 rad), %d states: max error %.3e\n", N_SINGULAR, worst);
    TEST_ASSERT_TRUE_MESSAGE(worst <= TOL, "transition Jacobian near the singularity");
}

static void test_noise_and_measurement_jacobians(void)
{
    printf("G (noise) max error: %.3e\n", worst_G);
    printf("H accelerometer max error: %.3e\n", worst_H);
    printf("H magnetometer heading max error: %.3e\n", worst_Hmag);
    TEST_ASSERT_TRUE(worst_G <= TOL);
    TEST_ASSERT_TRUE(worst_H <= TOL);
    TEST_ASSERT_TRUE(worst_Hmag <= TOL);
}

/* The FD check must be able to fail: a Jacobian with one entry perturbed by 1e-5 is
 * caught. */
static void test_checker_detects_wrong_entry(void)
{
    double x[ATT_N] = {0.3, -0.2, 0.5, 0.1, 0.2, 0.3, 0.4, -0.1, 0.2};
    double F[ATT_N * ATT_N], col[ATT_N];
    const double dt = 0.01;
    analytic_F(x, dt, F);
    F[ATT_PHID * ATT_N + ATT_THETA] += 1e-5;
    richardson(x, dt, 0, ATT_THETA, 1e-3, col);
    TEST_ASSERT_TRUE(entry_error(F[ATT_PHID * ATT_N + ATT_THETA], col[ATT_PHID]) > TOL);
}

static void test_body_euler_rate_round_trip(void)
{
    ts_rng_t r;
    double worst = 0.0;
    int n, i;
    ts_rng_seed(&r, 4);
    for (n = 0; n < 10000; ++n) {
        att_trig_t t;
        double w[3], e[3], back[3], e2[3];
        const double phi = ts_uniform_in(&r, -3.14159, 3.14159);
        const double theta = ts_uniform_in(&r, -1.4, 1.4); /* within 80 deg */
        (void)att_trig(phi, theta, NO_CLAMP, &t);
        for (i = 0; i < 3; ++i) {
            w[i] = ts_uniform_in(&r, -20.0, 20.0);
        }
        att_gen_euler_rates(&t, w, e);
        att_gen_body_rates(&t, e, back);
        att_gen_euler_rates(&t, back, e2);
        for (i = 0; i < 3; ++i) {
            const double d1 = fabs(back[i] - w[i]) / (fabs(w[i]) > 1.0 ? fabs(w[i]) : 1.0);
            const double d2 = fabs(e2[i] - e[i]) / (fabs(e[i]) > 1.0 ? fabs(e[i]) : 1.0);
            if (d1 > worst) {
                worst = d1;
            }
            if (d2 > worst) {
                worst = d2;
            }
        }
    }
    printf("body -> Euler -> body rate round trip, |theta| <= 80 deg: max error %.3e\n", worst);
    TEST_ASSERT_TRUE(worst <= 1e-12);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_transition_jacobian_random_states);
    RUN_TEST(test_transition_jacobian_at_rest);
    RUN_TEST(test_transition_jacobian_near_singularity);
    RUN_TEST(test_noise_and_measurement_jacobians);
    RUN_TEST(test_checker_detects_wrong_entry);
    RUN_TEST(test_body_euler_rate_round_trip);
    return UNITY_END();
}
