/*
 * attekf_vectors.c - writes reference outputs of the C estimator for a fixed scenario.
 *
 *     attekf_vectors_f OUT.txt     (float build; attekf_vectors_d: double build)
 *
 * The scenario (30 s at 100 Hz: rest, then smooth rotations about all axes, with noise from
 * a fixed-seed generator) is integrated here in double precision, fed to att_step sample by
 * sample exactly as firmware would, and every input and output is written as a C99 hex
 * float (%a), so that a reader gets the very same bits. A few deliberately bad samples
 * (NaN gyro, accelerometer out of range, a partial-NaN magnetometer row, a time step above
 * dt_max, magnetometer absent) exercise the refusal paths.
 *
 * tests/python/test_native.py runs this program and checks that the Python extension's batch
 * runner (Core.run, host_tools/native/core_filter.c) reproduces every value bit for bit once
 * the filter has aligned (before, the extension reports NaN and infinite variances: no
 * estimate). This loop is written independently of Core.run on purpose: the test compares
 * two paths to att_step.
 *
 * Line format after two header lines ('#' comment, then the column names):
 *   t dt gyr[3] acc[3] mag[3] | state[9] var[9] quat[4] flags status[5]
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "att.h"

#define RATE_HZ 100.0
#define N_SAMPLES 3000

/* xorshift64* and Box-Muller: fixed sequence on every platform. */
static uint64_t g_rng = 0x9E3779B97F4A7C15ull;

static double uniform01(void)
{
    g_rng ^= g_rng >> 12;
    g_rng ^= g_rng << 25;
    g_rng ^= g_rng >> 27;
    return (double)((g_rng * 0x2545F4914F6CDD1Dull) >> 11) * (1.0 / 9007199254740992.0);
}

