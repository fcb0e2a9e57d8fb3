/*
 * slam.h - EKF-SLAM with range-bearing landmarks (docs/models.md, "EKF-SLAM").
 *
 * State [X, Y, psi, m1x, m1y, ..., mkx, mky]: robot position (m) and heading (rad,
 * counter-clockwise from the world x axis, kept in [-pi, pi)), then the k landmarks mapped
 * so far (m), in the order they were first observed. The state grows by two entries each
 * time a new landmark is observed (state augmentation), up to SLAM_MAX_LANDMARKS, a
 * compile-time constant: all memory is in slam_ekf_t, sized for the maximum.
 *
 * Motion: body-frame odometry u = (xdot m/s forward, ydot m/s left, yaw rate rad/s) over dt:
 *     X += dt (xdot cos psi - ydot sin psi),  Y += dt (xdot sin psi + ydot cos psi),
 *     psi += dt yaw_rate.
 * Landmarks are static: F is the identity outside the 3x3 pose block, so the prediction
 * touches only the pose rows and columns of P: O(n) for n states.
 *
 * Observation of landmark j: range = |m_j - p| (m), bearing = atan2(m_jy - Y, m_jx - X) - psi
 * (rad, wrapped). Its Jacobian is a 2x3 pose block and a 2x2 landmark block; the update
 * uses them as sparse rows (5 non-zeros) and never forms a dense H. Data association is
 * the caller's: every observation carries the landmark's id. The first observation of an
 * id initialises the landmark with the standard augmentation Jacobians (cross-covariances
 * with the whole state included).
 *
 * Cost per call, n = 3 + 2k states (docs/models.md has the measured numbers):
 *     slam_predict    O(n)    (pose rows of P only)
 *     slam_observe    O(n^2)  per scalar update: the Jacobian, the innovation and P H^T
 *                             are O(1), O(1) and O(n), but the covariance update of any
 *                             EKF rewrites all n^2 entries of P
 *     new landmark    O(n^2)  (P is re-laid out with the larger stride; the
 *                             cross-covariances themselves are O(n))
 *
 * Usage:
 *     slam_ekf_t f;                                           caller-owned, ~4 KB in float
 *     slam_init(&f, &slam_default_settings, pose0, pose_var);
 *     slam_predict(&f, u, dt);
 *     slam_observe(&f, &obs, NULL);                           obs = {id, range, bearing}
 * Errors leave the filter unchanged, with one documented exception (slam_observe).
 */
#ifndef SLAM_H
#define SLAM_H

#include <stdint.h>

#include "ekf.h"
#include "slam_gen.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Landmark capacity. The generic core handles at most EKF_MAX_STATES (<= 255) states, so at
 * most (EKF_MAX_STATES - 3) / 2 landmarks. Override with -DSLAM_MAX_LANDMARKS=k. */
#ifndef SLAM_MAX_LANDMARKS
#define SLAM_MAX_LANDMARKS ((EKF_MAX_STATES - 3) / 2)
#endif
/* 3 = SLAM_POSE_N (an enum in slam_gen.h, which the preprocessor cannot see) */
#define SLAM_MAX_N (3 + 2 * SLAM_MAX_LANDMARKS)
#if SLAM_MAX_LANDMARKS < 1 || SLAM_MAX_N > EKF_MAX_STATES
#error "SLAM_MAX_LANDMARKS must be in 1 .. (EKF_MAX_STATES - 3) / 2"
#endif

/* Settings, with units; slam_default_settings holds the defaults. */
typedef struct {
    ekf_scalar_t vel_var;      /* noise of each body-frame velocity input (xdot, ydot), (m/s)^2 */
    ekf_scalar_t yaw_rate_var; /* noise of the yaw-rate input, (rad/s)^2 */
    ekf_scalar_t range_var;    /* range noise, m^2 */
    ekf_scalar_t bearing_var;  /* bearing noise, rad^2 */
    ekf_scalar_t min_range;    /* observations (measured or predicted) closer than this are
                                  refused with EKF_ERR_SINGULAR, m (> 0) */
    ekf_scalar_t gate_sigma;   /* innovation gate per scalar, sigmas; 0 = off */
    ekf_scalar_t max_dt;       /* longest accepted step, s */
    ekf_scalar_t var_floor;    /* floor of every state variance, m^2 or rad^2 */
} slam_settings_t;

extern const slam_settings_t slam_default_settings;

/* One range-bearing observation of a landmark. */
typedef struct {
    uint8_t id;           /* landmark identity (the caller's data association) */
    ekf_scalar_t range;   /* m, >= 0 */
    ekf_scalar_t bearing; /* rad, from the body x axis, counter-clockwise (any angle) */
} slam_observation_t;

/* What slam_observe did. */
typedef struct {
    uint8_t new_landmark;          /* 1: the observation initialised a landmark */
    uint8_t slot;                  /* the landmark's slot (state index 3 + 2 slot) */
    ekf_status_t status[SLAM_M];   /* per component (range, bearing); EKF_SKIPPED if not run */
    ekf_innov_t innov[SLAM_M];
} slam_obs_report_t;

