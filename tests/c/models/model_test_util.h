/*
 * model_test_util.h - dense reference linear algebra (double) and finite differences for
 * the model-library tests. Everything here is deliberately the plain textbook dense form
 * that the library avoids, so that the sparse, sequential library code is checked against
 * an independent computation.
 */
#ifndef MODEL_TEST_UTIL_H
#define MODEL_TEST_UTIL_H

#include "ekf_scalar.h"

#define MT_MAX 32
#define MT_PI 3.14159265358979323846

/* An angle wrapped into [-pi, pi), rad. */
double mt_wrap_pi(double a);

/* C = A B, A n x m, B m x p (row-major). C may not alias A or B. */
void mt_matmul(const double *A, const double *B, double *C, int n, int m, int p);
/* B = A^T, A n x m. */
void mt_transpose(const double *A, double *B, int n, int m);
/* In-place inverse of an n x n matrix (Gauss-Jordan, partial pivoting); 0 if singular. */
int mt_inverse(double *A, int n);
/* P <- F P F^T + Q, all n x n; Q may be NULL. */
void mt_propagate(double *P, const double *F, const double *Q, int n);
/*
 * Batch EKF update with an m-dimensional measurement: H (m x n), innovation nu (m),
 * diagonal noise r_var (m): S = H P H^T + R, K = P H^T S^-1, x += K nu,
 * P = (I - K H) P (I - K H)^T + K R K^T. Returns 0 if S is singular.
 */
int mt_ekf_update(double *x, double *P, int n, const double *H, const double *nu, const double *r_var, int m);

/* Largest |a_i - b_i| / max(1, |b_i|) over len entries. */
double mt_max_rel_diff(const double *a, const double *b, int len);

/* Conversions between the library's scalar and double. */
void mt_to_double(const ekf_scalar_t *a, double *b, int len);
void mt_from_double(const double *a, ekf_scalar_t *b, int len);

/* Upper p-quantile of chi-square with k degrees of freedom (Wilson-Hilferty; accurate to a
 * fraction of a percent for k >= 30). z: the standard-normal quantile of p. */
double mt_chi2_quantile(double k, double z);

/* 1 if a scalar-typed buffer equals a saved copy bit for bit. */
int mt_same_bits(const void *a, const void *b, unsigned long bytes);

/* Tolerances per scalar type: relative rounding unit of the build. */
#ifdef EKF_SCALAR_DOUBLE
#define MT_EPS 2.220446049250313e-16
#else
#define MT_EPS 1.1920929e-07
#endif

#endif /* MODEL_TEST_UTIL_H */
