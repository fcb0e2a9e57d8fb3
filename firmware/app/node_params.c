/*
 * node_params.c - attekf-node's parameter file and unique id (node_params.h).
 */
#define _GNU_SOURCE 1 /* fsync, fileno with -std=c99 */

#include "node_params.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "app_param.h"

int node_params_load(const char *path, app_config_t *cfg)
{
    char line[256], err[192];
    unsigned long n = 0;
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        if (errno == ENOENT) {
            return 1;
        }
        fprintf(stderr, "attekf-node: cannot read %s: %s\n", path, strerror(errno));
        return 0;
    }
    while (fgets(line, sizeof(line), f) != NULL) {
        const size_t len = strlen(line);
        ++n;
        if (len == sizeof(line) - 1u && line[len - 1u] != '\n' && !feof(f)) {
            fprintf(stderr, "attekf-node: %s:%lu: line longer than %u characters\n", path, n,
                    (unsigned)(sizeof(line) - 2u));
            fclose(f);
            return 0;
        }
        if (app_config_read_line(cfg, line, err, sizeof(err)) < 0) {
            fprintf(stderr, "attekf-node: %s:%lu: %s\n", path, n, err);
            fclose(f);
            return 0;
        }
    }
    if (ferror(f)) {
        fprintf(stderr, "attekf-node: %s: read error\n", path);
        fclose(f);
        return 0;
    }
    fclose(f);
    return 1;
}

static int put_line(void *user, const char *line)
{
    return fprintf((FILE *)user, "%s\n", line) > 0;
}

int node_params_save(const char *path, const app_config_t *cfg)
{
    char tmp[4096];
    FILE *f;
    int ok;
    if ((size_t)snprintf(tmp, sizeof(tmp), "%s.tmp", path) >= sizeof(tmp)) {
        fprintf(stderr, "attekf-node: %s: path too long\n", path);
        return 0;
    }
    f = fopen(tmp, "w");
    if (f == NULL) {
        fprintf(stderr, "attekf-node: cannot write %s: %s\n", tmp, strerror(errno));
        return 0;
    }
    ok = fprintf(f, "# attekf-node parameters that differ from their defaults (attekf-node --list-params)\n") > 0 &&
         app_config_write(cfg, put_line, f);
    ok = (fflush(f) == 0) && ok;
    ok = (fsync(fileno(f)) == 0) && ok;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rename(tmp, path) != 0) {
        fprintf(stderr, "attekf-node: cannot write %s: %s\n", path, strerror(errno));
        (void)remove(tmp);
        return 0;
    }
    return 1;
}

int node_params_erase(const char *path)
{
    if (remove(path) != 0 && errno != ENOENT) {
        fprintf(stderr, "attekf-node: cannot remove %s: %s\n", path, strerror(errno));
        return 0;
    }
    return 1;
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int node_parse_unique_id(const char *hex, uint8_t id[APP_UNIQUE_ID_BYTES])
{
    size_t i;
    if (hex == NULL || strlen(hex) != 2u * APP_UNIQUE_ID_BYTES) {
        return 0;
    }
    for (i = 0; i < APP_UNIQUE_ID_BYTES; ++i) {
        const int hi = hexval(hex[2 * i]), lo = hexval(hex[2 * i + 1]);
        if (hi < 0 || lo < 0) {
            return 0;
        }
        id[i] = (uint8_t)(hi * 16 + lo);
    }
    return 1;
}

int node_machine_unique_id(uint8_t node_id, uint8_t id[APP_UNIQUE_ID_BYTES])
{
    char buf[64];
    FILE *f = fopen("/etc/machine-id", "r");
    int ok = 0;
    if (f == NULL) {
        return 0;
    }
    if (fgets(buf, sizeof(buf), f) != NULL) {
        buf[strcspn(buf, "\r\n")] = '\0';
        ok = node_parse_unique_id(buf, id);
    }
    fclose(f);
    if (ok) {
        id[APP_UNIQUE_ID_BYTES - 1u] = node_id;
    }
    return ok;
}
