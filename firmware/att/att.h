/*
 * att.h - attitude estimator: the 9-state EKF (gyro, accelerometer, magnetometer).
 *
 * Usage:
 *     att_ekf_t ekf;                              caller owns the memory (static or stack)
 *     att_init(&ekf, &att_default_settings);      or a modified copy of the defaults
 *     for each IMU sample:
 *         att_sample_t s = { .dt = ..., .gyro = ..., .accel = ..., .valid = ... };
 *         att_step(&ekf, &s, NULL);
 *         att_get_euler(&ekf, euler);             rad; att_get_quaternion for (w,x,y,z)
 *
 * The first samples with an accelerometer reading align the filter (roll and pitch from
 * gravity, heading from the magnetometer when there is one); att_step then runs
 *     gyro update -> predict(dt) -> accelerometer update -> magnetometer update
 * (docs/derivation.md, "Step order"). The individual stages are public too. Every
 * complete sample also feeds the rest detector, which learns the gyroscope offset that
 * the gyro update subtracts (att_rest.h).
 *
 * Units: SI inside (rad, rad/s, m/s^2, s); the magnetometer in any unit (uT suggested),
 * used consistently with mag_range and mag_ref_norm. Frames: body to ENU (att_defs.h).
 *
 * Contract of every call that changes the filter (att_init, att_align, att_step and the
 * stages): it either succeeds, or it leaves the whole filter exactly as it was (state,
 * covariance, flags, every counter and diagnostic, rest detector, low-pass, clocks) except
 * its one error counter, diag.rejected (bad input) or diag.numeric (EKF_ERR_NUMERIC). Every
 * input is validated before the first write; the call then saves the filter's variables in one
 * copy, runs its stages on the variables themselves and puts the copy back if any stage or
 * the guard at the end fails. EKF_GATED and
 * EKF_SKIPPED are not errors: the call was applied. After every successful call P is
 * symmetric positive definite with every variance >= var_floor, checked by the guard at the
 * end of the call: a P that rounding made indefinite by no more than a rounding-sized
 * diagonal loading cures is repaired by that loading, and the repair reported as its own
 * event (ATT_FLAG_COV_REPAIRED on that call, diag.cov_repairs); a P indefinite beyond that
 * (a bug, or a filter whose memory was overwritten) refuses the call with EKF_ERR_NUMERIC,
 * and every later call too until att_reset() or att_init() starts the filter afresh. The
 * filter never stores NaN or Inf. Outputs (att_get_*) only read.
 */
#ifndef ATT_H
#define ATT_H

#include <stddef.h>
#include <stdint.h>

#include "att_cov.h"
#include "att_bias.h"
#include "att_consider.h"
#include "att_defs.h"
#include "att_rest.h"
#include "att_settings_table.h"
#include "ekf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Settings: every tunable, one field per row of att_settings_table.h (the table gives each
 * its unit, default, range and meaning; docs/architecture.md lists them). */
typedef struct {
    ATT_SETTINGS_MAIN(ATT_SETTING_FIELD)
    att_rest_settings_t rest; /* rest detection and gyroscope offset at rest (att_rest.h) */
    att_bias_settings_t bias; /* gyroscope offset in motion (att_bias.h) */
} att_settings_t;

extern const att_settings_t att_default_settings;

/* Status flags (att_flags()). "last" means the most recent sample of that sensor. */
#define ATT_FLAG_ALIGNED          (1u << 0)  /* initial attitude set */
#define ATT_FLAG_GIMBAL_LOCK      (1u << 1)  /* |theta| > gimbal_limit */
#define ATT_FLAG_ACCEL_DEWEIGHTED (1u << 2)  /* last accel: linear acceleration or clipped, noise variance >= doubled */
#define ATT_FLAG_ACCEL_REJECTED   (1u << 3)  /* last accel: norm beyond accel_reject, not fused */
#define ATT_FLAG_MAG_DISTURBED    (1u << 4)  /* last mag: norm or dip off reference, not fused */
#define ATT_FLAG_HEADING_HELD     (1u << 5)  /* last mag: not fused because of gimbal lock */
#define ATT_FLAG_GYRO_GATED       (1u << 6)  /* last gyro: at least one axis gated */
#define ATT_FLAG_ACCEL_GATED      (1u << 7)  /* last accel: at least one axis gated */
#define ATT_FLAG_MAG_GATED        (1u << 8)  /* last mag: gated */
#define ATT_FLAG_GATE_BYPASS      (1u << 9)  /* a gate is bypassed after gate_timeout */
#define ATT_FLAG_HEADING_LIMITED  (1u << 10) /* heading variance at heading_var_max, or no heading reference yet */
#define ATT_FLAG_REMAPPED         (1u << 11) /* last predict: pitch passed +-90 deg, remapped */
#define ATT_FLAG_COV_REPAIRED     (1u << 12) /* last call: P was loaded to stay positive definite */
#define ATT_FLAG_AT_REST          (1u << 13) /* last sample: at rest, gyroscope offset learned */

