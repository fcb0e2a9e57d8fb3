/*
 * node_linux.c - attekf-node: the estimator application (app.c) as a Linux program.
 *
 * Two modes, same loop:
 *   attekf-node -i vcan0                  live on a SocketCAN interface (hal_socketcan)
 *   attekf-node --replay in.log -o out.log  a candump log through the virtual backend;
 *                                           the outputs go to another candump log
 * The replay runs on the log's own time stamps (simulated clock), so it computes exactly
 * what the live node computes from the same frames; tests compare the two.
 *
 * Stops on SIGINT/SIGTERM, end of replay, or --duration. Counters and the node-side
 * latency (kernel receive time of a sample's last frame -> its output handed to the
 * kernel) are printed at exit and written as JSON with --stats.
 */
#define _GNU_SOURCE 1 /* sigaction, strtoull with -std=c99 */

#include <errno.h>
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "app.h"
#include "candump.h"
#include "hal.h"
#include "hal_can.h"
#include "hal_socketcan.h"
#include "hal_virtual.h"

#define NODE_VERSION "0.1.0"
#define REPLAY_QUEUE 4096u
/* Latency histogram: 1 us bins below 10 ms, 100 us bins from 10 ms to 1 s, one bin beyond. */
#define LAT_FINE_US 10000u
#define LAT_COARSE_US 100u
#define LAT_BINS (LAT_FINE_US + (1000000u - LAT_FINE_US) / LAT_COARSE_US)

static volatile sig_atomic_t g_stop = 0;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

/* ---- options ------------------------------------------------------------------------ */
typedef struct {
    const char *ifname;
    const char *replay;
    const char *output;
    const char *stats;
    const char *ready_file;
    const char *channel_name;
    double rate_hz;
    double stale_ms;
    double heartbeat_ms;
    double max_gap_ms;
    double duration_s;
    unsigned long rcvbuf;
    int log_level;
} options_t;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: attekf-node [options]\n"
            "\n"
            "Attitude EKF node: reads IMU frames (hal/can/attekf.dbc) from a CAN bus, runs the\n"
            "filter, sends ATT_* frames. Or replays a candump log through the same code.\n"
            "\n"
            "options:\n"
            "  -i, --interface NAME   SocketCAN interface (default can0)\n"
            "  -r, --replay FILE      replay a candump log (`candump -L` format, as written by\n"
            "                         `attekf replay --to-log`) through the virtual backend\n"
            "  -o, --output FILE      replay mode: write the output frames as a candump log\n"
            "                         (default: none)\n"
            "      --channel NAME     channel name written in the output log (default vcan0)\n"
            "      --rate HZ          attitude output rate on the sample clock, Hz; 0 = every\n"
            "                         sample (default 100)\n"
            "      --stale-ms MS      input stale after MS without a sample (default 100)\n"
            "      --heartbeat-ms MS  status heartbeat period while stale (default 100)\n"
            "      --max-gap-ms MS    re-align after a gap longer than MS (default 2000)\n"
            "      --rcvbuf BYTES     socket receive buffer (default 4194304)\n"
            "      --duration S       stop after S seconds (live mode; default: run until a\n"
            "                         signal)\n"
            "      --stats FILE       write counters and latency as JSON at exit\n"
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

static int parse_level(const char *s, int *out)
{
    static const char *const names[] = {"error", "warn", "info", "debug"};
    int i;
    for (i = 0; i < 4; ++i) {
        if (strcmp(s, names[i]) == 0) {
            *out = i;
            return 1;
        }
    }
    fprintf(stderr, "attekf-node: --log-level: '%s' is not one of error, warn, info, debug\n", s);
    return 0;
}

