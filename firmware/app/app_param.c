/*
 * app_param.c - the node's parameters (app_param.h): the filter's settings by name, then the
 * rows of APP_PARAMS; configuration lines; live and pending changes of a running node.
 */
#include "app_param.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The application's parameters, after the filter's. */
#define APP_PARAM_ID(name, field, lo, hi, integer, live, unit, help) APP_P_##field,
enum { APP_PARAMS(APP_PARAM_ID) APP_P_COUNT };
#undef APP_PARAM_ID

#define APP_PARAM_ROW(name, field, lo, hi, integer, live, unit, help) \
    {name, unit, help, (float)(lo), (float)(hi), 0.0f, integer, live},
static const app_param_info_t app_rows[APP_P_COUNT] = {APP_PARAMS(APP_PARAM_ROW)};
#undef APP_PARAM_ROW

size_t app_param_count(void) { return att_setting_count() + (size_t)APP_P_COUNT; }

/* Whole milliseconds of a time in microseconds (the parameters are in ms). */
static float whole_ms(uint64_t us)
{
    const uint64_t ms = us / 1000u;
    return (float)ms;
}

static float app_field(const app_config_t *c, int id)
{
    switch (id) {
    case APP_P_OUTPUT_PERIOD: return (float)c->app.output_period_us;
    case APP_P_STALE: return whole_ms(c->app.stale_timeout_us);
    case APP_P_HEARTBEAT: return whole_ms(c->app.heartbeat_period_us);
    case APP_P_MAX_GAP: return whole_ms(c->app.max_gap_us);
    case APP_P_SEQ_WINDOW: return (float)c->app.seq_window;
    case APP_P_PROTOCOL: return (float)c->node.protocol;
    case APP_P_INPUT: return (float)c->node.input;
    case APP_P_NODE_ID: return (float)c->node.node_id;
    case APP_P_IMU_NODE: return (float)c->node.imu_node;
    case APP_P_MAG_NODE: return (float)c->node.mag_node;
    case APP_P_DBC_BASE: return (float)c->node.dbc_base;
    case APP_P_DBC_IMU_BASE: return (float)c->node.dbc_imu_base;
    default: return 0.0f;
    }
}

/* v: a whole number within the row's range (checked by the caller). */
static void set_app_field(app_config_t *c, int id, float v)
{
    const uint32_t u = (uint32_t)v;
    switch (id) {
    case APP_P_OUTPUT_PERIOD: c->app.output_period_us = u; break;
    case APP_P_STALE: c->app.stale_timeout_us = u * 1000u; break;
    case APP_P_HEARTBEAT: c->app.heartbeat_period_us = u * 1000u; break;
    case APP_P_MAX_GAP: c->app.max_gap_us = u * 1000u; break;
    case APP_P_SEQ_WINDOW: c->app.seq_window = (uint16_t)u; break;
    case APP_P_PROTOCOL: c->node.protocol = (uint8_t)u; break;
    case APP_P_INPUT: c->node.input = (uint8_t)u; break;
    case APP_P_NODE_ID: c->node.node_id = (uint8_t)u; break;
    case APP_P_IMU_NODE: c->node.imu_node = (uint8_t)u; break;
    case APP_P_MAG_NODE: c->node.mag_node = (uint8_t)u; break;
    case APP_P_DBC_BASE: c->node.dbc_base = (uint16_t)u; break;
    case APP_P_DBC_IMU_BASE: c->node.dbc_imu_base = (uint16_t)u; break;
    default: break;
    }
}

