/*
 * att_settings_table.h - THE table of the attitude filter's settings: one row per setting.
 *
 * Everything else about a setting is expanded from its row: the fields of att_settings_t
 * (att.h), the defaults (att_default_settings) and the range check (att_settings.c), the
 * table that finds a setting by name at run time (att_setting_info, used by the Python
 * binding and the node's parameter service), and the settings table of
 * docs/architecture.md (written and checked by `python -m attekf.codegen`, which fails on
 * drift). Add or change a setting here only.
 *
 * Row: X(name, type, default, default_fixed, lo, hi, check, live, unit, help)
 *   type           S: ekf_scalar_t; U16: uint16_t (an integer count or choice)
 *   default        in the float and double builds; default_fixed in the fixed-point build
 *   lo, hi         accepted range, inclusive (numbers only: the docs generator reads them)
 *   check          what the square of the value must be in the build's scalar:
 *                  ANY, FIN2 (finite), POS2 (finite and > 0), ZPOS2 (value 0, or POS2)
 *   live           1: may change while the filter runs (att_set_settings); 0: needs att_init
 *   unit, help     for people: the docs table, the binding's help, the parameter service
 * Settings that bound each other (accel_range >= gravity, ...) are checked in
 * att_settings_check, and their help says so.
 *
 * Noise settings are densities (per sqrt(s)), not per-sample deviations, so that one set
 * serves every sample rate: a sample of interval dt is fused with the variance
 * density^2 / dt (docs/derivation.md, "Noise densities").
 */
#ifndef ATT_SETTINGS_TABLE_H
#define ATT_SETTINGS_TABLE_H

#include <stdint.h>

#include "ekf_scalar.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A row as a field of a settings struct. */
#define ATT_SETTING_CTYPE_S ekf_scalar_t
#define ATT_SETTING_CTYPE_U16 uint16_t
#define ATT_SETTING_FIELD(name, type, def, def_fixed, lo, hi, check, live, unit, help) \
    ATT_SETTING_CTYPE_##type name;

/* clang-format off */

