/*
 * test_jacobians.c - every Jacobian of the attitude model against central finite
 * differences (double build): the transition Jacobian both as D = F - I and as the factors
 * F = F2 F1 the covariance propagation uses.
 *
 * Finite differences of att_model_transition (the rotation composed exactly): Richardson-
 * extrapolated central differences,
 *   D(h) = (f(x+h) - f(x-h)) / 2h,  J_fd = (4 D(h/2) - D(h)) / 3   (error O(h^4)),
 * with a step scaled to the distance from the singularity, so that the comparison stays
 * meaningful where sec(theta) is in the thousands.
 *
 * Error measure per entry: |J - J_fd| / max(1, |J|), i.e. relative for entries of
 * magnitude >= 1 and absolute below. Required: max <= 1e-6 over >= 1000 random states,
 * the state at rest (all rates zero) and states within 0.06 deg .. 0.6 deg of +-90 deg.
 * The magnetometer's heading is checked against an independent sensor model (see there).
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

static double worst_F, worst_G, worst_H, worst_Hmag, worst_mag_level, worst_mag_value;
static double worst_F_rest;

void setUp(void) {}
void tearDown(void) {}

static double entry_error(double a, double b)
{
    const double scale = fabs(a) > 1.0 ? fabs(a) : 1.0;
    return fabs(a - b) / scale;
}

/* F = F2 F1 as the filter uses it, from att_gen_transition_factors. */
static void factored_F(const double x[ATT_N], double dt, double F[ATT_N * ATT_N])
{
    double xn[ATT_N], d1[ATT_GEN_F1_NNZ], d2[ATT_GEN_F2_NNZ], F1[ATT_N * ATT_N] = {0}, F2[ATT_N * ATT_N] = {0};
    att_motion_t mo;
    int i, j, k;
    att_model_transition(x, NULL, dt, NO_CLAMP, xn, &mo);
    att_gen_transition_factors(&mo.t0, &mo.t, x, mo.rot, mo.jd, d1, d2);
    for (i = 0; i < ATT_N; ++i) {
        F1[i * ATT_N + i] = F2[i * ATT_N + i] = 1.0;
    }
    for (k = 0; k < ATT_GEN_F1_NNZ; ++k) {
        F1[att_gen_f1_pattern[k].row * ATT_N + att_gen_f1_pattern[k].col] += d1[k];
    }
    for (k = 0; k < ATT_GEN_F2_NNZ; ++k) {
        F2[att_gen_f2_pattern[k].row * ATT_N + att_gen_f2_pattern[k].col] += d2[k];
    }
    for (i = 0; i < ATT_N; ++i) {
        for (j = 0; j < ATT_N; ++j) {
            double a = 0.0;
            for (k = 0; k < ATT_N; ++k) {
                a += F2[i * ATT_N + k] * F1[k * ATT_N + j];
            }
            F[i * ATT_N + j] = a;
        }
    }
}

static double wrap_pi(double a);

