/*
 * hal_target.h - the HAL backend of the bare-metal firmware image (hal/include/hal.h).
 *
 * Under QEMU the "IMU" is a recording read through semihosting file I/O (newlib's stdio
 * on librdimon: fopen/fgets reach the host's files), and the attitude outputs are written
 * to another file. On a real board, read_sample would take samples from the IMU driver
 * (interrupt -> ring buffer) and publish would hand outputs to CAN/UART; the application
 * loop (firmware/app) is the same (docs/porting.md).
 *
 * The backend is plain C99 stdio, so the host builds it too: attekf-fw-host runs the very
 * same loop and backend over the same file, which is how the firmware's output is checked
 * against the host float build (firmware/target/check_equality.py).
 *
 * Input: a recording CSV as written by the host tools (host_tools/attekf/io.py): '#' comment
 * lines, a header naming the columns, one row per sample. Used columns (any order, others
 * ignored): t_s, gyr_{x,y,z}_rad_s, acc_{x,y,z}_m_s2, and optionally mag_{x,y,z}_uT (an empty
 * or nan cell: no magnetometer in that sample). Numbers are parsed in double precision and
 * rounded once to float, identically on every C library.
 *
 * Output: CSV t_s, roll_rad, pitch_rad, yaw_rad, sigma_{roll,pitch,yaw}_rad, rate_{p,q,r}_rad_s,
 * flags (ATT_FLAG_*), hal_flags (HAL_FLAG_*), seq: one row per attitude output, floats with
 * 9 significant digits (exact for a float); empty angle cells while not aligned. Heartbeat
 * outputs are counted, not written (they repeat the last estimate).
 *
 * Clock: simulated, like hal/virtual: read_sample delivers the next row if its time is
 * within the timeout and moves the clock there, else advances the clock by the timeout
 * (HAL_EMPTY). The run is therefore deterministic and independent of the emulator's speed.
 *
 * A malformed row ends the replay: read_sample reports it (stderr, with the line number),
 * returns HAL_ERR_IO once, then HAL_END; hal_target_errors() is then non-zero.
 */
#ifndef HAL_TARGET_H
#define HAL_TARGET_H

#include <stdint.h>
#include <stdio.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_TARGET_LINE_MAX 1024

typedef struct {
    FILE *in;
    FILE *out;
    const char *in_name;
    int col[10];            /* field index of t, gyr xyz, acc xyz, mag xyz; -1 if absent */
    unsigned long lineno;   /* line of the input last read */
    char line[HAL_TARGET_LINE_MAX];
    hal_sample_t next;      /* the row read ahead */
    uint8_t have_next;
    uint8_t eof;
    uint8_t failed;
    uint16_t seq;
    uint64_t now_us;
    uint32_t heartbeats;    /* heartbeat outputs (not written) */
    uint32_t written;       /* attitude rows written */
    uint32_t errors;        /* malformed input rows or output write failures */
    uint32_t counters[HAL_CNT_COUNT]; /* link-level counters (this backend: tx only) */
} hal_target_t;

/* Opens the recording (reads its header and first row) and creates the output file with
 * its header. HAL_OK, HAL_ERR_ARG (NULL) or HAL_ERR_IO (message on stderr). */
hal_status_t hal_target_open(hal_target_t *t, const char *recording, const char *output);

/* Fills *hal with this backend's operations. */
void hal_target_bind(hal_target_t *t, hal_t *hal);

/* Closes both files; HAL_ERR_IO if the output could not be written completely. */
hal_status_t hal_target_close(hal_target_t *t);

/* Malformed input rows plus output write failures since hal_target_open. */
uint32_t hal_target_errors(const hal_target_t *t);

#ifdef __cplusplus
}
#endif

#endif /* HAL_TARGET_H */
