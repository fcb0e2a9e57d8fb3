/*
 * hal_socketcan.h - Linux SocketCAN backend of the HAL (PF_CAN, SOCK_RAW, CAN_RAW): CAN frames
 * in and out, 11-bit and 29-bit ids, whatever protocol they carry.
 *
 * One raw socket on the named interface (can0, vcan0, ...), non-blocking, waited on with
 * ppoll and read in batches (recvmmsg); every frame carries the kernel's receive timestamp
 * (SO_TIMESTAMPNS), converted to the backend's CLOCK_MONOTONIC time base. Frames are sent in
 * batches too (sendmmsg). Kernel-side drops (socket queue full) are read from SO_RXQ_OVFL and
 * counted (rx_overflow); the receive buffer is enlarged (SO_RCVBUFFORCE when allowed, else
 * SO_RCVBUF) because a burst of frames otherwise overflows the default 208 KiB.
 *
 * Link loss: ENETDOWN on the socket (interface set down) is counted once and reported; the
 * socket stays bound and frames flow again when the interface comes back up. ENODEV or any
 * other socket failure (interface deleted) closes the socket; it is re-opened by name every
 * reopen_period_us until that works. The process never has to restart.
 */
#ifndef HAL_SOCKETCAN_H
#define HAL_SOCKETCAN_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_SOCKETCAN_IFNAME_MAX 16 /* IFNAMSIZ, with the terminating NUL */
#define HAL_SOCKETCAN_BATCH 32      /* frames read per system call (recvmmsg) */

/* Events: "link_down" (errno), "link_up", "rx_overflow" (frames lost), "tx_error" (errno). */
typedef void (*hal_socketcan_report_fn)(void *user, hal_level_t level, const char *event, int32_t detail);

typedef struct {
    uint32_t rcvbuf_bytes;     /* receive buffer asked for, bytes (0: kernel default) */
    uint32_t reopen_period_us; /* retry period while the socket is closed, us, > 0 */
} hal_socketcan_config_t;

/* 4 MiB receive buffer, retry every 100 ms. */
extern const hal_socketcan_config_t hal_socketcan_default_config;

typedef struct {
    char ifname[HAL_SOCKETCAN_IFNAME_MAX];
    hal_socketcan_config_t cfg;
    int fd;                   /* -1 while closed */
    uint8_t link_up;
    uint8_t down_returned;    /* HAL_ERR_LINK_DOWN already returned for this outage */
    uint32_t kernel_drops;    /* last SO_RXQ_OVFL value seen on this socket */
    uint64_t next_reopen_us;
    uint64_t next_check_us;   /* next interface-flags check while down */
    int rcvbuf_actual;        /* bytes the kernel granted (0 if unknown) */
    hal_frame_t rxbuf[HAL_SOCKETCAN_BATCH]; /* read, not yet delivered */
    uint16_t rx_head;
    uint16_t rx_n;
    hal_link_stats_t stats;
    hal_socketcan_report_fn report;
    void *report_user;
} hal_socketcan_t;

/* Opens and binds the socket. HAL_ERR_ARG (bad name or config), HAL_ERR_IO with errno set
 * (no such interface, no PF_CAN in this kernel, ...): the caller decides whether to give up. */
hal_status_t hal_socketcan_open(hal_socketcan_t *c, const char *ifname,
                                const hal_socketcan_config_t *cfg,
                                hal_socketcan_report_fn report, void *report_user);

void hal_socketcan_close(hal_socketcan_t *c);

/* Fills *hal with this backend's operations. */
void hal_socketcan_bind(hal_socketcan_t *c, hal_t *hal);

/* CLOCK_MONOTONIC, us: the time base of this backend (now_us, sample rx_us). */
uint64_t hal_socketcan_now_us(void);

/* The receive path below the socket (used by receive; public as the seam the fuzz
 * target tests/fuzz/fuzz_socketcan.c feeds raw frames through, no kernel CAN needed): one
 * message as recvmmsg returned it, msg_len bytes of *cf with msg's control messages
 * (SCM_TIMESTAMPNS, SO_RXQ_OVFL), into the frame buffer receive delivers from.
 * mono_minus_real: CLOCK_MONOTONIC - CLOCK_REALTIME, us. Returns 1 if a frame was
 * buffered, 0 if the message was not a classic data frame (or the buffer is full). */
struct can_frame;
struct msghdr;
int hal_socketcan_rx_msg(hal_socketcan_t *c, const struct can_frame *cf, size_t msg_len,
                         struct msghdr *msg, int64_t mono_minus_real);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SOCKETCAN_H */
