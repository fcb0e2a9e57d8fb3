/*
 * test_models_radar.c - radar (polar) and lidar (Cartesian) measurements of a 2-D
 * constant-velocity target: h(x) values, the Jacobian against finite differences, bearing
 * wrap across +-pi, refusal near rho = 0, sequential updates against the batch EKF, bad
 * input, and an end-to-end tracking scenario whose position RMSE is checked against the
 * posterior Cramer-Rao bound computed from the measurement and process noise. Built for
 * float and double.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model_test_util.h"
#include "radar.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const double PI = MT_PI;

static void test_measurement_values(void)
{
    const ekf_scalar_t x[4] = {3, 4, 1, 2};
    ekf_scalar_t h[3];
    TEST_ASSERT_EQUAL_INT(EKF_OK, radar_measurement(x, EKF_C(1e-3), h));
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 5.0, (double)h[RADAR_RHO]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, atan2(4.0, 3.0), (double)h[RADAR_PHI]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 2.2, (double)h[RADAR_RHODOT]); /* (3*1 + 4*2) / 5 */
}

/*
 * Jacobian against Richardson-extrapolated central differences of radar_measurement, at
 * random states with ranges 0.5 m .. 200 m. Steps scale with the range (positions) or the
 * speed (velocities); the bearing difference is wrapped. Error per entry:
 * |H - H_fd| / max(|H|, 1/rho) (relative, with the Jacobian's natural scale 1/rho as the floor
 * of the bearing and range-rate rows).
 */