/* Counters saturate at UINT32_MAX. Test ratios: innovation^2 / (gate^2 S), > 1 gated. */
typedef struct {
    uint32_t steps;           /* att_step calls that ran a prediction */
    uint32_t gyro_fused;      /* scalar updates fused, per sensor */
    uint32_t accel_fused;
    uint32_t mag_fused;
    uint32_t gyro_gated;      /* scalar updates gated, per sensor */
    uint32_t accel_gated;
    uint32_t mag_gated;
    uint32_t accel_skipped;   /* samples not fused by policy (linear acceleration) */
    uint32_t mag_skipped;     /* samples not fused by policy (disturbance, gimbal lock) */
    uint32_t rejected;        /* calls refused for bad input (an error status other than
                                 EKF_ERR_NUMERIC; not for a NULL filter) */
    uint32_t numeric;         /* calls refused with EKF_ERR_NUMERIC (the whole call discarded) */
    uint32_t remaps;          /* pitch remaps through +-90 deg */
    uint32_t cov_repairs;     /* calls after which P needed diagonal loading */
    uint32_t heading_resets;  /* heading set to the magnetic heading (mag_reset_time) */
    uint32_t gyro_saturated;  /* samples with ATT_GYRO_SATURATED (rate variances raised) */
    ekf_scalar_t gyro_ratio[3];
    ekf_scalar_t accel_ratio[2]; /* the tangent-plane components: about the roll and pitch axes */
    ekf_scalar_t mag_ratio;
    ekf_scalar_t accel_norm_error; /* last | |a| - g |, m/s^2 */
    ekf_scalar_t mag_norm_error;   /* last |m| / ref - 1 */
    ekf_scalar_t mag_dip_error;    /* last dip - ref dip, rad */
} att_diag_t;

/* Everything a call of the filter can change (all but the settings). Treat as opaque:
 * read it through the accessors below. */
typedef struct {
    ekf_scalar_t x[ATT_N];
    att_cov_t cov;              /* covariance of x (att_cov.h; layout of the implementation) */
    ekf_scalar_t mag_ref_norm;  /* in use (set or learned) */
    ekf_scalar_t mag_ref_dip;
    ekf_scalar_t mag_tan2_dip;  /* tan^2 of mag_ref_dip (set with the reference) */
    ekf_scalar_t mag_avg_norm;  /* running means of the field's norm (mag units) and dip (rad) */
    ekf_scalar_t mag_avg_dip;
    ekf_scalar_t mag_new_clock; /* s: the reference's age while it settles, then how long a
                                   field off it has stayed consistent with itself */
    ekf_scalar_t align_acc[3];  /* sums during alignment */
    ekf_scalar_t align_mag[3];
    uint16_t align_count;
    uint16_t align_mag_count;
    ekf_scalar_t gated_time[3]; /* s of continuous gating: gyro, accel, mag */
    ekf_scalar_t accel_dev_var; /* running mean of ( |a| - g )^2, (m/s^2)^2 */
    ekf_scalar_t accel_hf_var;  /* running mean of |sample - low-pass|^2, (m/s^2)^2: the
                                   accelerometer's short-term motion (steps, impacts, shaking) */
    ekf_scalar_t accel_lp[3];   /* low-passed specific force, body frame, m/s^2 (last stage) */
    ekf_scalar_t accel_lp1[3];  /* its first stage when accel_lpf_order is 2, m/s^2 */
    uint8_t accel_lp_valid;     /* accel_lp holds a sample */
    uint8_t mag_settled;        /* the learned reference has settled (track_reference) */
    uint8_t rate_unmeasured;    /* the last gyro sample was saturated: the rate state is a guess */
    uint8_t tilt_ok;            /* last accelerometer update: fused, no linear acceleration,
                                   every innovation within 3 sigma (heading resets need it) */
    uint8_t heading_ref;        /* the heading is the field's: aligned with it, or a field
                                   fused or reset it since (else the heading is arbitrary) */
    ekf_scalar_t last_dt;       /* s, of the last prediction (time base of the running means) */
    att_trig_t trig;            /* sines and cosines (no clamp) of trig_at's roll and pitch, rad: */
    ekf_scalar_t trig_at[2];    /* left by the prediction for the measurement stage after it */
    ekf_scalar_t dt_nom;        /* s: the sample interval without gaps (a running mean of the
                                   steps that are not gaps; 0 before the first) */
    att_rest_t rest;            /* rest detector and gyroscope offset */
    att_bias_t bias;            /* gyroscope offset in motion (residual of the rest offset) */
    att_consider_t consider;    /* error sources carried in the reported covariance only */
    uint32_t flags;
    att_diag_t diag;
} att_vars_t;

