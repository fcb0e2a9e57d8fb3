/*
 * dsdl_bits.c - DroneCAN bit stream (dsdl_bits.h).
 */
#include "dsdl_bits.h"

#include <string.h>

/* Largest finite float16 and float32: the limits of the saturated casts. */
#define F16_MAX 65504.0f
#define F32_MAX 3.40282347e38f

void dsdl_writer_init(dsdl_writer_t *w, uint8_t *buf, size_t size)
{
    w->buf = buf;
    w->size_bits = (size > 0x1FFFFFFFu) ? 0xFFFFFFF8u : (uint32_t)size * 8u;
    w->bit = 0u;
    w->error = 0u;
}

int dsdl_writer_end(dsdl_writer_t *w)
{
    if (w->error) {
        return -1;
    }
    if (w->bit % 8u != 0u) {
        /* the padding of the last byte is zero (the bits beyond were never written) */
        w->buf[w->bit / 8u] = (uint8_t)(w->buf[w->bit / 8u] & (0xFFu << (8u - w->bit % 8u)));
    }
    return (int)((w->bit + 7u) / 8u);
}

void dsdl_reader_init(dsdl_reader_t *r, const uint8_t *buf, size_t len)
{
    r->buf = buf;
    r->len_bits = (len > 0x1FFFFFFFu) ? 0xFFFFFFF8u : (uint32_t)len * 8u;
    r->bit = 0u;
    r->error = 0u;
}

int dsdl_reader_end(const dsdl_reader_t *r)
{
    /* what is left must be the padding of the last byte */
    return (r->error || r->len_bits - r->bit >= 8u) ? -1 : 0;
}

uint32_t dsdl_left(const dsdl_reader_t *r) { return r->error ? 0u : r->len_bits - r->bit; }

/* nbits (1..8) of v, most significant first. */
static void put_bits(dsdl_writer_t *w, uint32_t nbits, uint32_t v)
{
    uint32_t k;
    for (k = nbits; k > 0u; --k) {
        const uint32_t byte = w->bit / 8u;
        const uint32_t mask = 0x80u >> (w->bit % 8u);
        if (((v >> (k - 1u)) & 1u) != 0u) {
            w->buf[byte] = (uint8_t)(w->buf[byte] | mask);
        } else {
            w->buf[byte] = (uint8_t)(w->buf[byte] & ~mask);
        }
        ++w->bit;
    }
}

static uint32_t get_bits(dsdl_reader_t *r, uint32_t nbits)
{
    uint32_t v = 0u, k;
    for (k = 0u; k < nbits; ++k) {
        const uint32_t bit = ((uint32_t)r->buf[r->bit / 8u] >> (7u - r->bit % 8u)) & 1u;
        v = (v << 1) | bit;
        ++r->bit;
    }
    return v;
}

void dsdl_put_u(dsdl_writer_t *w, uint32_t nbits, uint64_t v)
{
    uint32_t done = 0u;
    if (w->error || nbits == 0u || nbits > 64u || w->size_bits - w->bit < nbits || w->bit > w->size_bits) {
        w->error = 1u;
        return;
    }
    /* the lowest byte first, the top nbits mod 8 bits last */
    while (done < nbits) {
        const uint32_t k = (nbits - done >= 8u) ? 8u : nbits - done;
        put_bits(w, k, (uint32_t)((v >> done) & ((1u << k) - 1u)));
        done += k;
    }
}

void dsdl_put_i(dsdl_writer_t *w, uint32_t nbits, int64_t v)
{
    dsdl_put_u(w, nbits, (uint64_t)v); /* two's complement; put_u keeps the low nbits */
}