/* Returns -1 to exit 0 (help/version), 0 on a usage error, 1 ok. */
static int parse_args(int argc, char **argv, options_t *o)
{
    int i;
    memset(o, 0, sizeof(*o));
    o->ifname = "can0";
    o->channel_name = "vcan0";
    o->rate_hz = 100.0;
    o->stale_ms = 100.0;
    o->heartbeat_ms = 100.0;
    o->max_gap_ms = 2000.0;
    o->rcvbuf = 4194304ul;
    o->log_level = HAL_LOG_INFO;
    for (i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return -1;
        }
        if (strcmp(a, "-V") == 0 || strcmp(a, "--version") == 0) {
            printf("attekf-node %s\n", NODE_VERSION);
            return -1;
        }
        if (v == NULL) {
            static const char *const with_value[] = {
                "-i", "--interface", "-r", "--replay", "-o", "--output", "--channel", "--stats",
                "--ready-file", "--rate", "--stale-ms", "--heartbeat-ms", "--max-gap-ms",
                "--duration", "--rcvbuf", "-l", "--log-level"};
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
        if (strcmp(a, "-i") == 0 || strcmp(a, "--interface") == 0) {
            o->ifname = v;
        } else if (strcmp(a, "-r") == 0 || strcmp(a, "--replay") == 0) {
            o->replay = v;
        } else if (strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) {
            o->output = v;
        } else if (strcmp(a, "--channel") == 0) {
            o->channel_name = v;
        } else if (strcmp(a, "--stats") == 0) {
            o->stats = v;
        } else if (strcmp(a, "--ready-file") == 0) {
            o->ready_file = v;
        } else if (strcmp(a, "--rate") == 0) {
            if (!parse_double(a, v, 0.0, 1e6, &o->rate_hz)) return 0;
        } else if (strcmp(a, "--stale-ms") == 0) {
            if (!parse_double(a, v, 0.001, 4e6, &o->stale_ms)) return 0;
        } else if (strcmp(a, "--heartbeat-ms") == 0) {
            if (!parse_double(a, v, 0.001, 4e6, &o->heartbeat_ms)) return 0;
        } else if (strcmp(a, "--max-gap-ms") == 0) {
            if (!parse_double(a, v, 0.001, 60000.0, &o->max_gap_ms)) return 0;
        } else if (strcmp(a, "--duration") == 0) {
            if (!parse_double(a, v, 0.0, 1e9, &o->duration_s)) return 0;
        } else if (strcmp(a, "--rcvbuf") == 0) {
            double b;
            if (!parse_double(a, v, 0.0, 1073741824.0, &b)) return 0;
            o->rcvbuf = (unsigned long)b;
        } else if (strcmp(a, "-l") == 0 || strcmp(a, "--log-level") == 0) {
            if (!parse_level(v, &o->log_level)) return 0;
        } else {
            fprintf(stderr, "attekf-node: unknown option '%s'; see --help\n", a);
            return 0;
        }
        ++i; /* the value */
    }
    if (o->output != NULL && o->replay == NULL) {
        fprintf(stderr, "attekf-node: --output is for --replay mode (live outputs go to the bus)\n");
        return 0;
    }
    return 1;
}

/* ---- logging ------------------------------------------------------------------------ */
static int g_log_level = HAL_LOG_INFO;

static void log_event(void *user, hal_level_t level, hal_event_t event, int32_t detail)
{
    static const char *const lv[] = {"error", "warn", "info", "debug"};
    (void)user;
    if ((int)level > g_log_level) {
        return;
    }
    fprintf(stderr, "attekf-node: [%s] %s %" PRId32 "\n", lv[level], hal_event_name(event), detail);
}

/* ---- a wrapper backend that measures the output latency --------------------------------- */
typedef struct {
    hal_t inner;
    uint32_t lat_hist[LAT_BINS + 1u];
    uint64_t lat_n;
    uint64_t lat_max_us;
    int live; /* latency only means something on a real clock */
} node_t;

static uint64_t w_now(void *ctx) { return hal_now_us(&((node_t *)ctx)->inner); }

static hal_status_t w_read(void *ctx, hal_sample_t *out, uint32_t timeout_us)
{
    return hal_read_sample(&((node_t *)ctx)->inner, out, timeout_us);
}

static uint32_t lat_bin(uint64_t lat_us)
{
    if (lat_us < LAT_FINE_US) {
        return (uint32_t)lat_us;
    }
    if (lat_us < 1000000u) {
        return LAT_FINE_US + (uint32_t)((lat_us - LAT_FINE_US) / LAT_COARSE_US);
    }
    return LAT_BINS;
}

/* Lower edge of a bin, us. */
static uint64_t lat_bin_us(uint32_t bin)
{
    return (bin < LAT_FINE_US) ? bin : LAT_FINE_US + (uint64_t)(bin - LAT_FINE_US) * LAT_COARSE_US;
}

static hal_status_t w_publish(void *ctx, const hal_output_t *out)
{
    node_t *n = (node_t *)ctx;
    const hal_status_t st = hal_publish(&n->inner, out);
    if (st == HAL_OK && n->live && out->kind == HAL_OUT_ATTITUDE) {
        const uint64_t now = hal_now_us(&n->inner);
        const uint64_t lat = (now > out->rx_us) ? now - out->rx_us : 0u;
        ++n->lat_hist[lat_bin(lat)];
        ++n->lat_n;
        if (lat > n->lat_max_us) {
            n->lat_max_us = lat;
        }
    }
    return st;
}

static void w_counters(void *ctx, uint32_t counters[HAL_CNT_COUNT])
{
    hal_get_counters(&((node_t *)ctx)->inner, counters);
}

static void w_report(void *ctx, hal_level_t level, hal_event_t event, int32_t detail)
{
    hal_report(&((node_t *)ctx)->inner, level, event, detail);
}

static const hal_ops_t wrapper_ops = {w_now, w_read, w_publish, w_counters, w_report};

