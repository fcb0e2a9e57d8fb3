/*
 * candump.h - one line of a candump log, the text format of `candump -L` and of
 * python-can's .log writer, which attekf-node replays and writes (docs/hil.md):
 *
 *     (SECONDS.MICROSECONDS) CHANNEL ID#HEXDATA
 *
 * ID: 3 hex digits (or fewer) for an 11-bit frame, 4 to 8 for a 29-bit one (candump writes
 * 3 and 8); HEXDATA: 0 to 8 bytes, two hex digits each. Remote ("ID#R") and CAN FD
 * ("ID##...") frames are skipped; so are blank lines and lines starting with '#'.
 * Fuzzed by tests/fuzz/fuzz_candump.c.
 */
#ifndef CANDUMP_H
#define CANDUMP_H

#include <stddef.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    CANDUMP_BAD = -1,  /* not a candump line (or a value out of range): frame unspecified */
    CANDUMP_SKIP = 0,  /* blank, comment, remote or CAN FD frame: nothing for us */
    CANDUMP_FRAME = 1  /* *frame holds a classic data frame */
} candump_result_t;

/* Parses one NUL-terminated line (a trailing "\n" or "\r\n" is allowed). The time
 * becomes frame->t_us (us); a 29-bit id gets bit 31 set, as in hal_frame_t. */
candump_result_t candump_parse_line(const char *line, hal_frame_t *frame);

/* Writes the line for frame (with "\n") into buf of size bytes, NUL-terminated. Returns
 * the characters written without the NUL, or -1 if they do not fit or the frame cannot be
 * written (dlc > 8, id out of range, a channel name with a space). */
int candump_format_line(const hal_frame_t *frame, const char *channel, char *buf, size_t size);

#ifdef __cplusplus
}
#endif

#endif /* CANDUMP_H */
