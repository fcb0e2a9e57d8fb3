/*
 * testsim.c - see testsim.h.
 */
#include "testsim.h"

#include <math.h>
#include <stddef.h>

void ts_rng_seed(ts_rng_t *r, uint64_t seed)
{
    r->s = seed ? seed : 0x9E3779B97F4A7C15ull;
}

static uint64_t next_u64(ts_rng_t *r)
{
    uint64_t x = r->s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    r->s = x;
    return x * 0x2545F4914F6CDD1Dull;
}

double ts_uniform(ts_rng_t *r)
{
    return (double)(next_u64(r) >> 11) * (1.0 / 9007199254740992.0);
}

double ts_uniform_in(ts_rng_t *r, double lo, double hi)
{
    return lo + (hi - lo) * ts_uniform(r);
}

void ts_random_direction(ts_rng_t *r, double norm, ekf_scalar_t out[3])
{
    double v[3], n;
    int i;
    do {
        for (i = 0; i < 3; ++i) {
            v[i] = ts_uniform_in(r, -1.0, 1.0);
        }
        n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    } while (n < 1e-3 || n > 1.0);
    for (i = 0; i < 3; ++i) {
        out[i] = ekf_from_double(v[i] / n * norm);
    }
}

double ts_gauss(ts_rng_t *r)
{
    double u1 = ts_uniform(r), u2 = ts_uniform(r);
    if (u1 < 1e-300) {
        u1 = 1e-300;
    }
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

static void maybe_corrupt(ts_rng_t *r, ekf_scalar_t v[3])
{
    if (ts_uniform(r) < 0.01) {
        const int k = (int)(ts_uniform(r) * 3.0);
        v[k] = ekf_from_double((ts_uniform(r) < 0.5) ? (double)NAN : (double)INFINITY);
    }
}

void ts_stress_sample(ts_rng_t *r, const att_settings_t *s, att_sample_t *smp)
{
    const double u = ts_uniform(r);
    int i;
    smp->dt = ekf_from_double(exp(ts_uniform_in(r, log(1e-4), log(ekf_to_double(s->dt_max)))));
    if (u < 0.0025) {
        smp->dt = EKF_C(0);
    } else if (u < 0.005) {
        smp->dt = EKF_C(-0.01);
    } else if (u < 0.0075) {
        smp->dt = ekf_from_double((double)NAN);
    } else if (u < 0.01) {
        smp->dt = ekf_mul(s->dt_max, EKF_C(2));
    }
    for (i = 0; i < 3; ++i) {
        smp->gyro[i] = ekf_from_double(ts_uniform_in(r, -1.05 * ekf_to_double(s->gyro_range), 1.05 * ekf_to_double(s->gyro_range)));
    }
    ts_random_direction(r, ts_uniform_in(r, 0.0, 3.0 * ekf_to_double(s->gravity)), smp->accel);
    ts_random_direction(r, ts_uniform_in(r, 0.0, 100.0), smp->mag);
    maybe_corrupt(r, smp->gyro);
    maybe_corrupt(r, smp->accel);
    maybe_corrupt(r, smp->mag);
    smp->valid = 0u;
    if (ts_uniform(r) < 0.8) {
        smp->valid |= ATT_HAS_GYRO;
    }
    if (ts_uniform(r) < 0.8) {
        smp->valid |= ATT_HAS_ACCEL;
    }
    if (ts_uniform(r) < 0.8) {
        smp->valid |= ATT_HAS_MAG;
    }
}

/* 1 if setting i at value v, the others at their defaults, passes the settings check. */
static int accepted(size_t i, ekf_scalar_t v)
{
    att_settings_t s = att_default_settings;
    return att_setting_set(&s, i, v) == EKF_OK && att_settings_check(&s) == EKF_OK;
}

int ts_setting_at_bound(att_settings_t *s, size_t i, int hi)
{
    const att_setting_info_t *info = att_setting_info(i);
    ekf_scalar_t b, d;
    double out, in;
    int k;
    *s = att_default_settings;
    if (info == NULL || att_setting_get(s, i, &d) != EKF_OK) {
        return -1;
    }
    b = hi ? info->hi : info->lo;
    if (!accepted(i, b)) {
        const int logs = ekf_to_double(b) > 0.0 && ekf_to_double(d) > 0.0;
        if (info->type != ATT_SETTING_SCALAR || !accepted(i, d)) {
            return -1;
        }
        out = ekf_to_double(d); /* accepted */
        in = ekf_to_double(b);  /* refused */
        for (k = 0; k < 80; ++k) {
            const double mid = logs ? sqrt(out * in) : 0.5 * (out + in);
            const ekf_scalar_t m = ekf_from_double(mid);
            if (m == ekf_from_double(out) || m == ekf_from_double(in)) {
                break;
            }
            if (accepted(i, m)) {
                out = mid;
            } else {
                in = mid;
            }
        }
        b = ekf_from_double(out);
    }
    return (att_setting_set(s, i, b) == EKF_OK && att_settings_check(s) == EKF_OK) ? 0 : -1;
}

void ts_euler_to_R(double phi, double theta, double psi, double R[9])
{
    const double cr = cos(phi), sr = sin(phi), cp = cos(theta), sp = sin(theta), cy = cos(psi), sy = sin(psi);
    /* Rz(psi) Ry(theta) Rx(phi) */
    R[0] = cy * cp;
    R[1] = cy * sp * sr - sy * cr;
    R[2] = cy * sp * cr + sy * sr;
    R[3] = sy * cp;
    R[4] = sy * sp * sr + cy * cr;
    R[5] = sy * sp * cr - cy * sr;
    R[6] = -sp;
    R[7] = cp * sr;
    R[8] = cp * cr;
}

void ts_R_to_euler(const double R[9], double e[3])
{
    double s = -R[6];
    if (s > 1.0) {
        s = 1.0;
    } else if (s < -1.0) {
        s = -1.0;
    }
    e[0] = atan2(R[7], R[8]);
    e[1] = asin(s);
    e[2] = atan2(R[3], R[0]);
}

double ts_euler_angle_between(const double a[3], const double b[3])
{
    double Ra[9], Rb[9], tr = 0.0, c;
    int i, k;
    ts_euler_to_R(a[0], a[1], a[2], Ra);
    ts_euler_to_R(b[0], b[1], b[2], Rb);
    /* trace(Ra Rb^T) = 1 + 2 cos(angle) */
    for (i = 0; i < 3; ++i) {
        for (k = 0; k < 3; ++k) {
            tr += Ra[i * 3 + k] * Rb[i * 3 + k];
        }
    }
    c = (tr - 1.0) / 2.0;
    if (c > 1.0) {
        c = 1.0;
    } else if (c < -1.0) {
        c = -1.0;
    }
    return acos(c);
}

void ts_sim_default(ts_sim_cfg_t *c)
{
    c->gravity = 9.81;
    c->mag_h = 20.0;
    c->mag_v = 44.0;
    c->gyro_noise = 0.005;
    c->gyro_bias[0] = c->gyro_bias[1] = c->gyro_bias[2] = 0.0;
    c->accel_noise = 0.05;
    c->mag_noise = 0.3;
    c->dt = 0.01;
    c->substeps = 10;
}

void ts_sim_init(ts_sim_t *s, const ts_sim_cfg_t *cfg, uint64_t seed, double phi, double theta, double psi)
{
    s->cfg = *cfg;
    ts_rng_seed(&s->rng, seed);
    ts_euler_to_R(phi, theta, psi, s->R);
    s->w[0] = s->w[1] = s->w[2] = 0.0;
    s->t = 0.0;
}

/* R <- R * exp([w dt]x) (body-fixed rotation), Rodrigues, then re-orthonormalised. */
static void rotate_body(double R[9], const double w[3], double dt)
{
    const double ax = w[0] * dt, ay = w[1] * dt, az = w[2] * dt;
    const double ang = sqrt(ax * ax + ay * ay + az * az);
    double E[9], Rn[9];
    int i, j, k;
    if (ang < 1e-15) {
        return;
    }
    {
        const double x = ax / ang, y = ay / ang, z = az / ang, c = cos(ang), s = sin(ang), v = 1.0 - c;
        E[0] = c + x * x * v;     E[1] = x * y * v - z * s; E[2] = x * z * v + y * s;
        E[3] = y * x * v + z * s; E[4] = c + y * y * v;     E[5] = y * z * v - x * s;
        E[6] = z * x * v - y * s; E[7] = z * y * v + x * s; E[8] = c + z * z * v;
    }
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            double acc = 0.0;
            for (k = 0; k < 3; ++k) {
                acc += R[i * 3 + k] * E[k * 3 + j];
            }
            Rn[i * 3 + j] = acc;
        }
    }
    for (i = 0; i < 9; ++i) {
        R[i] = Rn[i];
    }
}

