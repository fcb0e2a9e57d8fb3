/*
 * fuzz_socketcan.c - libFuzzer target: the SocketCAN backend's receive path
 * (hal/socketcan/hal_socketcan.c) fed raw messages as recvmmsg would return them, without a
 * kernel CAN socket: hal_socketcan_rx_msg() takes the received struct can_frame bytes,
 * their length and the control messages (SCM_TIMESTAMPNS receive time, SO_RXQ_OVFL drop
 * count; both with fuzzed contents and lengths), and the backend's own receive, send_frames
 * and get_stats operations run on what was buffered.
 *
 * The backend is "opened" on an interface that does not exist (as when the node starts
 * before its interface): the socket stays closed, the reopen period is long, so no system
 * call but clock_gettime runs while fuzzing.
 *
 * Invariants: no crash or undefined behaviour; a frame is buffered only if it is a classic
 * data frame (16 bytes, no RTR/ERR flag); receive returns only the statuses of hal.h and
 * delivers every buffered frame once, in order, with an 11-bit id or a 29-bit id marked
 * HAL_FRAME_EXT; frame receive times within [0, 2^62) us; rx_frames equals the frames
 * buffered; the overflow counter equals the (saturating) sum of the increments of the kernel's
 * drop count.
 */
#define _GNU_SOURCE 1

#include <linux/can.h>
#include <linux/can/raw.h>
#include <sys/socket.h>
#include <time.h>

#include "fuzz_common.h"
#include "hal_socketcan.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const uint32_t ids[] = {0x100u, 0x101u, 0x102u, 0x103u, 0x103u, 0x7FFu, 0x180u, 0x0u};

static void on_report(void *user, hal_level_t level, const char *event, int32_t detail)
{
    (void)user;
    (void)detail;
    FZ_CHECK((int)level >= HAL_LOG_ERROR && (int)level <= HAL_LOG_DEBUG, "level %d", (int)level);
    FZ_CHECK(event != NULL && event[0] != '\0', "event name");
}

