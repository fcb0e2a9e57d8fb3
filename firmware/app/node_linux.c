/*
 * node_linux.c - attekf-node: the estimator application (app.c) as a Linux program.
 *
 * Two modes, same loop:
 *   attekf-node -i vcan0                  live on a SocketCAN interface (hal_socketcan)
 *   attekf-node --replay in.log -o out.log  a candump log through the virtual backend;
 *                                           the frames the node sends go to another candump log
 * The replay runs on the log's own time stamps (simulated clock), so it computes exactly
 * what the live node computes from the same frames; tests compare the two. Either mode speaks
 * our DBC protocol or DroneCAN (--protocol), takes its configuration from a parameter file, the
 * command line and the bus (app_param.h), and saves it to the file on request.
 *
 * Stops on SIGINT/SIGTERM, end of replay, or --duration. Counters, the node-side latency
 * (kernel receive time of a sample's last frame -> its output handed to the kernel) and the CPU
 * time are printed at exit and written as JSON with --stats (node_stats.c).
 */
#define _GNU_SOURCE 1 /* sigaction, getrusage with -std=c99 */

#include <errno.h>
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "app.h"
#include "app_param.h"
#include "candump.h"
#include "hal.h"
#include "hal_socketcan.h"
#include "hal_virtual.h"
#include "node_params.h"
#include "node_stats.h"

#define NODE_VERSION "0.2.0"
#define REPLAY_QUEUE 4096u
#define MAX_SETS 64

static volatile sig_atomic_t g_stop = 0;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

/* ---- options ------------------------------------------------------------------------ */
typedef struct {
    const char *ifname, *replay, *output, *stats, *ready_file, *channel_name, *params, *unique_id;
    const char *sets[MAX_SETS];
    int n_sets;
    double rate_hz, stale_ms, heartbeat_ms, max_gap_ms, duration_s;
    long protocol, input, node_id, dbc_base, dbc_imu_base; /* -1: not given */
    unsigned long rcvbuf;
    int log_level, list_params;
} options_t;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: attekf-node [options]\n"
            "\n"
            "Attitude EKF node: reads IMU frames from a CAN bus, runs the filter, sends the\n"
            "attitude, in our DBC protocol or DroneCAN. Or replays a candump log through the same\n"
            "code. docs/can_protocol.md describes both protocols and every parameter.\n"
            "\n"
            "options:\n"
            "  -i, --interface NAME   SocketCAN interface (default can0)\n"
            "  -r, --replay FILE      replay a candump log (`candump -L` format, as written by\n"
            "                         `attekf replay --to-log`) through the virtual backend\n"
            "  -o, --output FILE      replay mode: write the frames the node sends as a candump log\n"
            "      --channel NAME     channel name written in the output log (default vcan0)\n"
            "      --protocol P       dbc (firmware/app/dbc/attekf.dbc) or dronecan: outputs, status\n"
            "                         and configuration (default dbc)\n"
            "      --input P          dbc or dronecan (RawIMU, MagneticFieldStrength2): where the IMU\n"
            "                         samples come from (default: the protocol)\n"
            "      --node-id N        DroneCAN node id, 1..127 (default 100)\n"
            "      --dbc-base ID      DBC: id of ATT_EULER, the node's first frame (default 0x180)\n"
            "      --dbc-imu-base ID  DBC: id of IMU_GYRO, the IMU's first frame (default 0x100)\n"
            "      --params FILE      parameter file: read at start (if it exists), written by the\n"
            "                         save requests of the bus (DroneCAN ExecuteOpcode, DBC save)\n"
            "      --set NAME=VALUE   set a parameter (repeatable; after --params)\n"
            "      --list-params      print every parameter and exit\n"
            "      --unique-id HEX    DroneCAN unique id, 32 hex digits (default: /etc/machine-id\n"
            "                         with the node id in its last byte)\n"
            "      --rate HZ          attitude output rate on the sample clock, Hz; 0 = every\n"
            "                         sample (default 100)\n"
            "      --stale-ms MS      input stale after MS without a sample (default 100)\n"
            "      --heartbeat-ms MS  status heartbeat period while stale (default 100)\n"
            "      --max-gap-ms MS    re-align after a gap longer than MS (default 2000)\n"
            "      --rcvbuf BYTES     socket receive buffer (default 4194304)\n"
            "      --duration S       stop after S seconds (live mode; default: run until a\n"
            "                         signal)\n"
            "      --stats FILE       write counters, latency and CPU time as JSON at exit\n"
            "      --ready-file FILE  create FILE once the interface is open (for scripts)\n"
            "  -l, --log-level L      error, warn, info (default) or debug\n"
            "  -V, --version          print the version and exit\n"
            "  -h, --help             this help\n"
            "\n"
            "exit status: 0 done, 1 runtime error (interface, file), 2 usage error\n");
}

