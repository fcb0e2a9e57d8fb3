/*
 * testsim.h - test-side truth simulator and checks (always double precision).
 *
 * Generates IMU samples for a body whose attitude is integrated exactly from a body-rate
 * profile, with deterministic noise, and measures filter errors as rotation angles (so
 * they are meaningful at any attitude, gimbal lock included).
 */
#ifndef TESTSIM_H
#define TESTSIM_H

#include <stdint.h>

#include "att.h"

/* Deterministic PRNG (xorshift64*) with Gaussian draws. */
typedef struct {
    uint64_t s;
} ts_rng_t;
void ts_rng_seed(ts_rng_t *r, uint64_t seed);
double ts_uniform(ts_rng_t *r);             /* [0, 1) */
double ts_uniform_in(ts_rng_t *r, double lo, double hi);
/* A uniformly random direction (rejection sampling in the unit ball) of length norm. */
void ts_random_direction(ts_rng_t *r, double norm, ekf_scalar_t out[3]);
double ts_gauss(ts_rng_t *r);               /* N(0, 1) */

/* One sample of the random stress input (tests/c/test_att_stress.c, test_att_bounds.c), from
 * the settings s: dt log-uniform in [1e-4, dt_max] s (1 % invalid: 0, negative, NaN, twice
 * dt_max); gyro uniform within +-1.05 gyro_range (about 5 % of samples out of range per axis);
 * accel of norm 0 .. 3 gravity and mag of norm 0 .. 100 uT in random directions; each sensor
 * present with probability 0.8; 1 % of vectors with a NaN or Inf component. */
void ts_stress_sample(ts_rng_t *r, const att_settings_t *s, att_sample_t *smp);

/* Setting i (att_setting_info) at its lower (hi = 0) or upper (hi = 1) bound in *s, the
 * other settings at their defaults: the bound itself if the settings check accepts it, else
 * the accepted value closest to it, by bisection towards the default (a bound that only makes
 * sense with another setting changed too, such as a gravity above the default accelerometer
 * range, or one that the fixed-point build cannot represent). 0, or -1 if nothing is
 * accepted. */
int ts_setting_at_bound(att_settings_t *s, size_t i, int hi);

/* Rotation matrices (row-major 3x3), body to ENU. */
void ts_euler_to_R(double phi, double theta, double psi, double R[9]);
void ts_R_to_euler(const double R[9], double e[3]);
/* Angle (rad) of the rotation between two ZYX Euler triples. */
double ts_euler_angle_between(const double a[3], const double b[3]);

typedef struct {
    double gravity;        /* m/s^2 */
    double mag_h, mag_v;   /* horizontal and downward field, uT */
    double gyro_noise;     /* rad/s, 1 sigma */
    double gyro_bias[3];   /* rad/s */
    double accel_noise;    /* m/s^2 */
    double mag_noise;      /* uT */
    double dt;             /* s */
    int substeps;          /* exact-integration substeps per sample */
} ts_sim_cfg_t;

void ts_sim_default(ts_sim_cfg_t *c);

typedef struct {
    ts_sim_cfg_t cfg;
    ts_rng_t rng;
    double R[9];           /* true attitude */
    double w[3];           /* current true body rate, rad/s */
    double t;              /* s */
} ts_sim_t;

void ts_sim_init(ts_sim_t *s, const ts_sim_cfg_t *cfg, uint64_t seed, double phi, double theta, double psi);
/* Advances by one sample with body rate w (rad/s) held over the interval and fills an
 * att_sample_t (gyro = mean rate over the interval). lin_acc: extra specific force in
 * the earth frame (m/s^2) or NULL. */
void ts_sim_step(ts_sim_t *s, const double w[3], const double lin_acc[3], att_sample_t *out);
void ts_sim_euler(const ts_sim_t *s, double e[3]);

/* The firmware benchmark's recording (firmware/target/bench.c): ts_sim_default with seed
 * TS_BENCH_SEED from the attitude TS_BENCH_PHI/THETA/PSI (rad), at rest until the filter is
 * aligned, then this slow tumble (body rate in rad/s at time t in s: components of
 * different frequencies, so that every angle and rate takes many values). */
#define TS_BENCH_SEED 12345u
#define TS_BENCH_PHI 0.2
#define TS_BENCH_THETA (-0.1)
#define TS_BENCH_PSI 1.0
void ts_bench_motion(double t, double w[3]);

/* Covariance checks on a row-major n x n matrix (any scalar, passed as double). */
int ts_is_symmetric_exact(const ekf_scalar_t *P, int n);
/* Cholesky in double: 1 if positive definite (every pivot > 0), min pivot in *min_pivot. */
int ts_is_positive_definite(const ekf_scalar_t *P, int n, double *min_pivot);

#endif /* TESTSIM_H */