/* Latency percentile (0..100) in us from the histogram (resolution 1 us below 10 ms, 100 us
 * above; beyond 1 s the maximum). */
static uint64_t lat_percentile(const node_t *n, double pct)
{
    uint64_t want, acc = 0u;
    uint32_t i;
    if (n->lat_n == 0u) {
        return 0u;
    }
    want = (uint64_t)(pct / 100.0 * (double)n->lat_n + 0.999999);
    if (want == 0u) {
        want = 1u;
    }
    for (i = 0; i <= LAT_BINS; ++i) {
        acc += n->lat_hist[i];
        if (acc >= want) {
            return (i < LAT_BINS) ? lat_bin_us(i) : n->lat_max_us;
        }
    }
    return n->lat_max_us;
}

/* ---- candump log files ------------------------------------------------------------------ */
typedef struct {
    FILE *f;
    const char *path;
    unsigned long line;
} logreader_t;

/* Next data frame: 1, 0 at end of file, -1 on a malformed line (message printed). The
 * line format is candump.h's. */
static int log_next(logreader_t *r, hal_can_frame_t *f)
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

static void write_frame(void *user, const hal_can_frame_t *f)
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

static void replay_report(void *user, hal_level_t level, hal_event_t event, int32_t detail)
{
    log_event(user, level, event, detail);
}

/* ---- statistics -------------------------------------------------------------------------- */
static void print_stats(FILE *f, const app_t *app, const node_t *n, const char *mode, int json,
                        int rcvbuf)
{
    uint32_t c[HAL_CNT_COUNT];
    int i;
    app_get_counters(app, c);
    if (json) {
        fprintf(f, "{\n  \"mode\": \"%s\",\n  \"rcvbuf_bytes\": %d,\n  \"counters\": {\n", mode, rcvbuf);
        for (i = 0; i < HAL_CNT_COUNT; ++i) {
            fprintf(f, "    \"%s\": %" PRIu32 "%s\n", hal_counter_name((hal_counter_id_t)i), c[i],
                    i + 1 < HAL_CNT_COUNT ? "," : "");
        }
        fprintf(f,
                "  },\n  \"latency_us\": {\"count\": %" PRIu64 ", \"p50\": %" PRIu64 ", \"p90\": %" PRIu64
                ", \"p99\": %" PRIu64 ", \"max\": %" PRIu64 "}\n}\n",
                n->lat_n, lat_percentile(n, 50.0), lat_percentile(n, 90.0), lat_percentile(n, 99.0),
                n->lat_max_us);
        return;
    }
    fprintf(f, "attekf-node: counters:");
    for (i = 0; i < HAL_CNT_COUNT; ++i) {
        fprintf(f, " %s=%" PRIu32, hal_counter_name((hal_counter_id_t)i), c[i]);
    }
    fprintf(f, "\n");
    if (n->lat_n > 0u) {
        fprintf(f, "attekf-node: output latency us: n=%" PRIu64 " p50=%" PRIu64 " p99=%" PRIu64 " max=%" PRIu64 "\n",
                n->lat_n, lat_percentile(n, 50.0), lat_percentile(n, 99.0), n->lat_max_us);
    }
}

static int write_stats(const char *path, const app_t *app, const node_t *n, const char *mode, int rcvbuf)
{
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        fprintf(stderr, "attekf-node: cannot write %s: %s\n", path, strerror(errno));
        return 0;
    }
    print_stats(f, app, n, mode, 1, rcvbuf);
    if (fclose(f) != 0) {
        fprintf(stderr, "attekf-node: cannot write %s: %s\n", path, strerror(errno));
        return 0;
    }
    return 1;
}

/* ---- main ------------------------------------------------------------------------------- */
static app_t g_app;
static node_t g_node;
static hal_virtual_t g_virtual;
static hal_can_frame_t g_queue[REPLAY_QUEUE];
static hal_socketcan_t g_can;

static int settings_from(const options_t *o, app_settings_t *s)
{
    *s = app_default_settings;
    s->output_period_us = (o->rate_hz > 0.0) ? (uint32_t)(1e6 / o->rate_hz + 0.5) : 0u;
    s->stale_timeout_us = (uint32_t)(o->stale_ms * 1000.0 + 0.5);
    s->heartbeat_period_us = (uint32_t)(o->heartbeat_ms * 1000.0 + 0.5);
    s->max_gap_us = (uint32_t)(o->max_gap_ms * 1000.0 + 0.5);
    if (o->rate_hz > 0.0 && s->output_period_us == 0u) {
        fprintf(stderr, "attekf-node: --rate %g is above 1 MHz\n", o->rate_hz);
        return 0;
    }
    if (app_settings_check(s) != EKF_OK) {
        fprintf(stderr, "attekf-node: the timing options are out of range (see --help)\n");
        return 0;
    }
    return 1;
}