static void test_jacobian_finite_differences(void)
{
#ifdef EKF_SCALAR_DOUBLE
    const double rel_step = 1e-4, tol = 1e-7;
#else
    const double rel_step = 3e-2, tol = 3e-3;
#endif
    ts_rng_t rng;
    double worst = 0.0;
    int trial;
    ts_rng_seed(&rng, 21);
    for (trial = 0; trial < 2000; ++trial) {
        const double range = exp(ts_uniform_in(&rng, log(0.5), log(200.0)));
        const double ang = ts_uniform_in(&rng, -PI, PI);
        ekf_scalar_t x[4], H[12];
        int j, m;
        x[0] = (ekf_scalar_t)(range * cos(ang));
        x[1] = (ekf_scalar_t)(range * sin(ang));
        x[2] = (ekf_scalar_t)ts_uniform_in(&rng, -30, 30);
        x[3] = (ekf_scalar_t)ts_uniform_in(&rng, -30, 30);
        TEST_ASSERT_EQUAL_INT(EKF_OK, radar_jacobian(x, EKF_C(1e-3), H));
        for (j = 0; j < 4; ++j) {
            const double scale = (j < 2) ? range : 30.0;
            double d[2][3];
            int pass;
            for (pass = 0; pass < 2; ++pass) {
                const double hstep = rel_step * scale / (pass == 0 ? 1.0 : 2.0);
                ekf_scalar_t xp[4], xm[4], hp[3], hm[3];
                memcpy(xp, x, sizeof x);
                memcpy(xm, x, sizeof x);
                xp[j] = (ekf_scalar_t)((double)x[j] + hstep);
                xm[j] = (ekf_scalar_t)((double)x[j] - hstep);
                TEST_ASSERT_EQUAL_INT(EKF_OK, radar_measurement(xp, EKF_C(1e-3), hp));
                TEST_ASSERT_EQUAL_INT(EKF_OK, radar_measurement(xm, EKF_C(1e-3), hm));
                for (m = 0; m < 3; ++m) {
                    double diff = (double)hp[m] - (double)hm[m];
                    if (m == RADAR_PHI) {
                        diff = mt_wrap_pi(diff);
                    }
                    d[pass][m] = diff / ((double)xp[j] - (double)xm[j]);
                }
            }
            for (m = 0; m < 3; ++m) {
                const double fd = (4.0 * d[1][m] - d[0][m]) / 3.0;
                const double an = (double)H[m * 4 + j];
                const double floor_scale = 1.0 / range;
                const double e = fabs(an - fd) / fmax(fabs(an), floor_scale);
                worst = e > worst ? e : worst;
            }
        }
    }
    printf("radar Jacobian max relative error vs finite differences: %.3g (%s)\n", worst, EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE(worst < tol);
}

static void init(radar_ekf_t *f, const radar_settings_t *s, double px, double py, double vx, double vy, double var)
{
    ekf_scalar_t x0[4], p0[4];
    int i;
    x0[0] = (ekf_scalar_t)px;
    x0[1] = (ekf_scalar_t)py;
    x0[2] = (ekf_scalar_t)vx;
    x0[3] = (ekf_scalar_t)vy;
    for (i = 0; i < 4; ++i) {
        p0[i] = (ekf_scalar_t)var;
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, radar_init(f, s, x0, p0));
}

/*
 * Target just above the negative x axis (bearing pi - 0.01), measured just below it
 * (bearing -pi + 0.02): the true bearing difference is +0.03 rad, not -2 pi + 0.03. The
 * wrapped innovation must be used (with a gate on, the unwrapped one would be gated), and
 * the estimate must move across the axis by the small angle only.
 */
static void test_bearing_wrap(void)
{
    radar_settings_t s = radar_default_settings;
    radar_ekf_t f;
    radar_report_t rep;
    ekf_scalar_t z[3], h[3];
    const double r = 20.0;
    s.gate_sigma = EKF_C(5.0);
    init(&f, &s, r * cos(PI - 0.01), r * sin(PI - 0.01), 0.0, 0.0, 1.0);
    TEST_ASSERT_EQUAL_INT(EKF_OK, radar_measurement(f.x, s.min_range, h));
    z[RADAR_RHO] = h[RADAR_RHO];
    z[RADAR_PHI] = (ekf_scalar_t)(-PI + 0.02);
    z[RADAR_RHODOT] = h[RADAR_RHODOT];
    TEST_ASSERT_EQUAL_INT(EKF_OK, radar_update_radar(&f, z, &rep));
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 0.03, (double)rep.innov[RADAR_PHI].innovation);
    /* posterior bearing between prior and measurement, and the position moved along the
     * circle by a fraction of r * 0.03 = 0.6 m only: a tangential move d raises the range
     * by about d^2 / 2r < 0.01 m (the unwrapped innovation would have moved it by metres) */
    {
        const double bearing = atan2((double)f.x[RADAR_PY], (double)f.x[RADAR_PX]);
        const double moved = mt_wrap_pi(bearing - (PI - 0.01));
        TEST_ASSERT_TRUE_MESSAGE(moved > 0.0 && moved < 0.03, "bearing did not move by the wrapped angle");
        TEST_ASSERT_FLOAT_WITHIN(1e-2, r, hypot((double)f.x[RADAR_PX], (double)f.x[RADAR_PY]));
    }
    /* and the other way round: prior below the axis, measurement above */
    init(&f, &s, r * cos(-PI + 0.01), r * sin(-PI + 0.01), 0.0, 0.0, 1.0);
    z[RADAR_PHI] = (ekf_scalar_t)(PI - 0.02);
    TEST_ASSERT_EQUAL_INT(EKF_OK, radar_update_radar(&f, z, &rep));
    TEST_ASSERT_FLOAT_WITHIN(1e-4, -0.03, (double)rep.innov[RADAR_PHI].innovation);
}

