/*
 * test_models_slam_loop.c - EKF-SLAM in a simulated loop: SLAM's pose error stays below dead
 * reckoning's, the landmarks converge and no landmark covariance ever grows. Built for float
 * and double. The algebra itself (Jacobians, prediction, augmentation, update) is checked in
 * test_models_slam.c.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model_test_util.h"
#include "slam.h"
#include "testsim.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const double PI = MT_PI;

enum { LOOP_LANDMARKS = 12, LOOP_STEPS = 1000, OBS_EVERY = 5 };

typedef struct {
    double slam_rms, dr_rms;        /* RMS position error over the run, m */
    double slam_final, dr_final;    /* final position error, m */
    double lm_err_first_rms;        /* landmark errors right after initialisation, RMS, m */
    double lm_err_final_rms;        /* at the end, RMS, m */
    double lm_err_final_max;        /* at the end, largest, m */
    double lm_sd_first, lm_sd_final; /* mean sqrt(trace of the 2x2 covariance), m */
    double lm_nees_final;           /* summed landmark NEES at the end (2 dof each) */
    int monotone_violations;        /* landmark covariance traces that grew between updates */
} loop_result_t;

/*
 * The robot drives two loops of a circle of radius 8 m at 1 m/s (dt 0.1 s) with noisy
 * odometry (0.2 m/s and 0.05 rad/s, 1 sigma per sample); 12 landmarks lie 4..12 m from
 * the circle's centre; every 0.5 s each landmark within 7 m is observed (0.1 m, 0.02 rad).
 * Dead reckoning integrates the same odometry with the same motion model.
 */
