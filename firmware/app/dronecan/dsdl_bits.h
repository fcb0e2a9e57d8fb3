/*
 * dsdl_bits.h - the bit-level rules of DroneCAN serialisation, used by the generated
 * dsdl_gen.c (host_tools/attekf/dsdlgen.py).
 *
 * A payload is a stream of bits written most significant bit first into each byte. A field of
 * n bits goes into it as its bytes in little-endian order (the lowest byte first, the top
 * n mod 8 bits last), each byte most significant bit first: the rule of the DroneCAN
 * specification and of the dronecan Python package (transport.py). Signed integers are two's
 * complement; float16 is converted with libuavcan's algorithm, which the Python package also
 * uses, so both sides give the same bits. Saturated casts clamp to the type's range.
 *
 * Writer and reader never go past their buffer: they set error instead, and the generated
 * _encode / _decode return -1.
 */
#ifndef DSDL_BITS_H
#define DSDL_BITS_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint8_t *buf;
    uint32_t size_bits; /* capacity */
    uint32_t bit;       /* next bit to write */
    uint8_t error;      /* set on overflow or an invalid value (a length beyond its array) */
} dsdl_writer_t;

typedef struct {
    const uint8_t *buf;
    uint32_t len_bits;
    uint32_t bit;       /* next bit to read */
    uint8_t error;      /* set on reading past the end or an invalid value */
} dsdl_reader_t;

void dsdl_writer_init(dsdl_writer_t *w, uint8_t *buf, size_t size);
/* Bytes written (the last one padded with zero bits: its bits beyond the stream are cleared),
 * or -1 after an error. */
int dsdl_writer_end(dsdl_writer_t *w);
void dsdl_reader_init(dsdl_reader_t *r, const uint8_t *buf, size_t len);
/* 0, or -1 after an error or if more than the zero padding of the last byte is left over. */
int dsdl_reader_end(const dsdl_reader_t *r);
/* Bits left to read. */
uint32_t dsdl_left(const dsdl_reader_t *r);

/* The low nbits (1..64) of v. */
void dsdl_put_u(dsdl_writer_t *w, uint32_t nbits, uint64_t v);
void dsdl_put_i(dsdl_writer_t *w, uint32_t nbits, int64_t v);
void dsdl_put_f16(dsdl_writer_t *w, float v);
void dsdl_put_f32(dsdl_writer_t *w, float v);
uint64_t dsdl_get_u(dsdl_reader_t *r, uint32_t nbits);
int64_t dsdl_get_i(dsdl_reader_t *r, uint32_t nbits); /* sign-extended */
float dsdl_get_f16(dsdl_reader_t *r);
float dsdl_get_f32(dsdl_reader_t *r);
void dsdl_skip(dsdl_reader_t *r, uint32_t nbits);

/* Saturated casts of the DSDL: v clamped to [0, max] / [lo, hi]. */
uint64_t dsdl_sat_u(uint64_t v, uint64_t max);
int64_t dsdl_sat_i(int64_t v, int64_t lo, int64_t hi);

/* float <-> IEEE half precision bits (libuavcan's conversion: NaN 0x7FFF, overflow to infinity;
 * the saturated cast of dsdl_put_f16 clamps finite and infinite values to +-65504 first). */
uint16_t dsdl_f16_from_float(float v);
float dsdl_f16_to_float(uint16_t h);

#ifdef __cplusplus
}
#endif

#endif /* DSDL_BITS_H */
