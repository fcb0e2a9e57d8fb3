/*
 * hal_target.c - HAL backend of the firmware image: a recording and a command file in, the
 * application's lines out, over semihosting stdio (see hal_target.h).
 */
#include "hal_target.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Column order of hal_target_t.col. */
enum { COL_T = 0, COL_GYR = 1, COL_ACC = 4, COL_MAG = 7, COL_N = 10 };

static const char *const col_names[COL_N] = {
    "t_s",        "gyr_x_rad_s", "gyr_y_rad_s", "gyr_z_rad_s", "acc_x_m_s2",
    "acc_y_m_s2", "acc_z_m_s2",  "mag_x_uT",    "mag_y_uT",    "mag_z_uT",
};

#define MAX_FIELDS 64
/* Largest accepted time, s (31,700 years): t * 1e6 stays far inside uint64_t. */
#define T_MAX_S 1e12

static void fail_at(hal_target_t *t, const char *file, unsigned long line, const char *what, const char *detail)
{
    fprintf(stderr, "%s:%lu: %s%s%s\n", file, line, what, detail[0] ? ": " : "", detail);
    if (t->errors != UINT32_MAX) {
        ++t->errors;
    }
    t->failed = 1u;
}

static void fail(hal_target_t *t, const char *what, const char *detail)
{
    fail_at(t, t->in_name, t->lineno, what, detail);
}

/* Next line that is neither empty nor a comment, without its line break; 0 at the end of
 * the file. A line longer than the buffer is an error. */
static int next_line(hal_target_t *t)
{
    while (fgets(t->line, sizeof t->line, t->in) != NULL) {
        size_t len = strlen(t->line);
        ++t->lineno;
        if (len == sizeof t->line - 1u && t->line[len - 1u] != '\n' && !feof(t->in)) {
            fail(t, "line too long", "");
            return 0;
        }
        while (len > 0u && (t->line[len - 1u] == '\n' || t->line[len - 1u] == '\r')) {
            t->line[--len] = '\0';
        }
        if (len > 0u && t->line[0] != '#') {
            return 1;
        }
    }
    if (ferror(t->in)) {
        fail(t, "read error", "");
    }
    return 0;
}

/* Splits the line at commas in place, trimming spaces; returns the number of fields. */
static int split(char *line, char *fields[MAX_FIELDS])
{
    int n = 0;
    char *p = line;
    for (;;) {
        char *end = strchr(p, ',');
        char *q;
        if (n == MAX_FIELDS) {
            return -1;
        }
        if (end != NULL) {
            *end = '\0';
        }
        while (*p == ' ' || *p == '\t') {
            ++p;
        }
        q = p + strlen(p);
        while (q > p && (q[-1] == ' ' || q[-1] == '\t')) {
            *--q = '\0';
        }
        fields[n++] = p;
        if (end == NULL) {
            return n;
        }
        p = end + 1;
    }
}

/* A number cell: 1 and *v on success (nan/inf included), 0 for an empty cell, -1 if the
 * cell is not a number. Parsed as double, then rounded once to float. */
static int parse_cell(const char *s, double *v)
{
    char *end = NULL;
    if (s[0] == '\0') {
        return 0;
    }
    *v = strtod(s, &end);
    return (end != s && *end == '\0') ? 1 : -1;
}

static int read_header(hal_target_t *t)
{
    char *fields[MAX_FIELDS];
    int n, i, k;
    if (!next_line(t)) {
        if (!t->failed) {
            fail(t, "no header line", "");
        }
        return 0;
    }
    n = split(t->line, fields);
    if (n < 0) {
        fail(t, "too many columns", "");
        return 0;
    }
    for (k = 0; k < COL_N; ++k) {
        t->col[k] = -1;
        for (i = 0; i < n; ++i) {
            if (strcmp(fields[i], col_names[k]) == 0) {
                t->col[k] = i;
            }
        }
        if (k < COL_MAG && t->col[k] < 0) {
            fail(t, "header lacks column", col_names[k]);
            return 0;
        }
    }
    if ((t->col[COL_MAG] < 0) != (t->col[COL_MAG + 1] < 0) || (t->col[COL_MAG] < 0) != (t->col[COL_MAG + 2] < 0)) {
        fail(t, "header has some magnetometer columns but not all three", "");
        return 0;
    }
    return 1;
}

/* Reads the next row into t->next. 1: a sample; 0: end of file or a malformed row
 * (t->failed set, message printed). */
