/*
 * app_text.c - the node's text protocol, for a backend with a text channel (a console, the
 * firmware's semihosting files): one CSV line per attitude output, and commands in, each
 * answered with a comment line ("# ...") on the same channel:
 *
 *   get NAME | set NAME VALUE | list | save | erase | restart
 *
 * The CSV columns: t_s, roll_rad, pitch_rad, yaw_rad, sigma_{roll,pitch,yaw}_rad,
 * rate_{p,q,r}_rad_s, flags (ATT_FLAG_*), node_flags (APP_FLAG_*), seq; floats with 9
 * significant digits (exact for a float), the angle, sigma and rate cells empty until the
 * filter is aligned. Heartbeats are not written (they repeat the last estimate).
 */
#include "app_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CSV_HEADER                                                                                     \
    "t_s,roll_rad,pitch_rad,yaw_rad,sigma_roll_rad,sigma_pitch_rad,sigma_yaw_rad,rate_p_rad_s,rate_q_rad_s," \
    "rate_r_rad_s,flags,node_flags,seq"

static void reply(app_t *a, const char *text) { (void)hal_write_line(a->hal, text); }

/* "# NAME VALUE" of parameter i. */
static void reply_param(app_t *a, size_t i, const char *suffix)
{
    app_config_t cfg;
    char line[HAL_LINE_MAX], param[HAL_LINE_MAX - 32];
    app_current_config(a, &cfg);
    if (app_param_format(&cfg, i, param, sizeof(param))) {
        (void)snprintf(line, sizeof(line), "# %s%s", param, suffix);
        reply(a, line);
    }
}

/* The next blank-separated word of *p (at most size-1 characters), *p moved past it. */
static int next_word(const char **p, char *word, size_t size)
{
    size_t n = 0;
    while (**p == ' ' || **p == '\t') {
        ++*p;
    }
    while (**p != '\0' && **p != ' ' && **p != '\t') {
        if (n + 1u < size) {
            word[n++] = **p;
        } else {
            return 0;
        }
        ++*p;
    }
    word[n] = '\0';
    return n > 0u;
}

static int set_command(app_t *a, const char *args)
{
    char name[96], value[48], *end = NULL, line[256];
    const char *p = args;
    app_param_result_t r;
    float v;
    int i;
    if (!next_word(&p, name, sizeof(name)) || !next_word(&p, value, sizeof(value))) {
        reply(a, "# error: set NAME VALUE");
        return 0;
    }
    i = app_param_index(name);
    v = strtof(value, &end);
    if (i < 0 || end == value || *end != '\0') {
        (void)snprintf(line, sizeof(line), "# error: %s", i < 0 ? "no such parameter (list)" : "not a number");
        reply(a, line);
        return 0;
    }
    r = app_param_set(a, (size_t)i, v);
    if (r != APP_PARAM_OK && r != APP_PARAM_PENDING) {
        (void)snprintf(line, sizeof(line), "# error: %s %s: %s", name, value, app_param_result_name(r));
        reply(a, line);
        return 0;
    }
    reply_param(a, (size_t)i, r == APP_PARAM_PENDING ? " (pending restart)" : "");
    return 1;
}

int app_text_line(app_t *a, const hal_line_t *l)
{
    char cmd[16], name[96];
    const char *p = l->text;
    int ok = 1, i;
    size_t k;
    if (!next_word(&p, cmd, sizeof(cmd)) || cmd[0] == '#') {
        return 0; /* blank or a comment */
    }
    if (strcmp(cmd, "set") == 0) {
        ok = set_command(a, p);
    } else if (strcmp(cmd, "get") == 0) {
        i = next_word(&p, name, sizeof(name)) ? app_param_index(name) : -1;
        ok = i >= 0;
        if (ok) {
            reply_param(a, (size_t)i, "");
        } else {
            reply(a, "# error: get NAME (list shows the names)");
        }
    } else if (strcmp(cmd, "list") == 0) {
        for (k = 0; k < app_param_count(); ++k) {
            reply_param(a, k, "");
        }
    } else if (strcmp(cmd, "save") == 0 || strcmp(cmd, "erase") == 0) {
        ok = (cmd[0] == 's') ? app_save(a) : app_erase(a);
        reply(a, ok ? "# done" : "# error: no storage here");
    } else if (strcmp(cmd, "restart") == 0) {
        a->restart_requested = 1u;
        reply(a, "# restarting");
    } else {
        ok = 0;
        reply(a, "# error: unknown command (get, set, list, save, erase, restart)");
    }
    app_count_request(a, ok);
    return 1;
}

/* ",value" or "," when not aligned. */
static size_t put_cell(char *buf, size_t size, float v, int aligned)
{
    const int n = aligned ? snprintf(buf, size, ",%.9g", (double)v) : snprintf(buf, size, ",");
    return (n > 0 && (size_t)n < size) ? (size_t)n : 0u;
}

hal_status_t app_text_publish(app_t *a, const app_output_t *o)
{
    char line[256];
    const int aligned = (o->flags & APP_FLAG_ALIGNED) != 0u;
    size_t n;
    int i, k;
    if (o->kind != APP_OUT_ATTITUDE) {
        return HAL_OK;
    }
    if (!a->text_header) {
        const hal_status_t st = hal_write_line(a->hal, CSV_HEADER);
        if (st != HAL_OK) {
            return st;
        }
        a->text_header = 1u;
    }
    k = snprintf(line, sizeof(line), "%llu.%06llu", (unsigned long long)(o->t_us / 1000000u),
                 (unsigned long long)(o->t_us % 1000000u));
    n = (k > 0) ? (size_t)k : 0u;
    for (i = 0; i < 3; ++i) {
        n += put_cell(line + n, sizeof(line) - n, o->euler[i], aligned);
    }
    for (i = 0; i < 3; ++i) {
        n += put_cell(line + n, sizeof(line) - n, o->sigma[i], aligned);
    }
    for (i = 0; i < 3; ++i) {
        n += put_cell(line + n, sizeof(line) - n, o->rates[i], aligned);
    }
    (void)snprintf(line + n, sizeof(line) - n, ",%lu,%u,%u", (unsigned long)o->att_flags, (unsigned)o->flags,
                   (unsigned)o->seq);
    return hal_write_line(a->hal, line);
}