/* Filter memory: the settings (fixed by att_init) and the variables. Treat as opaque. */
typedef struct {
    att_settings_t settings;
    att_vars_t vars;
} att_ekf_t;

/* The relative margin below accel_range at which an accelerometer reading counts as clipped
 * (not fused; the step goes on with the other sensors): a sensor at its full scale reports its
 * largest code, a few parts in 10^4 below the nominal range for 12 bits and more. */
#define ATT_ACCEL_CLIP_MARGIN 1e-3

/* Sensor presence bits of att_sample_t.valid */
#define ATT_HAS_GYRO  (1u << 0)
#define ATT_HAS_ACCEL (1u << 1)
#define ATT_HAS_MAG   (1u << 2)
/* gyro[] is clamped at the device's full scale on some axis (the device or the link
 * flagged it): the true rate is at least as large, by an unknown amount. The reading is not
 * fused, and the body-rate variances are raised to at least the square of its largest
 * component, so that the attitude uncertainty grows while the rotation is not measured
 * (docs/derivation.md, "Gyroscope saturation"). Set with or without ATT_HAS_GYRO. */
#define ATT_GYRO_SATURATED (1u << 3)

/* One IMU sample. Sensors whose bit is clear in valid are ignored. */
typedef struct {
    ekf_scalar_t dt;       /* time since the previous sample, s (ignored while aligning) */
    ekf_scalar_t gyro[3];  /* rad/s, body frame */
    ekf_scalar_t accel[3]; /* m/s^2, specific force, body frame (+g up at rest) */
    ekf_scalar_t mag[3];   /* magnetic field, body frame (uT or the unit of the settings) */
    uint8_t valid;         /* ATT_HAS_* bits, ATT_GYRO_SATURATED */
} att_sample_t;

/* Per-stage result of att_step. Applied sample: each stage's status, EKF_OK for a stage whose
 * sensor was absent (and for predict while aligning). Refused sample: the slot of each bad
 * input (dt: predict) holds its error, or the slot of the stage that failed numerically
 * EKF_ERR_NUMERIC; every other slot EKF_SKIPPED (nothing was applied). A NULL filter or
 * sample: EKF_ERR_NULL in every slot. */
typedef struct {
    ekf_status_t predict;
    ekf_status_t gyro;
    ekf_status_t accel;
    ekf_status_t mag;
} att_step_report_t;

/* What the prediction of one att_step did, for a smoother that runs backwards over a
 * recording (the host tools' Rauch-Tung-Striebel pass, docs/derivation.md, "Smoother"):
 * the state and covariance before the prediction (after the step's gyroscope update) and
 * after it (its process noise, gaps and caps included), and the transition Jacobian F of the
 * mean's map between them (row-major). predicted is 0 for a step that ran no prediction
 * (aligning, or refused). */