static int parse_double(const char *opt, const char *s, double lo, double hi, double *out)
{
    char *end = NULL;
    double v;
    errno = 0;
    v = strtod(s, &end);
    if (errno != 0 || end == s || *end != '\0' || !(v >= lo && v <= hi)) {
        fprintf(stderr, "attekf-node: %s: '%s' is not a number in [%g, %g]\n", opt, s, lo, hi);
        return 0;
    }
    *out = v;
    return 1;
}

static int parse_long(const char *opt, const char *s, long lo, long hi, long *out)
{
    char *end = NULL;
    long v;
    errno = 0;
    v = strtol(s, &end, 0); /* 0x... allowed for ids */
    if (errno != 0 || end == s || *end != '\0' || v < lo || v > hi) {
        fprintf(stderr, "attekf-node: %s: '%s' is not a whole number in [%ld, %ld]\n", opt, s, lo, hi);
        return 0;
    }
    *out = v;
    return 1;
}

static int parse_choice(const char *opt, const char *s, const char *const names[], int n, long *out)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (strcmp(s, names[i]) == 0) {
            *out = i;
            return 1;
        }
    }
    fprintf(stderr, "attekf-node: %s: '%s' is not one of", opt, s);
    for (i = 0; i < n; ++i) {
        fprintf(stderr, " %s", names[i]);
    }
    fprintf(stderr, "\n");
    return 0;
}

static const char *const protocol_names[] = {"dbc", "dronecan"};
static const char *const level_names[] = {"error", "warn", "info", "debug"};

/* One option with a value; 0 on a usage error. */
static int parse_value(options_t *o, const char *a, const char *v)
{
    long l;
    if (strcmp(a, "-i") == 0 || strcmp(a, "--interface") == 0) o->ifname = v;
    else if (strcmp(a, "-r") == 0 || strcmp(a, "--replay") == 0) o->replay = v;
    else if (strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) o->output = v;
    else if (strcmp(a, "--channel") == 0) o->channel_name = v;
    else if (strcmp(a, "--stats") == 0) o->stats = v;
    else if (strcmp(a, "--ready-file") == 0) o->ready_file = v;
    else if (strcmp(a, "--params") == 0) o->params = v;
    else if (strcmp(a, "--unique-id") == 0) o->unique_id = v;
    else if (strcmp(a, "--set") == 0) {
        if (o->n_sets == MAX_SETS || strchr(v, '=') == NULL) {
            fprintf(stderr, "attekf-node: --set %s: expected NAME=VALUE (at most %d)\n", v, MAX_SETS);
            return 0;
        }
        o->sets[o->n_sets++] = v;
    } else if (strcmp(a, "--protocol") == 0) return parse_choice(a, v, protocol_names, 2, &o->protocol);
    else if (strcmp(a, "--input") == 0) return parse_choice(a, v, protocol_names, 2, &o->input);
    else if (strcmp(a, "--node-id") == 0) return parse_long(a, v, 1, 127, &o->node_id);
    else if (strcmp(a, "--dbc-base") == 0) return parse_long(a, v, 0, 0x7FF, &o->dbc_base);
    else if (strcmp(a, "--dbc-imu-base") == 0) return parse_long(a, v, 0, 0x7FF, &o->dbc_imu_base);
    else if (strcmp(a, "--rate") == 0) return parse_double(a, v, 0.0, 1e6, &o->rate_hz);
    else if (strcmp(a, "--stale-ms") == 0) return parse_double(a, v, 1.0, 4e6, &o->stale_ms);
    else if (strcmp(a, "--heartbeat-ms") == 0) return parse_double(a, v, 1.0, 4e6, &o->heartbeat_ms);
    else if (strcmp(a, "--max-gap-ms") == 0) return parse_double(a, v, 1.0, 60000.0, &o->max_gap_ms);
    else if (strcmp(a, "--duration") == 0) return parse_double(a, v, 0.0, 1e9, &o->duration_s);
    else if (strcmp(a, "--rcvbuf") == 0) {
        if (!parse_long(a, v, 0, 1073741824L, &l)) return 0;
        o->rcvbuf = (unsigned long)l;
    } else if (strcmp(a, "-l") == 0 || strcmp(a, "--log-level") == 0) {
        if (!parse_choice(a, v, level_names, 4, &l)) return 0;
        o->log_level = (int)l;
    } else {
        fprintf(stderr, "attekf-node: unknown option '%s'; see --help\n", a);
        return 0;
    }
    return 1;
}

