/*
 * hal_socketcan.c - Linux SocketCAN backend (hal_socketcan.h).
 */
#define _GNU_SOURCE 1 /* ppoll, recvmmsg, sendmmsg, if_nametoindex with -std=c99 */

#include "hal_socketcan.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

const hal_socketcan_config_t hal_socketcan_default_config = {
    .rcvbuf_bytes = 4u * 1024u * 1024u,
    .reopen_period_us = 100000u,
};

static uint64_t clock_us(clockid_t id)
{
    struct timespec ts;
    (void)clock_gettime(id, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

uint64_t hal_socketcan_now_us(void) { return clock_us(CLOCK_MONOTONIC); }

static void report(const hal_socketcan_t *c, hal_level_t level, const char *ev, int32_t detail)
{
    if (c->report != NULL) {
        c->report(c->report_user, level, ev, detail);
    }
}

static int open_socket(hal_socketcan_t *c)
{
    struct sockaddr_can addr;
    const int one = 1;
    int fd, ifindex;
    socklen_t len;

    ifindex = (int)if_nametoindex(c->ifname);
    if (ifindex == 0) {
        return -1; /* errno from if_nametoindex (ENODEV) */
    }
    fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd < 0) {
        return -1;
    }
    if (c->cfg.rcvbuf_bytes > 0u) {
        const int want = (int)c->cfg.rcvbuf_bytes;
        /* FORCE ignores net.core.rmem_max but needs CAP_NET_ADMIN; else the capped one. */
        if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &want, sizeof(want)) != 0) {
            (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &want, sizeof(want));
        }
    }
    len = sizeof(c->rcvbuf_actual);
    if (getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &c->rcvbuf_actual, &len) != 0) {
        c->rcvbuf_actual = 0;
    }
    if (setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one)) != 0 ||
        setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one)) != 0) {
        const int e = errno;
        (void)close(fd);
        errno = e;
        return -1;
    }
    memset(&addr, 0, sizeof(addr));
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifindex;
    if (bind(fd, (struct sockaddr *)&addr, sizeof(addr)) != 0 ||
        fcntl(fd, F_SETFL, fcntl(fd, F_GETFL, 0) | O_NONBLOCK) != 0) {
        const int e = errno;
        (void)close(fd);
        errno = e;
        return -1;
    }
    return fd;
}

hal_status_t hal_socketcan_open(hal_socketcan_t *c, const char *ifname,
                                const hal_socketcan_config_t *cfg,
                                hal_socketcan_report_fn report_fn, void *report_user)
{
    size_t n;
    if (c == NULL || ifname == NULL || cfg == NULL || cfg->reopen_period_us == 0u) {
        return HAL_ERR_ARG;
    }
    n = strlen(ifname);
    if (n == 0u || n >= HAL_SOCKETCAN_IFNAME_MAX) {
        return HAL_ERR_ARG;
    }
    memset(c, 0, sizeof(*c));
    memcpy(c->ifname, ifname, n + 1u);
    c->cfg = *cfg;
    c->report = report_fn;
    c->report_user = report_user;
    c->fd = open_socket(c);
    if (c->fd < 0) {
        return HAL_ERR_IO;
    }
    c->link_up = 1u;
    return HAL_OK;
}

void hal_socketcan_close(hal_socketcan_t *c)
{
    if (c != NULL && c->fd >= 0) {
        (void)close(c->fd);
        c->fd = -1;
    }
}

/* The link is gone (counted once per outage). close_it: the socket is useless (ENODEV...). */
static void link_lost(hal_socketcan_t *c, int err, int close_it)
{
    if (c->link_up) {
        c->link_up = 0u;
        c->down_returned = 0u;
        hal_count(&c->stats.link_down);
        report(c, HAL_LOG_WARN, "link_down", (int32_t)err);
    }
    if (close_it && c->fd >= 0) {
        (void)close(c->fd);
        c->fd = -1;
        c->next_reopen_us = hal_socketcan_now_us(); /* first retry at once */
    }
}

static void link_back(hal_socketcan_t *c)
{
    if (!c->link_up) {
        c->link_up = 1u;
        report(c, HAL_LOG_INFO, "link_up", 0);
    }
}

