/*
 * peers_bench.c - the peers' filters (peers.h) on the samples of firmware/target/bench.c.
 *
 * The samples are bench.c's, generated the same way (tests/c/support/testsim.c, seed 12345,
 * 100 Hz, the same tumbling motion, still until attekf's filter is aligned), so attekf's
 * att_step runs alongside, untimed, to decide that moment; every peer gets every sample
 * and is measured on the samples after the alignment, the ones bench.c measures att_step on.
 * "ours" measures att_step itself (a cross-check of bench.c; the host callgrind figure).
 *
 * Target (ATTEKF_BARE_METAL, under QEMU -icount shift=8): instructions of each full update
 * from SysTick as in bench.c (min / mean / max), the deepest stack of one update (stack
 * painting) and the size of the filter object. Host: no timing; run it under callgrind with
 * --toggle-collect=peers_measured_step, which is called for the measured samples only
 * (scripts/bench_firmware.py --peers does both).
 *
 * Usage: attekf_peers_bench[.elf] [samples] [Fusion|VQF|BasicVQF|ours ...]
 *        (default 3000 samples, the three peers)
 * Output: "peer <name> insns min .. mean .. max .. n .. stack .. state .. tilt_deg .." lines;
 * exit status 0, 2 (not under -icount) or 3 (bad argument).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "att.h"
#include "peers.h"
#include "testsim.h"
#if defined(ATTEKF_BARE_METAL)
#include "target.h"
#endif

#define SAMPLES_DEFAULT 3000ul
#define STACK_DEPTH 8192u
#define STACK_MARGIN 128u

static const peer_t *const all_peers[] = {&peer_fusion, &peer_vqf, &peer_basicvqf};

/* One measured update: of a peer, or of attekf (peer NULL). Not inlined, so that callgrind
 * can collect exactly these calls. */
__attribute__((noinline)) void peers_measured_step(const peer_t *peer, att_ekf_t *ours, const att_sample_t *s,
                                                   const float g[3], const float a[3], const float m[3]);
__attribute__((noinline)) void peers_measured_step(const peer_t *peer, att_ekf_t *ours, const att_sample_t *s,
                                                   const float g[3], const float a[3], const float m[3])
{
    if (peer != NULL) {
        peer->step(g, a, m);
    } else {
        (void)att_step(ours, s, NULL);
    }
}

/* Angle between the true and the estimated up direction in the body frame, deg. */
static double tilt_error_deg(const ts_sim_t *sim, const float q[4])
{
    double e[3], up_true[3], up_est[3], dot = 0.0, n1 = 0.0, n2 = 0.0;
    const double w = (double)q[0], x = (double)q[1], y = (double)q[2], z = (double)q[3];
    int i;
    ts_sim_euler(sim, e);
    up_true[0] = -sin(e[1]);
    up_true[1] = sin(e[0]) * cos(e[1]);
    up_true[2] = cos(e[0]) * cos(e[1]);
    /* third row of the rotation body -> earth: earth z in body coordinates */
    up_est[0] = 2.0 * (x * z - w * y);
    up_est[1] = 2.0 * (y * z + w * x);
    up_est[2] = 1.0 - 2.0 * (x * x + y * y);
    for (i = 0; i < 3; ++i) {
        dot += up_true[i] * up_est[i];
        n1 += up_true[i] * up_true[i];
        n2 += up_est[i] * up_est[i];
    }
    return acos(fmax(-1.0, fmin(1.0, dot / sqrt(n1 * n2)))) * 57.29577951308232;
}

#if defined(ATTEKF_BARE_METAL)
static uint32_t to_insns(uint32_t t0, uint32_t t1, uint32_t base)
{
    const uint32_t ticks = ((t0 - t1) & TARGET_SYSTICK_MASK) - base;
    return (ticks * 10u + 32u) / 64u; /* 6.4 ticks per instruction */
}
#endif

