/*
 * bench_slam_cost.c - cost of the EKF-SLAM operations as a function of the number of
 * mapped landmarks k (state dimension n = 3 + 2k). Not a timed test: it runs one operation
 * `iterations` times inside bench_measured(), and run_slam_cost.sh runs it under
 *     valgrind --tool=callgrind --toggle-collect=bench_measured
 * which counts the instructions executed inside that function only (set-up excluded).
 *
 *     bench_slam_cost_<f|d> <phase> <landmarks> <iterations>
 * phases:
 *     predict        slam_predict (sparse F: pose rows only)
 *     observe        slam_observe of a mapped landmark (range + bearing scalar updates)
 *     augment        slam_observe of a new landmark (state augmentation), k -> k + 1
 *     dense_predict  the same prediction with a dense F and P <- F P F^T (textbook O(n^3)),
 *                    for comparison only (not library code)
 *     all            every phase once, checking that every call succeeds (the smoke test)
 * Prints one line: phase, k, n, iterations, and a checksum (so the work is not optimised out).
 * Exit status 1 if a library call fails.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "slam.h"

static slam_ekf_t g_filter;
static slam_ekf_t g_prepared;
static ekf_scalar_t g_dense_F[SLAM_MAX_N * SLAM_MAX_N];
static ekf_scalar_t g_dense_tmp[SLAM_MAX_N * SLAM_MAX_N];

enum { PH_PREDICT, PH_OBSERVE, PH_AUGMENT, PH_DENSE_PREDICT };

/* Landmarks on a circle of radius 6 m around the origin; the robot stays near the origin. */
static slam_observation_t observation_of(int id)
{
    /* the robot at the origin heading 0 sees landmark id at bearing 2 pi id / 16 */
    slam_observation_t o;
    o.id = (uint8_t)id;
    o.range = EKF_C(6.0);
    o.bearing = ekf_wrap_pi(ekf_mul(EKF_C(0.39269908169872414), (ekf_scalar_t)id));
    return o;
}

static int prepare(int landmarks)
{
    static const ekf_scalar_t pose0[3] = {0, 0, 0};
    static const ekf_scalar_t var0[3] = {EKF_C(0.01), EKF_C(0.01), EKF_C(0.001)};
    static const ekf_scalar_t u[3] = {EKF_C(0.1), EKF_C(0.0), EKF_C(0.01)};
    int k;
    if (slam_init(&g_prepared, &slam_default_settings, pose0, var0) != EKF_OK) {
        return 0;
    }
    for (k = 0; k < landmarks; ++k) {
        const slam_observation_t o = observation_of(k);
        if (slam_observe(&g_prepared, &o, NULL) != EKF_OK) {
            return 0;
        }
    }
    /* a little motion and re-observation so that P is a full, correlated matrix */
    for (k = 0; k < landmarks; ++k) {
        const slam_observation_t o = observation_of(k);
        if (slam_predict(&g_prepared, u, EKF_C(0.1)) != EKF_OK || slam_observe(&g_prepared, &o, NULL) != EKF_OK) {
            return 0;
        }
    }
    return 1;
}

/* The textbook dense prediction, for comparison: F (n x n) formed explicitly, P <- F P F^T
 * by two dense products. */
static void dense_predict(slam_ekf_t *f, const ekf_scalar_t u[3], ekf_scalar_t dt)
{
    const int n = f->n;
    ekf_scalar_t Fp[9], pose[3];
    int i, j, k;
    (void)slam_motion(f->x, u, dt, pose, Fp, NULL);
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            g_dense_F[i * n + j] = (i == j) ? EKF_C(1) : EKF_C(0);
        }
    }
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            g_dense_F[i * n + j] = Fp[i * 3 + j];
        }
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            ekf_scalar_t acc = EKF_C(0);
            for (k = 0; k < n; ++k) {
                acc = ekf_mac(acc, g_dense_F[i * n + k], f->P[k * n + j]);
            }
            g_dense_tmp[i * n + j] = acc;
        }
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j < n; ++j) {
            ekf_scalar_t acc = EKF_C(0);
            for (k = 0; k < n; ++k) {
                acc = ekf_mac(acc, g_dense_tmp[i * n + k], g_dense_F[j * n + k]);
            }
            f->P[i * n + j] = acc;
        }
    }
    for (i = 0; i < 3; ++i) {
        f->x[i] = pose[i];
    }
}