/* While down with the socket open: is the interface up and running again? */
static void check_interface(hal_socketcan_t *c, uint64_t now)
{
    struct ifreq ifr;
    if (c->link_up || c->fd < 0 || now < c->next_check_us) {
        return;
    }
    c->next_check_us = now + c->cfg.reopen_period_us;
    memset(&ifr, 0, sizeof(ifr));
    memcpy(ifr.ifr_name, c->ifname, sizeof(c->ifname) < sizeof(ifr.ifr_name) ? sizeof(c->ifname) : sizeof(ifr.ifr_name));
    if (ioctl(c->fd, SIOCGIFFLAGS, &ifr) == 0 && (ifr.ifr_flags & IFF_UP) != 0 &&
        (ifr.ifr_flags & IFF_RUNNING) != 0) {
        link_back(c);
    }
}

static void try_reopen(hal_socketcan_t *c, uint64_t now)
{
    if (c->fd >= 0 || now < c->next_reopen_us) {
        return;
    }
    c->next_reopen_us = now + c->cfg.reopen_period_us;
    c->fd = open_socket(c);
    if (c->fd >= 0) {
        c->kernel_drops = 0u; /* SO_RXQ_OVFL counts per socket */
        c->next_check_us = 0u;
        check_interface(c, now);
    }
}

/* The control message has a payload of `size` bytes inside the control buffer. */
static int cmsg_fits(const struct msghdr *msg, const struct cmsghdr *cm, size_t size)
{
    const unsigned char *end = (const unsigned char *)msg->msg_control + msg->msg_controllen;
    return cm->cmsg_len >= CMSG_LEN(size) && (size_t)(end - CMSG_DATA(cm)) >= size;
}

/* One message as recvmmsg returned it into the frame buffer (timestamp mapped to the
 * monotonic base). Everything in it is checked: this is the seam the fuzz target
 * tests/fuzz/fuzz_socketcan.c feeds without a kernel socket. */
