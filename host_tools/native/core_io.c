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

/* The attitude in ENU (quaternion w, x, y, z and ZYX Euler angles) into the output frame. */
static void to_frame(const core_frame_t *fr, const double qe[4], const double ee[3], double q[4], double euler[3])
{
    int i;
    if (!fr->ned) {
        for (i = 0; i < 4; ++i) {
            q[i] = qe[i];
        }
        for (i = 0; i < 3; ++i) {
            euler[i] = ee[i];
        }
        return;
    }
    /* q_ned = q_T * q_enu with q_T = (0, 1, 1, 0) / sqrt(2), the rotation T of core_io.h */
    {
        const double h = 0.70710678118654752440;
        const double w = qe[0], x = qe[1], y = qe[2], z = qe[3];
        q[0] = h * (-x - y);
        q[1] = h * (w + z);
        q[2] = h * (w - z);
        q[3] = h * (y - x);
    }
    euler[0] = wrap(ee[0] + CORE_PI);
    euler[1] = -ee[1];
    euler[2] = wrap(0.5 * CORE_PI - ee[2]);
}

void core_attitude(const core_frame_t *fr, const att_ekf_t *f, double q[4], double euler[3])
{
    ekf_scalar_t qs[4], es[3];
    double qe[4], ee[3];
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
    for (i = 0; i < 4; ++i) {
        qe[i] = ekf_to_double(qs[i]);
    }
    for (i = 0; i < 3; ++i) {
        ee[i] = ekf_to_double(es[i]);
    }
    to_frame(fr, qe, ee, q, euler);
}

void core_attitude_from_euler(const core_frame_t *fr, const double e[3], double q[4], double euler[3])
{
    /* q = qz(psi) * qy(theta) * qx(phi), as att_model_euler_to_quat */
    const double cr = cos(0.5 * e[0]), sr = sin(0.5 * e[0]);
    const double cp = cos(0.5 * e[1]), sp = sin(0.5 * e[1]);
    const double cy = cos(0.5 * e[2]), sy = sin(0.5 * e[2]);
    const double qe[4] = {cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr, cy * sp * cr + sy * cp * sr,
                          sy * cp * cr - cy * sp * sr};
    to_frame(fr, qe, e, q, euler);
}

void core_cov_to_frame(const core_frame_t *fr, double c[6])
{
    if (fr->ned) { /* D C D with D = diag(1, -1, -1) */
        c[3] = -c[3];
        c[4] = -c[4];
    }
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
    core_cov_to_frame(fr, c);
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

void core_run_sample(const core_frame_t *fr, const core_run_io_t *io, size_t i, att_sample_t *s)
{
    core_sample(fr, io->dt[i], &io->gyr[3 * i], &io->acc[3 * i], (io->mag != NULL) ? &io->mag[3 * i] : NULL, s);
}

void core_write_row(const core_frame_t *fr, const att_ekf_t *f, size_t i, ekf_status_t st,
                    const att_step_report_t *rep, const core_run_io_t *io)
{
    double q[4], e[3], b[3], bs[3];
    if (io->state != NULL || io->var != NULL) {
        core_state(f, (io->state != NULL) ? &io->state[(size_t)ATT_N * i] : NULL,
                   (io->var != NULL) ? &io->var[(size_t)ATT_N * i] : NULL);
    }
    if (io->quat != NULL || io->euler != NULL) {
        core_attitude(fr, f, (io->quat != NULL) ? &io->quat[4 * i] : q, (io->euler != NULL) ? &io->euler[3 * i] : e);
    }
    if (io->cov != NULL) {
        core_angle_cov(fr, f, &io->cov[6 * i]);
    }
    if (io->bias != NULL || io->bias_sigma != NULL) {
        core_gyro_bias(f, (io->bias != NULL) ? &io->bias[3 * i] : b, (io->bias_sigma != NULL) ? &io->bias_sigma[3 * i] : bs);
    }
    if (io->flags != NULL) {
        io->flags[i] = att_flags(f);
    }
    if (io->status != NULL) {
        uint8_t *row = &io->status[(size_t)CORE_STATUS_COLS * i];
        row[CORE_STATUS_STEP] = (uint8_t)st;
        row[CORE_STATUS_PREDICT] = (uint8_t)rep->predict;
        row[CORE_STATUS_GYRO] = (uint8_t)rep->gyro;
        row[CORE_STATUS_ACCEL] = (uint8_t)rep->accel;
        row[CORE_STATUS_MAG] = (uint8_t)rep->mag;
    }
}