/* Returns -1 to exit 0 (help/version), 0 on a usage error, 1 ok. */
static int parse_args(int argc, char **argv, options_t *o)
{
    int i;
    memset(o, 0, sizeof(*o));
    o->ifname = "can0";
    o->channel_name = "vcan0";
    o->rate_hz = o->stale_ms = o->heartbeat_ms = o->max_gap_ms = -1.0;
    o->protocol = o->input = o->node_id = o->dbc_base = o->dbc_imu_base = -1;
    o->rcvbuf = 4194304ul;
    o->log_level = HAL_LOG_INFO;
    for (i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return -1;
        }
        if (strcmp(a, "-V") == 0 || strcmp(a, "--version") == 0) {
            printf("attekf-node %s\n", NODE_VERSION);
            return -1;
        }
        if (strcmp(a, "--list-params") == 0) {
            o->list_params = 1;
            continue;
        }
        if (i + 1 >= argc) {
            static const char *const with_value[] = {
                "-i", "--interface", "-r", "--replay", "-o", "--output", "--channel", "--stats", "--ready-file",
                "--params", "--unique-id", "--set", "--protocol", "--input", "--node-id", "--dbc-base",
                "--dbc-imu-base", "--rate", "--stale-ms", "--heartbeat-ms", "--max-gap-ms", "--duration", "--rcvbuf",
                "-l", "--log-level"};
            size_t k;
            for (k = 0; k < sizeof(with_value) / sizeof(with_value[0]); ++k) {
                if (strcmp(a, with_value[k]) == 0) {
                    fprintf(stderr, "attekf-node: %s needs a value; see --help\n", a);
                    return 0;
                }
            }
            fprintf(stderr, "attekf-node: unknown option '%s'; see --help\n", a);
            return 0;
        }
        if (!parse_value(o, a, argv[++i])) {
            return 0;
        }
    }
    if (o->output != NULL && o->replay == NULL) {
        fprintf(stderr, "attekf-node: --output is for --replay mode (live outputs go to the bus)\n");
        return 0;
    }
    return 1;
}

/* The configuration: defaults, the parameter file, then the command line. Returns 0, or the
 * exit status after an error (message printed): 1 the parameter file, 2 the command line. */