/* Near rho = 0 the update is refused, nothing changes, nothing is NaN. */
static void test_singular_near_origin(void)
{
    radar_ekf_t f, saved;
    const ekf_scalar_t z[3] = {EKF_C(1.0), EKF_C(0.5), EKF_C(0.0)};
    ekf_scalar_t h[3] = {7, 7, 7}, H[12];
    static const double points[][2] = {{0.0, 0.0}, {1e-5, -1e-5}, {-3e-4, 2e-4}, {1e-30, 0.0}};
    unsigned i;
    for (i = 0; i < sizeof points / sizeof points[0]; ++i) {
        init(&f, &radar_default_settings, points[i][0], points[i][1], 1.0, -1.0, 1.0);
        saved = f;
        TEST_ASSERT_EQUAL_INT(EKF_ERR_SINGULAR, radar_update_radar(&f, z, NULL));
        TEST_ASSERT_TRUE(mt_same_bits(f.x, saved.x, sizeof f.x) && mt_same_bits(f.P, saved.P, sizeof f.P));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_SINGULAR, radar_measurement(f.x, radar_default_settings.min_range, h));
        TEST_ASSERT_EQUAL_INT(EKF_ERR_SINGULAR, radar_jacobian(f.x, radar_default_settings.min_range, H));
        TEST_ASSERT_TRUE(h[0] == EKF_C(7)); /* untouched */
        TEST_ASSERT_EQUAL_UINT32(1u, f.singular);
        /* the lidar still works there: it has no singularity */
        TEST_ASSERT_EQUAL_INT(EKF_OK, radar_update_lidar(&f, z, NULL));
        TEST_ASSERT_TRUE(ekf_all_finite(f.P, 16) && ekf_all_finite(f.x, 4));
    }
}

static void random_spd(ts_rng_t *rng, double *P, int n, double scale)
{
    double A[16];
    int i, j, k;
    for (i = 0; i < n * n; ++i) {
        A[i] = ts_uniform_in(rng, -1, 1);
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            double acc = (i == j) ? 0.2 : 0.0;
            for (k = 0; k < n; ++k) {
                acc += A[i * n + k] * A[j * n + k];
            }
            P[i * n + j] = acc * scale;
        }
    }
}

