/*
 * hal_target.h - the HAL backend of the bare-metal firmware image (hal/include/hal.h).
 *
 * Under QEMU the "IMU" is a recording read through semihosting file I/O (newlib's stdio
 * on librdimon: fopen/fgets reach the host's files), the node's commands come from an optional
 * command file, and the lines the node writes (its text protocol: CSV outputs, replies) go to
 * another file. On a real board, receive would take samples from the IMU driver (interrupt ->
 * ring buffer) and command lines from a UART, and write_line would go to the UART (or the board
 * would use a CAN backend); the application loop (firmware/app) is the same (docs/porting.md).
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
 * Commands (optional file): one per line, "T_S COMMAND", delivered when the recording's clock
 * reaches T_S (before a sample of the same time); '#' comment lines and blank lines are
 * skipped. The commands are the application's text protocol (firmware/app/app_text.c:
 * get, set, list, save, erase, restart).
 *
 * Output: every line the application writes (app_text.c: a CSV row per attitude output, "# "
 * replies to commands).
 *
 * Clock: simulated, like hal/virtual: receive delivers the next row or command if its time is
 * within the timeout and moves the clock there, else advances the clock by the timeout
 * (HAL_EMPTY). The run is therefore deterministic and independent of the emulator's speed.
 *
 * A malformed row or command line ends the replay: receive reports it (stderr, with the file
 * and line number), returns HAL_ERR_IO once, then HAL_END; hal_target_errors() is then non-zero.
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
    FILE *cmd;              /* command file, or NULL */
    const char *in_name;
    const char *cmd_name;
    int col[10];            /* field index of t, gyr xyz, acc xyz, mag xyz; -1 if absent */
    unsigned long lineno;   /* line of the recording last read */
    unsigned long cmd_lineno; /* line of the command file last read */
    char line[HAL_TARGET_LINE_MAX];
    hal_sample_t next;      /* the row read ahead */
    hal_line_t next_cmd;    /* the command read ahead */
    uint8_t have_next;
    uint8_t have_cmd;
    uint8_t eof;
    uint8_t cmd_eof;
    uint8_t failed;
    uint8_t failure_returned;
    uint16_t seq;
    uint64_t now_us;
    uint32_t errors;        /* malformed input lines or output write failures */
    hal_link_stats_t stats; /* rows and commands in, lines out */
} hal_target_t;

/* Opens the recording (reads its header and first row), the command file if commands is not
 * NULL (reads its first command), and creates the output file. HAL_OK, HAL_ERR_ARG (NULL) or
 * HAL_ERR_IO (message on stderr). */
hal_status_t hal_target_open(hal_target_t *t, const char *recording, const char *output, const char *commands);

/* Fills *hal with this backend's operations. */
void hal_target_bind(hal_target_t *t, hal_t *hal);

/* Closes the files; HAL_ERR_IO if the output could not be written completely. */
hal_status_t hal_target_close(hal_target_t *t);

/* Malformed input lines plus output write failures since hal_target_open. */
uint32_t hal_target_errors(const hal_target_t *t);

#ifdef __cplusplus
}
#endif

#endif /* HAL_TARGET_H */