int hal_socketcan_rx_msg(hal_socketcan_t *c, const struct can_frame *cf, size_t msg_len,
                         struct msghdr *msg, int64_t mono_minus_real)
{
    struct cmsghdr *cm;
    uint64_t ts_real_us = 0u;
    hal_frame_t *f;
    if (msg_len != sizeof(*cf) || c->rx_n >= HAL_SOCKETCAN_BATCH) {
        return 0; /* not a classic CAN frame (CAN FD is off), or no room (never: one batch) */
    }
    for (cm = CMSG_FIRSTHDR(msg); cm != NULL; cm = CMSG_NXTHDR(msg, cm)) {
        if (cm->cmsg_level != SOL_SOCKET) {
            continue;
        }
        if (cm->cmsg_type == SCM_TIMESTAMPNS && cmsg_fits(msg, cm, sizeof(struct timespec))) {
            struct timespec ts;
            memcpy(&ts, CMSG_DATA(cm), sizeof(ts));
            if (ts.tv_sec >= 0 && ts.tv_nsec >= 0 && ts.tv_nsec < 1000000000L) {
                ts_real_us = (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
            }
        } else if (cm->cmsg_type == SO_RXQ_OVFL && cmsg_fits(msg, cm, sizeof(uint32_t))) {
            /* Frames the kernel dropped on this socket so far (queue full). */
            uint32_t drops;
            memcpy(&drops, CMSG_DATA(cm), sizeof(drops));
            if (drops != c->kernel_drops) {
                const uint32_t lost = drops - c->kernel_drops;
                hal_count_n(&c->stats.rx_overflow, lost);
                report(c, HAL_LOG_WARN, "rx_overflow", (int32_t)(lost > INT32_MAX ? INT32_MAX : lost));
                c->kernel_drops = drops;
            }
        }
    }
    if ((cf->can_id & (CAN_RTR_FLAG | CAN_ERR_FLAG)) != 0u) {
        return 0; /* only data frames carry the protocol; error frames are not enabled */
    }
    f = &c->rxbuf[(c->rx_head + c->rx_n) % HAL_SOCKETCAN_BATCH];
    /* Unsigned arithmetic: a timestamp far from now must not overflow (it is then replaced). */
    {
        const uint64_t mono = ts_real_us + (uint64_t)mono_minus_real; /* mod 2^64 */
        if (ts_real_us != 0u && mono != 0u && mono < ((uint64_t)1 << 62) &&
            (mono_minus_real >= 0 ? mono >= ts_real_us : mono < ts_real_us)) {
            f->t_us = mono;
        } else {
            f->t_us = hal_socketcan_now_us(); /* no usable timestamp: now is the best estimate */
        }
    }
    f->id = (cf->can_id & CAN_EFF_FLAG) ? (cf->can_id & CAN_EFF_MASK) | HAL_FRAME_EXT : cf->can_id & CAN_SFF_MASK;
    f->dlc = cf->can_dlc; /* > 8 is refused by the protocol that takes the id */
    memcpy(f->data, cf->data, 8u);
    ++c->rx_n;
    return 1;
}

/* Reads up to HAL_SOCKETCAN_BATCH queued frames with one recvmmsg call into the (empty)
 * frame buffer. Returns 0, or -1 if the link failed (already handled). */
static int fill(hal_socketcan_t *c)
{
    struct can_frame cf[HAL_SOCKETCAN_BATCH];
    struct iovec iov[HAL_SOCKETCAN_BATCH];
    struct mmsghdr mm[HAL_SOCKETCAN_BATCH];
    union {
        char buf[CMSG_SPACE(sizeof(struct timespec)) + CMSG_SPACE(sizeof(uint32_t))];
        size_t align; /* cmsghdr alignment */
    } ctrl[HAL_SOCKETCAN_BATCH];
    /* Kernel timestamps are CLOCK_REALTIME: map them to the monotonic base with one offset
     * per call (clock_gettime is a real system call on some machines, e.g. user-mode Linux). */
    const int64_t mono_minus_real = (int64_t)hal_socketcan_now_us() - (int64_t)clock_us(CLOCK_REALTIME);
    int i, n;

    memset(mm, 0, sizeof(mm));
    for (i = 0; i < HAL_SOCKETCAN_BATCH; ++i) {
        iov[i].iov_base = &cf[i];
        iov[i].iov_len = sizeof(cf[i]);
        mm[i].msg_hdr.msg_iov = &iov[i];
        mm[i].msg_hdr.msg_iovlen = 1;
        mm[i].msg_hdr.msg_control = ctrl[i].buf;
        mm[i].msg_hdr.msg_controllen = sizeof(ctrl[i].buf);
    }
    c->rx_head = 0u;
    c->rx_n = 0u;
    n = recvmmsg(c->fd, mm, HAL_SOCKETCAN_BATCH, MSG_DONTWAIT, NULL);
    if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) {
            return 0;
        }
        /* ENETDOWN: interface down, socket still bound (frames flow when it is up). */
        link_lost(c, errno, errno != ENETDOWN);
        return -1;
    }
    if (n > 0 && !c->link_up) {
        /* Frames queued before an outage are still delivered after the one ENETDOWN
         * report: data alone does not prove the link is back, the interface flags do. */
        c->next_check_us = 0u;
        check_interface(c, hal_socketcan_now_us());
    }
    for (i = 0; i < n; ++i) {
        (void)hal_socketcan_rx_msg(c, &cf[i], mm[i].msg_len, &mm[i].msg_hdr, mono_minus_real);
    }
    return 0;
}

static uint64_t op_now(void *ctx)
{
    (void)ctx;
    return hal_socketcan_now_us();
}

static hal_status_t op_receive(void *ctx, hal_input_t *in, uint32_t timeout_us)
{
    hal_socketcan_t *c = (hal_socketcan_t *)ctx;
    const uint64_t deadline = hal_socketcan_now_us() + timeout_us;
    if (in == NULL) {
        return HAL_ERR_ARG;
    }
    for (;;) {
        uint64_t now;
        struct pollfd p;
        struct timespec wait;
        uint64_t left;
        int r;

        if (c->rx_n > 0u) {
            in->kind = HAL_IN_FRAME;
            in->u.frame = c->rxbuf[c->rx_head];
            c->rx_head = (uint16_t)((c->rx_head + 1u) % HAL_SOCKETCAN_BATCH);
            --c->rx_n;
            hal_count(&c->stats.rx_frames);
            return HAL_OK;
        }
        if (c->fd >= 0 && fill(c) == 0 && c->rx_n > 0u) {
            continue; /* frames were waiting: no need to sleep */
        }
        now = hal_socketcan_now_us();
        try_reopen(c, now);
        check_interface(c, now);
        if (!c->link_up && !c->down_returned) {
            c->down_returned = 1u;
            return HAL_ERR_LINK_DOWN;
        }
        if (now >= deadline) {
            return HAL_EMPTY;
        }
        left = deadline - now;
        if (!c->link_up && left > c->cfg.reopen_period_us) {
            left = c->cfg.reopen_period_us; /* wake up to look at the interface */
        }
        wait.tv_sec = (time_t)(left / 1000000u);
        wait.tv_nsec = (long)((left % 1000000u) * 1000u);
        if (c->fd < 0) {
            (void)nanosleep(&wait, NULL);
            continue;
        }
        p.fd = c->fd;
        p.events = POLLIN;
        p.revents = 0;
        r = ppoll(&p, 1, &wait, NULL);
        if (r < 0) {
            if (errno == EINTR) {
                return HAL_EMPTY; /* a signal: let the caller look at its stop flag */
            }
            link_lost(c, errno, 1);
            continue;
        }
        /* readable (or timed out): the top of the loop reads */
    }
}