/* The three sequential scalar updates equal the batch EKF update (dense H, 3x3 S inverted). */
static void test_sequential_equals_batch(void)
{
#ifdef EKF_SCALAR_DOUBLE
    const double tol = 1e-9;
#else
    const double tol = 2e-3;
#endif
    ts_rng_t rng;
    double worst = 0.0;
    int trial;
    ts_rng_seed(&rng, 22);
    for (trial = 0; trial < 200; ++trial) {
        radar_ekf_t f;
        double P[16], x[4], H[12], nu[3], r[3], out[16];
        ekf_scalar_t h[3], Hs[12], z[3];
        const double range = ts_uniform_in(&rng, 2.0, 100.0), ang = ts_uniform_in(&rng, -PI, PI);
        int i;
        init(&f, &radar_default_settings, range * cos(ang), range * sin(ang), ts_uniform_in(&rng, -10, 10),
             ts_uniform_in(&rng, -10, 10), 1.0);
        random_spd(&rng, P, 4, 0.5);
        mt_from_double(P, f.P, 16);
        mt_to_double(f.P, P, 16);
        mt_to_double(f.x, x, 4);
        TEST_ASSERT_EQUAL_INT(EKF_OK, radar_measurement(f.x, f.settings.min_range, h));
        TEST_ASSERT_EQUAL_INT(EKF_OK, radar_jacobian(f.x, f.settings.min_range, Hs));
        mt_to_double(Hs, H, 12);
        z[0] = (ekf_scalar_t)((double)h[0] + 0.3 * ts_gauss(&rng));
        z[1] = (ekf_scalar_t)mt_wrap_pi((double)h[1] + 0.03 * ts_gauss(&rng));
        z[2] = (ekf_scalar_t)((double)h[2] + 0.3 * ts_gauss(&rng));
        for (i = 0; i < 3; ++i) {
            nu[i] = (double)z[i] - (double)h[i];
        }
        nu[1] = mt_wrap_pi(nu[1]);
        r[0] = (double)f.settings.rho_var;
        r[1] = (double)f.settings.phi_var;
        r[2] = (double)f.settings.rhodot_var;
        TEST_ASSERT_TRUE(mt_ekf_update(x, P, 4, H, nu, r, 3));
        TEST_ASSERT_EQUAL_INT(EKF_OK, radar_update_radar(&f, z, NULL));
        mt_to_double(f.x, out, 4);
        worst = fmax(worst, mt_max_rel_diff(out, x, 4));
        mt_to_double(f.P, out, 16);
        worst = fmax(worst, mt_max_rel_diff(out, P, 16));
        TEST_ASSERT_TRUE(ts_is_symmetric_exact(f.P, 4));
    }
    printf("radar sequential vs batch update: max relative difference %.3g (%s)\n", worst, EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE(worst < tol);
}

static void test_lidar_equals_batch(void)
{
    ts_rng_t rng;
    radar_ekf_t f;
    double P[16], x[4], H[8] = {1, 0, 0, 0, 0, 1, 0, 0}, nu[2], r[2], out[16];
    ekf_scalar_t z[2];
    ts_rng_seed(&rng, 23);
    init(&f, &radar_default_settings, 5, -3, 1, 2, 1.0);
    random_spd(&rng, P, 4, 1.0);
    mt_from_double(P, f.P, 16);
    mt_to_double(f.P, P, 16);
    mt_to_double(f.x, x, 4);
    z[0] = EKF_C(5.2);
    z[1] = EKF_C(-3.1);
    nu[0] = (double)z[0] - x[0];
    nu[1] = (double)z[1] - x[1];
    r[0] = r[1] = (double)f.settings.lidar_var;
    TEST_ASSERT_TRUE(mt_ekf_update(x, P, 4, H, nu, r, 2));
    TEST_ASSERT_EQUAL_INT(EKF_OK, radar_update_lidar(&f, z, NULL));
    mt_to_double(f.P, out, 16);
    TEST_ASSERT_TRUE(mt_max_rel_diff(out, P, 16) < 100 * MT_EPS);
    mt_to_double(f.x, out, 4);
    TEST_ASSERT_TRUE(mt_max_rel_diff(out, x, 4) < 100 * MT_EPS);
}

static void test_bad_input(void)
{
    radar_ekf_t f, saved;
    radar_settings_t s = radar_default_settings;
    const ekf_scalar_t nan = (ekf_scalar_t)NAN;
    ekf_scalar_t z[3] = {EKF_C(10), EKF_C(0.1), EKF_C(0)}, x0[4] = {10, 1, 0, 0}, p0[4] = {1, 1, 1, 1};
    init(&f, &radar_default_settings, 10, 1, 0, 0, 1.0);
    saved = f;
    z[1] = nan;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, radar_update_radar(&f, z, NULL));
    z[1] = EKF_C(0.1);
    z[0] = EKF_C(-1);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, radar_update_radar(&f, z, NULL));
    z[0] = (ekf_scalar_t)INFINITY;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, radar_update_lidar(&f, z, NULL));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_NONPOSITIVE, radar_predict(&f, EKF_C(0)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NOT_FINITE, radar_predict(&f, nan));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_DT_TOO_LARGE, radar_predict(&f, EKF_C(100)));
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NULL, radar_update_radar(NULL, z, NULL));
    TEST_ASSERT_TRUE(mt_same_bits(f.x, saved.x, sizeof f.x) && mt_same_bits(f.P, saved.P, sizeof f.P));
    s.min_range = EKF_C(0);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_SETTINGS, radar_init(&f, &s, x0, p0));
    p0[2] = EKF_C(0);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_RANGE, radar_init(&f, &radar_default_settings, x0, p0));
    TEST_ASSERT_TRUE(mt_same_bits(f.x, saved.x, sizeof f.x));
}

/* A covariance that is not positive along the bearing row (only possible if P was
 * corrupted): the range component fuses, the bearing component is refused with
 * EKF_ERR_NUMERIC, and the whole update must be undone, bit for bit. */