#define ATT_SETTINGS_MAIN(X) \
    /* process model */ \
    X(rate_walk, S, 2.0, 2.0, 0.1, 1e3, POS2, 1, "rad/s/sqrt(s)", \
      "body-rate random walk: the rate changes by N(0, rate_walk^2 dt) per axis over dt") \
    X(angle_walk, S, 0.001, 0.001, 0, 1e6, ZPOS2, 1, "rad/sqrt(s)", \
      "extra angle random walk (model error)") \
    X(angle_walk_rate, S, 0.0015, 0.0015, 0, 1, ANY, 1, "sqrt(s)", \
      "angle random walk per rad/s of body rate (gyroscope scale and misalignment errors); " \
      "reported covariance only") \
    X(euler_rate_rel, S, 0.001, 0.001, 3e-4, 1, ANY, 1, "1", \
      "independent error of each Euler rate and angle increment, fraction of its variance; " \
      "keeps P well conditioned") \
    /* gyroscope */ \
    X(gyro_noise, S, 2.958e-4, 2.958e-4, 1e-9, 100, POS2, 1, "rad/sqrt(s)", \
      "gyroscope white-noise density (angle random walk): a sample of interval dt has " \
      "variance gyro_noise^2 / dt per axis") \
    X(gyro_gate, S, 0, 0, 0, 1e6, FIN2, 1, "sigma", "gyroscope innovation gate; 0 = off") \
    X(gyro_range, S, 40, 40, 1e-3, 100, ANY, 1, "rad/s", \
      "gyroscope full scale: a sample with a component at or beyond it is saturated") \
    /* accelerometer */ \
    X(gravity, S, 9.81, 9.81, 0.1, 1e6, FIN2, 1, "m/s^2", "magnitude of gravity") \
    X(accel_noise, S, 0.041413, 0.041413, 1e-9, 100, POS2, 1, "m/s^2*sqrt(s)", \
      "accelerometer noise density incl. unmodelled motion: a sample of interval dt has " \
      "variance accel_noise^2 / dt per axis") \
    X(accel_band, S, 0, 0, 0, 1e6, ANY, 1, "m/s^2", \
      "| |a| - g | at which a sample's variance doubles; 0 = off") \
    X(accel_reject, S, 50, 50, 1e-6, 1e6, ANY, 1, "m/s^2", \
      "| |a| - g | above which a sample is not fused") \
    X(accel_adapt_tau, S, 0.5, 0.5, 0, 1e6, ANY, 1, "s", \
      "time constant of the running linear-acceleration variance (adaptive noise); 0 = off") \
    X(accel_adapt_weight, S, 0.0035, 0.0035, 0, 100, ANY, 1, "s", \
      "the running linear-acceleration variance v enters the accelerometer's density^2 as " \
      "v accel_adapt_weight") \
    X(accel_lpf_tau, S, 1.0, 1.0, 0, 1e6, ANY, 1, "s", \
      "time constant of each stage of the accelerometer low-pass in an earth-fixed frame; " \
      "0 = off") \
    X(accel_lpf_order, U16, 2, 2, 1, 2, ANY, 0, "stages", "stages of that low-pass, 1 or 2") \
    X(accel_gate, S, 10, 10, 0, 1e6, FIN2, 1, "sigma", "accelerometer innovation gate; 0 = off") \
    X(accel_range, S, 160, 160, 1e-3, 1e6, ANY, 1, "m/s^2", \
      "accelerometer full scale (>= gravity): a sample with a component within 0.1 % of it " \
      "or beyond is clipped: not fused, the gyroscope goes on") \
    X(accel_ref_sigma, S, 0.005, 0.005, 0, 1.5707963267948966, ANY, 1, "rad", \
      "gravity-direction error that averaging cannot remove; reported covariance only") \
    /* magnetometer */ \
    X(mag_heading_noise, S, 0.015, 0.015, 1e-9, 100, POS2, 1, "rad*sqrt(s)", \
      "magnetic heading noise density: a sample of interval dt has variance " \
      "mag_heading_noise^2 / dt") \
    X(mag_gate, S, 3, 3, 0, 1e6, FIN2, 1, "sigma", "heading innovation gate; 0 = off") \
    X(mag_norm_tol, S, 0.15, 0.15, 1e-6, 1e6, ANY, 1, "1", \
      "allowed | |m| / reference - 1 | before the field counts as disturbed") \
    X(mag_dip_tol, S, 0.17, 0.17, 1e-6, 3.141592653589793, ANY, 1, "rad", \
      "allowed |dip - reference dip| before the field counts as disturbed") \
    X(mag_norm_band, S, 0.08, 0.08, 0, 1e3, ANY, 1, "1", \
      "relative field-norm error at which a sample's heading variance doubles (with " \
      "mag_dip_band); 0 = off") \
    X(mag_dip_band, S, 0.14, 0.14, 0, 3.141592653589793, ANY, 1, "rad", \
      "dip error at which a sample's heading variance doubles (with mag_norm_band); 0 = off") \
    X(mag_new_time, S, 20, 20, 0, 1e6, ANY, 1, "s", \
      "a learned reference (mag_ref_norm 0) settles over the first quarter of this after it " \
      "was set, and a field off it that stays consistent with itself this long becomes the " \
      "reference; 0 = the first reference is kept") \
    X(mag_reset_time, S, 3, 3, 0, 1e6, ANY, 1, "s", \
      "gating of an undisturbed field after which the heading is reset to it; 0 = never") \
    X(mag_ref_norm, S, 0, 0, 0, 1e6, ANY, 0, "mag unit", \
      "reference field norm; 0 = learn at alignment") \
    X(mag_ref_dip, S, 0, 0, -1.5707963267948966, 1.5707963267948966, ANY, 0, "rad", \
      "reference dip, positive down; used if mag_ref_norm > 0") \
    X(mag_declination, S, 0, 0, -3.141592653589793, 3.141592653589793, ANY, 1, "rad", \
      "magnetic declination, east positive") \
    X(mag_ref_sigma, S, 0.05, 0.05, 0, 3.141592653589793, ANY, 1, "rad", \
      "magnetic-reference direction error that averaging cannot remove; reported covariance only") \
    X(mag_range, S, 5000, 5000, 1e-6, 1e6, ANY, 1, "mag unit", \
      "magnetometer full scale: a sample with a component at or beyond it is not fused") \
    /* robustness */ \
    X(gate_timeout, S, 1, 1, 0, 1e6, ANY, 1, "s", \
      "continuous gating of the gyroscope or accelerometer after which its gate is bypassed; " \
      "0 = never") \
    X(gimbal_limit, S, 1.55, 1.55, 0.1, 1.56, ANY, 1, "rad", \
      "|pitch| above which the heading is held (ATT_FLAG_GIMBAL_LOCK)") \
    X(dt_max, S, 0.5, 0.5, 1e-6, 60, ANY, 1, "s", "longest accepted time step") \
    X(heading_var_max, S, 9.869604401089358, 9.869604401089358, 1e-5, 1e6, ANY, 1, "rad^2", \
      "cap on the heading variance (>= var_floor)") \
    X(var_floor, S, 1e-10, 1e-9, 1e-30, 1e-2, ANY, 1, "rad^2, (rad/s)^2", \
      "floor of every state variance") \
    /* initialisation */ \
    X(init_tilt_sigma, S, 0.1, 0.1, 1e-6, 3.141592653589793, POS2, 1, "rad", \
      "initial roll and pitch sigma") \
    X(init_heading_sigma, S, 0.2, 0.2, 1e-6, 6.283185307179586, POS2, 1, "rad", \
      "initial heading sigma with a magnetometer") \
    X(init_rate_sigma, S, 0.1, 0.1, 1e-6, 1e3, POS2, 1, "rad/s", "initial body-rate sigma") \
    X(align_samples, U16, 10, 10, 1, 65535, ANY, 1, "samples", \
      "accelerometer samples averaged for the alignment")

