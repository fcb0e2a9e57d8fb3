/*
 * dsdl_dump_gen.h - the printer generated into dsdl_dump_gen.c (host_tools/attekf/dsdlgen.py).
 */
#ifndef DSDL_DUMP_GEN_H
#define DSDL_DUMP_GEN_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

/* Decodes a payload of the named type ("uavcan.protocol.param.GetSet.req", a message's full
 * name) and prints its fields as a JSON object ("null" if it does not decode). Returns 0, -1
 * (does not decode), -2 (decoded, but encoding it again does not give the same bytes) or -3
 * (no such type). */
int dsdl_dump(FILE *f, const char *type, const uint8_t *buf, size_t len);

#endif /* DSDL_DUMP_GEN_H */