static void test_rollback_on_numeric_failure(void)
{
    radar_ekf_t f, saved;
    radar_report_t rep;
    ekf_scalar_t z[3] = {EKF_C(10.5), EKF_C(0.8), EKF_C(0.0)};
    /* target at 45 deg, 10 m: H_rho = (0.71, 0.71), H_phi = (-0.07, 0.07). P: unit variances,
     * vx correlated +0.9 with px and -0.9 with py (indefinite: the (px, py, vx) block has
     * determinant -0.62). Along H_rho the vx correlations cancel and the range update is a
     * valid one, but after it the bearing update would give vx a variance of -0.48. */
    init(&f, &radar_default_settings, 7.0710678, 7.0710678, 0.0, 0.0, 1.0);
    f.P[RADAR_PX * RADAR_N + RADAR_VX] = f.P[RADAR_VX * RADAR_N + RADAR_PX] = EKF_C(0.9);
    f.P[RADAR_PY * RADAR_N + RADAR_VX] = f.P[RADAR_VX * RADAR_N + RADAR_PY] = EKF_C(-0.9);
    saved = f;
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, radar_update_radar(&f, z, &rep));
    TEST_ASSERT_EQUAL_INT(EKF_OK, rep.status[RADAR_RHO]);
    TEST_ASSERT_EQUAL_INT(EKF_ERR_NUMERIC, rep.status[RADAR_PHI]);
    TEST_ASSERT_TRUE_MESSAGE(mt_same_bits(f.x, saved.x, sizeof f.x) && mt_same_bits(f.P, saved.P, sizeof f.P),
                             "the fused range component was not undone");
    TEST_ASSERT_EQUAL_UINT32(0u, f.fused);
}

/* ---- end-to-end scenario ------------------------------------------------------------- */

enum { RUNS = 200, STEPS = 400, SKIP = 100 };
static const double DT = 0.05;      /* s */
static const double SIGMA_A = 0.5;  /* m/s^2, acceleration held over each step (truth and filter) */

/* Posterior CRLB information recursion for x+ = F x + G a (a ~ N(0, SIGMA_A^2 I)), radar
 * (and lidar) with the Jacobian at the true state (Tichavsky, Muravchik, Nehorai 1998):
 *     J+ = (Q + F J^-1 F^T)^-1 + H^T R^-1 H. */
static void crlb_step(double *J, const double *truth, int use_lidar, const radar_settings_t *s)
{
    double Jinv[16], F[16] = {1, 0, DT, 0, 0, 1, 0, DT, 0, 0, 1, 0, 0, 0, 0, 1}, Q[16];
    ekf_scalar_t xs[4], Hs[12];
    double H[12], r[3];
    int i, j, m;
    memcpy(Jinv, J, sizeof Jinv);
    TEST_ASSERT_TRUE(mt_inverse(Jinv, 4));
    {
        const double t4 = DT * DT * DT * DT / 4.0, t3 = DT * DT * DT / 2.0, t2 = DT * DT, q = SIGMA_A * SIGMA_A;
        const double Qv[16] = {t4 * q, 0, t3 * q, 0, 0, t4 * q, 0, t3 * q, t3 * q, 0, t2 * q, 0, 0, t3 * q, 0, t2 * q};
        memcpy(Q, Qv, sizeof Q);
    }
    mt_propagate(Jinv, F, Q, 4);
    TEST_ASSERT_TRUE(mt_inverse(Jinv, 4));
    mt_from_double(truth, xs, 4);
    TEST_ASSERT_EQUAL_INT(EKF_OK, radar_jacobian(xs, s->min_range, Hs));
    mt_to_double(Hs, H, 12);
    r[0] = (double)s->rho_var;
    r[1] = (double)s->phi_var;
    r[2] = (double)s->rhodot_var;
    for (i = 0; i < 4; ++i) {
        for (j = 0; j < 4; ++j) {
            double info = Jinv[i * 4 + j];
            for (m = 0; m < 3; ++m) {
                info += H[m * 4 + i] * H[m * 4 + j] / r[m];
            }
            if (use_lidar && i == j && i < 2) {
                info += 1.0 / (double)s->lidar_var;
            }
            J[i * 4 + j] = info;
        }
    }
}

typedef struct {
    double rmse;       /* empirical position RMSE over runs and steps SKIP..STEPS-1, m */
    double se_mse;     /* standard error of the empirical MSE (from the spread over runs), m^2 */
    double crlb_rmse;  /* sqrt of the mean PCRLB position MSE over the same steps, m */
    double raw_rmse;   /* RMS position error of the raw measurements (polar -> Cartesian), m */
} scenario_result_t;

