/*
 * dsdl_check.c - the generated DroneCAN serialisation (dsdl_gen.c) driven from a script:
 * tests/python/test_dsdl.py writes payloads the dronecan Python package encoded, one per line,
 *
 *     TYPE HEX        e.g. "uavcan.equipment.ahrs.Solution 00a1b2..."
 *
 * and this program prints one line per input: {"rc": RC, "value": FIELDS} where FIELDS is the
 * payload decoded by the C code (dsdl_dump_gen.c) and RC is dsdl_dump's answer (0: decoded, and
 * encoded again to the same bytes). A line "f16 HEX8" (the bits of a float32) prints the
 * float16 bits the encoder writes for that value (saturated cast and conversion), as a number:
 * {"f16": BITS}. Exit status 0, or 2 on a line that is neither.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dsdl_bits.h"
#include "dsdl_dump_gen.h"

/* The float16 bits dsdl_put_f16 writes for the float32 with these bits. */
static unsigned f16_of(uint32_t bits)
{
    uint8_t buf[2];
    float v;
    dsdl_writer_t w;
    dsdl_reader_t r;
    memcpy(&v, &bits, sizeof(v));
    dsdl_writer_init(&w, buf, sizeof(buf));
    dsdl_put_f16(&w, v);
    dsdl_reader_init(&r, buf, sizeof(buf));
    return (unsigned)dsdl_get_u(&r, 16u);
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    return -1;
}

int main(void)
{
    static char line[4096];
    static uint8_t buf[1024];
    unsigned long lineno = 0;
    while (fgets(line, sizeof(line), stdin) != NULL) {
        char *sp = strchr(line, ' ');
        size_t n = 0, i;
        int rc;
        ++lineno;
        if (sp == NULL) {
            fprintf(stderr, "dsdl_check: line %lu: expected TYPE HEX\n", lineno);
            return 2;
        }
        *sp = '\0';
        if (strcmp(line, "f16") == 0) {
            printf("{\"f16\": %u}\n", f16_of((uint32_t)strtoul(sp + 1, NULL, 16)));
            continue;
        }
        for (i = 1; sp[i] != '\0' && sp[i] != '\n' && sp[i + 1] != '\0' && sp[i + 1] != '\n'; i += 2) {
            const int hi = hexval(sp[i]), lo = hexval(sp[i + 1]);
            if (hi < 0 || lo < 0 || n == sizeof(buf)) {
                fprintf(stderr, "dsdl_check: line %lu: bad hex\n", lineno);
                return 2;
            }
            buf[n++] = (uint8_t)(hi * 16 + lo);
        }
        printf("{\"value\": ");
        rc = dsdl_dump(stdout, line, buf, n);
        printf(", \"rc\": %d}\n", rc);
    }
    return 0;
}