static loop_result_t run_loop(uint64_t seed)
{
    slam_settings_t s = slam_default_settings;
    slam_ekf_t f;
    loop_result_t res;
    ts_rng_t rng;
    const double R = 8.0, v = 1.0, dt = 0.1, sv = 0.2, sr = 0.05, s_range = 0.1, s_bearing = 0.02, max_range = 7.0;
    double lm[LOOP_LANDMARKS][2], truth[3] = {0.0, -R, 0.0}, dr[3] = {0.0, -R, 0.0};
    double sum_slam = 0.0, sum_dr = 0.0, first_err2 = 0.0, first_sd = 0.0, trace_prev[LOOP_LANDMARKS];
    int seen[LOOP_LANDMARKS], k, l, n_first = 0;
    ekf_scalar_t pose0[3];

    memset(&res, 0, sizeof res);
    s.vel_var = (ekf_scalar_t)(sv * sv);
    s.yaw_rate_var = (ekf_scalar_t)(sr * sr);
    s.range_var = (ekf_scalar_t)(s_range * s_range);
    s.bearing_var = (ekf_scalar_t)(s_bearing * s_bearing);
    ts_rng_seed(&rng, seed);
    for (l = 0; l < LOOP_LANDMARKS; ++l) {
        const double a = 2.0 * PI * (l + ts_uniform_in(&rng, -0.3, 0.3)) / LOOP_LANDMARKS;
        const double rad = (l % 2 == 0) ? ts_uniform_in(&rng, 4.0, 6.0) : ts_uniform_in(&rng, 10.0, 12.0);
        lm[l][0] = rad * cos(a);
        lm[l][1] = rad * sin(a);
        seen[l] = 0;
        trace_prev[l] = 0.0;
    }
    mt_from_double(truth, pose0, 3);
    TEST_ASSERT_EQUAL_INT(EKF_OK, slam_init(&f, &s, pose0, (const ekf_scalar_t[3]){0, 0, 0}));
    for (k = 0; k < LOOP_STEPS; ++k) {
        const double u_true[3] = {v, 0.0, v / R};
        double u_meas[3], e2;
        ekf_scalar_t u[3];
        int i;
        u_meas[0] = u_true[0] + sv * ts_gauss(&rng);
        u_meas[1] = u_true[1] + sv * ts_gauss(&rng);
        u_meas[2] = u_true[2] + sr * ts_gauss(&rng);
        for (i = 0; i < 3; ++i) {
            u[i] = (ekf_scalar_t)u_meas[i];
        }
        /* truth and dead reckoning: the same forward-Euler model as the filter */
        truth[0] += dt * (u_true[0] * cos(truth[2]) - u_true[1] * sin(truth[2]));
        truth[1] += dt * (u_true[0] * sin(truth[2]) + u_true[1] * cos(truth[2]));
        truth[2] = mt_wrap_pi(truth[2] + dt * u_true[2]);
        dr[0] += dt * (u_meas[0] * cos(dr[2]) - u_meas[1] * sin(dr[2]));
        dr[1] += dt * (u_meas[0] * sin(dr[2]) + u_meas[1] * cos(dr[2]));
        dr[2] = mt_wrap_pi(dr[2] + dt * u_meas[2]);
        TEST_ASSERT_EQUAL_INT(EKF_OK, slam_predict(&f, u, (ekf_scalar_t)dt));
        if (k % OBS_EVERY == OBS_EVERY - 1) {
            for (l = 0; l < LOOP_LANDMARKS; ++l) {
                const double ddx = lm[l][0] - truth[0], ddy = lm[l][1] - truth[1];
                const double range = hypot(ddx, ddy);
                slam_observation_t o;
                slam_obs_report_t rep;
                ekf_scalar_t m[2], cov[4];
                if (range > max_range) {
                    continue;
                }
                o.id = (uint8_t)(100 + l);
                o.range = (ekf_scalar_t)(range + s_range * ts_gauss(&rng));
                o.bearing = (ekf_scalar_t)mt_wrap_pi(atan2(ddy, ddx) - truth[2] + s_bearing * ts_gauss(&rng));
                TEST_ASSERT_EQUAL_INT(EKF_OK, slam_observe(&f, &o, &rep));
                TEST_ASSERT_EQUAL_INT(EKF_OK, slam_get_landmark(&f, o.id, m, cov));
                if (rep.new_landmark) {
                    const double ex = (double)m[0] - lm[l][0], ey = (double)m[1] - lm[l][1];
                    seen[l] = 1;
                    first_err2 += ex * ex + ey * ey;
                    first_sd += sqrt((double)cov[0] + (double)cov[3]);
                    ++n_first;
                }
            }
            /* EKF-SLAM with static landmarks: no landmark covariance ever grows (the
             * prediction leaves the map block alone, an update subtracts a PSD term) */
            for (l = 0; l < LOOP_LANDMARKS; ++l) {
                ekf_scalar_t m[2], cov[4];
                double tr;
                if (!seen[l]) {
                    continue;
                }
                TEST_ASSERT_EQUAL_INT(EKF_OK, slam_get_landmark(&f, (uint8_t)(100 + l), m, cov));
                tr = (double)cov[0] + (double)cov[3];
                if (trace_prev[l] > 0.0 && tr > trace_prev[l] * (1.0 + 1e3 * MT_EPS)) {
                    ++res.monotone_violations;
                }
                trace_prev[l] = tr;
            }
        }
        e2 = pow((double)f.x[0] - truth[0], 2) + pow((double)f.x[1] - truth[1], 2);
        sum_slam += e2;
        sum_dr += pow(dr[0] - truth[0], 2) + pow(dr[1] - truth[1], 2);
        if (k == LOOP_STEPS - 1) {
            res.slam_final = sqrt(e2);
            res.dr_final = hypot(dr[0] - truth[0], dr[1] - truth[1]);
        }
    }
    res.slam_rms = sqrt(sum_slam / LOOP_STEPS);
    res.dr_rms = sqrt(sum_dr / LOOP_STEPS);
    res.lm_err_first_rms = sqrt(first_err2 / n_first);
    res.lm_sd_first = first_sd / n_first;
    {
        double err2 = 0.0, sd = 0.0;
        int count = 0;
        for (l = 0; l < LOOP_LANDMARKS; ++l) {
            ekf_scalar_t m[2], cov[4];
            double ex, ey, c[4], ci[4], e;
            if (!seen[l]) {
                continue;
            }
            TEST_ASSERT_EQUAL_INT(EKF_OK, slam_get_landmark(&f, (uint8_t)(100 + l), m, cov));
            ex = (double)m[0] - lm[l][0];
            ey = (double)m[1] - lm[l][1];
            e = hypot(ex, ey);
            err2 += e * e;
            res.lm_err_final_max = fmax(res.lm_err_final_max, e);
            sd += sqrt((double)cov[0] + (double)cov[3]);
            mt_to_double(cov, c, 4);
            memcpy(ci, c, sizeof c);
            TEST_ASSERT_TRUE(mt_inverse(ci, 2));
            res.lm_nees_final += ex * (ci[0] * ex + ci[1] * ey) + ey * (ci[2] * ex + ci[3] * ey);
            ++count;
        }
        TEST_ASSERT_EQUAL_INT_MESSAGE(LOOP_LANDMARKS, count, "every landmark must have been seen");
        res.lm_err_final_rms = sqrt(err2 / count);
        res.lm_sd_final = sd / count;
    }
    return res;
}