/* Filter memory (treat as opaque; use the accessors). P is n x n, row-major, stride n. */
typedef struct {
    ekf_scalar_t x[SLAM_MAX_N];
    ekf_scalar_t P[SLAM_MAX_N * SLAM_MAX_N];
    slam_settings_t settings;
    uint8_t n;                       /* state dimension in use: 3 + 2 landmarks; 0 = not initialised */
    uint8_t landmarks;               /* landmarks mapped */
    uint8_t id[SLAM_MAX_LANDMARKS];  /* id of each slot */
    uint32_t predicts;               /* counters saturate at UINT32_MAX */
    uint32_t fused;                  /* scalar updates fused */
    uint32_t gated;                  /* scalar updates gated */
    uint32_t singular;               /* observations refused near range 0 */
    uint32_t rejected;               /* other refused calls */
} slam_ekf_t;

/* ---- model functions (pure; the filter uses exactly these) ---- */

/* Pose after dt (s) from odometry u = (xdot m/s, ydot m/s, yaw rate rad/s); heading
 * wrapped into [-pi, pi). F (may be NULL) = d pose+/d pose, G (may be NULL) = d pose+/du,
 * both 3x3 row-major. EKF_ERR_NULL, EKF_ERR_NOT_FINITE, EKF_ERR_DT_NONPOSITIVE. */
ekf_status_t slam_motion(const ekf_scalar_t pose[SLAM_POSE_N], const ekf_scalar_t u[3], ekf_scalar_t dt,
                         ekf_scalar_t out[SLAM_POSE_N], ekf_scalar_t F[9], ekf_scalar_t G[9]);

/* Predicted observation h = (range m, bearing rad, wrapped) of landmark m (m) from pose;
 * A (may be NULL) = dh/d pose (2x3), B (may be NULL) = dh/dm (2x2), row-major.
 * EKF_ERR_SINGULAR if the range is below min_range (m). */
ekf_status_t slam_observation(const ekf_scalar_t pose[SLAM_POSE_N], const ekf_scalar_t m[2],
                              ekf_scalar_t min_range, ekf_scalar_t h[SLAM_M], ekf_scalar_t A[6],
                              ekf_scalar_t B[4]);

/* Landmark position from an observation (range m, bearing rad) at pose; Gx (may be NULL)
 * = dm/d pose (2x3), Gz (may be NULL) = dm/d(range, bearing) (2x2), row-major. */
ekf_status_t slam_inverse_observation(const ekf_scalar_t pose[SLAM_POSE_N], ekf_scalar_t range,
                                      ekf_scalar_t bearing, ekf_scalar_t m[2], ekf_scalar_t Gx[6],
                                      ekf_scalar_t Gz[4]);

/* ---- filter ---- */

/* 0 if the settings are usable, else EKF_ERR_SETTINGS (or EKF_ERR_NULL). */
ekf_status_t slam_settings_check(const slam_settings_t *s);

/* Starts with no landmarks at pose0 (X m, Y m, psi rad) with diagonal covariance
 * pose_var (>= 0: zero anchors the map frame at the start pose). */
ekf_status_t slam_init(slam_ekf_t *f, const slam_settings_t *s, const ekf_scalar_t pose0[SLAM_POSE_N],
                       const ekf_scalar_t pose_var[SLAM_POSE_N]);

/* Odometry prediction u = (xdot m/s, ydot m/s, yaw rate rad/s) over dt in (0, max_dt] s. */
ekf_status_t slam_predict(slam_ekf_t *f, const ekf_scalar_t u[3], ekf_scalar_t dt);

/*
 * Fuses one observation: initialises the landmark if its id is new (returns EKF_OK, or
 * EKF_ERR_DIMENSION when SLAM_MAX_LANDMARKS are already mapped), else two sequential
 * scalar updates (range, bearing) linearised at the prior state, equal to the batch EKF
 * update. Returns EKF_OK, EKF_GATED (a component gated, the other fused) or an error:
 * EKF_ERR_SINGULAR (measured or predicted range below min_range), EKF_ERR_NOT_FINITE,
 * EKF_ERR_RANGE (range < 0), EKF_ERR_NUMERIC. Errors other than EKF_ERR_NUMERIC are
 * detected before anything changes. EKF_ERR_NUMERIC from the bearing update (the
 * covariance would lose positive definiteness) leaves the range update fused: the
 * filter is consistent, rep->status says which component was fused. (Undoing it would
 * need a copy of P, n^2 scalars.) rep may be NULL.
 */
ekf_status_t slam_observe(slam_ekf_t *f, const slam_observation_t *obs, slam_obs_report_t *rep);

/* Accessors. */
void slam_get_pose(const slam_ekf_t *f, ekf_scalar_t pose[SLAM_POSE_N]); /* no-op on NULL */
/* Landmark id's position (m) and 2x2 covariance (m^2, may be NULL); EKF_ERR_DIMENSION if
 * the id is not mapped. */
ekf_status_t slam_get_landmark(const slam_ekf_t *f, uint8_t id, ekf_scalar_t m[2], ekf_scalar_t cov[4]);
uint8_t slam_dim(const slam_ekf_t *f);                    /* n (0 for NULL) */
const ekf_scalar_t *slam_state(const slam_ekf_t *f);      /* x[n] */
const ekf_scalar_t *slam_covariance(const slam_ekf_t *f); /* P, n x n, row-major */

#ifdef __cplusplus
}
#endif

#endif /* SLAM_H */