static void check_frame(const hal_frame_t *f)
{
    FZ_CHECK((f->id & HAL_FRAME_EXT) ? (f->id & ~HAL_FRAME_EXT) <= 0x1FFFFFFFu : f->id <= 0x7FFu, "id 0x%x",
             (unsigned)f->id);
    FZ_CHECK(f->t_us < ((uint64_t)1 << 62), "t_us %llu", (unsigned long long)f->t_us);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static hal_socketcan_t c;
    hal_socketcan_config_t cfg = hal_socketcan_default_config;
    hal_t hal;
    fz_t z = {data, size};
    uint32_t buffered = 0u, drops_prev = 0u;
    uint64_t overflow = 0u;
    int rounds = 0;

    cfg.reopen_period_us = UINT32_MAX; /* one reopen attempt per input at most */
    FZ_CHECK(hal_socketcan_open(&c, "fuzz-no-if0", &cfg, on_report, NULL) == HAL_ERR_IO, "open");
    c.link_up = 1u; /* as after an interface that was up: receive just reads the buffer */
    hal_socketcan_bind(&c, &hal);

    while (fz_more(&z) && rounds++ < 64) {
        const unsigned batch = 1u + fz_u8(&z) % HAL_SOCKETCAN_BATCH;
        const uint8_t mm = fz_u8(&z);
        int64_t mono_minus_real = -(int64_t)fz_u32(&z) * 1000; /* CLOCK_MONOTONIC behind REALTIME */
        unsigned i;
        hal_input_t in;
        hal_status_t st;
        hal_link_stats_t stats;
        uint32_t delivered = 0u;
        int polls = 0;

        if (mm & 1u) { /* anything */
            mono_minus_real = (int64_t)(((uint64_t)fz_u32(&z) << 32) | fz_u32(&z));
        }
        c.rx_head = 0u; /* as fill() does before each recvmmsg */
        c.rx_n = 0u;
        for (i = 0; i < batch && fz_more(&z); ++i) {
            struct can_frame cf;
            union {
                char buf[2 * CMSG_SPACE(sizeof(struct timespec)) + CMSG_SPACE(sizeof(uint32_t))];
                struct cmsghdr align;
            } ctrl;
            struct msghdr msg;
            struct cmsghdr *cm;
            const uint8_t shape = fz_u8(&z);
            size_t msg_len = sizeof(cf);
            int r, well_formed = 1;

            memset(&cf, 0, sizeof(cf));
            if (shape & 1u) {
                fz_bytes(&z, &cf, sizeof(cf)); /* anything: flags, DLC > 8, padding */
            } else {
                cf.can_id = ids[(shape >> 1) & 7u];
                cf.can_dlc = 8u;
                fz_bytes(&z, cf.data, 8u);
            }
            if ((shape & 0x30u) == 0x30u) {
                msg_len = fz_u8(&z) % 80u; /* CAN FD (72) or short reads */
            }
            memset(&ctrl, 0, sizeof(ctrl));
            memset(&msg, 0, sizeof(msg));
            msg.msg_control = ctrl.buf;
            msg.msg_controllen = sizeof(ctrl.buf);
            cm = CMSG_FIRSTHDR(&msg);
            if (shape & 0x40u) { /* receive time */
                struct timespec ts;
                cm->cmsg_level = SOL_SOCKET;
                cm->cmsg_type = SCM_TIMESTAMPNS;
                cm->cmsg_len = CMSG_LEN(sizeof(ts));
                if ((fz_u8(&z) & 0x0Fu) == 0u) {
                    cm->cmsg_len = (size_t)fz_u8(&z); /* malformed length */
                    well_formed = 0;
                }
                if (fz_u8(&z) & 1u) {
                    const uint64_t hi = fz_u32(&z);
                    ts.tv_sec = (time_t)(int64_t)((hi << 32) | fz_u32(&z));
                    ts.tv_nsec = (long)(int32_t)fz_u32(&z);
                } else {
                    ts.tv_sec = (time_t)(1700000000 + fz_u16(&z));
                    ts.tv_nsec = (long)(fz_u32(&z) % 1000000000u);
                }
                memcpy(CMSG_DATA(cm), &ts, sizeof(ts));
                cm = CMSG_NXTHDR(&msg, cm);
            }
            if (cm != NULL && well_formed && (shape & 0x80u)) { /* kernel drop count */
                uint32_t drops = drops_prev + (fz_u8(&z) & 1u ? fz_u32(&z) : fz_u8(&z));
                cm->cmsg_level = SOL_SOCKET;
                cm->cmsg_type = SO_RXQ_OVFL;
                cm->cmsg_len = CMSG_LEN(sizeof(drops));
                memcpy(CMSG_DATA(cm), &drops, sizeof(drops));
                if (msg_len == sizeof(cf)) { /* read only from frames of the right size */
                    overflow += (uint32_t)(drops - drops_prev);
                    drops_prev = drops;
                }
            } else if (fz_u8(&z) == 0xA5u) {
                msg.msg_controllen = fz_u8(&z) % sizeof(ctrl.buf); /* truncated control data */
            }
            r = hal_socketcan_rx_msg(&c, &cf, msg_len, &msg, mono_minus_real);
            FZ_CHECK(r == 0 || r == 1, "rx_msg %d", r);
            FZ_CHECK(r == (msg_len == sizeof(cf) && (cf.can_id & (CAN_RTR_FLAG | CAN_ERR_FLAG)) == 0u), "accepted");
            if (r) {
                const hal_frame_t *f = &c.rxbuf[(c.rx_head + c.rx_n - 1u) % HAL_SOCKETCAN_BATCH];
                FZ_CHECK(f->t_us < ((uint64_t)1 << 62), "t_us %llu", (unsigned long long)f->t_us);
                ++buffered;
            }
        }
        do {
            st = hal.ops->receive(hal.ctx, &in, 0u);
            FZ_CHECK(st == HAL_OK || st == HAL_EMPTY || st == HAL_ERR_LINK_DOWN, "receive %d", (int)st);
            if (st == HAL_OK) {
                FZ_CHECK(in.kind == HAL_IN_FRAME, "kind %u", (unsigned)in.kind);
                check_frame(&in.u.frame);
                ++delivered;
            }
        } while (st == HAL_OK && ++polls < 1000);
        FZ_CHECK(c.rx_n == 0u, "frames left in the buffer: %u", c.rx_n);
        hal.ops->get_stats(hal.ctx, &stats);
        FZ_CHECK(stats.rx_frames == buffered, "rx_frames %u buffered %u", (unsigned)stats.rx_frames, (unsigned)buffered);
        FZ_CHECK(delivered <= buffered, "delivered %u of %u", (unsigned)delivered, (unsigned)buffered);
        FZ_CHECK(stats.rx_overflow == (overflow > UINT32_MAX ? UINT32_MAX : (uint32_t)overflow),
                 "rx_overflow %u expected %llu", (unsigned)stats.rx_overflow, (unsigned long long)overflow);
        if (fz_u8(&z) == 0x5Au) { /* send while the socket is closed: counted, not sent */
            hal_frame_t f;
            const uint32_t before = stats.tx_errors;
            memset(&f, 0, sizeof(f));
            FZ_CHECK(hal.ops->send_frames(hal.ctx, &f, 1u) == HAL_ERR_LINK_DOWN, "send");
            hal.ops->get_stats(hal.ctx, &stats);
            FZ_CHECK(stats.tx_errors == before + 1u || before == UINT32_MAX, "tx_errors");
        }
    }
    hal_socketcan_close(&c);
    return 0;
}
