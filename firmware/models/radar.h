/*
 * radar.h - 2-D target tracking with a polar radar (range, bearing, range rate) and a
 * Cartesian lidar, on a constant-velocity motion model: the classic "H versus h(x)" pair
 * (lidar linear, radar linearised). docs/models.md, "Radar and lidar".
 *
 * State [px, py, vx, vy] (RADAR_PX..RADAR_VY): m and m/s in the sensor frame (sensor at
 * the origin). Radar measurement z = (rho m, phi rad, rhodot m/s):
 *     rho = sqrt(px^2 + py^2),  phi = atan2(py, px),  rhodot = (px vx + py vy) / rho.
 * Lidar measurement z = (px, py), m.
 *
 * The radar's three components are fused as sequential scalar updates linearised once at
 * the prior state, which is exactly the batch EKF update (docs/models.md); the bearing
 * innovation is wrapped into [-pi, pi). Below min_range the bearing and range rate are
 * undefined: the update is refused with EKF_ERR_SINGULAR and the filter left unchanged.
 *
 * Usage:
 *     radar_ekf_t f;                                       caller-owned
 *     radar_init(&f, &radar_default_settings, x0, p0_diag);
 *     radar_predict(&f, dt);
 *     radar_update_radar(&f, z_radar, NULL);  or  radar_update_lidar(&f, z_lidar, NULL);
 * Every function validates its input; an error leaves the filter exactly as it was.
 */
#ifndef RADAR_H
#define RADAR_H

#include <stdint.h>

#include "ekf.h"
#include "radar_gen.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Settings, with units; radar_default_settings holds the defaults. */
typedef struct {
    ekf_scalar_t accel_var_x; /* variance of the target acceleration held over a step, x axis, (m/s^2)^2 */
    ekf_scalar_t accel_var_y; /* same, y axis, (m/s^2)^2 */
    ekf_scalar_t rho_var;     /* radar range noise, m^2 */
    ekf_scalar_t phi_var;     /* radar bearing noise, rad^2 */
    ekf_scalar_t rhodot_var;  /* radar range-rate noise, (m/s)^2 */
    ekf_scalar_t lidar_var;   /* lidar position noise per axis, m^2 */
    ekf_scalar_t min_range;   /* radar updates refused below this predicted range, m (> 0) */
    ekf_scalar_t gate_sigma;  /* innovation gate per scalar, sigmas; 0 = off */
    ekf_scalar_t max_dt;      /* longest accepted step, s */
    ekf_scalar_t var_floor;   /* floor of every state variance, m^2 or (m/s)^2 */
} radar_settings_t;

extern const radar_settings_t radar_default_settings;

/* Filter memory (treat as opaque). */
typedef struct {
    ekf_scalar_t x[RADAR_N];
    ekf_scalar_t P[RADAR_N * RADAR_N];
    radar_settings_t settings;
    uint8_t initialised;
    uint32_t predicts;  /* counters saturate at UINT32_MAX */
    uint32_t fused;     /* scalar updates fused (radar and lidar) */
    uint32_t gated;     /* scalar updates gated */
    uint32_t singular;  /* radar updates refused near rho = 0 */
    uint32_t rejected;  /* other refused calls */
} radar_ekf_t;

/* What one radar or lidar update did, per component (lidar: the first two entries). */
typedef struct {
    ekf_status_t status[RADAR_M];
    ekf_innov_t innov[RADAR_M];
} radar_report_t;

/*
 * h(x) = (rho m, phi rad, rhodot m/s). EKF_ERR_SINGULAR if rho < min_range (m), h untouched;
 * EKF_ERR_NULL, EKF_ERR_NOT_FINITE.
 */
ekf_status_t radar_measurement(const ekf_scalar_t x[RADAR_N], ekf_scalar_t min_range, ekf_scalar_t h[RADAR_M]);

/* Radar Jacobian H = dh/dx, dense 3x4 row-major (zeros included). Errors as radar_measurement. */
ekf_status_t radar_jacobian(const ekf_scalar_t x[RADAR_N], ekf_scalar_t min_range, ekf_scalar_t H[RADAR_M * RADAR_N]);

/* 0 if the settings are usable, else EKF_ERR_SETTINGS (or EKF_ERR_NULL). */
ekf_status_t radar_settings_check(const radar_settings_t *s);

/* Starts the filter at x0 with diagonal covariance p0_diag (> 0). */
ekf_status_t radar_init(radar_ekf_t *f, const radar_settings_t *s, const ekf_scalar_t x0[RADAR_N],
                        const ekf_scalar_t p0_diag[RADAR_N]);

/* Constant-velocity prediction over dt in (0, max_dt] s. */
ekf_status_t radar_predict(radar_ekf_t *f, ekf_scalar_t dt);

/*
 * Fuses a radar measurement z = (rho m >= 0, phi rad (any angle), rhodot m/s).
 * Returns EKF_OK (all fused), EKF_GATED (at least one component gated, the others
 * fused), or an error with the filter unchanged: EKF_ERR_SINGULAR (predicted range below
 * min_range), EKF_ERR_NOT_FINITE, EKF_ERR_RANGE (rho < 0), EKF_ERR_NUMERIC. rep may be NULL.
 */
ekf_status_t radar_update_radar(radar_ekf_t *f, const ekf_scalar_t z[RADAR_M], radar_report_t *rep);

/* Fuses a lidar position z = (px, py), m. Returns as radar_update_radar (no SINGULAR). */
ekf_status_t radar_update_lidar(radar_ekf_t *f, const ekf_scalar_t z[2], radar_report_t *rep);

#ifdef __cplusplus
}
#endif

#endif /* RADAR_H */
