/*
 * core_io.c - see core_io.h.
 */
#include "core_io.h"

#include <math.h>
#include <string.h>

#define CORE_PI 3.14159265358979323846
#define CORE_NAN ((double)NAN)
#define CORE_INF ((double)INFINITY)

static void put3(const core_frame_t *fr, const double v[3], ekf_scalar_t out[3])
{
    int i;
    if (!fr->mounted) {
        for (i = 0; i < 3; ++i) {
            out[i] = ekf_from_double(v[i]);
        }
        return;
    }
    for (i = 0; i < 3; ++i) {
        const double *r = &fr->mount[3 * i];
        out[i] = ekf_from_double(r[0] * v[0] + r[1] * v[1] + r[2] * v[2]);
    }
}

void core_sample(const core_frame_t *fr, double dt, const double gyr[3], const double acc[3], const double *mag,
                 att_sample_t *s)
{
    memset(s, 0, sizeof *s);
    s->dt = ekf_from_double(dt);
    put3(fr, gyr, s->gyro);
    put3(fr, acc, s->accel);
    s->valid = (uint8_t)(ATT_HAS_GYRO | ATT_HAS_ACCEL);
    /* all three NaN: the magnetometer did not sample at this time */
    if (mag != NULL && !(isnan(mag[0]) && isnan(mag[1]) && isnan(mag[2]))) {
        put3(fr, mag, s->mag);
        s->valid = (uint8_t)(s->valid | ATT_HAS_MAG);
    }
}

int core_aligned(const att_ekf_t *f) { return (att_flags(f) & ATT_FLAG_ALIGNED) != 0u; }

/* angle in (-pi, pi] for a in (-pi, 3 pi] */
static double wrap(double a) { return (a > CORE_PI) ? a - 2.0 * CORE_PI : a; }

void core_attitude(const core_frame_t *fr, const att_ekf_t *f, double q[4], double euler[3])
{
    ekf_scalar_t qs[4], es[3];
    double w, x, y, z;
    int i;
    if (!core_aligned(f)) {
        for (i = 0; i < 4; ++i) {
            q[i] = CORE_NAN;
        }
        euler[0] = euler[1] = euler[2] = CORE_NAN;
        return;
    }
    att_get_quaternion(f, qs);
    att_get_euler(f, es);
    w = ekf_to_double(qs[0]);
    x = ekf_to_double(qs[1]);
    y = ekf_to_double(qs[2]);
    z = ekf_to_double(qs[3]);
    if (!fr->ned) {
        q[0] = w;
        q[1] = x;
        q[2] = y;
        q[3] = z;
        for (i = 0; i < 3; ++i) {
            euler[i] = ekf_to_double(es[i]);
        }
        return;
    }
    /* q_ned = q_T * q_enu with q_T = (0, 1, 1, 0) / sqrt(2), the rotation T of core_io.h */
    {
        const double h = 0.70710678118654752440;
        q[0] = h * (-x - y);
        q[1] = h * (w + z);
        q[2] = h * (w - z);
        q[3] = h * (y - x);
    }
    euler[0] = wrap(ekf_to_double(es[0]) + CORE_PI);
    euler[1] = -ekf_to_double(es[1]);
    euler[2] = wrap(0.5 * CORE_PI - ekf_to_double(es[2]));
}

void core_angle_cov(const core_frame_t *fr, const att_ekf_t *f, double c[6])
{
    ekf_scalar_t cs[6];
    int i;
    if (!core_aligned(f)) {
        c[0] = c[1] = c[2] = CORE_INF;
        c[3] = c[4] = c[5] = 0.0;
        return;
    }
    att_get_angle_covariance(f, cs);
    for (i = 0; i < 6; ++i) {
        c[i] = ekf_to_double(cs[i]);
    }
    if (fr->ned) { /* D C D with D = diag(1, -1, -1) */
        c[3] = -c[3];
        c[4] = -c[4];
    }
}

void core_unpack_cov(const double c[6], double m[9])
{
    m[0] = c[0];
    m[4] = c[1];
    m[8] = c[2];
    m[1] = m[3] = c[3];
    m[2] = m[6] = c[4];
    m[5] = m[7] = c[5];
}

void core_state(const att_ekf_t *f, double *x, double *var)
{
    const int aligned = core_aligned(f);
    int k;
    if (x != NULL) {
        const ekf_scalar_t *s = att_state(f);
        for (k = 0; k < ATT_N; ++k) {
            x[k] = aligned ? ekf_to_double(s[k]) : CORE_NAN;
        }
    }
    if (var != NULL) {
        ekf_scalar_t v[ATT_N];
        att_get_variances(f, v);
        for (k = 0; k < ATT_N; ++k) {
            var[k] = aligned ? ekf_to_double(v[k]) : CORE_INF;
        }
    }
}

void core_gyro_bias(const att_ekf_t *f, double b[3], double sigma[3])
{
    ekf_scalar_t v[3];
    int i;
    att_get_gyro_bias(f, v);
    for (i = 0; i < 3; ++i) {
        b[i] = ekf_to_double(v[i]);
    }
    att_get_gyro_bias_sigma(f, v);
    for (i = 0; i < 3; ++i) {
        sigma[i] = ekf_to_double(v[i]);
    }
}