static int read_row(hal_target_t *t)
{
    char *fields[MAX_FIELDS];
    double v[COL_N];
    int n, k, mag_cells = 0;
    hal_sample_t *s = &t->next;

    if (!next_line(t)) {
        return 0;
    }
    n = split(t->line, fields);
    for (k = 0; k < COL_N; ++k) {
        int r;
        v[k] = NAN;
        if (t->col[k] < 0) {
            continue;
        }
        if (t->col[k] >= n) {
            fail(t, "missing field", col_names[k]);
            return 0;
        }
        r = parse_cell(fields[t->col[k]], &v[k]);
        if (r < 0) {
            fail(t, "not a number in column", col_names[k]);
            return 0;
        }
        if (r == 0 && k < COL_MAG) {
            fail(t, "empty cell in column", col_names[k]);
            return 0;
        }
        if (k >= COL_MAG && r == 1 && !isnan(v[k])) {
            ++mag_cells;
        }
    }
    if (!(v[COL_T] >= 0.0 && v[COL_T] <= T_MAX_S)) {
        fail(t, "t_s must be a time in 0..1e12 s", fields[t->col[COL_T]]);
        return 0;
    }
    if (mag_cells != 0 && mag_cells != 3) {
        fail(t, "magnetometer row partly empty (all three cells or none)", "");
        return 0;
    }
    memset(s, 0, sizeof *s);
    s->t_us = (uint64_t)(v[COL_T] * 1e6 + 0.5);
    s->rx_us = s->t_us;
    for (k = 0; k < 3; ++k) {
        /* gyro and accelerometer cells may hold nan/inf: passed on, the filter refuses
         * them with a status (that is the application's business, not the file's) */
        s->gyro[k] = (float)v[COL_GYR + k];
        s->accel[k] = (float)v[COL_ACC + k];
        s->mag[k] = (mag_cells == 3) ? (float)v[COL_MAG + k] : 0.0f;
    }
    s->valid = (uint8_t)(HAL_HAS_GYRO | HAL_HAS_ACCEL | (mag_cells == 3 ? HAL_HAS_MAG : 0u));
    s->seq = t->seq++;
    return 1;
}

/* Reads the next command into t->next_cmd: 1, or 0 at the end of the file or on a malformed
 * line (t->failed set, message printed). */
static int read_command(hal_target_t *t)
{
    char buf[HAL_TARGET_LINE_MAX];
    while (fgets(buf, sizeof buf, t->cmd) != NULL) {
        size_t len = strlen(buf);
        char *p = buf, *end = NULL;
        double ts;
        ++t->cmd_lineno;
        if (len == sizeof buf - 1u && buf[len - 1u] != '\n' && !feof(t->cmd)) {
            fail_at(t, t->cmd_name, t->cmd_lineno, "line too long", "");
            return 0;
        }
        while (len > 0u && (buf[len - 1u] == '\n' || buf[len - 1u] == '\r')) {
            buf[--len] = '\0';
        }
        while (*p == ' ' || *p == '\t') {
            ++p;
        }
        if (*p == '\0' || *p == '#') {
            continue;
        }
        ts = strtod(p, &end);
        if (end == p || !(ts >= 0.0 && ts <= T_MAX_S) || (*end != ' ' && *end != '\t')) {
            fail_at(t, t->cmd_name, t->cmd_lineno, "expected: T_S COMMAND (a time in 0..1e12 s, then the command)", "");
            return 0;
        }
        while (*end == ' ' || *end == '\t') {
            ++end;
        }
        len = strlen(end);
        if (len >= sizeof t->next_cmd.text) {
            fail_at(t, t->cmd_name, t->cmd_lineno, "command too long", "");
            return 0;
        }
        t->next_cmd.t_us = (uint64_t)(ts * 1e6 + 0.5);
        memcpy(t->next_cmd.text, end, len + 1u);
        return 1;
    }
    if (ferror(t->cmd)) {
        fail_at(t, t->cmd_name, t->cmd_lineno, "read error", "");
    }
    return 0;
}

static uint64_t op_now_us(void *ctx)
{
    return ((const hal_target_t *)ctx)->now_us;
}

/* Reads ahead what is missing of the next row and the next command. */
static void read_ahead(hal_target_t *t)
{
    if (!t->have_next && !t->eof) {
        t->have_next = (uint8_t)read_row(t);
        t->eof = (uint8_t)!t->have_next;
    }
    if (t->cmd != NULL && !t->have_cmd && !t->cmd_eof && !t->failed) {
        t->have_cmd = (uint8_t)read_command(t);
        t->cmd_eof = (uint8_t)!t->have_cmd;
    }
}

