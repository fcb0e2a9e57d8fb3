/*
 * can_blast.c - attekf-can-blast: the sender of the CAN throughput benchmark.
 *
 * Sends IMU samples in the node's protocol (firmware/app/dbc, 4 frames per sample: gyro, accel, mag,
 * sync) on a SocketCAN interface at a fixed frame rate, on an absolute time schedule, in
 * batches of up to --batch frames per system call (sendmmsg), and reports what it sent.
 * The samples are a slow rotation about the vertical axis, stamped with their own
 * (simulated) sample clock, so the node has real work to do on every sample.
 *
 *   attekf-can-blast -i vcan0 --rate 20000 --duration 5 [--batch 32]
 *
 * prints one JSON object: frames, samples, failed sends, seconds, achieved frames/s.
 * Exit status 0, 1 (interface), 2 (usage).
 */
#define _GNU_SOURCE 1 /* sendmmsg, clock_nanosleep with -std=c99 */

#include <errno.h>
#include <inttypes.h>
#include <linux/can.h>
#include <math.h>
#include <net/if.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "hal.h"
#include "dbc.h"

#define MAX_BATCH 256

static uint64_t now_ns(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void usage(FILE *f)
{
    fprintf(f, "usage: attekf-can-blast -i IFACE --rate FRAMES_PER_S --duration S [--batch N]\n"
               "Sends IMU frames of firmware/app/dbc/attekf.dbc at a fixed rate (benchmark sender).\n");
}

/* Sample k of a slow rotation about z: level, 0.5 rad/s yaw rate, field north and down. */
static void make_sample(uint32_t k, double sample_rate, hal_sample_t *s)
{
    const double t = (double)k / sample_rate;
    const double yaw = 0.5 * t;
    memset(s, 0, sizeof(*s));
    s->seq = (uint16_t)(k & 0xFFFFu);
    s->t_us = (uint64_t)llround(t * 1e6);
    s->gyro[2] = 0.5f;
    s->accel[2] = 9.81f;
    s->mag[0] = (float)(25.0 * sin(yaw));
    s->mag[1] = (float)(25.0 * cos(yaw));
    s->mag[2] = -43.0f;
    s->valid = HAL_HAS_ALL;
}

int main(int argc, char **argv)
{
    const char *ifname = NULL;
    double rate = 0.0, duration = 0.0;
    long batch = 32;
    int i, fd;
    struct sockaddr_can addr;
    uint64_t sent = 0u, failed = 0u, total, t0, t_end;
    uint32_t k = 0u;
    hal_frame_t pend[DBC_SAMPLE_FRAMES];
    size_t pend_n = 0u, pend_i = 0u;
    static struct can_frame cf[MAX_BATCH];
    static struct iovec iov[MAX_BATCH];
    static struct mmsghdr mm[MAX_BATCH];

    for (i = 1; i < argc; ++i) {
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (strcmp(argv[i], "-h") == 0 || strcmp(argv[i], "--help") == 0) {
            usage(stdout);
            return 0;
        }
        if (v == NULL) {
            usage(stderr);
            return 2;
        }
        if (strcmp(argv[i], "-i") == 0) {
            ifname = v;
        } else if (strcmp(argv[i], "--rate") == 0) {
            rate = strtod(v, NULL);
        } else if (strcmp(argv[i], "--duration") == 0) {
            duration = strtod(v, NULL);
        } else if (strcmp(argv[i], "--batch") == 0) {
            batch = strtol(v, NULL, 10);
        } else {
            usage(stderr);
            return 2;
        }
        ++i;
    }
    if (ifname == NULL || !(rate >= 4.0 && rate <= 1e7) || !(duration > 0.0 && duration <= 3600.0) ||
        batch < 1 || batch > MAX_BATCH) {
        usage(stderr);
        return 2;
    }
    fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    memset(&addr, 0, sizeof(addr));
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)if_nametoindex(ifname);
    if (fd < 0 || addr.can_ifindex == 0 || bind(fd, (struct sockaddr *)&addr, sizeof(addr)) != 0) {
        fprintf(stderr, "attekf-can-blast: cannot open %s: %s\n", ifname, strerror(errno));
        return 1;
    }
    for (i = 0; i < MAX_BATCH; ++i) {
        iov[i].iov_base = &cf[i];
        iov[i].iov_len = sizeof(cf[i]);
        memset(&mm[i], 0, sizeof(mm[i]));
        mm[i].msg_hdr.msg_iov = &iov[i];
        mm[i].msg_hdr.msg_iovlen = 1;
    }
    total = (uint64_t)llround(rate * duration);
    t0 = now_ns();
    t_end = t0 + (uint64_t)llround(duration * 1e9);
    while (sent + failed < total) {
        /* Frames due by now on the schedule t0 + n / rate. */
        const uint64_t now = now_ns();
        uint64_t due = (uint64_t)((double)(now - t0) * 1e-9 * rate);
        uint64_t n;
        int j, r;
        if (due > total) {
            due = total;
        }
        if (due <= sent + failed) {
            /* Sleep until `batch` more frames are due (or the end). */
            struct timespec ts;
            uint64_t wake = t0 + (uint64_t)((double)(sent + failed + (uint64_t)batch) / rate * 1e9);
            if (wake > t_end) {
                wake = t_end;
            }
            ts.tv_sec = (time_t)(wake / 1000000000u);
            ts.tv_nsec = (long)(wake % 1000000000u);
            (void)clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
            continue;
        }
        n = due - sent - failed;
        if (n > (uint64_t)batch) {
            n = (uint64_t)batch;
        }
        for (j = 0; j < (int)n; ++j) {
            if (pend_i == pend_n) {
                hal_sample_t s;
                make_sample(k++, rate / 4.0, &s);
                pend_n = dbc_encode_sample(&s, pend);
                pend_i = 0u;
            }
            memset(&cf[j], 0, sizeof(cf[j]));
            cf[j].can_id = pend[pend_i].id;
            cf[j].can_dlc = pend[pend_i].dlc;
            memcpy(cf[j].data, pend[pend_i].data, 8u);
            ++pend_i;
        }
        r = sendmmsg(fd, mm, (unsigned)n, 0);
        if (r < 0) {
            /* ENOBUFS (transmit queue full) or worse: these frames are lost, which makes this
             * rate a failure of the benchmark; say why once. */
            if (failed == 0u) {
                fprintf(stderr, "attekf-can-blast: send: %s\n", strerror(errno));
            }
            failed += n;
            continue;
        }
        sent += (uint64_t)r;
        failed += n - (uint64_t)r;
    }
    {
        const double secs = (double)(now_ns() - t0) * 1e-9;
        printf("{\"frames\": %" PRIu64 ", \"samples\": %" PRIu32 ", \"failed\": %" PRIu64
               ", \"seconds\": %.6f, \"frames_per_s\": %.1f, \"target_frames_per_s\": %.1f}\n",
               sent, k, failed, secs, (double)sent / secs, rate);
    }
    close(fd);
    return 0;
}
