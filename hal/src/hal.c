/*
 * hal.c - the backend-independent part of hal.h: names for logs, saturating counters.
 */
#include "hal.h"

#include <stddef.h>

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

/* Indexed by hal_counter_id_t; the names are the DBC's counter signal names in lower case. */
static const char *const counter_names[HAL_CNT_COUNT] = {
    "rx_frames", "unknown_id", "bad_dlc", "duplicate", "late", "incomplete", "discarded",
    "rx_overflow", "link_down", "tx_frames", "tx_errors", "samples", "gaps", "missing",
    "stale", "time_errors", "resync", "saturated", "ekf_rejected", "realign", "outputs",
};

const char *hal_counter_name(hal_counter_id_t id)
{
    if ((unsigned)id >= (unsigned)HAL_CNT_COUNT) {
        return "unknown_counter";
    }
    return counter_names[id];
}

static const char *const event_names[HAL_EV_COUNT] = {
    "started", "link_down", "link_up", "rx_overflow", "tx_error", "aligned", "gap", "stale",
    "resumed", "time_error", "resync", "realign", "ekf_reject", "saturated", "late",
};

const char *hal_event_name(hal_event_t event)
{
    if ((unsigned)event >= (unsigned)HAL_EV_COUNT) {
        return "unknown_event";
    }
    return event_names[event];
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
    return h != NULL && h->ops != NULL && h->ops->now_us != NULL && h->ops->read_sample != NULL &&
           h->ops->publish != NULL;
}
