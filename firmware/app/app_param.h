/*
 * app_param.h - every setting of the node as a parameter with a name: the filter's (one per
 * row of firmware/att/att_settings_table.h, named as there: "gyro_noise", "rest.bias_tau"),
 * then the application's ("app.*") and the node's ("node.*"), the rows of APP_PARAMS below.
 * The DroneCAN param.GetSet service, the DBC's ATT_PARAM frames, the text commands, the
 * parameter file of attekf-node and `attekf-node --list-params` all use this one list.
 *
 * A parameter marked live changes a running node at once (the filter's through
 * att_set_settings); the others are kept as pending and take effect at the next restart of the
 * node (app_restart: RestartNode, the DBC's restart operation, the text command "restart"),
 * and the node says so (APP_PARAM_PENDING, APP_FLAG_CONFIG_PENDING in its status). Ranges
 * are checked by the settings checks of each part (att_settings_check, app_config_check),
 * bounds between parameters included.
 */
#ifndef APP_PARAM_H
#define APP_PARAM_H

#include <stddef.h>
#include <stdint.h>

#include "app.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Row: X(name, field, lo, hi, integer, live, unit, help). field names the member of
 * app_config_t (app_param.c); the timing ones in ms are kept in us (exact: whole numbers). */
#define APP_PARAMS(X) \
    X("app.output_period_us", OUTPUT_PERIOD, 0, 1000000, 1, 1, "us", \
      "attitude output period on the sample clock; 0 = every sample (10000: 100 Hz)") \
    X("app.stale_ms", STALE, 1, 4000000, 1, 1, "ms", "input stale after this long without a sample") \
    X("app.heartbeat_ms", HEARTBEAT, 1, 4000000, 1, 1, "ms", "status heartbeat period while stale") \
    X("app.max_gap_ms", MAX_GAP, 1, 60000, 1, 1, "ms", "the filter re-aligns after a longer gap") \
    X("app.seq_window", SEQ_WINDOW, 1, 32767, 1, 1, "samples", \
      "a sequence step up to this continues the stream") \
    X("node.protocol", PROTOCOL, 0, 2, 1, 0, "0/1/2", "outputs and configuration: 0 DBC, 1 DroneCAN, 2 text") \
    X("node.input", INPUT, 0, 1, 1, 0, "0/1", "IMU frames taken on a bus: 0 DBC, 1 DroneCAN RawIMU") \
    X("node.id", NODE_ID, 1, 127, 1, 0, "", "DroneCAN node id") \
    X("node.imu_node", IMU_NODE, 0, 127, 1, 0, "", \
      "DroneCAN node id of the IMU; 0 = the first node heard sending RawIMU") \
    X("node.mag_node", MAG_NODE, 0, 127, 1, 0, "", \
      "DroneCAN node id of the magnetometer; 0 = the first node heard sending MagneticFieldStrength2") \
    X("node.dbc_base", DBC_BASE, 0, 2047, 1, 0, "", "DBC: id of ATT_EULER (default 384 = 0x180)") \
    X("node.dbc_imu_base", DBC_IMU_BASE, 0, 2047, 1, 0, "", "DBC: id of IMU_GYRO (default 256 = 0x100)")

typedef struct {
    const char *name;
    const char *unit;
    const char *help;   /* NULL for the filter's (their help is in att_settings_table.h) */
    float lo, hi;       /* accepted range, inclusive */
    float def;          /* default */
    uint8_t integer;    /* 1: a whole number */
    uint8_t live;       /* 1: changes a running node at once; 0: at the next restart */
} app_param_info_t;

typedef enum {
    APP_PARAM_OK = 0,        /* in force */
    APP_PARAM_PENDING = 1,   /* accepted; in force at the next restart */
    APP_PARAM_NO_SUCH = 2,
    APP_PARAM_RANGE = 3      /* refused (out of range, not whole, not finite, or inconsistent
                                with another parameter): nothing changed */
} app_param_result_t;

/* Number of parameters; the description of parameter i (0 if there is none). */
size_t app_param_count(void);
int app_param_info(size_t i, app_param_info_t *info);
/* Index of the parameter called name, or -1. */
int app_param_index(const char *name);

/* Parameter i of a configuration: 1 and *value, or 0 (no such parameter). */
int app_config_get(const app_config_t *cfg, size_t i, float *value);
/* Sets parameter i of a configuration if the result passes app_config_check (cfg unchanged
 * otherwise). */
app_param_result_t app_config_set(app_config_t *cfg, size_t i, float value);

/* A configuration line "name value" (blank lines and '#' comments skip): 1 set, 0 nothing on
 * the line, -1 refused (err gets one line saying why). */
int app_config_read_line(app_config_t *cfg, const char *line, char *err, size_t err_size);
/* Calls line_fn with one "name value" line (no line break) per parameter that differs from its
 * default; stops at the first line_fn that returns 0. Returns 1 if every call returned 1. */
int app_config_write(const app_config_t *cfg, int (*line_fn)(void *user, const char *line), void *user);
/* "name value" of parameter i into buf (the value with 9 significant digits, exact for a float). */
int app_param_format(const app_config_t *cfg, size_t i, char *buf, size_t size);

/* The running node's configuration: what is in force, with the pending parameters applied. */
void app_current_config(const app_t *app, app_config_t *cfg);
/* Parameter i of the running node (pending value if one is waiting). */
int app_param_get(const app_t *app, size_t i, float *value);
/* Sets parameter i of the running node: live ones at once, others pending (see above). */
app_param_result_t app_param_set(app_t *app, size_t i, float value);

#ifdef __cplusplus
}
#endif

#endif /* APP_PARAM_H */
