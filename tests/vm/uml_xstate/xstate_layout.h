/* Layout of this CPU's XSAVE area in the standard (non-compacted) format that ptrace's
 * NT_X86_XSTATE regset uses, from CPUID leaf 0xD (Intel SDM vol. 1, ch. 13):
 *   bytes 0..511     legacy region (x87 state, MXCSR, XMM0-15): components 0 and 1
 *   bytes 512..575   XSAVE header; its first 8 bytes are XSTATE_BV, one bit per component
 *                    whose state the image holds (a clear bit means "initial state")
 *   then component i >= 2 at the offset CPUID(0xD, i).EBX, CPUID(0xD, i).EAX bytes long.
 * Shared by the ptrace wrapper and its self-test. */
#ifndef UML_XSTATE_LAYOUT_H
#define UML_XSTATE_LAYOUT_H

#include <cpuid.h>
#include <stddef.h>
#include <stdint.h>

#define XS_LEGACY_BYTES 512u
#define XS_HEADER_OFFSET 512u
#define XS_HEADER_BYTES 64u
#define XS_MIN_BYTES (XS_HEADER_OFFSET + XS_HEADER_BYTES) /* 576: legacy region + header */
#define XS_MAX_COMPONENTS 63u

typedef struct {
    uint64_t user_mask;                  /* components the CPU can save in user state (XCR0) */
    uint32_t size_bytes;                 /* standard-format size for the enabled components */
    uint32_t offset[XS_MAX_COMPONENTS];  /* bytes from the start of the area (0 for 0 and 1) */
    uint32_t length[XS_MAX_COMPONENTS];  /* bytes */
} xs_layout;

/* Fills *l from CPUID; returns 0, or -1 if the CPU has no XSAVE leaf. */
static inline int xs_layout_read(xs_layout *l)
{
    unsigned int a = 0u, b = 0u, c = 0u, d = 0u;
    unsigned int i;
    if (__get_cpuid_max(0u, NULL) < 0xDu) {
        return -1;
    }
    __cpuid_count(0xDu, 0u, a, b, c, d);
    /* EBX: size needed for the components currently enabled in XCR0, which is the size the
     * kernel's xstateregs_set insists on (fpu_user_cfg.max_size). */
    l->size_bytes = (uint32_t)b;
    l->user_mask = ((uint64_t)d << 32) | (uint64_t)a;
    /* Components 0 (x87) and 1 (SSE) share the legacy region; they have no entry here. */
    for (i = 0u; i < XS_MAX_COMPONENTS; ++i) {
        l->offset[i] = 0u;
        l->length[i] = 0u;
        if (i >= 2u && ((l->user_mask >> i) & 1u)) {
            __cpuid_count(0xDu, i, a, b, c, d);
            l->length[i] = (uint32_t)a;
            l->offset[i] = (uint32_t)b;
        }
    }
    return (l->size_bytes >= XS_MIN_BYTES) ? 0 : -1;
}

/* Components that lie entirely inside the first n bytes of an image (0 and 1 when n covers
 * the header too; a component cut by n counts as outside). */
static inline uint64_t xs_covered_mask(const xs_layout *l, size_t n)
{
    uint64_t m = 0u;
    unsigned int i;
    if (n < XS_MIN_BYTES) {
        return 0u;
    }
    m = 3u;
    for (i = 2u; i < XS_MAX_COMPONENTS; ++i) {
        if (((l->user_mask >> i) & 1u) && l->length[i] != 0u
            && (size_t)l->offset[i] + (size_t)l->length[i] <= n) {
            m |= (uint64_t)1u << i;
        }
    }
    return m;
}

static inline uint64_t xs_get_bv(const unsigned char *image)
{
    uint64_t v = 0u;
    unsigned int k;
    for (k = 0u; k < 8u; ++k) {
        v |= (uint64_t)image[XS_HEADER_OFFSET + k] << (8u * k);
    }
    return v;
}

static inline void xs_set_bv(unsigned char *image, uint64_t v)
{
    unsigned int k;
    for (k = 0u; k < 8u; ++k) {
        image[XS_HEADER_OFFSET + k] = (unsigned char)((v >> (8u * k)) & 0xFFu);
    }
}

#endif
