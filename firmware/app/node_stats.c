/*
 * node_stats.c - attekf-node's statistics (node_stats.h).
 */
#define _GNU_SOURCE 1 /* getrusage with -std=c99 */

#include "node_stats.h"

#include <errno.h>
#include <inttypes.h>
#include <string.h>
#include <sys/resource.h>

/* Latency histogram: 1 us bins below 10 ms, 100 us bins from 10 ms to 1 s, one bin beyond. */
static uint32_t lat_bin(uint64_t lat_us)
{
    if (lat_us < NODE_LAT_FINE_US) {
        return (uint32_t)lat_us;
    }
    return (lat_us < 1000000u) ? NODE_LAT_FINE_US + (uint32_t)((lat_us - NODE_LAT_FINE_US) / NODE_LAT_COARSE_US)
                               : NODE_LAT_BINS;
}

/* Lower edge of a bin, us. */
static uint64_t lat_bin_us(uint32_t bin)
{
    return (bin < NODE_LAT_FINE_US) ? bin : NODE_LAT_FINE_US + (uint64_t)(bin - NODE_LAT_FINE_US) * NODE_LAT_COARSE_US;
}

void node_latency_add(node_latency_t *n, uint64_t lat_us)
{
    ++n->hist[lat_bin(lat_us)];
    ++n->n;
    if (lat_us > n->max_us) {
        n->max_us = lat_us;
    }
}

/* Latency percentile (0..100) in us from the histogram (resolution 1 us below 10 ms, 100 us
 * above; beyond 1 s the maximum). */
uint64_t node_latency_percentile(const node_latency_t *n, double pct)
{
    uint64_t want, acc = 0u;
    uint32_t i;
    if (n->n == 0u) {
        return 0u;
    }
    want = (uint64_t)(pct / 100.0 * (double)n->n + 0.999999);
    want = (want == 0u) ? 1u : want;
    for (i = 0; i <= NODE_LAT_BINS; ++i) {
        acc += n->hist[i];
        if (acc >= want) {
            return (i < NODE_LAT_BINS) ? lat_bin_us(i) : n->max_us;
        }
    }
    return n->max_us;
}

double node_cpu_seconds(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) {
        return 0.0;
    }
    return (double)ru.ru_utime.tv_sec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

void node_stats_print(FILE *f, const app_t *app, const node_latency_t *n, const node_run_t *run, int json)
{
    uint32_t c[APP_CNT_COUNT];
    int i;
    app_get_counters(app, c);
    if (json) {
        fprintf(f, "{\n  \"mode\": \"%s\",\n  \"protocol\": \"%s\",\n  \"rcvbuf_bytes\": %d,\n  \"cpu_s\": %.6f,\n"
                   "  \"wall_s\": %.6f,\n  \"counters\": {\n",
                run->mode, app->node.protocol == APP_PROTO_DRONECAN ? "dronecan" : "dbc", run->rcvbuf, node_cpu_seconds(),
                run->wall_s);
        for (i = 0; i < APP_CNT_COUNT; ++i) {
            fprintf(f, "    \"%s\": %" PRIu32 "%s\n", app_counter_name((app_counter_id_t)i), c[i],
                    i + 1 < APP_CNT_COUNT ? "," : "");
        }
        fprintf(f,
                "  },\n  \"latency_us\": {\"count\": %" PRIu64 ", \"p50\": %" PRIu64 ", \"p90\": %" PRIu64
                ", \"p99\": %" PRIu64 ", \"max\": %" PRIu64 "}\n}\n",
                n->n, node_latency_percentile(n, 50.0), node_latency_percentile(n, 90.0), node_latency_percentile(n, 99.0), n->max_us);
        return;
    }
    fprintf(f, "attekf-node: counters:");
    for (i = 0; i < APP_CNT_COUNT; ++i) {
        fprintf(f, " %s=%" PRIu32, app_counter_name((app_counter_id_t)i), c[i]);
    }
    fprintf(f, "\n");
    if (n->n > 0u) {
        fprintf(f, "attekf-node: output latency us: n=%" PRIu64 " p50=%" PRIu64 " p99=%" PRIu64 " max=%" PRIu64 "\n",
                n->n, node_latency_percentile(n, 50.0), node_latency_percentile(n, 99.0), n->max_us);
    }
}

int node_stats_write(const char *path, const app_t *app, const node_latency_t *n, const node_run_t *run)
{
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        fprintf(stderr, "attekf-node: cannot write %s: %s\n", path, strerror(errno));
        return 0;
    }
    node_stats_print(f, app, n, run, 1);
    if (fclose(f) != 0) {
        fprintf(stderr, "attekf-node: cannot write %s: %s\n", path, strerror(errno));
        return 0;
    }
    return 1;
}