static void central(const double x[ATT_N], const double w[3], double dt, int wrt_noise, int j, double h,
                    double out[ATT_N])
{
    double xp[ATT_N], xm[ATT_N], wp[3], wm[3], fp[ATT_N], fm[ATT_N];
    att_motion_t mo;
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
    att_model_transition(xp, wp, dt, NO_CLAMP, fp, &mo);
    att_model_transition(xm, wm, dt, NO_CLAMP, fm, &mo);
    for (i = 0; i < ATT_N; ++i) {
        /* the angles come back in [-pi, pi): a difference across the wrap is the short way */
        const int angle = i >= ATT_PHI && i <= ATT_PSI;
        out[i] = (angle ? wrap_pi(fp[i] - fm[i]) : fp[i] - fm[i]) / (2.0 * h);
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

/* Finite-difference step for state j. W is singular at theta = +-90 deg: the step must move
 * the pitch before the step (distance margin0 from 90 deg) and the advanced pitch (margin_n)
 * by a small fraction of their margins, and each roll by a small fraction of a radian. F's
 * angle rows give the advanced angles' sensitivity. */
static double step_for(int j, const double F[ATT_N * ATT_N], double margin0, double margin_n)
{
    const double c = 1.0 / 200.0;
    double h = 1e-3;
    const double d_phin = fabs(F[ATT_PHI * ATT_N + j]);
    const double d_thn = fabs(F[ATT_THETA * ATT_N + j]);
    if (j == ATT_THETA) h = fmin(h, c * margin0);
    if (d_phin > 0.0) h = fmin(h, c / d_phin);
    if (d_thn > 0.0) h = fmin(h, c * margin_n / d_thn);
    return h;
}

static double check_transition(const double x[ATT_N], double dt, double margin0, double margin_n)
{
    double F[ATT_N * ATT_N], col[ATT_N], G[ATT_N * 3], g[9];
    double worst = 0.0;
    att_motion_t mo;
    double xn[ATT_N];
    int i, j;
    factored_F(x, dt, F);
    for (j = 0; j < ATT_N; ++j) {
        richardson(x, dt, 0, j, step_for(j, F, margin0, margin_n), col);
        for (i = 0; i < ATT_N; ++i) {
            const double e = entry_error(F[i * ATT_N + j], col[i]);
            if (e > worst) {
                worst = e;
            }
        }
    }
    /* noise Jacobian G = [I; 0; g] */
    att_model_transition(x, NULL, dt, NO_CLAMP, xn, &mo);
    att_gen_noise_jacobian(&mo.t, g);
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

/* ---- magnetometer ---------------------------------------------------------------------
 * The filter's heading measurement (stage_mag; docs/derivation.md, "Magnetometer"): the field
 * m (body frame) levelled with the estimated roll and pitch by att_gen_mag_level, then
 * psi_meas = wrap(atan2(l_x, l_y) - D), fused with H = e_psi. Checked against a model of the
 * sensor written independently of the generated formulas: the earth field
 * (B_h sin D, B_h cos D, -B_v) in ENU, taken into the body frame by R^T with
 * R = Rz(psi) Ry(theta) Rx(phi) of the test simulator (testsim.c, ts_euler_to_R).
 *   - l = Rz(psi)^T m_earth (the levelling);
 *   - z(x) = psi_meas(R(x)^T m_earth, roll and pitch of x) has the gradient H = e_psi over all
 *     nine states (finite differences: the reported "H magnetometer" error);
 *   - the tilt error the heading noise covers (not in H): with the field held, at level,
 *     d psi_meas / d(phi, theta) = -tan(dip) (sin(psi + D), cos(psi + D)). */
typedef struct {
    double field, dip, decl; /* field strength (uT), dip (rad, down positive), declination (rad) */
} earth_field_t;

/* Body-frame field of the attitude (phi, theta, psi): R^T m_earth. */
static void body_field(const earth_field_t *e, double phi, double theta, double psi, double m[3])
{
    double R[9], me[3];
    int i;
    ts_euler_to_R(phi, theta, psi, R);
    me[0] = e->field * cos(e->dip) * sin(e->decl);
    me[1] = e->field * cos(e->dip) * cos(e->decl);
    me[2] = -e->field * sin(e->dip);
    for (i = 0; i < 3; ++i) {
        m[i] = R[0 * 3 + i] * me[0] + R[1 * 3 + i] * me[1] + R[2 * 3 + i] * me[2];
    }
}

static double wrap_pi(double a)
{
    const double two_pi = 6.283185307179586;
    return a - two_pi * floor((a + 0.5 * two_pi) / two_pi);
}

/* The filter's heading from the field m, levelled with the roll and pitch (phi, theta);
 * level_swapped: a deliberately wrong levelling (Rx Ry instead of Ry Rx), for the test that
 * the check can fail. */
static double heading_of(const earth_field_t *e, const double m[3], double phi, double theta, int level_swapped)
{
    att_trig_t t;
    double l[3];
    (void)att_trig(phi, theta, NO_CLAMP, &t);
    if (!level_swapped) {
        att_gen_mag_level(&t, m, l);
    } else {
        const double a = t.cth * m[0] + t.sth * m[2];
        const double c = -t.sth * m[0] + t.cth * m[2];
        l[0] = a;
        l[1] = t.cphi * m[1] - t.sphi * c;
        l[2] = t.sphi * m[1] + t.cphi * c;
    }
    return wrap_pi(atan2(l[0], l[1]) - e->decl);
}

/* z(x): the heading measured at the attitude of x, levelled with the attitude of x. */
static double z_of(const earth_field_t *e, const double x[ATT_N], int level_swapped)
{
    double m[3];
    body_field(e, x[ATT_PHI], x[ATT_THETA], x[ATT_PSI], m);
    return heading_of(e, m, x[ATT_PHI], x[ATT_THETA], level_swapped);
}

static void random_field(ts_rng_t *r, earth_field_t *e)
{
    e->field = ts_uniform_in(r, 20.0, 65.0);
    e->dip = ts_uniform_in(r, -1.4, 1.4); /* within 80 deg */
    e->decl = ts_uniform_in(r, -3.0, 3.0);
}

/* Largest |H - dz/dx| over the nine states at x (H = e_psi), Richardson differences. */
static double mag_jacobian_error(const earth_field_t *e, const double x[ATT_N], int level_swapped)
{
    double worst = 0.0;
    int j;
    for (j = 0; j < ATT_N; ++j) {
        const double h = 1e-3;
        double xp[ATT_N], xm[ATT_N], d[2];
        int i, k;
        for (k = 0; k < 2; ++k) {
            const double hk = (k == 0) ? h : h / 2.0;
            for (i = 0; i < ATT_N; ++i) {
                xp[i] = xm[i] = x[i];
            }
            xp[j] += hk;
            xm[j] -= hk;
            d[k] = wrap_pi(z_of(e, xp, level_swapped) - z_of(e, xm, level_swapped)) / (2.0 * hk);
        }
        {
            const double fd = (4.0 * d[1] - d[0]) / 3.0;
            const double e_j = entry_error((j == ATT_PSI) ? 1.0 : 0.0, fd);
            if (e_j > worst) {
                worst = e_j;
            }
        }
    }
    return worst;
}

static void check_mag(ts_rng_t *r, const double x[ATT_N])
{
    earth_field_t e;
    double m[3], l[3], a, worst_l = 0.0;
    att_trig_t t;
    int i;
    random_field(r, &e);
    /* levelling: l = Rz(psi)^T m_earth = (B_h sin(psi + D), B_h cos(psi + D), -B_v) */
    body_field(&e, x[ATT_PHI], x[ATT_THETA], x[ATT_PSI], m);
    (void)att_trig(x[ATT_PHI], x[ATT_THETA], NO_CLAMP, &t);
    att_gen_mag_level(&t, m, l);
    a = x[ATT_PSI] + e.decl;
    {
        const double want[3] = {e.field * cos(e.dip) * sin(a), e.field * cos(e.dip) * cos(a), -e.field * sin(e.dip)};
        for (i = 0; i < 3; ++i) {
            const double d = fabs(l[i] - want[i]) / e.field;
            worst_l = (d > worst_l) ? d : worst_l;
        }
    }
    if (worst_l > worst_mag_level) {
        worst_mag_level = worst_l;
    }
    {
        const double v = fabs(wrap_pi(z_of(&e, x, 0) - x[ATT_PSI]));
        if (v > worst_mag_value) {
            worst_mag_value = v;
        }
    }
    {
        const double err = mag_jacobian_error(&e, x, 0);
        if (err > worst_Hmag) {
            worst_Hmag = err;
        }
    }
}
/* Random state whose advanced pitch (at_start = 0) or pitch before the step (at_start = 1) is
 * close to theta_target. margin0, margin_n: distances of the pitch before the step and of the
 * advanced pitch from +-90 deg (rad), the latter from the transition itself. */
static void random_state(ts_rng_t *r, double x[ATT_N], double dt, double theta_target, int at_start,
                         double *margin0, double *margin_n)
{
    const double half_pi = 1.5707963267948966;
    double xn[ATT_N];
    att_motion_t mo;
    int i;
    for (i = 0; i < 3; ++i) {
        x[ATT_P + i] = ts_uniform_in(r, -10.0, 10.0);
        x[ATT_PHID + i] = ts_uniform_in(r, -10.0, 10.0);
    }
    x[ATT_PHI] = ts_uniform_in(r, -3.14159, 3.14159);
    x[ATT_PSI] = ts_uniform_in(r, -3.14159, 3.14159);
    /* to first order theta+ = theta + dt (cos(phi) q - sin(phi) r) */
    x[ATT_THETA] = at_start ? theta_target
                            : theta_target - dt * (cos(x[ATT_PHI]) * x[ATT_Q] - sin(x[ATT_PHI]) * x[ATT_R]);
    if (fabs(x[ATT_THETA]) > half_pi - 1e-6) {
        x[ATT_THETA] = (x[ATT_THETA] > 0.0) ? half_pi - 1e-6 : -(half_pi - 1e-6);
    }
    att_model_transition(x, NULL, dt, NO_CLAMP, xn, &mo);
    *margin0 = half_pi - fabs(x[ATT_THETA]);
    *margin_n = half_pi - fabs(xn[ATT_THETA]);
}

static void test_transition_jacobian_random_states(void)
{
    ts_rng_t r, rf;
    int n;
    ts_rng_seed(&r, 1);
    ts_rng_seed(&rf, 5); /* earth fields of the magnetometer check */
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
        check_mag(&rf, x);
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
        /* alternately the pitch before the step and the advanced pitch next to the singularity */
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
    printf("magnetometer: levelled field vs Rz(psi)^T m_earth %.3e (relative), heading vs psi %.3e rad\n",
           worst_mag_level, worst_mag_value);
    printf("H magnetometer heading (e_psi) vs finite differences of the sensor model, all 9 states: %.3e\n",
           worst_Hmag);
    TEST_ASSERT_TRUE(worst_G <= TOL);
    TEST_ASSERT_TRUE(worst_H <= TOL);
    TEST_ASSERT_TRUE(worst_mag_level <= 1e-12); /* rounding only: measured 4.9e-16 */
    TEST_ASSERT_TRUE(worst_mag_value <= 1e-12); /* measured 8.9e-16 */
    TEST_ASSERT_TRUE(worst_Hmag <= TOL);
}

/* The magnetometer check must be able to fail: a levelling in the wrong order (roll after
 * pitch) makes the heading depend on roll and pitch, which the finite differences see. */
static void test_mag_checker_detects_wrong_levelling(void)
{
    const double x[ATT_N] = {0.1, -0.2, 0.3, 0.4, 0.5, -2.0, 0.0, 0.0, 0.0};
    const earth_field_t e = {48.0, 1.1, 0.2};
    TEST_ASSERT_TRUE(mag_jacobian_error(&e, x, 0) <= TOL);
    TEST_ASSERT_TRUE(mag_jacobian_error(&e, x, 1) > 1e-3);
}

/* What H leaves out: with the field fixed, a roll or pitch error d moves the heading by
 * tan(dip) d at most (level body), the term behind the heading noise's tan^2(dip) share
 * (stage_mag, docs/derivation.md "Magnetometer"). */
static void test_mag_heading_sensitivity_to_tilt_error(void)
{
    ts_rng_t r;
    double worst = 0.0;
    int n;
    ts_rng_seed(&r, 6);
    for (n = 0; n < 500; ++n) {
        earth_field_t e;
        double m[3], a, want[2], got[2];
        const double psi = ts_uniform_in(&r, -3.14159, 3.14159), h = 1e-5;
        int k;
        random_field(&r, &e);
        body_field(&e, 0.0, 0.0, psi, m);
        a = psi + e.decl;
        want[0] = -tan(e.dip) * sin(a);
        want[1] = -tan(e.dip) * cos(a);
        got[0] = wrap_pi(heading_of(&e, m, h, 0.0, 0) - heading_of(&e, m, -h, 0.0, 0)) / (2.0 * h);
        got[1] = wrap_pi(heading_of(&e, m, 0.0, h, 0) - heading_of(&e, m, 0.0, -h, 0)) / (2.0 * h);
        for (k = 0; k < 2; ++k) {
            const double d = entry_error(want[k], got[k]);
            worst = (d > worst) ? d : worst;
        }
    }
    printf("heading sensitivity to a tilt error at level vs -tan(dip) (sin, cos)(psi + D): %.3e\n", worst);
    TEST_ASSERT_TRUE(worst <= TOL);
}

/* The heading att_align takes from the field (the same heading function as the update):
 * the attitude of the sensor model, the declination east positive. */
static void test_alignment_heading_from_the_field(void)
{
    ts_rng_t r;
    double worst = 0.0;
    int n;
    ts_rng_seed(&r, 7);
    for (n = 0; n < 500; ++n) {
        att_settings_t set = att_default_settings;
        att_ekf_t f;
        earth_field_t e;
        double m[3], acc[3], eul[3];
        const double phi = ts_uniform_in(&r, -3.14159, 3.14159), theta = ts_uniform_in(&r, -1.4, 1.4);
        const double psi = ts_uniform_in(&r, -3.14159, 3.14159);
        const earth_field_t up = {set.gravity, -1.5707963267948966, 0.0}; /* (0, 0, g) in ENU */
        random_field(&r, &e);
        set.mag_declination = e.decl;
        body_field(&e, phi, theta, psi, m);
        body_field(&up, phi, theta, psi, acc); /* gravity's specific force: up, R^T (0, 0, g) */
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_init(&f, &set));
        TEST_ASSERT_EQUAL_INT(EKF_OK, att_align(&f, acc, m));
        att_get_euler(&f, eul);
        {
            const double d[3] = {wrap_pi(eul[0] - phi), eul[1] - theta, wrap_pi(eul[2] - psi)};
            int k;
            for (k = 0; k < 3; ++k) {
                worst = (fabs(d[k]) > worst) ? fabs(d[k]) : worst;
            }
        }
    }
    printf("att_align from the sensor model (|theta| <= 80 deg): max Euler error %.3e rad\n", worst);
    TEST_ASSERT_TRUE(worst <= 1e-12); /* rounding only: measured 1.3e-15 */
}

/* The FD check must be able to fail: a Jacobian with one entry perturbed by 1e-5 is
 * caught. */
static void test_checker_detects_wrong_entry(void)
{
    double x[ATT_N] = {0.3, -0.2, 0.5, 0.1, 0.2, 0.3, 0.4, -0.1, 0.2};
    double F[ATT_N * ATT_N], col[ATT_N];
    const double dt = 0.01;
    factored_F(x, dt, F);
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
    RUN_TEST(test_mag_checker_detects_wrong_levelling);
    RUN_TEST(test_mag_heading_sensitivity_to_tilt_error);
    RUN_TEST(test_alignment_heading_from_the_field);
    RUN_TEST(test_checker_detects_wrong_entry);
    RUN_TEST(test_body_euler_rate_round_trip);
    return UNITY_END();
}
