/*
 * hal.c - the backend-independent part of hal.h: status names, saturating counters.
 */
#include "hal.h"

const char *hal_status_name(hal_status_t status)
{
    switch (status) {
    case HAL_OK: return "HAL_OK";
    case HAL_EMPTY: return "HAL_EMPTY";
    case HAL_END: return "HAL_END";
    case HAL_ERR_ARG: return "HAL_ERR_ARG";
    case HAL_ERR_IO: return "HAL_ERR_IO";
    case HAL_ERR_LINK_DOWN: return "HAL_ERR_LINK_DOWN";
    case HAL_ERR_FULL: return "HAL_ERR_FULL";
    }
    return "HAL_UNKNOWN_STATUS";
}

void hal_count(uint32_t *counter)
{
    if (*counter != UINT32_MAX) {
        ++*counter;
    }
}

void hal_count_n(uint32_t *counter, uint32_t n)
{
    *counter = (UINT32_MAX - *counter < n) ? UINT32_MAX : *counter + n;
}

int hal_valid(const hal_t *h)
{
    return h != NULL && h->ops != NULL && h->ops->now_us != NULL && h->ops->receive != NULL;
}