static double gauss(void)
{
    const double u1 = uniform01() + 1e-300;
    const double u2 = uniform01();
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

/* q (w x y z, body to ENU) advanced by body rate w (rad/s) over dt (s): q <- q * exp(w dt / 2). */
static void quat_advance(double q[4], const double w[3], double dt)
{
    const double a = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * dt;
    double d[4], r[4];
    double k;
    int i;
    d[0] = cos(a / 2.0);
    k = (a > 1e-12) ? sin(a / 2.0) / a * dt : dt / 2.0;
    d[1] = w[0] * k;
    d[2] = w[1] * k;
    d[3] = w[2] * k;
    r[0] = q[0] * d[0] - q[1] * d[1] - q[2] * d[2] - q[3] * d[3];
    r[1] = q[0] * d[1] + q[1] * d[0] + q[2] * d[3] - q[3] * d[2];
    r[2] = q[0] * d[2] - q[1] * d[3] + q[2] * d[0] + q[3] * d[1];
    r[3] = q[0] * d[3] + q[1] * d[2] - q[2] * d[1] + q[3] * d[0];
    k = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    for (i = 0; i < 4; ++i) {
        q[i] = r[i] / k;
    }
}

/* v_body = R(q)^T v_earth */
static void earth_to_body(const double q[4], const double ve[3], double vb[3])
{
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    const double R[9] = {
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    };
    int i;
    for (i = 0; i < 3; ++i) {
        vb[i] = R[i] * ve[0] + R[3 + i] * ve[1] + R[6 + i] * ve[2];
    }
}

/* True body rate (rad/s) at time t (s): rest for 2 s, then smooth rotations. */
static void body_rate(double t, double w[3])
{
    if (t < 2.0) {
        w[0] = w[1] = w[2] = 0.0;
        return;
    }
    w[0] = 0.9 * sin(0.7 * t);
    w[1] = 0.5 * sin(1.1 * t + 1.0);
    w[2] = 1.2 * sin(0.3 * t);
}

static void put(FILE *fp, double v) { fprintf(fp, " %a", v); }

int main(int argc, char **argv)
{
    static const double g_up[3] = {0.0, 0.0, 9.81};          /* m/s^2, ENU */
    static const double m_earth[3] = {0.0, 20.0, -45.0};      /* uT, north + down */
    static const double gyro_bias[3] = {0.01, -0.02, 0.005};  /* rad/s */
    const double dt0 = 1.0 / RATE_HZ;
    double q[4] = {0.9659258262890683, 0.0, 0.0, 0.25881904510252074}; /* 30 deg yaw */
    double t = 0.0, t_prev = 0.0;
    att_ekf_t f;
    FILE *fp;
    int i, k;

    if (argc != 2) {
        fprintf(stderr, "usage: %s OUT.txt\n", argv[0]);
        return 2;
    }
    fp = fopen(argv[1], "w");
    if (fp == NULL) {
        perror(argv[1]);
        return 1;
    }
    if (att_init(&f, &att_default_settings) != EKF_OK) {
        fprintf(stderr, "att_init failed\n");
        fclose(fp);
        return 1;
    }
    fprintf(fp, "# attekf test vectors v1 scalar=%s n=%d\n", EKF_SCALAR_NAME, N_SAMPLES);
    fprintf(fp, "t dt gyr_x gyr_y gyr_z acc_x acc_y acc_z mag_x mag_y mag_z |"
                " x0..x8 var0..var8 qw qx qy qz flags st_step st_predict st_gyro st_accel st_mag\n");
    for (i = 0; i < N_SAMPLES; ++i) {
        double w[3], gyr[3], acc[3], mag[3];
        double dt;
        att_sample_t s;
        att_step_report_t rep;
        ekf_status_t st;
        ekf_scalar_t v[ATT_N], qe[4];
        const ekf_scalar_t *x;

        /* a time step of 0.6 s (> dt_max) at sample 1500: the whole sample is refused */
        t = (i == 1500) ? t + 0.6 : t + dt0;
        dt = (i == 0) ? dt0 : t - t_prev;
        t_prev = t;
        body_rate(t, w);
        quat_advance(q, w, dt);
        earth_to_body(q, g_up, acc);
        earth_to_body(q, m_earth, mag);
        for (k = 0; k < 3; ++k) {
            gyr[k] = w[k] + gyro_bias[k] + 0.005 * gauss();
            acc[k] += 0.05 * gauss();
            mag[k] += 0.3 * gauss();
        }
        if (i == 700) {
            gyr[1] = NAN; /* a NaN gyro: the whole sample is refused */
        }
        if (i == 900) {
            acc[2] = 500.0; /* beyond accel_range: clipped (taken at the range), not refused */
        }
        if (i == 1100) {
            mag[0] = NAN; /* partial NaN: passed to the filter, refused */
        }
        if (i % 10 == 5) {
            mag[0] = mag[1] = mag[2] = NAN; /* magnetometer absent (lower rate) */
        }

        memset(&s, 0, sizeof s);
        s.dt = ekf_from_double(dt);
        for (k = 0; k < 3; ++k) {
            s.gyro[k] = ekf_from_double(gyr[k]);
            s.accel[k] = ekf_from_double(acc[k]);
            s.mag[k] = ekf_from_double(mag[k]);
        }
        s.valid = ATT_HAS_GYRO | ATT_HAS_ACCEL;
        if (!(isnan(mag[0]) && isnan(mag[1]) && isnan(mag[2]))) {
            s.valid |= ATT_HAS_MAG;
        }
        st = att_step(&f, &s, &rep);

        fprintf(fp, "%a %a", t, dt);
        for (k = 0; k < 3; ++k) {
            put(fp, gyr[k]);
        }
        for (k = 0; k < 3; ++k) {
            put(fp, acc[k]);
        }
        for (k = 0; k < 3; ++k) {
            put(fp, mag[k]);
        }
        fprintf(fp, " |");
        x = att_state(&f);
        for (k = 0; k < ATT_N; ++k) {
            put(fp, ekf_to_double(x[k]));
        }
        att_get_variances(&f, v);
        for (k = 0; k < ATT_N; ++k) {
            put(fp, ekf_to_double(v[k]));
        }
        att_get_quaternion(&f, qe);
        for (k = 0; k < 4; ++k) {
            put(fp, ekf_to_double(qe[k]));
        }
        fprintf(fp, " %lu %d %d %d %d %d\n", (unsigned long)att_flags(&f), (int)st, (int)rep.predict,
                (int)rep.gyro, (int)rep.accel, (int)rep.mag);
    }
    if (fclose(fp) != 0) {
        perror(argv[1]);
        return 1;
    }
    return 0;
}
