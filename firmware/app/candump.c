/*
 * candump.c - candump log lines (see candump.h). Hand-written digit loops instead of
 * strtoul/strtoull: those accept signs, "0x" and leading blanks, and wrap a negative
 * number to a huge one.
 */
#include "candump.h"

#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#define EFF_FLAG HAL_FRAME_EXT
#define SEC_MAX 18446744073709ull /* UINT64_MAX / 10^6: a larger second has no 64-bit time */

static int hexval(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

static int is_end(char c)
{
    return c == '\0' || c == '\n' || c == '\r';
}

candump_result_t candump_parse_line(const char *line, hal_frame_t *frame)
{
    const char *p = line;
    uint64_t sec = 0u, usec = 0u;
    uint32_t id = 0u;
    int k, digits;

    if (line == NULL || frame == NULL) {
        return CANDUMP_BAD;
    }
    while (*p == ' ' || *p == '\t') ++p;
    if (is_end(*p) || *p == '#') {
        return CANDUMP_SKIP;
    }
    /* (SECONDS.MICROSECONDS) */
    if (*p++ != '(') return CANDUMP_BAD;
    for (digits = 0; *p >= '0' && *p <= '9'; ++p, ++digits) {
        if (sec > SEC_MAX / 10u) return CANDUMP_BAD;
        sec = sec * 10u + (uint64_t)(*p - '0');
    }
    if (digits == 0 || sec > SEC_MAX || *p++ != '.') return CANDUMP_BAD;
    for (k = 0; k < 6; ++k, ++p) {
        if (*p < '0' || *p > '9') return CANDUMP_BAD;
        usec = usec * 10u + (uint64_t)(*p - '0');
    }
    if (sec > (UINT64_MAX - usec) / 1000000u) return CANDUMP_BAD; /* beyond 2^64 - 1 us */
    while (*p >= '0' && *p <= '9') ++p; /* finer than microseconds: dropped */
    if (*p++ != ')') return CANDUMP_BAD;
    /* CHANNEL (any run of non-blanks) */
    if (*p != ' ') return CANDUMP_BAD;
    while (*p == ' ') ++p;
    if (is_end(*p)) return CANDUMP_BAD;
    while (*p != ' ' && !is_end(*p)) ++p;
    while (*p == ' ') ++p;
    /* ID# */
    for (digits = 0; hexval(*p) >= 0; ++p, ++digits) {
        if (digits == 8) return CANDUMP_BAD;
        id = id * 16u + (uint32_t)hexval(*p);
    }
    if (digits == 0 || *p++ != '#') return CANDUMP_BAD;
    if (digits <= 3) {
        if (id > 0x7FFu) return CANDUMP_BAD;
    } else {
        if (id > 0x1FFFFFFFu) return CANDUMP_BAD;
        id |= EFF_FLAG;
    }
    if (*p == 'R' || *p == '#') {
        return CANDUMP_SKIP; /* remote or CAN FD frame: not ours */
    }
    /* HEXDATA */
    memset(frame->data, 0, sizeof(frame->data));
    for (k = 0; hexval(p[0]) >= 0 && hexval(p[1]) >= 0; ++k, p += 2) {
        if (k == 8) return CANDUMP_BAD;
        frame->data[k] = (uint8_t)(hexval(p[0]) * 16 + hexval(p[1]));
    }
    if (!is_end(*p) && *p != ' ') return CANDUMP_BAD; /* an odd digit or a stray character */
    frame->t_us = sec * 1000000u + usec;
    frame->id = id;
    frame->dlc = (uint8_t)k;
    return CANDUMP_FRAME;
}

int candump_format_line(const hal_frame_t *frame, const char *channel, char *buf, size_t size)
{
    uint32_t raw;
    int eff, n, i;

    if (frame == NULL || channel == NULL || buf == NULL || size == 0u) {
        return -1;
    }
    raw = frame->id & ~EFF_FLAG;
    eff = (frame->id & EFF_FLAG) != 0u;
    if (frame->dlc > 8u || raw > (eff ? 0x1FFFFFFFu : 0x7FFu) || channel[0] == '\0' ||
        strpbrk(channel, " \t\r\n") != NULL) {
        return -1;
    }
    n = snprintf(buf, size, "(%" PRIu64 ".%06" PRIu64 ") %s %0*" PRIX32 "#", frame->t_us / 1000000u,
                 frame->t_us % 1000000u, channel, eff ? 8 : 3, raw);
    if (n < 0 || (size_t)n >= size) {
        return -1;
    }
    for (i = 0; i < frame->dlc; ++i) {
        if ((size_t)n + 3u > size) {
            return -1;
        }
        n += snprintf(buf + n, size - (size_t)n, "%02X", frame->data[i]);
    }
    if ((size_t)n + 2u > size) {
        return -1;
    }
    buf[n++] = '\n';
    buf[n] = '\0';
    return n;
}