int app_param_info(size_t i, app_param_info_t *info)
{
    const size_t n_att = att_setting_count();
    if (info == NULL || i >= app_param_count()) {
        return 0;
    }
    if (i < n_att) {
        const att_setting_info_t *a = att_setting_info(i);
        ekf_scalar_t def = EKF_C(0.0);
        (void)att_setting_get(&att_default_settings, i, &def);
        info->name = a->name;
        info->unit = a->unit;
        info->help = NULL;
        info->lo = ekf_to_float(a->lo);
        info->hi = ekf_to_float(a->hi);
        info->def = ekf_to_float(def);
        info->integer = (uint8_t)(a->type == ATT_SETTING_U16);
        info->live = a->live;
    } else {
        app_config_t d;
        app_default_config(&d);
        *info = app_rows[i - n_att];
        info->def = app_field(&d, (int)(i - n_att));
    }
    return 1;
}

int app_param_index(const char *name)
{
    size_t i;
    int k;
    if (name == NULL) {
        return -1;
    }
    k = att_setting_index(name);
    if (k >= 0) {
        return k;
    }
    for (i = 0; i < (size_t)APP_P_COUNT; ++i) {
        if (strcmp(app_rows[i].name, name) == 0) {
            return (int)(att_setting_count() + i);
        }
    }
    return -1;
}

int app_config_get(const app_config_t *cfg, size_t i, float *value)
{
    const size_t n_att = att_setting_count();
    ekf_scalar_t v;
    if (cfg == NULL || value == NULL || i >= app_param_count()) {
        return 0;
    }
    if (i < n_att) {
        if (att_setting_get(&cfg->att, i, &v) != EKF_OK) {
            return 0;
        }
        *value = ekf_to_float(v);
    } else {
        *value = app_field(cfg, (int)(i - n_att));
    }
    return 1;
}

app_param_result_t app_config_set(app_config_t *cfg, size_t i, float value)
{
    app_param_info_t info;
    app_config_t tmp;
    if (cfg == NULL || !app_param_info(i, &info)) {
        return APP_PARAM_NO_SUCH;
    }
    if (!isfinite(value) || value < info.lo || value > info.hi ||
        (info.integer && floorf(value) != value)) {
        return APP_PARAM_RANGE;
    }
    tmp = *cfg;
    if (i < att_setting_count()) {
        if (att_setting_set(&tmp.att, i, ekf_from_float(value)) != EKF_OK) {
            return APP_PARAM_RANGE;
        }
    } else {
        set_app_field(&tmp, (int)(i - att_setting_count()), value);
    }
    if (app_config_check(&tmp) != EKF_OK) {
        return APP_PARAM_RANGE; /* inconsistent with another parameter */
    }
    *cfg = tmp;
    return APP_PARAM_OK;
}

int app_param_format(const app_config_t *cfg, size_t i, char *buf, size_t size)
{
    app_param_info_t info;
    float v;
    int n;
    if (!app_param_info(i, &info) || !app_config_get(cfg, i, &v) || buf == NULL) {
        return 0;
    }
    n = snprintf(buf, size, "%s %.9g", info.name, (double)v);
    return n > 0 && (size_t)n < size;
}

int app_config_write(const app_config_t *cfg, int (*line_fn)(void *user, const char *line), void *user)
{
    char line[HAL_LINE_MAX];
    size_t i;
    for (i = 0; i < app_param_count(); ++i) {
        app_param_info_t info;
        float v;
        if (!app_param_info(i, &info) || !app_config_get(cfg, i, &v) || v == info.def) {
            continue;
        }
        if (!app_param_format(cfg, i, line, sizeof(line)) || !line_fn(user, line)) {
            return 0;
        }
    }
    return 1;
}