static int configure(const options_t *o, app_config_t *cfg)
{
    char line[160], err[192];
    int k;
    app_default_config(cfg);
    if (o->params != NULL && !node_params_load(o->params, cfg)) {
        return 1;
    }
    if (o->rate_hz >= 0.0) {
        const double period = (o->rate_hz > 0.0) ? 1e6 / o->rate_hz + 0.5 : 0.0;
        if (o->rate_hz > 0.0 && period < 1.0) {
            fprintf(stderr, "attekf-node: --rate %g is above 1 MHz\n", o->rate_hz);
            return 2;
        }
        cfg->app.output_period_us = (uint32_t)period;
    }
    if (o->stale_ms > 0.0) cfg->app.stale_timeout_us = (uint32_t)(o->stale_ms * 1000.0 + 0.5);
    if (o->heartbeat_ms > 0.0) cfg->app.heartbeat_period_us = (uint32_t)(o->heartbeat_ms * 1000.0 + 0.5);
    if (o->max_gap_ms > 0.0) cfg->app.max_gap_us = (uint32_t)(o->max_gap_ms * 1000.0 + 0.5);
    if (o->protocol >= 0) cfg->node.protocol = (uint8_t)o->protocol;
    cfg->node.input = (o->input >= 0) ? (uint8_t)o->input : (o->protocol >= 0) ? (uint8_t)o->protocol : cfg->node.input;
    if (o->node_id >= 0) cfg->node.node_id = (uint8_t)o->node_id;
    if (o->dbc_base >= 0) cfg->node.dbc_base = (uint16_t)o->dbc_base;
    if (o->dbc_imu_base >= 0) cfg->node.dbc_imu_base = (uint16_t)o->dbc_imu_base;
    for (k = 0; k < o->n_sets; ++k) {
        const char *eq = strchr(o->sets[k], '=');
        (void)snprintf(line, sizeof(line), "%.*s %s", (int)(eq - o->sets[k]), o->sets[k], eq + 1);
        if (app_config_read_line(cfg, line, err, sizeof(err)) < 0) {
            fprintf(stderr, "attekf-node: --set %s: %s\n", o->sets[k], err);
            return 2;
        }
    }
    if (o->unique_id != NULL) {
        if (!node_parse_unique_id(o->unique_id, cfg->node.unique_id)) {
            fprintf(stderr, "attekf-node: --unique-id: expected 32 hexadecimal digits\n");
            return 2;
        }
    } else {
        (void)node_machine_unique_id(cfg->node.node_id, cfg->node.unique_id);
    }
    if (cfg->node.protocol == APP_PROTO_TEXT) {
        fprintf(stderr, "attekf-node: node.protocol 2 (text lines) needs a text channel; on CAN use 0 (dbc) or 1 "
                        "(dronecan)\n");
        return o->params != NULL ? 1 : 2;
    }
    if (app_config_check(cfg) != EKF_OK) {
        fprintf(stderr, "attekf-node: the configuration is not consistent (the timing options against the "
                        "filter's dt_max, or the DBC base ids overlap); see --help\n");
        return 2;
    }
    return 0;
}

static void list_params(const app_config_t *cfg)
{
    size_t i;
    printf("%-5s %-28s %-14s %-14s %-28s %-16s %s\n", "index", "name", "value", "default", "range", "unit", "takes effect");
    for (i = 0; i < app_param_count(); ++i) {
        app_param_info_t in;
        char range[64];
        float v = 0.0f;
        (void)app_param_info(i, &in);
        (void)app_config_get(cfg, i, &v);
        (void)snprintf(range, sizeof(range), "%g .. %g", (double)in.lo, (double)in.hi);
        printf("%-5u %-28s %-14.9g %-14.9g %-28s %-16s %s\n", (unsigned)i, in.name, (double)v, (double)in.def, range,
               in.unit[0] ? in.unit : "-", in.live ? "at once" : "at restart");
    }
}

/* ---- logging, latency, persistence: the hooks ---------------------------------------- */
static int g_log_level = HAL_LOG_INFO;

static void log_event(void *user, hal_level_t level, const char *event, int32_t detail)
{
    (void)user;
    if ((int)level <= g_log_level) {
        fprintf(stderr, "attekf-node: [%s] %s %" PRId32 "\n", level_names[level], event, detail);
    }
}

typedef struct {
    const hal_t *inner;
    const char *params;      /* parameter file (NULL: none) */
    node_latency_t lat;
    int live;                /* latency only means something on a real clock */
} node_t;

/* After every output sent: its latency (live mode). */
static void on_output(void *user, const app_output_t *out)
{
    node_t *n = (node_t *)user;
    if (n->live && out->kind == APP_OUT_ATTITUDE) {
        const uint64_t now = hal_now_us(n->inner);
        node_latency_add(&n->lat, (now > out->rx_us) ? now - out->rx_us : 0u);
    }
}