/* Runs one subject over the samples; prints its line. 0 on success. */
static int run(const peer_t *peer, unsigned long samples)
{
    static att_ekf_t filter;
    ts_sim_cfg_t cfg;
    ts_sim_t sim;
    unsigned long k, n = 0ul;
    uint32_t lo = 0xFFFFFFFFu, hi = 0u, max_stack = 0u;
    uint64_t sum = 0u;
    float q[4] = {1.0f, 0.0f, 0.0f, 0.0f};
#if defined(ATTEKF_BARE_METAL)
    const uintptr_t sp = target_sp();
    uint32_t base;
    {
        const uint32_t t0 = TARGET_SYSTICK_NOW, t1 = TARGET_SYSTICK_NOW;
        base = (t0 - t1) & TARGET_SYSTICK_MASK;
    }
#endif
    if (att_init(&filter, &att_default_settings) != EKF_OK) {
        printf("error: att_init failed\n");
        return 1;
    }
    ts_sim_default(&cfg);
    ts_sim_init(&sim, &cfg, TS_BENCH_SEED, TS_BENCH_PHI, TS_BENCH_THETA, TS_BENCH_PSI);
    if (peer != NULL) {
        peer->init(0.01f);
    }
    for (k = 0; k < samples; ++k) {
        static const double still[3] = {0.0, 0.0, 0.0};
        const int aligned = (att_flags(&filter) & ATT_FLAG_ALIGNED) != 0u;
        double w[3];
        att_sample_t s;
        float g[3], a[3], m[3];
        int i;
        ts_bench_motion(sim.t, w);
        ts_sim_step(&sim, aligned ? w : still, NULL, &s);
        for (i = 0; i < 3; ++i) {
            g[i] = ekf_to_float(s.gyro[i]);
            a[i] = ekf_to_float(s.accel[i]);
            m[i] = ekf_to_float(s.mag[i]);
        }
        if (!aligned) { /* unmeasured, as in bench.c */
            (void)att_step(&filter, &s, NULL);
            if (peer != NULL) {
                peer->step(g, a, m);
            }
            continue;
        }
        if (peer != NULL) {
            (void)att_step(&filter, &s, NULL); /* the sample gate of the next sample */
        }
#if defined(ATTEKF_BARE_METAL)
        {
            uint32_t t0, t1, insns, used;
            target_stack_paint(sp - STACK_DEPTH, sp - STACK_MARGIN);
            t0 = TARGET_SYSTICK_NOW;
            if (peer != NULL) {
                peer->step(g, a, m);
            } else {
                (void)att_step(&filter, &s, NULL);
            }
            t1 = TARGET_SYSTICK_NOW;
            used = (uint32_t)(sp - target_stack_lowest_touched(sp - STACK_DEPTH, sp - STACK_MARGIN));
            insns = to_insns(t0, t1, base);
            lo = (insns < lo) ? insns : lo;
            hi = (insns > hi) ? insns : hi;
            max_stack = (used > max_stack) ? used : max_stack;
            sum += insns;
        }
#else
        peers_measured_step(peer, &filter, &s, g, a, m);
#endif
        ++n;
    }
    if (peer != NULL) {
        peer->quaternion(q);
    } else {
        att_get_quaternion(&filter, q);
    }
#if !defined(ATTEKF_BARE_METAL)
    lo = 0u; /* no timing on the host: callgrind counts */
#endif
    printf("peer %s insns min %lu mean %lu max %lu n %lu stack %lu state %lu tilt_deg %.3f\n",
           peer != NULL ? peer->name : "ours", (unsigned long)(n ? lo : 0u),
           (unsigned long)(n ? (sum + n / 2u) / n : 0u), (unsigned long)hi, n, (unsigned long)max_stack,
           (unsigned long)(peer != NULL ? peer->state_bytes : sizeof filter), tilt_error_deg(&sim, q));
    return 0;
}

int main(int argc, char **argv)
{
    unsigned long samples = SAMPLES_DEFAULT;
    int i, first = 1, status = 0;
#if defined(ATTEKF_BARE_METAL)
    target_systick_start();
    {
        const uint32_t t0 = TARGET_SYSTICK_NOW;
        __asm__ volatile("movs r0, #250\n"
                         "lsls r0, r0, #2\n"
                         "1: subs r0, r0, #1\n"
                         "bne 1b\n" ::: "r0", "cc");
        if (to_insns(t0, TARGET_SYSTICK_NOW, 0u) < 1990u || to_insns(t0, TARGET_SYSTICK_NOW, 0u) > 2020u) {
            printf("error: SysTick does not count instructions; run under qemu -icount shift=8\n");
            return 2;
        }
    }
#endif
    if (argc > 1 && argv[1][0] >= '0' && argv[1][0] <= '9') {
        char *end = NULL;
        samples = strtoul(argv[1], &end, 10);
        if (*end != '\0' || samples < 20ul || samples > 1000000ul) {
            printf("error: samples must be an integer in 20..1000000, got '%s'\n", argv[1]);
            return 3;
        }
        first = 2;
    }
    if (first >= argc) {
        for (i = 0; i < (int)(sizeof all_peers / sizeof all_peers[0]); ++i) {
            status |= run(all_peers[i], samples);
        }
        return status;
    }
    for (i = first; i < argc; ++i) {
        const peer_t *p = NULL;
        int j, found = strcmp(argv[i], "ours") == 0;
        for (j = 0; j < (int)(sizeof all_peers / sizeof all_peers[0]); ++j) {
            if (strcmp(argv[i], all_peers[j]->name) == 0) {
                p = all_peers[j];
                found = 1;
            }
        }
        if (!found) {
            printf("error: unknown filter '%s' (Fusion, VQF, BasicVQF, ours)\n", argv[i]);
            return 3;
        }
        status |= run(p, samples);
    }
    return status;
}
