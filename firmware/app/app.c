/*
 * app.c - the estimator application loop (app.h): configuration, start and restart, the
 * poll that hands each input to its protocol, the counters. Target-independent: it talks only
 * to the HAL (hal.h) and the filter (att.h). Policies and their reasons: docs/can_protocol.md,
 * "Node behaviour".
 */
#include "app_internal.h"

#include <string.h>

/* A gap is predicted across in steps of at most the filter's dt_max; more steps than this
 * (max_gap_us / dt_max) is refused by the configuration check so that one sample never costs
 * unbounded time. */
#define APP_MAX_PREDICT_STEPS 1000u
/* Inputs handled per poll at most, when none completes a sample (foreign traffic): the clock
 * work of the poll (staleness, status) must not wait for a quiet bus. */
#define APP_POLL_MAX_INPUTS 64u

const app_settings_t app_default_settings = {
    .output_period_us = 10000u,
    .stale_timeout_us = 100000u,
    .heartbeat_period_us = 100000u,
    .max_gap_us = 2000000u,
    .seq_window = 1000u,
};

const app_node_settings_t app_default_node = {
    .protocol = APP_PROTO_DBC,
    .input = APP_PROTO_DBC,
    .node_id = 100u,
    .imu_node = 0u,
    .mag_node = 0u,
    .dbc_base = 0x180u,
    .dbc_imu_base = 0x100u,
    .unique_id = {0},
};

#define APP_COUNTER_NAME(id, name, help) #name,
static const char *const counter_names[APP_CNT_COUNT] = {APP_COUNTERS(APP_COUNTER_NAME)};
#undef APP_COUNTER_NAME

const char *app_counter_name(app_counter_id_t id)
{
    return ((unsigned)id < (unsigned)APP_CNT_COUNT) ? counter_names[id] : "unknown_counter";
}

void app_default_config(app_config_t *cfg)
{
    cfg->app = app_default_settings;
    cfg->node = app_default_node;
    cfg->att = att_default_settings;
}