static int on_save(void *user, const app_config_t *cfg)
{
    const node_t *n = (const node_t *)user;
    return n->params != NULL && node_params_save(n->params, cfg);
}

static int on_erase(void *user)
{
    const node_t *n = (const node_t *)user;
    return n->params != NULL && node_params_erase(n->params);
}

/* ---- candump log files ------------------------------------------------------------------ */
typedef struct {
    FILE *f;
    const char *path;
    unsigned long line;
} logreader_t;

/* Next data frame: 1, 0 at end of file, -1 on a malformed line (message printed). The
 * line format is candump.h's. */
static int log_next(logreader_t *r, hal_frame_t *f)
{
    char buf[512];
    while (fgets(buf, sizeof(buf), r->f) != NULL) {
        const size_t len = strlen(buf);
        ++r->line;
        if (len == sizeof(buf) - 1u && buf[len - 1u] != '\n' && !feof(r->f)) {
            fprintf(stderr, "attekf-node: %s:%lu: line longer than %u characters\n", r->path, r->line,
                    (unsigned)(sizeof(buf) - 2u));
            return -1;
        }
        switch (candump_parse_line(buf, f)) {
        case CANDUMP_FRAME: return 1;
        case CANDUMP_SKIP: break;
        default:
            fprintf(stderr, "attekf-node: %s:%lu: not a candump log line\n", r->path, r->line);
            return -1;
        }
    }
    if (ferror(r->f)) {
        fprintf(stderr, "attekf-node: %s: read error\n", r->path);
        return -1;
    }
    return 0;
}

typedef struct {
    FILE *out;
    const char *channel;
    int write_error;
} replay_sink_t;

static void write_frame(void *user, const hal_frame_t *f)
{
    replay_sink_t *s = (replay_sink_t *)user;
    char line[96];
    if (s->out == NULL) {
        return;
    }
    if (candump_format_line(f, s->channel, line, sizeof(line)) < 0 || fputs(line, s->out) == EOF) {
        s->write_error = 1;
    }
}

/* ---- main ------------------------------------------------------------------------------- */
static app_t g_app;
static node_t g_node;
static hal_virtual_t g_virtual;
static hal_frame_t g_queue[REPLAY_QUEUE];
static hal_socketcan_t g_can;

static int start_app(const app_config_t *cfg, const hal_t *hal)
{
    const app_hooks_t hooks = {on_save, on_erase, on_output, &g_node};
    const ekf_status_t est = app_init(&g_app, cfg, hal);
    if (est != EKF_OK) {
        fprintf(stderr, "attekf-node: app_init: %s\n", ekf_status_str(est));
        return 0;
    }
    g_node.inner = hal;
    app_set_hooks(&g_app, &hooks);
    return 1;
}

static int run_replay(const options_t *o, const app_config_t *cfg, hal_t *hal)
{
    logreader_t r;
    replay_sink_t sink;
    hal_frame_t f;
    int eof = 0, rc = 0, got;

    memset(&sink, 0, sizeof(sink));
    r.path = o->replay;
    r.line = 0u;
    r.f = fopen(o->replay, "r");
    if (r.f == NULL) {
        fprintf(stderr, "attekf-node: cannot open %s: %s\n", o->replay, strerror(errno));
        return 1;
    }
    sink.channel = o->channel_name;
    if (o->output != NULL && (sink.out = fopen(o->output, "w")) == NULL) {
        fprintf(stderr, "attekf-node: cannot write %s: %s\n", o->output, strerror(errno));
        fclose(r.f);
        return 1;
    }
    hal_virtual_init(&g_virtual, g_queue, REPLAY_QUEUE, NULL, 0u, NULL, 0u);
    hal_virtual_set_sinks(&g_virtual, write_frame, NULL, log_event, &sink);
    hal_virtual_bind(&g_virtual, hal);
    g_node.live = 0;

    got = log_next(&r, &f);
    if (got > 0) {
        hal_virtual_set_clock(&g_virtual, f.t_us);
        (void)hal_virtual_push_frame(&g_virtual, &f);
    }
    eof = (got == 0);
    if (got < 0 || !start_app(cfg, hal)) {
        rc = 1;
    }
    while (rc == 0 && !g_stop) {
        while (!eof && hal_virtual_frame_space(&g_virtual) > 0u) {
            got = log_next(&r, &f);
            if (got <= 0) {
                eof = 1;
                rc = (got < 0);
                break;
            }
            (void)hal_virtual_push_frame(&g_virtual, &f);
        }
        if (eof) {
            hal_virtual_end(&g_virtual);
        }
        if (rc != 0 || app_poll(&g_app, 10000u) == HAL_END) {
            break;
        }
    }
    fclose(r.f);
    if (sink.out != NULL && (fclose(sink.out) != 0 || sink.write_error)) {
        fprintf(stderr, "attekf-node: write error on %s\n", o->output);
        rc = 1;
    }
    return rc;
}