/*
 * 20 independent runs. Asserted per run: SLAM's position RMS below dead reckoning's; every
 * landmark covariance non-increasing between updates (an exact property of EKF-SLAM with
 * static landmarks) and smaller at the end than at initialisation. Asserted over the runs:
 * the landmark RMS error at the end is below the one at first sight. (Not per run: the
 * absolute landmark error also carries the robot's pose error at the time of first sight,
 * and in about 1 run in 10 the map as a whole ends slightly further off than some landmark
 * was at first sight: 19 of the 20 runs here shrink, 181 of 200 seeds tried.)
 * Reported, not asserted: the landmark NEES (24 dof per run). Standard EKF-SLAM is known to
 * become over-confident (Bailey et al. 2006; Huang et al. 2010: spurious information along
 * the unobservable global heading), with rare runs far above the chi-square bound, so a
 * strict NEES test would test that known property rather than this implementation.
 */
static void test_loop_slam_beats_dead_reckoning(void)
{
    enum { SEEDS = 20 };
    double slam_sum = 0.0, dr_sum = 0.0, nees_sum = 0.0, first_sum = 0.0, final_sum = 0.0, sd_ratio = 0.0;
    int i, shrank = 0;
    for (i = 0; i < SEEDS; ++i) {
        const loop_result_t r = run_loop((uint64_t)(41 + i));
        if (i < 3) {
            printf("SLAM loop seed %d: position RMS SLAM %.3f m vs dead reckoning %.3f m (final %.3f vs %.3f m); "
                   "landmarks RMS error %.3f m at first sight -> %.3f m at the end (max %.3f m), "
                   "mean sd %.3f -> %.3f m, landmark NEES %.1f (24 dof) (%s)\n",
                   i, r.slam_rms, r.dr_rms, r.slam_final, r.dr_final, r.lm_err_first_rms, r.lm_err_final_rms,
                   r.lm_err_final_max, r.lm_sd_first, r.lm_sd_final, r.lm_nees_final, EKF_SCALAR_NAME);
        }
        TEST_ASSERT_TRUE_MESSAGE(r.slam_rms < r.dr_rms, "SLAM pose error above dead reckoning's");
        TEST_ASSERT_TRUE_MESSAGE(r.lm_sd_final < r.lm_sd_first, "landmark uncertainty did not shrink");
        TEST_ASSERT_EQUAL_INT_MESSAGE(0, r.monotone_violations, "a landmark covariance grew");
        slam_sum += r.slam_rms;
        dr_sum += r.dr_rms;
        nees_sum += r.lm_nees_final;
        first_sum += r.lm_err_first_rms;
        final_sum += r.lm_err_final_rms;
        sd_ratio += r.lm_sd_final / r.lm_sd_first;
        shrank += r.lm_err_final_rms < r.lm_err_first_rms;
    }
    printf("SLAM loop, %d runs: mean position RMS SLAM %.3f m vs dead reckoning %.3f m; landmark RMS error "
           "%.3f m at first sight -> %.3f m at the end (smaller in %d of %d runs); sd ratio end/first %.2f; "
           "mean landmark NEES %.1f (24 dof) (%s)\n",
           SEEDS, slam_sum / SEEDS, dr_sum / SEEDS, first_sum / SEEDS, final_sum / SEEDS, shrank, SEEDS,
           sd_ratio / SEEDS, nees_sum / SEEDS, EKF_SCALAR_NAME);
    TEST_ASSERT_TRUE_MESSAGE(final_sum < first_sum, "landmark errors did not shrink on average");
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_loop_slam_beats_dead_reckoning);
    return UNITY_END();
}