/* Rest detection and the gyroscope offset learned at rest (att_rest.h): names "rest.*". */
#define ATT_SETTINGS_REST(X) \
    X(rest_gyro, S, 0.035, 0.035, 1e-6, 1e6, POS2, 1, "rad/s", \
      "rate (and its deviation) below which the sensor may be at rest") \
    X(rest_accel, S, 0.5, 0.5, 1e-6, 1e6, POS2, 1, "m/s^2", \
      "deviation of the specific force from its low-passed value at rest") \
    X(rest_time, S, 1.5, 1.5, 0, 1e6, ANY, 1, "s", \
      "continuous rest before the offset is learned") \
    X(rest_tau, S, 0.5, 0.5, 0, 1e6, ANY, 1, "s", \
      "time constant of the rest detector's low-pass filters") \
    X(bias_tau, S, 10, 10, 0, 1e6, ANY, 1, "s", \
      "averaging time of the offset; 0 = no offset estimation") \
    X(bias_max, S, 0.035, 0.035, 0, 1e6, ANY, 1, "rad/s", \
      "largest offset per axis (<= gyro_range)") \
    X(accel_noise, S, 0.005, 0.005, 0, 1e6, ZPOS2, 1, "m/s^2*sqrt(s)", \
      "accelerometer noise density at rest, where no linear acceleration is left to allow for: " \
      "the sample itself is fused with it; 0 = as in motion")

/* The gyroscope offset learned in motion (att_bias.h): names "bias.*". */
#define ATT_SETTINGS_BIAS(X) \
    X(sigma_init, S, 0.0087, 0.0087, 0, 1, ANY, 1, "rad/s", \
      "1 sigma of the offset before the first rest, per axis (<= gyro_range)") \
    X(walk, S, 6.7e-5, 6.7e-5, 0, 0.01, ANY, 1, "rad/s/sqrt(s)", \
      "random walk of the offset (its instability)") \
    X(mag_derate, S, 30, 30, 1, 1e4, ANY, 1, "1", \
      "factor on the magnetometer innovations' variance in the offset's update") \
    X(motion, U16, 2, 2, 0, 2, ANY, 1, "0/1/2", \
      "learn the offset in motion: 0 no, 1 from the accelerometer, 2 and the magnetometer") \
    X(quiet_accel, S, 20, 20, 0, 1e3, ANY, 1, "m/s^2", \
      "the offset is learned in motion only while the accelerometer's short-term deviation " \
      "from its low-pass (impacts, shaking, clipping) stays below this") \
    X(hold_time, S, 2, 2, 0, 1e3, ANY, 1, "s", \
      "no learning for this long after evidence the offset cannot explain: a gap in the samples, " \
      "a clipped accelerometer, a saturated gyroscope, a bypassed gate")

/* clang-format on */

#ifdef __cplusplus
}
#endif

#endif /* ATT_SETTINGS_TABLE_H */