void ts_sim_step(ts_sim_t *s, const double w[3], const double lin_acc[3], att_sample_t *out)
{
    const ts_sim_cfg_t *c = &s->cfg;
    const double me[3] = {0.0, c->mag_h, -c->mag_v};
    double fe[3] = {0.0, 0.0, c->gravity};
    int i, k;
    for (k = 0; k < c->substeps; ++k) {
        rotate_body(s->R, w, c->dt / (double)c->substeps);
    }
    s->t += c->dt;
    for (i = 0; i < 3; ++i) {
        s->w[i] = w[i];
        if (lin_acc != NULL) {
            fe[i] += lin_acc[i];
        }
    }
    out->dt = ekf_from_double(c->dt);
    for (i = 0; i < 3; ++i) {
        /* body = R^T earth */
        const double fb = s->R[0 * 3 + i] * fe[0] + s->R[1 * 3 + i] * fe[1] + s->R[2 * 3 + i] * fe[2];
        const double mb = s->R[0 * 3 + i] * me[0] + s->R[1 * 3 + i] * me[1] + s->R[2 * 3 + i] * me[2];
        out->gyro[i] = ekf_from_double(w[i] + c->gyro_bias[i] + c->gyro_noise * ts_gauss(&s->rng));
        out->accel[i] = ekf_from_double(fb + c->accel_noise * ts_gauss(&s->rng));
        out->mag[i] = ekf_from_double(mb + c->mag_noise * ts_gauss(&s->rng));
    }
    out->valid = ATT_HAS_GYRO | ATT_HAS_ACCEL | ATT_HAS_MAG;
}