typedef struct {
    int predicted;
    ekf_scalar_t x_pre[ATT_N];
    ekf_scalar_t P_pre[ATT_N * ATT_N];
    ekf_scalar_t F[ATT_N * ATT_N];
    ekf_scalar_t x_pred[ATT_N];
    ekf_scalar_t P_pred[ATT_N * ATT_N];
} att_trace_t;

/* Linked as att_init_for_EKF_SCALAR_<type>: see EKF_SCALAR_LINK_NAME in ekf_config.h. */
#define att_init EKF_SCALAR_LINK_NAME(att_init)
/* Validates settings and resets the filter to "not aligned". EKF_ERR_SETTINGS if a setting
 * is out of range (f is not written: a filter never initialised stays unusable). */
ekf_status_t att_init(att_ekf_t *f, const att_settings_t *settings);

/* EKF_OK if the settings are usable, else EKF_ERR_SETTINGS (or EKF_ERR_NULL). */
ekf_status_t att_settings_check(const att_settings_t *s);

/* Back to "not aligned" with the settings it has (what att_init did after its check): the
 * next samples align it again. EKF_ERR_NULL for NULL. */
ekf_status_t att_reset(att_ekf_t *f);

/* Changes the settings of a running filter: EKF_OK, the new settings in force from the next
 * call, the state kept; EKF_ERR_SETTINGS (nothing changed) if they fail the check or change
 * a setting that cannot change while the filter runs (live = 0 in att_settings_table.h:
 * those need att_init). */
ekf_status_t att_set_settings(att_ekf_t *f, const att_settings_t *settings);

/* ---- the settings by name (the rows of att_settings_table.h) ---- */

enum { ATT_SETTING_SCALAR = 0, ATT_SETTING_U16 = 1 };

typedef struct {
    const char *name;   /* "rate_walk", "rest.rest_gyro", "bias.walk", ... */
    const char *unit;
    uint16_t offset;    /* byte offset of the field in att_settings_t */
    uint8_t type;       /* ATT_SETTING_SCALAR or ATT_SETTING_U16 */
    uint8_t check;      /* what its square must be in the build's scalar (internal) */
    uint8_t live;       /* 1: may change while the filter runs (att_set_settings) */
    ekf_scalar_t lo;    /* accepted range, inclusive; a setting that bounds another (see */
    ekf_scalar_t hi;    /* att_settings_table.h) is also checked by att_settings_check */
} att_setting_info_t;

/* Number of settings; their descriptions by index 0..count-1 (NULL beyond). */
size_t att_setting_count(void);
const att_setting_info_t *att_setting_info(size_t i);
/* Index of the setting called name, or -1. */
int att_setting_index(const char *name);
/* The value of setting i (a count as a scalar). EKF_ERR_NULL, EKF_ERR_DIMENSION (no such
 * setting). */
ekf_status_t att_setting_get(const att_settings_t *s, size_t i, ekf_scalar_t *value);
/* Sets setting i if value is within its own range (a count must be a whole number):
 * EKF_OK, or EKF_ERR_SETTINGS / EKF_ERR_DIMENSION / EKF_ERR_NULL with *s unchanged. The
 * bounds between settings are checked by att_settings_check. */
ekf_status_t att_setting_set(att_settings_t *s, size_t i, ekf_scalar_t value);

/* Sets the attitude from one accelerometer sample (m/s^2; EKF_ERR_RANGE if its norm is
 * below 0.1 g: no gravity direction) and optionally a magnetometer sample (NULL: heading 0
 * with variance heading_var_max), rates zero; resets P. */
ekf_status_t att_align(att_ekf_t *f, const ekf_scalar_t accel[3], const ekf_scalar_t mag[3]);

