/*
 * fx_count.c - see fx_count.h.
 */
#include "fx_count.h"

static uint32_t g_count;

uint32_t fx_count_saturations(void) { return g_count; }

void fx_count_reset(void) { g_count = 0u; }

void fx_count_saturation(void)
{
    if (g_count != UINT32_MAX) {
        ++g_count;
    }
}
