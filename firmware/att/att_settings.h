/*
 * att_settings.h - what the filter's own code needs of the settings beyond the public API
 * (att.h). Not part of the public API.
 */
#ifndef ATT_SETTINGS_H
#define ATT_SETTINGS_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* 1 if every setting that cannot change while the filter runs (live = 0 in
 * att_settings_table.h) is the same in a and b (att_settings.c). */
int att_settings_same_fixed_part(const att_settings_t *a, const att_settings_t *b);

#ifdef __cplusplus
}
#endif

#endif /* ATT_SETTINGS_H */