uint64_t dsdl_get_u(dsdl_reader_t *r, uint32_t nbits)
{
    uint64_t v = 0u;
    uint32_t done = 0u;
    if (r->error || nbits == 0u || nbits > 64u || r->bit > r->len_bits || r->len_bits - r->bit < nbits) {
        r->error = 1u;
        return 0u;
    }
    while (done < nbits) {
        const uint32_t k = (nbits - done >= 8u) ? 8u : nbits - done;
        v |= (uint64_t)get_bits(r, k) << done;
        done += k;
    }
    return v;
}

int64_t dsdl_get_i(dsdl_reader_t *r, uint32_t nbits)
{
    const uint64_t u = dsdl_get_u(r, nbits);
    if (nbits < 64u && nbits > 0u && ((u >> (nbits - 1u)) & 1u) != 0u) {
        /* negative: the value is u - 2^nbits, computed without overflow */
        return -(int64_t)(((uint64_t)1 << nbits) - u);
    }
    return (int64_t)u;
}

void dsdl_skip(dsdl_reader_t *r, uint32_t nbits)
{
    if (r->error || r->bit > r->len_bits || r->len_bits - r->bit < nbits) {
        r->error = 1u;
        return;
    }
    r->bit += nbits;
}

uint64_t dsdl_sat_u(uint64_t v, uint64_t max) { return v > max ? max : v; }

int64_t dsdl_sat_i(int64_t v, int64_t lo, int64_t hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* The float's bits and back, without aliasing a pointer. */
static uint32_t f32_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof(u));
    return u;
}

static float f32_from_bits(uint32_t u)
{
    float f;
    memcpy(&f, &u, sizeof(f));
    return f;
}

uint16_t dsdl_f16_from_float(float v)
{
    /* libuavcan's conversion (as the dronecan package): round by adding half of the dropped
     * mantissa after a multiplication that moves the exponent into float16's range */
    const uint32_t f32_inf = 255u << 23;
    const uint32_t f16_inf = 31u << 23;
    const float magic = f32_from_bits(15u << 23);
    const uint32_t round_mask = ~0xFFFu;
    uint32_t in = f32_bits(v);
    const uint32_t sign = in & 0x80000000u;
    uint16_t out;
    in ^= sign;
    if (in >= f32_inf) {
        out = (in > f32_inf) ? 0x7FFFu : 0x7C00u; /* NaN, infinity */
    } else {
        in &= round_mask;
        in = f32_bits(f32_from_bits(in) * magic);
        in -= round_mask;
        if (in > f16_inf) {
            in = f16_inf; /* overflow: infinity */
        }
        out = (uint16_t)((in >> 13) & 0xFFFFu);
    }
    return (uint16_t)(out | (uint16_t)(sign >> 16));
}

float dsdl_f16_to_float(uint16_t h)
{
    const float magic = f32_from_bits((254u - 15u) << 23);
    const float was_inf_nan = f32_from_bits((127u + 16u) << 23);
    uint32_t out = f32_bits(f32_from_bits((uint32_t)(h & 0x7FFFu) << 13) * magic);
    if (f32_from_bits(out) >= was_inf_nan) {
        out |= 255u << 23;
    }
    out |= (uint32_t)(h & 0x8000u) << 16;
    return f32_from_bits(out);
}

void dsdl_put_f16(dsdl_writer_t *w, float v)
{
    if (v > F16_MAX) {
        v = F16_MAX;
    } else if (v < -F16_MAX) {
        v = -F16_MAX;
    }
    dsdl_put_u(w, 16u, dsdl_f16_from_float(v));
}

void dsdl_put_f32(dsdl_writer_t *w, float v)
{
    if (v > F32_MAX) {
        v = F32_MAX;
    } else if (v < -F32_MAX) {
        v = -F32_MAX;
    }
    dsdl_put_u(w, 32u, f32_bits(v));
}

float dsdl_get_f16(dsdl_reader_t *r) { return dsdl_f16_to_float((uint16_t)dsdl_get_u(r, 16u)); }

float dsdl_get_f32(dsdl_reader_t *r) { return f32_from_bits((uint32_t)dsdl_get_u(r, 32u)); }