ekf_status_t app_settings_check(const app_settings_t *s)
{
    if (s == NULL) {
        return EKF_ERR_NULL;
    }
    if (s->stale_timeout_us == 0u || s->heartbeat_period_us == 0u || s->max_gap_us == 0u ||
        s->max_gap_us > 60000000u || s->seq_window == 0u || s->seq_window > 32767u) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

ekf_status_t app_node_check(const app_node_settings_t *n)
{
    if (n == NULL) {
        return EKF_ERR_NULL;
    }
    if (n->protocol > APP_PROTO_TEXT || n->input > APP_PROTO_DRONECAN || n->node_id < 1u || n->node_id > 127u ||
        n->imu_node > 127u || n->mag_node > 127u || !dbc_bases_ok(n->dbc_base, n->dbc_imu_base)) {
        return EKF_ERR_SETTINGS;
    }
    return EKF_OK;
}

ekf_status_t app_config_check(const app_config_t *c)
{
    ekf_status_t st;
    if (c == NULL) {
        return EKF_ERR_NULL;
    }
    st = app_settings_check(&c->app);
    if (st == EKF_OK) {
        st = app_node_check(&c->node);
    }
    if (st == EKF_OK) {
        st = att_settings_check(&c->att);
    }
    /* dt_max is in s, max_gap in us: steps = max_gap * 1e-6 / dt_max. */
    if (st == EKF_OK && (ekf_scalar_t)c->app.max_gap_us * EKF_C(1e-6) >
                            c->att.dt_max * (ekf_scalar_t)APP_MAX_PREDICT_STEPS) {
        st = EKF_ERR_SETTINGS;
    }
    return st;
}

void app_log(const app_t *a, hal_level_t level, const char *event, int32_t detail)
{
    hal_log(a->hal, level, event, detail);
}

/* Everything but the HAL, the hooks and the counters back to the start. */
static ekf_status_t start(app_t *a, const app_config_t *cfg)
{
    const ekf_status_t st = att_init(&a->ekf, &cfg->att);
    /* the published counters count over the process's life: a restart starts the receive
     * assemblers afresh, their counts carry on (app_init starts from zero) */
    const dbc_rx_counts_t rx_counts = a->dbc_rx.n;
    const uint32_t transfer_errors = a->dcan.rx.errors;
    uint64_t now;
    if (st != EKF_OK) {
        return st;
    }
    a->settings = cfg->app;
    a->node = cfg->node;
    a->n_pending = 0u;
    a->restart_requested = 0u;
    memset(&a->out, 0, sizeof(a->out));
    memset(a->last_accel, 0, sizeof(a->last_accel));
    a->have_sample = 0u;
    a->stale = 0u;
    a->restart_n = 0u;
    a->was_aligned = 0u;
    a->out_index = 0u;
    dbc_rx_init(&a->dbc_rx, cfg->node.dbc_imu_base);
    a->dbc_rx.n = rx_counts;
    dbc_tx_init(&a->dbc_tx, cfg->node.dbc_base);
    now = hal_now_us(a->hal);
    a->last_local_us = now;
    app_dcan_start(a, now);
    a->dcan.rx.errors = transfer_errors;
    return EKF_OK;
}

ekf_status_t app_init(app_t *app, const app_config_t *cfg, const hal_t *hal)
{
    ekf_status_t st;
    if (app == NULL || cfg == NULL || !hal_valid(hal)) {
        return EKF_ERR_NULL;
    }
    st = app_config_check(cfg);
    if (st != EKF_OK) {
        return st;
    }
    memset(app, 0, sizeof(*app));
    app->hal = hal;
    st = start(app, cfg);
    if (st == EKF_OK) {
        app_log(app, HAL_LOG_INFO, "started", 0);
    }
    return st;
}

void app_set_hooks(app_t *app, const app_hooks_t *hooks)
{
    if (hooks != NULL) {
        app->hooks = *hooks;
    } else {
        memset(&app->hooks, 0, sizeof(app->hooks));
    }
}

void app_restart(app_t *app)
{
    app_config_t cfg;
    app_current_config(app, &cfg);
    /* every pending value passed the configuration check with the others when it was set */
    if (start(app, &cfg) != EKF_OK) {
        app_default_config(&cfg);
        (void)start(app, &cfg);
    }
    app->latched |= APP_FLAG_RESTARTED;
    app_log(app, HAL_LOG_WARN, "node_restart", 0);
}

void app_count_request(app_t *a, int ok)
{
    hal_count(&a->counters[APP_CNT_REQUESTS]);
    if (!ok) {
        hal_count(&a->counters[APP_CNT_REFUSED]);
    }
}

const char *app_param_result_name(app_param_result_t r)
{
    switch (r) {
    case APP_PARAM_OK: return "ok";
    case APP_PARAM_PENDING: return "pending restart";
    case APP_PARAM_NO_SUCH: return "no such parameter";
    case APP_PARAM_RANGE: return "out of range";
    }
    return "?";
}

int app_save(app_t *a)
{
    app_config_t cfg;
    if (a->hooks.save == NULL) {
        return 0;
    }
    app_current_config(a, &cfg);
    return a->hooks.save(a->hooks.user, &cfg);
}

int app_erase(app_t *a) { return a->hooks.erase != NULL && a->hooks.erase(a->hooks.user); }

void app_get_counters(const app_t *app, uint32_t c[APP_CNT_COUNT])
{
    hal_link_stats_t s;
    int i;
    for (i = 0; i < APP_CNT_COUNT; ++i) {
        c[i] = app->counters[i];
    }
    hal_get_stats(app->hal, &s);
    c[APP_CNT_RX_FRAMES] = s.rx_frames;
    c[APP_CNT_RX_OVERFLOW] = s.rx_overflow;
    c[APP_CNT_LINK_DOWN] = s.link_down;
    c[APP_CNT_TX_FRAMES] = s.tx_frames;
    c[APP_CNT_TX_ERRORS] = s.tx_errors;
    c[APP_CNT_BAD_DLC] = app->dbc_rx.n.bad_dlc;
    c[APP_CNT_DUPLICATE] = app->dbc_rx.n.duplicate;
    hal_count_n(&c[APP_CNT_DUPLICATE], app->counters[APP_CNT_DUPLICATE]); /* DroneCAN's */
    c[APP_CNT_LATE] = app->dbc_rx.n.late;
    hal_count_n(&c[APP_CNT_LATE], app->counters[APP_CNT_LATE]);          /* late samples */
    c[APP_CNT_INCOMPLETE] = app->dbc_rx.n.incomplete;
    c[APP_CNT_DISCARDED] = app->dbc_rx.n.discarded;
    hal_count_n(&c[APP_CNT_TRANSFER_ERRORS], app->dcan.rx.errors);
}

void app_latch_errors(app_t *a)
{
    uint32_t c[APP_CNT_COUNT];
    uint32_t now[3];
    app_get_counters(a, c);
    /* sums wrap together with their parts: only a change matters */
    now[0] = c[APP_CNT_BAD_DLC] + c[APP_CNT_DUPLICATE] + c[APP_CNT_LATE] + c[APP_CNT_TRANSFER_ERRORS];
    now[1] = c[APP_CNT_INCOMPLETE] + c[APP_CNT_DISCARDED];
    now[2] = c[APP_CNT_RX_OVERFLOW] + c[APP_CNT_LINK_DOWN] + c[APP_CNT_TX_ERRORS];
    if (now[0] != a->errors_seen[0]) {
        a->latched |= APP_FLAG_FRAME_ERROR;
    }
    if (now[1] != a->errors_seen[1]) {
        a->latched |= APP_FLAG_INCOMPLETE;
    }
    if (now[2] != a->errors_seen[2]) {
        a->latched |= APP_FLAG_LINK_ERROR;
    }
    memcpy(a->errors_seen, now, sizeof(now));
}

/* A frame to whichever protocol takes it; 1 if it completed a sample or a request. Each
 * protocol counts the frames it does not know as foreign. */
static int handle_frame(app_t *a, const hal_frame_t *f)
{
    const int ext = (f->id & HAL_FRAME_EXT) != 0u;
    if (ext && (a->node.protocol == APP_PROTO_DRONECAN || a->node.input == APP_PROTO_DRONECAN)) {
        return app_dcan_frame(a, f);
    }
    if (!ext && (a->node.protocol == APP_PROTO_DBC || a->node.input == APP_PROTO_DBC)) {
        return app_dbc_frame(a, f);
    }
    hal_count(&a->counters[APP_CNT_FOREIGN]);
    return 0;
}

/* One input; 1 if the poll should end (a sample or a request was handled). */
static int handle_input(app_t *a, const hal_input_t *in, int *got_sample)
{
    const uint32_t before = a->counters[APP_CNT_SAMPLES];
    int done = 0;
    switch (in->kind) {
    case HAL_IN_FRAME:
        done = handle_frame(a, &in->u.frame);
        break;
    case HAL_IN_SAMPLE:
        app_process_sample(a, &in->u.sample);
        done = 1;
        break;
    case HAL_IN_LINE:
        done = app_text_line(a, &in->u.line);
        break;
    default:
        break;
    }
    if (a->counters[APP_CNT_SAMPLES] != before) {
        *got_sample = 1;
    }
    return done;
}

hal_status_t app_poll(app_t *app, uint32_t timeout_us)
{
    hal_input_t in;
    hal_status_t first = HAL_EMPTY;
    uint32_t k, wait = timeout_us;
    int got_sample = 0;
    uint64_t now;

    if (app == NULL) {
        return HAL_ERR_ARG;
    }
    for (k = 0; k < APP_POLL_MAX_INPUTS; ++k) {
        const hal_status_t st = hal_receive(app->hal, &in, wait);
        if (k == 0u) {
            first = st;
        }
        if (st == HAL_END) {
            app_dbc_end(app); /* what is still being assembled */
        } else if (st == HAL_ERR_LINK_DOWN || st == HAL_ERR_IO) {
            app->latched |= APP_FLAG_LINK_ERROR;
        }
        if (st != HAL_OK || handle_input(app, &in, &got_sample)) {
            break;
        }
        wait = 0u;
    }
    now = hal_now_us(app->hal);
    if (got_sample) {
        app->last_local_us = now;
    }
    app_tick(app, now);
    if (app->restart_requested) {
        app_restart(app);
    }
    return first;
}

const att_ekf_t *app_filter(const app_t *app) { return &app->ekf; }

const app_output_t *app_last_output(const app_t *app) { return &app->out; }