/* A failed send of `failed` frames: counted, the link's state updated. */
static hal_status_t send_failed(hal_socketcan_t *c, size_t failed, int err)
{
    hal_count_n(&c->stats.tx_errors, (uint32_t)failed);
    if (err == ENETDOWN || err == ENODEV || err == ENXIO) {
        link_lost(c, err, err != ENETDOWN);
        return HAL_ERR_LINK_DOWN;
    }
    /* ENOBUFS: the interface's transmit queue is full (a slow real bus). */
    report(c, HAL_LOG_DEBUG, "tx_error", (int32_t)err);
    return HAL_ERR_IO;
}

#define SEND_BATCH 16u /* frames per sendmmsg call */

static hal_status_t op_send_frames(void *ctx, const hal_frame_t *frames, size_t n)
{
    hal_socketcan_t *c = (hal_socketcan_t *)ctx;
    size_t done = 0;
    if (frames == NULL && n > 0u) {
        return HAL_ERR_ARG;
    }
    while (done < n) {
        struct can_frame cf[SEND_BATCH];
        struct iovec iov[SEND_BATCH];
        struct mmsghdr mm[SEND_BATCH];
        size_t k = n - done; /* > 0 */
        size_t i;
        int sent;
        if (c->fd < 0) {
            hal_count_n(&c->stats.tx_errors, (uint32_t)(n - done));
            return HAL_ERR_LINK_DOWN;
        }
        if (k > SEND_BATCH) {
            k = SEND_BATCH;
        }
        memset(mm, 0, sizeof(mm));
        for (i = 0; i < k; ++i) {
            const hal_frame_t *f = &frames[done + i];
            memset(&cf[i], 0, sizeof(cf[i]));
            cf[i].can_id = (f->id & HAL_FRAME_EXT) ? (f->id & CAN_EFF_MASK) | CAN_EFF_FLAG : f->id & CAN_SFF_MASK;
            cf[i].can_dlc = (f->dlc > 8u) ? 8u : f->dlc;
            memcpy(cf[i].data, f->data, 8u);
            iov[i].iov_base = &cf[i];
            iov[i].iov_len = sizeof(cf[i]);
            mm[i].msg_hdr.msg_iov = &iov[i];
            mm[i].msg_hdr.msg_iovlen = 1;
        }
        sent = sendmmsg(c->fd, mm, (unsigned)k, MSG_DONTWAIT);
        if (sent <= 0) {
            return send_failed(c, n - done, sent < 0 ? errno : EIO);
        }
        hal_count_n(&c->stats.tx_frames, (uint32_t)sent);
        done += (size_t)sent;
    }
    return HAL_OK;
}

static void op_stats(void *ctx, hal_link_stats_t *s) { *s = ((const hal_socketcan_t *)ctx)->stats; }

static void op_log(void *ctx, hal_level_t level, const char *event, int32_t detail)
{
    report((const hal_socketcan_t *)ctx, level, event, detail);
}

static const hal_ops_t socketcan_ops = {
    op_now, op_receive, op_send_frames, NULL, op_stats, op_log,
};

void hal_socketcan_bind(hal_socketcan_t *c, hal_t *hal)
{
    hal->ops = &socketcan_ops;
    hal->ctx = c;
}