/* One sample: align (first align_samples accelerometer samples) or gyro update, predict,
 * accelerometer and magnetometer updates. All or nothing: dt (once aligned; while aligning
 * it is not an input, and the rest detector skips a sample without a valid one) and every
 * present sensor vector are validated first, and any bad one (NULL, non-finite, out of
 * range, dt <= 0 or > dt_max; while aligning, a sample without accelerometer:
 * EKF_ERR_NOT_INITIALISED) refuses the whole sample, as does a numeric failure in any
 * stage (EKF_ERR_NUMERIC). A caller that wants the rest of a sample with one bad sensor
 * clears that sensor's bit and calls again (firmware/app does, and counts it).
 * Returns: refused, the first error in the report (order predict, gyro, accel, mag);
 * applied, EKF_OK if everything present was fused, else the first non-OK stage status
 * (EKF_GATED or EKF_SKIPPED). report (may be NULL): see att_step_report_t. If the averaged
 * alignment samples have no usable gravity direction, the averaging restarts (EKF_SKIPPED
 * for accel, diag.accel_skipped). */
ekf_status_t att_step(att_ekf_t *f, const att_sample_t *sample, att_step_report_t *report);

/* att_step, and what its prediction did in *trace (att_trace_t; may be NULL). */
ekf_status_t att_step_traced(att_ekf_t *f, const att_sample_t *sample, att_step_report_t *report, att_trace_t *trace);

/* The stages, one call each (require an aligned filter; EKF_ERR_NOT_INITIALISED
 * otherwise), under the same contract. */
ekf_status_t att_predict(att_ekf_t *f, ekf_scalar_t dt);
/* dt (s): the interval the sample covers (its variance is the noise density^2 / dt), checked
 * like att_predict's. */
ekf_status_t att_update_gyro(att_ekf_t *f, const ekf_scalar_t gyro[3], ekf_scalar_t dt);
ekf_status_t att_update_accel(att_ekf_t *f, const ekf_scalar_t accel[3], ekf_scalar_t dt);
ekf_status_t att_update_mag(att_ekf_t *f, const ekf_scalar_t mag[3], ekf_scalar_t dt);

/* Outputs. */
void att_get_euler(const att_ekf_t *f, ekf_scalar_t euler[3]);       /* phi, theta, psi, rad */
void att_get_body_rates(const att_ekf_t *f, ekf_scalar_t w[3]);      /* p, q, r, rad/s */
void att_get_euler_rates(const att_ekf_t *f, ekf_scalar_t e[3]);     /* rad/s */
/* Gyroscope offset (rad/s, body frame) subtracted from every gyro sample: learned at rest,
 * plus what the bias filter learned in motion (att_bias.h). */
void att_get_gyro_bias(const att_ekf_t *f, ekf_scalar_t b[3]);
/* 1-sigma uncertainty of that offset per body axis (rad/s): the square roots of the bias
 * filter's variances (att_bias.h, Pb), which at rest follow the rest average's own. */
void att_get_gyro_bias_sigma(const att_ekf_t *f, ekf_scalar_t sigma[3]);
void att_get_quaternion(const att_ekf_t *f, ekf_scalar_t q[4]);      /* w, x, y, z: body to ENU */
/* Variances of the state errors: the diagonal of P, and for the angles that of the
 * attitude covariance of att_get_angle_covariance (P plus the gyroscope offset's, the
 * considered error sources' and the sensors' reference uncertainty). */
void att_get_variances(const att_ekf_t *f, ekf_scalar_t var[ATT_N]);
/* Covariance of the roll, pitch and yaw errors (rad^2), packed (phi phi, theta theta,
 * psi psi, phi theta, phi psi, theta psi): P's angle block + V Pb V^T (the gyroscope
 * offset's uncertainty, att_bias.h) + the considered errors (att_consider.h) +
 * accel_ref_sigma^2 on roll and pitch + mag_ref_sigma^2 on yaw while the heading is
 * magnetometer-referenced (docs/derivation.md, "Reported covariance"). */
void att_get_angle_covariance(const att_ekf_t *f, ekf_scalar_t c[6]);
void att_get_covariance(const att_ekf_t *f, ekf_scalar_t P[ATT_N * ATT_N]); /* all of P, row-major */
const ekf_scalar_t *att_state(const att_ekf_t *f);                   /* x[ATT_N] */
const att_settings_t *att_settings(const att_ekf_t *f);              /* the settings in force */
uint32_t att_flags(const att_ekf_t *f);
const att_diag_t *att_diag(const att_ekf_t *f);

#ifdef __cplusplus
}
#endif

#endif /* ATT_H */