/*
 * A target starting at (-30, -30) m with velocity (0.5, 3) m/s plus random acceleration
 * (SIGMA_A, piecewise constant over each step) passes the negative x axis at t ~ 10 s: its
 * bearing crosses +-pi. Radar at every step (and lidar too, if use_lidar). The filter is
 * initialised from the first measurement's position with a large covariance.
 */
static scenario_result_t run_scenario(int use_lidar)
{
    radar_settings_t s = radar_default_settings;
    scenario_result_t res;
    ts_rng_t rng;
    double sum_mse = 0.0, sum_mse2 = 0.0, sum_crlb = 0.0, sum_raw = 0.0;
    int run, k;
    s.accel_var_x = s.accel_var_y = (ekf_scalar_t)(SIGMA_A * SIGMA_A);
    ts_rng_seed(&rng, use_lidar ? 25 : 24);
    for (run = 0; run < RUNS; ++run) {
        radar_ekf_t f;
        double truth[4] = {-30.0, -30.0, 0.5, 3.0}, J[16], run_mse = 0.0;
        int crossed = 0, i;
        init(&f, &s, truth[0] + 1.0 * ts_gauss(&rng), truth[1] + 1.0 * ts_gauss(&rng), 0.0, 0.0, 25.0);
        memset(J, 0, sizeof J);
        for (i = 0; i < 4; ++i) {
            J[i * 4 + i] = 1.0 / 25.0;
        }
        for (k = 0; k < STEPS; ++k) {
            ekf_scalar_t z[3], zl[2];
            const double ax = SIGMA_A * ts_gauss(&rng), ay = SIGMA_A * ts_gauss(&rng);
            double rho, phi, e2;
            truth[0] += DT * truth[2] + 0.5 * DT * DT * ax;
            truth[1] += DT * truth[3] + 0.5 * DT * DT * ay;
            truth[2] += DT * ax;
            truth[3] += DT * ay;
            rho = hypot(truth[0], truth[1]);
            phi = atan2(truth[1], truth[0]);
            z[RADAR_RHO] = (ekf_scalar_t)(rho + sqrt((double)s.rho_var) * ts_gauss(&rng));
            z[RADAR_PHI] = (ekf_scalar_t)mt_wrap_pi(phi + sqrt((double)s.phi_var) * ts_gauss(&rng));
            z[RADAR_RHODOT] = (ekf_scalar_t)((truth[0] * truth[2] + truth[1] * truth[3]) / rho +
                                             sqrt((double)s.rhodot_var) * ts_gauss(&rng));
            zl[0] = (ekf_scalar_t)(truth[0] + sqrt((double)s.lidar_var) * ts_gauss(&rng));
            zl[1] = (ekf_scalar_t)(truth[1] + sqrt((double)s.lidar_var) * ts_gauss(&rng));
            TEST_ASSERT_EQUAL_INT(EKF_OK, radar_predict(&f, (ekf_scalar_t)DT));
            TEST_ASSERT_EQUAL_INT(EKF_OK, radar_update_radar(&f, z, NULL));
            if (use_lidar) {
                TEST_ASSERT_EQUAL_INT(EKF_OK, radar_update_lidar(&f, zl, NULL));
            }
            crlb_step(J, truth, use_lidar, &s);
            if (truth[0] < 0.0 && fabs(truth[1]) < 1.0) {
                crossed = 1;
            }
            if (k >= SKIP) {
                double Jinv[16], ex, ey, raw_x, raw_y;
                memcpy(Jinv, J, sizeof Jinv);
                TEST_ASSERT_TRUE(mt_inverse(Jinv, 4));
                ex = (double)f.x[RADAR_PX] - truth[0];
                ey = (double)f.x[RADAR_PY] - truth[1];
                e2 = ex * ex + ey * ey;
                run_mse += e2;
                sum_crlb += Jinv[0] + Jinv[5];
                raw_x = (double)z[RADAR_RHO] * cos((double)z[RADAR_PHI]) - truth[0];
                raw_y = (double)z[RADAR_RHO] * sin((double)z[RADAR_PHI]) - truth[1];
                sum_raw += use_lidar ? 0.0 : raw_x * raw_x + raw_y * raw_y;
            }
        }
        TEST_ASSERT_TRUE_MESSAGE(crossed, "the scenario must cross the +-pi bearing");
        run_mse /= (double)(STEPS - SKIP);
        sum_mse += run_mse;
        sum_mse2 += run_mse * run_mse;
    }
    {
        const double n = (double)RUNS, mean = sum_mse / n;
        const double var = (sum_mse2 - n * mean * mean) / (n - 1.0);
        res.rmse = sqrt(mean);
        res.se_mse = sqrt(var / n);
        res.crlb_rmse = sqrt(sum_crlb / (n * (double)(STEPS - SKIP)));
        res.raw_rmse = sqrt(sum_raw / (n * (double)(STEPS - SKIP)));
    }
    return res;
}

