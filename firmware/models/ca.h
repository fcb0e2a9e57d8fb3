/*
 * ca.h - constant-acceleration (CA) motion model with MATLAB constacc / constaccjac
 * semantics, and a small CA Kalman filter with position measurements built on the core.
 *
 * State (3 entries per spatial axis, 1 to 3 axes):
 *     1-D [x; vx; ax]   2-D [x; vx; ax; y; vy; ay]   3-D [x; vx; ax; y; vy; ay; z; vz; az]
 * positions m, velocities m/s, accelerations m/s^2.
 *
 * Transition over dt (s) with process noise w (one value per axis, m/s^2: the acceleration
 * increment applied at the start of the step and held over it):
 *     x+ = x + dt vx + dt^2/2 (ax + w),  vx+ = vx + dt (ax + w),  ax+ = ax + w.
 * Jacobians (block diagonal, one block per axis):
 *     Jx = df/dx = [1 dt dt^2/2; 0 1 dt; 0 0 1],   Jw = df/dw = [dt^2/2; dt; 1].
 * MATLAB's default time step is 1 s (CA_DEFAULT_DT_S). docs/models.md gives the
 * derivation, the noise convention and the MATLAB documentation it was checked against.
 *
 * Usage of the filter:
 *     ca_ekf_t f;                                             caller-owned
 *     ca_init(&f, &ca_default_settings, 2, x0, p0_diag);      2-D
 *     ca_predict(&f, dt);  ca_update_position(&f, z, NULL);   z: (x, y) in m
 * Every function validates its input; an error leaves the filter exactly as it was.
 */
#ifndef CA_H
#define CA_H

#include <stdint.h>

#include "ca_gen.h"
#include "ekf.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CA_MAX_DIMS 3
#define CA_MAX_N (CA_BLOCK * CA_MAX_DIMS)
#define CA_DEFAULT_DT_S EKF_C(1.0) /* MATLAB constacc/constaccjac default step, s */

/*
 * MATLAB constacc: xn = f(x, w, dt) for a state of dims axes (x, xn: 3 dims entries; xn
 * may not alias x). w: dims acceleration increments (m/s^2), or NULL for zero noise.
 * Errors (xn untouched): EKF_ERR_NULL, EKF_ERR_DIMENSION (dims not 1..3),
 * EKF_ERR_DT_NONPOSITIVE, EKF_ERR_NOT_FINITE (dt, x or w).
 */
ekf_status_t ca_transition(const ekf_scalar_t *x, uint8_t dims, const ekf_scalar_t *w, ekf_scalar_t dt,
                           ekf_scalar_t *xn);

/*
 * MATLAB constaccjac: Jx (3 dims x 3 dims, row-major) and, if Jw is not NULL, Jw
 * (3 dims x dims, row-major). The CA model is linear, so neither depends on the state
 * (constaccjac's state argument only fixes the dimension). Errors as ca_transition.
 */
ekf_status_t ca_jacobian(uint8_t dims, ekf_scalar_t dt, ekf_scalar_t *Jx, ekf_scalar_t *Jw);

/* Filter settings; ca_default_settings holds the defaults. */
typedef struct {
    ekf_scalar_t accel_increment_var; /* Var(w) per axis and step, (m/s^2)^2: MATLAB's
                                         ProcessNoise of a non-additive trackingEKF */
    ekf_scalar_t position_var;        /* position measurement noise per axis, m^2 */
    ekf_scalar_t gate_sigma;          /* innovation gate, sigmas; 0 = off */
    ekf_scalar_t max_dt;              /* longest accepted step, s */
    ekf_scalar_t var_floor;           /* floor of every state variance (state units^2) */
} ca_settings_t;

extern const ca_settings_t ca_default_settings;

/* Filter memory (treat as opaque). Only the first n = 3 dims entries of x and the first
 * n*n of P (row-major, stride n) are in use. */
typedef struct {
    ekf_scalar_t x[CA_MAX_N];
    ekf_scalar_t P[CA_MAX_N * CA_MAX_N];
    ca_settings_t settings;
    uint8_t dims;
    uint8_t n;
    uint32_t predicts; /* counters saturate at UINT32_MAX */
    uint32_t fused;    /* scalar position updates fused */
    uint32_t gated;    /* scalar position updates gated */
    uint32_t rejected; /* calls refused with an error */
} ca_ekf_t;

/* 0 if the settings are usable, else EKF_ERR_SETTINGS (or EKF_ERR_NULL). */
ekf_status_t ca_settings_check(const ca_settings_t *s);

/* Starts the filter at x0 (3 dims entries) with diagonal covariance p0_diag (> 0).
 * EKF_ERR_SETTINGS, EKF_ERR_DIMENSION, EKF_ERR_NOT_FINITE, EKF_ERR_RANGE (p0 <= 0). */
ekf_status_t ca_init(ca_ekf_t *f, const ca_settings_t *s, uint8_t dims, const ekf_scalar_t *x0,
                     const ekf_scalar_t *p0_diag);

/* x <- f(x, 0, dt), P <- Jx P Jx^T + Jw Var(w) Jw^T. dt in (0, max_dt]. */
ekf_status_t ca_predict(ca_ekf_t *f, ekf_scalar_t dt);

/* Fuses a position measurement z (dims entries, m), one scalar update per axis.
 * Returns EKF_OK, or EKF_GATED if at least one axis was gated (the others are fused);
 * info (may be NULL) receives dims ekf_innov_t. Errors leave the filter unchanged. */
ekf_status_t ca_update_position(ca_ekf_t *f, const ekf_scalar_t *z, ekf_innov_t *info);

#ifdef __cplusplus
}
#endif

#endif /* CA_H */
