/*
 * att_fixture.h - what the module tests of firmware/att/ (tests/c/att/) share: the
 * filter's variables set up at a chosen attitude and covariance without running the filter,
 * the sensor vectors of an attitude computed in double from the rotation matrix (the test's
 * own route, testsim.h), and comparisons in double with a tolerance in units of the build's
 * rounding.
 */
#ifndef ATT_FIXTURE_H
#define ATT_FIXTURE_H

#include "att.h"

/* The relative rounding unit of the build's scalar as a double (float 2^-23, double 2^-52,
 * fixed point 2^-27: its covariance words, docs/fixed_point.md). */
double af_eps(void);
/* One unit of rounding of a value of magnitude scale: af_eps() scale, plus in fixed point
 * the absolute resolution of a state (2^-34). Tolerances of results that are exact but for
 * rounding are small multiples of it: any error of the method is orders of magnitude more. */
double af_ulp(double scale);

/* Fails the test, naming what and the line, unless |got - want| <= tol. */
void af_near(double want, double got, double tol, const char *what, int line);
#define AF_NEAR(want, got, tol) af_near((want), (got), (tol), #got, __LINE__)
/* The same for a scalar of the build. */
#define AF_NEAR_S(want, got, tol) af_near((want), ekf_to_double(got), (tol), #got, __LINE__)
/* Prints the largest |got - want| / tol that af_near has seen (how much room the tolerances
 * leave, for whoever tunes them). */
void af_print_worst(void);

/* R^T v: an earth-frame (ENU) vector in the body axes of the attitude (phi, theta, psi), rad. */
void af_to_body(double phi, double theta, double psi, const double v_enu[3], ekf_scalar_t out[3]);
/* The specific force at rest, g up in ENU, in the body axes. */
void af_gravity_body(double g, double phi, double theta, ekf_scalar_t out[3]);
/* An earth field of horizontal strength bh towards magnetic north, turned east by the
 * declination decl (rad), and vertical strength bv pointing down, in the body axes. */
void af_field_body(double bh, double bv, double decl, double phi, double theta, double psi, ekf_scalar_t out[3]);

/* The rotation by the vector u (rad), Exp([u]x), row-major, by Rodrigues' formula. */
void af_rotation(const double u[3], double C[9]);

/* Variables of an aligned filter with the state x (angles in range) and P = diag(var),
 * everything else as after att_reset: no magnetic reference, the accelerometer low-pass
 * empty, no rest, every clock stopped. */
void af_vars(att_vars_t *v, const att_settings_t *s, const double x[ATT_N], const double var[ATT_N]);
/* The same with a full covariance (row-major, symmetric). */
void af_vars_full(att_vars_t *v, const att_settings_t *s, const double x[ATT_N], const double P[ATT_N * ATT_N]);

/* A covariance with the variances var[ATT_N] and random correlations of moderate size
 * (the normalised B B^T + 9 I, B uniform in [-1, 1), seeded): symmetric positive definite. */
void af_random_cov(uint64_t seed, const double var[ATT_N], double P[ATT_N * ATT_N]);

/* P of the variables as doubles, row-major. */
void af_cov(const att_vars_t *v, double P[ATT_N * ATT_N]);

/* The textbook batch Kalman update in double, a route independent of the filter's
 * sequential scalar updates (docs/derivation.md, "Sequential vector updates"): m (1..3)
 * measurements with rows H (m x ATT_N, row-major), innovations nu[m] and independent noise
 * variances r[m]: S = H P H^T + diag(r), K = P H^T S^-1, x += K nu, P -= K H P. */
void af_batch_update(double x[ATT_N], double P[ATT_N * ATT_N], const double *H, const double *nu, const double *r,
                     int m);

/* Fails the test unless every entry of the filter's P is within tol of want (row-major). */
void af_cov_near(const att_vars_t *v, const double want[ATT_N * ATT_N], double tol, int line);

#endif /* ATT_FIXTURE_H */