static int run_replay(const options_t *o, const app_settings_t *s, hal_t *hal)
{
    logreader_t r;
    replay_sink_t sink;
    hal_can_frame_t f;
    int eof = 0, rc = 0, got;
    ekf_status_t est;

    memset(&sink, 0, sizeof(sink));
    r.path = o->replay;
    r.line = 0u;
    r.f = fopen(o->replay, "r");
    if (r.f == NULL) {
        fprintf(stderr, "attekf-node: cannot open %s: %s\n", o->replay, strerror(errno));
        return 1;
    }
    sink.channel = o->channel_name;
    if (o->output != NULL) {
        sink.out = fopen(o->output, "w");
        if (sink.out == NULL) {
            fprintf(stderr, "attekf-node: cannot write %s: %s\n", o->output, strerror(errno));
            fclose(r.f);
            return 1;
        }
    }
    hal_virtual_init(&g_virtual, g_queue, REPLAY_QUEUE, NULL, 0u);
    hal_virtual_set_sinks(&g_virtual, NULL, write_frame, replay_report, &sink);
    hal_virtual_bind(&g_virtual, &g_node.inner);
    g_node.live = 0;

    got = log_next(&r, &f);
    if (got < 0) {
        rc = 1;
        goto done;
    }
    if (got > 0) {
        hal_virtual_set_clock(&g_virtual, f.t_us);
        (void)hal_virtual_push_frame(&g_virtual, &f);
    } else {
        eof = 1;
    }
    est = app_init(&g_app, s, &att_default_settings, hal);
    if (est != EKF_OK) {
        fprintf(stderr, "attekf-node: app_init: %s\n", ekf_status_str(est));
        rc = 1;
        goto done;
    }
    while (!g_stop) {
        hal_status_t st;
        while (!eof && hal_virtual_frame_space(&g_virtual) > 0u) {
            got = log_next(&r, &f);
            if (got < 0) {
                rc = 1;
                goto done;
            }
            if (got == 0) {
                eof = 1;
                hal_virtual_end(&g_virtual);
                break;
            }
            (void)hal_virtual_push_frame(&g_virtual, &f);
        }
        if (eof) {
            hal_virtual_end(&g_virtual);
        }
        st = app_poll(&g_app, 10000u);
        if (st == HAL_END) {
            break;
        }
    }
done:
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

static int run_live(const options_t *o, const app_settings_t *s, hal_t *hal)
{
    hal_socketcan_config_t cfg = hal_socketcan_default_config;
    uint64_t t_end = 0u;
    ekf_status_t est;
    cfg.rcvbuf_bytes = (uint32_t)o->rcvbuf;
    if (hal_socketcan_open(&g_can, o->ifname, &cfg, log_event, NULL) != HAL_OK) {
        fprintf(stderr, "attekf-node: cannot open CAN interface '%s': %s\n", o->ifname, strerror(errno));
        return 1;
    }
    hal_socketcan_bind(&g_can, &g_node.inner);
    g_node.live = 1;
    est = app_init(&g_app, s, &att_default_settings, hal);
    if (est != EKF_OK) {
        fprintf(stderr, "attekf-node: app_init: %s\n", ekf_status_str(est));
        hal_socketcan_close(&g_can);
        return 1;
    }
    if (o->log_level >= HAL_LOG_INFO) {
        fprintf(stderr, "attekf-node: listening on %s (receive buffer %d bytes)\n", o->ifname, g_can.rcvbuf_actual);
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

int main(int argc, char **argv)
{
    options_t o;
    app_settings_t s;
    struct sigaction sa;
    hal_t hal;
    int rc, p;

    p = parse_args(argc, argv, &o);
    if (p < 0) {
        return 0;
    }
    if (p == 0 || !settings_from(&o, &s)) {
        return 2;
    }
    g_log_level = o.log_level;
    memset(&sa, 0, sizeof(sa));
    sa.sa_handler = on_signal; /* no SA_RESTART: ppoll returns EINTR and the loop looks */
    sigemptyset(&sa.sa_mask);
    (void)sigaction(SIGINT, &sa, NULL);
    (void)sigaction(SIGTERM, &sa, NULL);

    hal.ops = &wrapper_ops;
    hal.ctx = &g_node;
    rc = (o.replay != NULL) ? run_replay(&o, &s, &hal) : run_live(&o, &s, &hal);
    if (g_app.hal != NULL) {
        if (o.log_level >= HAL_LOG_INFO) {
            print_stats(stderr, &g_app, &g_node, o.replay ? "replay" : "socketcan", 0, 0);
        }
        if (o.stats != NULL &&
            !write_stats(o.stats, &g_app, &g_node, o.replay ? "replay" : "socketcan",
                         o.replay ? 0 : g_can.rcvbuf_actual)) {
            rc = 1;
        }
    }
    return rc;
}