/* Everything executed in here (and only here) is counted by run_slam_cost.sh. */
__attribute__((noinline)) int bench_measured(int phase, int landmarks, int iterations);
__attribute__((noinline)) int bench_measured(int phase, int landmarks, int iterations)
{
    static const ekf_scalar_t u[3] = {EKF_C(0.1), EKF_C(0.0), EKF_C(0.01)};
    int it, fails = 0;
    for (it = 0; it < iterations; ++it) {
        if (phase == PH_PREDICT) {
            fails += slam_predict(&g_filter, u, EKF_C(0.01)) != EKF_OK;
        } else if (phase == PH_OBSERVE) {
            const slam_observation_t o = observation_of(it % landmarks);
            fails += slam_observe(&g_filter, &o, NULL) != EKF_OK;
        } else if (phase == PH_AUGMENT) {
            const slam_observation_t o = observation_of(landmarks);
            fails += slam_observe(&g_filter, &o, NULL) != EKF_OK;
        } else {
            dense_predict(&g_filter, u, EKF_C(0.01));
        }
    }
    return fails;
}

static int run(int phase, int landmarks, int iterations)
{
    static const char *const names[] = {"predict", "observe", "augment", "dense_predict"};
    double checksum = 0.0;
    int fails, i;
    memcpy(&g_filter, &g_prepared, sizeof g_filter);
    if (phase == PH_AUGMENT && landmarks >= SLAM_MAX_LANDMARKS) {
        printf("%-14s k=%2d: capacity reached (SLAM_MAX_LANDMARKS %d), skipped\n", names[phase], landmarks,
               SLAM_MAX_LANDMARKS);
        return 1;
    }
    if (phase == PH_AUGMENT) {
        /* one augmentation per run: it re-lays out P for the larger state, so a second one
         * would need the original filter back (instruction counts are deterministic, one
         * call is an exact measurement) */
        iterations = 1;
    }
    fails = bench_measured(phase, landmarks, iterations);
    for (i = 0; i < g_filter.n; ++i) {
        checksum += (double)g_filter.x[i];
    }
    printf("%-14s k=%2d n=%2d iterations=%d checksum=%.6g fails=%d (%s)\n", names[phase], landmarks,
           g_prepared.n, iterations, checksum, fails, EKF_SCALAR_NAME);
    return fails == 0;
}

int main(int argc, char **argv)
{
    int landmarks, iterations, ok = 1;
    if (argc != 4) {
        fprintf(stderr, "usage: %s predict|observe|augment|dense_predict|all <landmarks 1..%d> <iterations>\n",
                argv[0], SLAM_MAX_LANDMARKS);
        return 2;
    }
    landmarks = atoi(argv[2]);
    iterations = atoi(argv[3]);
    if (landmarks < 1 || landmarks > SLAM_MAX_LANDMARKS || iterations < 1) {
        fprintf(stderr, "%s: landmarks must be 1..%d and iterations >= 1\n", argv[0], SLAM_MAX_LANDMARKS);
        return 2;
    }
    if (!prepare(landmarks)) {
        fprintf(stderr, "%s: set-up failed\n", argv[0]);
        return 1;
    }
    if (strcmp(argv[1], "all") == 0) {
        int l;
        for (l = 1; l <= landmarks; ++l) {
            if (!prepare(l)) {
                fprintf(stderr, "%s: set-up failed\n", argv[0]);
                return 1;
            }
            ok &= run(PH_PREDICT, l, iterations);
            ok &= run(PH_OBSERVE, l, iterations);
            ok &= run(PH_AUGMENT, l, 1);
            ok &= run(PH_DENSE_PREDICT, l, iterations);
        }
    } else if (strcmp(argv[1], "predict") == 0) {
        ok = run(PH_PREDICT, landmarks, iterations);
    } else if (strcmp(argv[1], "observe") == 0) {
        ok = run(PH_OBSERVE, landmarks, iterations);
    } else if (strcmp(argv[1], "augment") == 0) {
        ok = run(PH_AUGMENT, landmarks, iterations);
    } else if (strcmp(argv[1], "dense_predict") == 0) {
        ok = run(PH_DENSE_PREDICT, landmarks, iterations);
    } else {
        fprintf(stderr, "%s: unknown phase '%s'\n", argv[0], argv[1]);
        return 2;
    }
    return ok ? 0 : 1;
}