/*
 * Bound: RMSE^2 <= 1.10 * CRLB + 3 standard errors of the Monte Carlo MSE.
 * - The posterior CRLB is the smallest MSE any estimator can reach with these noises
 *   (process SIGMA_A, radar 0.3 m / 0.03 rad / 0.3 m/s, lidar 0.15 m); it is computed
 *   along each true trajectory, so the bound follows from the noise, not from the filter.
 * - The EKF linearises at its estimate instead of the truth; at 25..45 m with a bearing
 *   noise of 0.03 rad the neglected second-order terms are of relative size
 *   (sigma_cross-range / rho)^2 < 1e-3, so an efficient-to-10 % filter is the expectation:
 *   the 10 % is that allowance.
 * - 3 standard errors of the Monte Carlo mean (estimated from the spread over runs) keep
 *   the test deterministic-seed-robust.
 * Also: RMSE^2 >= 0.9 * CRLB - 3 SE (beating the bound would mean the simulation and the
 * bound disagree), and the filter beats the raw radar position (polar to Cartesian).
 */
static void check_scenario(const char *name, const scenario_result_t *r)
{
    const double mse = r->rmse * r->rmse, crlb = r->crlb_rmse * r->crlb_rmse;
    printf("%s: position RMSE %.4f m, PCRLB %.4f m (ratio %.3f, MC standard error of MSE %.2g m^2)", name, r->rmse,
           r->crlb_rmse, r->rmse / r->crlb_rmse, r->se_mse);
    if (r->raw_rmse > 0.0) {
        printf(", raw radar position RMSE %.3f m", r->raw_rmse);
    }
    printf(" (%s)\n", EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE_MESSAGE(mse <= 1.10 * crlb + 3.0 * r->se_mse, "RMSE above the CRLB-based bound");
    TEST_ASSERT_TRUE_MESSAGE(mse >= 0.90 * crlb - 3.0 * r->se_mse, "RMSE below the CRLB: simulation inconsistent");
    if (r->raw_rmse > 0.0) {
        TEST_ASSERT_TRUE(r->rmse < r->raw_rmse);
    }
}

static scenario_result_t g_radar_only;

static void test_scenario_radar_only(void)
{
    g_radar_only = run_scenario(0);
    check_scenario("radar only", &g_radar_only);
}

static void test_scenario_radar_and_lidar(void)
{
    const scenario_result_t both = run_scenario(1);
    check_scenario("radar + lidar", &both);
    TEST_ASSERT_TRUE(g_radar_only.rmse > 0.0 && both.rmse < g_radar_only.rmse);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_measurement_values);
    RUN_TEST(test_jacobian_finite_differences);
    RUN_TEST(test_bearing_wrap);
    RUN_TEST(test_singular_near_origin);
    RUN_TEST(test_sequential_equals_batch);
    RUN_TEST(test_lidar_equals_batch);
    RUN_TEST(test_bad_input);
    RUN_TEST(test_rollback_on_numeric_failure);
    RUN_TEST(test_scenario_radar_only);
    RUN_TEST(test_scenario_radar_and_lidar);
    return UNITY_END();
}
