/*
 * fuzz_common.h - shared helpers of the libFuzzer targets (tests/fuzz/README.md).
 *
 * fz_t reads the fuzz input as a stream: past its end every read returns zeros, so a
 * target never has to check lengths. FZ_CHECK aborts with a message when an invariant
 * fails: libFuzzer reports the abort as a crash and writes the input that caused it.
 */
#ifndef FUZZ_COMMON_H
#define FUZZ_COMMON_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const uint8_t *p;
    size_t n;
} fz_t;

static inline int fz_more(const fz_t *z) { return z->n > 0u; }

static inline uint8_t fz_u8(fz_t *z)
{
    uint8_t v = 0u;
    if (z->n > 0u) {
        v = *z->p++;
        --z->n;
    }
    return v;
}

static inline void fz_bytes(fz_t *z, void *out, size_t len)
{
    uint8_t *o = (uint8_t *)out;
    size_t i;
    for (i = 0; i < len; ++i) {
        o[i] = fz_u8(z);
    }
}

static inline uint16_t fz_u16(fz_t *z)
{
    const uint16_t lo = fz_u8(z);
    return (uint16_t)(lo | (uint16_t)(fz_u8(z) << 8));
}

static inline uint32_t fz_u32(fz_t *z)
{
    const uint32_t lo = fz_u16(z);
    return lo | ((uint32_t)fz_u16(z) << 16);
}

static inline float fz_f32_bits(fz_t *z)
{
    const uint32_t u = fz_u32(z);
    float f;
    memcpy(&f, &u, sizeof(f));
    return f;
}

static inline double fz_f64_bits(fz_t *z)
{
    uint64_t u = fz_u32(z);
    double d;
    u |= (uint64_t)fz_u32(z) << 32;
    memcpy(&d, &u, sizeof(d));
    return d;
}

/* A real number shaped for fuzzing a physical input of typical size `scale`: mostly
 * ordinary values (int16 fraction of 2*scale), sometimes raw bit patterns (NaN, Inf,
 * subnormals, huge) and the special values at the edges. */
static inline double fz_real(fz_t *z, double scale)
{
    const uint8_t kind = fz_u8(z);
    switch (kind & 7u) {
    case 0:
    case 1:
    case 2:
    case 3: return (double)(int16_t)fz_u16(z) / 16384.0 * scale;
    case 4: return (double)fz_f32_bits(z);
    case 5: return fz_f64_bits(z);
    case 6: {
        static const double special[] = {0.0, -0.0, 1e-300, -1e-300, 1e-38, 3.4e38, -3.4e38, 1e300};
        return special[(kind >> 3) & 7u];
    }
    default: return (kind & 8u) ? (double)INFINITY : (double)NAN;
    }
}

#define FZ_CHECK(cond, ...)                                                              \
    do {                                                                                 \
        if (!(cond)) {                                                                   \
            fprintf(stderr, "invariant failed at %s:%d: %s: ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                                \
            fprintf(stderr, "\n");                                                       \
            abort();                                                                     \
        }                                                                                \
    } while (0)

#endif /* FUZZ_COMMON_H */