int app_config_read_line(app_config_t *cfg, const char *line, char *err, size_t err_size)
{
    char name[96];
    const char *p = line;
    char *end = NULL;
    size_t n = 0;
    double v;
    int i;
    while (*p == ' ' || *p == '\t') {
        ++p;
    }
    if (*p == '\0' || *p == '\n' || *p == '\r' || *p == '#') {
        return 0;
    }
    while (p[n] != '\0' && p[n] != ' ' && p[n] != '\t' && p[n] != '\n' && p[n] != '\r') {
        ++n;
    }
    if (n >= sizeof(name)) {
        snprintf(err, err_size, "parameter name longer than %u characters", (unsigned)(sizeof(name) - 1u));
        return -1;
    }
    memcpy(name, p, n);
    name[n] = '\0';
    i = app_param_index(name);
    if (i < 0) {
        snprintf(err, err_size, "no parameter '%s' (attekf-node --list-params)", name);
        return -1;
    }
    v = strtod(p + n, &end);
    while (end != NULL && (*end == ' ' || *end == '\t' || *end == '\n' || *end == '\r')) {
        ++end;
    }
    if (end == p + n || end == NULL || *end != '\0') {
        snprintf(err, err_size, "%s: the value is not a number", name);
        return -1;
    }
    if (app_config_set(cfg, (size_t)i, (float)v) != APP_PARAM_OK) {
        app_param_info_t info;
        memset(&info, 0, sizeof(info));
        (void)app_param_info((size_t)i, &info);
        snprintf(err, err_size, "%s = %g: outside [%g, %g]%s, or inconsistent with another parameter", name, v,
                 (double)info.lo, (double)info.hi, info.integer ? " or not a whole number" : "");
        return -1;
    }
    return 1;
}

/* ---- the running node --------------------------------------------------------------- */
void app_current_config(const app_t *app, app_config_t *cfg)
{
    uint8_t k;
    cfg->app = app->settings;
    cfg->node = app->node;
    cfg->att = app->ekf.settings;
    for (k = 0; k < app->n_pending; ++k) {
        (void)app_config_set(cfg, app->pending[k].index, app->pending[k].value);
    }
}

int app_param_get(const app_t *app, size_t i, float *value)
{
    app_config_t c;
    app_current_config(app, &c);
    return app_config_get(&c, i, value);
}

/* Keeps value of parameter i for the next restart (replacing an earlier one); none is kept
 * when it equals the value in force. 0 if the list is full. */
static int keep_pending(app_t *app, size_t i, float value, float in_force)
{
    uint8_t k;
    for (k = 0; k < app->n_pending; ++k) {
        if (app->pending[k].index == i) {
            break;
        }
    }
    if (value == in_force) {
        if (k < app->n_pending) {
            app->pending[k] = app->pending[--app->n_pending];
        }
        return 1;
    }
    if (k == app->n_pending) {
        if (app->n_pending == APP_PENDING_MAX) {
            return 0;
        }
        ++app->n_pending;
    }
    app->pending[k].index = (uint16_t)i;
    app->pending[k].value = value;
    return 1;
}

app_param_result_t app_param_set(app_t *app, size_t i, float value)
{
    app_config_t future, now;
    app_param_info_t info;
    app_param_result_t r;
    float in_force = 0.0f;
    if (app == NULL || !app_param_info(i, &info)) {
        return APP_PARAM_NO_SUCH;
    }
    /* the configuration after the restart must be consistent ... */
    app_current_config(app, &future);
    r = app_config_set(&future, i, value);
    if (r != APP_PARAM_OK) {
        return r;
    }
    now.app = app->settings;
    now.node = app->node;
    now.att = app->ekf.settings;
    (void)app_config_get(&now, i, &in_force);
    if (!info.live) {
        return keep_pending(app, i, value, in_force) ? APP_PARAM_PENDING : APP_PARAM_RANGE;
    }
    /* ... and a live change consistent with what is in force now */
    if (i < att_setting_count()) {
        att_settings_t s = app->ekf.settings;
        if (att_setting_set(&s, i, ekf_from_float(value)) != EKF_OK || att_set_settings(&app->ekf, &s) != EKF_OK) {
            return APP_PARAM_RANGE;
        }
    } else {
        set_app_field(&now, (int)(i - att_setting_count()), value);
        if (app_config_check(&now) != EKF_OK) {
            return APP_PARAM_RANGE;
        }
        app->settings = now.app;
        app->node = now.node;
    }
    return APP_PARAM_OK;
}