void ts_bench_motion(double t, double w[3])
{
    w[0] = 0.8 * sin(2.0 * 3.141592653589793 * 0.23 * t);
    w[1] = 0.5 * sin(2.0 * 3.141592653589793 * 0.17 * t + 1.0);
    w[2] = 0.6 * sin(2.0 * 3.141592653589793 * 0.11 * t + 2.0);
}

void ts_sim_euler(const ts_sim_t *s, double e[3])
{
    ts_R_to_euler(s->R, e);
}

int ts_is_symmetric_exact(const ekf_scalar_t *P, int n)
{
    int i, j;
    for (i = 0; i < n; ++i) {
        for (j = i + 1; j < n; ++j) {
            if (!(P[i * n + j] == P[j * n + i])) {
                return 0;
            }
        }
    }
    return 1;
}

int ts_is_positive_definite(const ekf_scalar_t *P, int n, double *min_pivot)
{
    double L[32 * 32];
    double minp = HUGE_VAL;
    int i, j, k;
    if (n > 32) {
        return 0;
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j <= i; ++j) {
            double sum = ekf_to_double(P[i * n + j]);
            for (k = 0; k < j; ++k) {
                sum -= L[i * 32 + k] * L[j * 32 + k];
            }
            if (i == j) {
                if (!(sum > 0.0) || !isfinite(sum)) {
                    if (min_pivot != NULL) {
                        *min_pivot = sum;
                    }
                    return 0;
                }
                if (sum < minp) {
                    minp = sum;
                }
                L[i * 32 + i] = sqrt(sum);
            } else {
                L[i * 32 + j] = sum / L[j * 32 + j];
            }
        }
    }
    if (min_pivot != NULL) {
        *min_pivot = minp;
    }
    return 1;
}