static hal_status_t op_receive(void *ctx, hal_input_t *in, uint32_t timeout_us)
{
    hal_target_t *t = ctx;
    int take_cmd;
    uint64_t due;
    if (in == NULL) {
        return HAL_ERR_ARG;
    }
    read_ahead(t);
    if (t->failed) {
        if (!t->failure_returned) {
            t->failure_returned = 1u;
            return HAL_ERR_IO; /* once; then HAL_END */
        }
        return HAL_END;
    }
    if (!t->have_next && !t->have_cmd) {
        return HAL_END;
    }
    /* a command goes before a sample of the same time */
    take_cmd = t->have_cmd && (!t->have_next || t->next_cmd.t_us <= t->next.rx_us);
    due = take_cmd ? t->next_cmd.t_us : t->next.rx_us;
    if (due > t->now_us + timeout_us) {
        t->now_us += timeout_us; /* "waited" the whole timeout */
        return HAL_EMPTY;
    }
    if (take_cmd) {
        in->kind = HAL_IN_LINE;
        in->u.line = t->next_cmd;
        t->have_cmd = 0u;
    } else {
        in->kind = HAL_IN_SAMPLE;
        in->u.sample = t->next;
        t->have_next = 0u;
    }
    if (due > t->now_us) {
        t->now_us = due;
    }
    hal_count(&t->stats.rx_frames);
    return HAL_OK;
}

static hal_status_t op_write_line(void *ctx, const char *text)
{
    hal_target_t *t = ctx;
    if (text == NULL) {
        return HAL_ERR_ARG;
    }
    if (fputs(text, t->out) == EOF || fputc('\n', t->out) == EOF) {
        hal_count(&t->stats.tx_errors);
        hal_count(&t->errors);
        return HAL_ERR_IO;
    }
    hal_count(&t->stats.tx_frames);
    return HAL_OK;
}

static void op_stats(void *ctx, hal_link_stats_t *s) { *s = ((const hal_target_t *)ctx)->stats; }

static void op_log(void *ctx, hal_level_t level, const char *event, int32_t detail)
{
    (void)ctx;
    if (level <= HAL_LOG_WARN) {
        fprintf(stderr, "%s: %s %ld\n", level == HAL_LOG_ERROR ? "error" : "warning", event, (long)detail);
    }
}

static const hal_ops_t target_ops = {op_now_us, op_receive, NULL, op_write_line, op_stats, op_log};

hal_status_t hal_target_open(hal_target_t *t, const char *recording, const char *output, const char *commands)
{
    if (t == NULL || recording == NULL || output == NULL) {
        return HAL_ERR_ARG;
    }
    memset(t, 0, sizeof *t);
    t->in_name = recording;
    t->in = fopen(recording, "r");
    if (t->in == NULL) {
        fprintf(stderr, "%s: cannot open\n", recording);
        return HAL_ERR_IO;
    }
    if (!read_header(t)) {
        fclose(t->in);
        t->in = NULL;
        return HAL_ERR_IO;
    }
    if (commands != NULL) {
        t->cmd_name = commands;
        t->cmd = fopen(commands, "r");
        if (t->cmd == NULL) {
            fprintf(stderr, "%s: cannot open\n", commands);
            fclose(t->in);
            t->in = NULL;
            return HAL_ERR_IO;
        }
    }
    t->out = fopen(output, "w");
    if (t->out == NULL) {
        fprintf(stderr, "%s: cannot create\n", output);
        fclose(t->in);
        t->in = NULL;
        if (t->cmd != NULL) {
            fclose(t->cmd);
            t->cmd = NULL;
        }
        return HAL_ERR_IO;
    }
    /* start the clock at the first sample, so the application does not see a silence
     * before the recording starts */
    read_ahead(t);
    if (t->have_next) {
        t->now_us = t->next.rx_us;
    }
    return HAL_OK;
}

void hal_target_bind(hal_target_t *t, hal_t *hal)
{
    hal->ops = &target_ops;
    hal->ctx = t;
}

hal_status_t hal_target_close(hal_target_t *t)
{
    hal_status_t st = HAL_OK;
    if (t == NULL) {
        return HAL_ERR_ARG;
    }
    if (t->out != NULL && fclose(t->out) != 0) {
        hal_count(&t->errors);
        st = HAL_ERR_IO;
    }
    if (t->in != NULL) {
        fclose(t->in);
    }
    if (t->cmd != NULL) {
        fclose(t->cmd);
    }
    t->in = NULL;
    t->cmd = NULL;
    t->out = NULL;
    return st;
}

uint32_t hal_target_errors(const hal_target_t *t)
{
    return t->errors;
}
