/*
 * node_stats.h - attekf-node's statistics: the node-side latency (kernel receive time of a
 * sample's last frame -> its output handed to the kernel) as a histogram, the CPU time, and the
 * counters, printed at exit and written as JSON (--stats).
 */
#ifndef NODE_STATS_H
#define NODE_STATS_H

#include <stdint.h>
#include <stdio.h>

#include "app.h"

#define NODE_LAT_FINE_US 10000u
#define NODE_LAT_COARSE_US 100u
#define NODE_LAT_BINS (NODE_LAT_FINE_US + (1000000u - NODE_LAT_FINE_US) / NODE_LAT_COARSE_US)

typedef struct {
    uint32_t hist[NODE_LAT_BINS + 1u];
    uint64_t n;
    uint64_t max_us;
} node_latency_t;

/* What the statistics say about the run. */
typedef struct {
    const char *mode;   /* "socketcan" or "replay" */
    int rcvbuf;         /* receive buffer the kernel granted, bytes (0: none) */
    double wall_s;      /* since the start of the program */
} node_run_t;

void node_latency_add(node_latency_t *n, uint64_t lat_us);
/* Percentile (0..100) in us (resolution 1 us below 10 ms, 100 us above; beyond 1 s the maximum). */
uint64_t node_latency_percentile(const node_latency_t *n, double pct);
/* User + system CPU time of the process, s. */
double node_cpu_seconds(void);
/* The counters and the latency: one line each (json 0) or a JSON object. */
void node_stats_print(FILE *f, const app_t *app, const node_latency_t *n, const node_run_t *run, int json);
/* node_stats_print as JSON into path; 1 if done, else 0 with a message. */
int node_stats_write(const char *path, const app_t *app, const node_latency_t *n, const node_run_t *run);

#endif /* NODE_STATS_H */