static int touch(const char *path)
{
    FILE *f = fopen(path, "w");
    if (f == NULL || fclose(f) != 0) {
        fprintf(stderr, "attekf-node: cannot create %s: %s\n", path, strerror(errno));
        return 0;
    }
    return 1;
}

static int run_live(const options_t *o, const app_config_t *cfg, hal_t *hal)
{
    hal_socketcan_config_t scfg = hal_socketcan_default_config;
    uint64_t t_end = 0u;
    scfg.rcvbuf_bytes = (uint32_t)o->rcvbuf;
    if (hal_socketcan_open(&g_can, o->ifname, &scfg, log_event, NULL) != HAL_OK) {
        fprintf(stderr, "attekf-node: cannot open CAN interface '%s': %s\n", o->ifname, strerror(errno));
        return 1;
    }
    hal_socketcan_bind(&g_can, hal);
    g_node.live = 1;
    if (!start_app(cfg, hal)) {
        hal_socketcan_close(&g_can);
        return 1;
    }
    if (o->log_level >= HAL_LOG_INFO) {
        fprintf(stderr, "attekf-node: listening on %s (%s, receive buffer %d bytes)\n", o->ifname,
                protocol_names[cfg->node.protocol == APP_PROTO_DRONECAN], g_can.rcvbuf_actual);
    }
    if (o->ready_file != NULL && !touch(o->ready_file)) {
        hal_socketcan_close(&g_can);
        return 1;
    }
    if (o->duration_s > 0.0) {
        t_end = hal_socketcan_now_us() + (uint64_t)(o->duration_s * 1e6);
    }
    while (!g_stop) {
        (void)app_poll(&g_app, 50000u);
        if (t_end != 0u && hal_socketcan_now_us() >= t_end) {
            break;
        }
    }
    hal_socketcan_close(&g_can);
    return 0;
}

static double wall_now(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    options_t o;
    app_config_t cfg;
    struct sigaction sa;
    hal_t hal;
    const double t0 = wall_now();
    int rc, p;

    p = parse_args(argc, argv, &o);
    if (p < 0) {
        return 0;
    }
    if (p == 0) {
        return 2;
    }
    rc = configure(&o, &cfg);
    if (rc != 0) {
        return rc;
    }
    if (o.list_params) {
        list_params(&cfg);
        return 0;
    }
    g_log_level = o.log_level;
    g_node.params = o.params;
    memset(&sa, 0, sizeof(sa));
    sa.sa_handler = on_signal; /* no SA_RESTART: ppoll returns EINTR and the loop looks */
    sigemptyset(&sa.sa_mask);
    (void)sigaction(SIGINT, &sa, NULL);
    (void)sigaction(SIGTERM, &sa, NULL);

    rc = (o.replay != NULL) ? run_replay(&o, &cfg, &hal) : run_live(&o, &cfg, &hal);
    if (g_app.hal != NULL) {
        const char *mode = o.replay ? "replay" : "socketcan";
        const node_run_t run = {mode, o.replay ? 0 : g_can.rcvbuf_actual, wall_now() - t0};
        if (o.log_level >= HAL_LOG_INFO) {
            node_stats_print(stderr, &g_app, &g_node.lat, &run, 0);
        }
        if (o.stats != NULL && !node_stats_write(o.stats, &g_app, &g_node.lat, &run)) {
            rc = 1;
        }
    }
    return rc;
}
