/*
 * node_params.h - attekf-node's parameter file and unique id (Linux): the file holds one
 * "name value" line per parameter that differs from its default (app_param.h), read at start
 * and written by the save requests (DroneCAN param.ExecuteOpcode SAVE, the DBC's save
 * operation), atomically: a new file renamed over the old one.
 */
#ifndef NODE_PARAMS_H
#define NODE_PARAMS_H

#include <stddef.h>
#include <stdint.h>

#include "app.h"

/* Applies the file's lines to cfg. 1 if done (a missing file is no error: nothing to apply),
 * 0 after printing "attekf-node: FILE:LINE: why" for the first bad line (cfg may then hold the
 * lines before it). */
int node_params_load(const char *path, app_config_t *cfg);

/* Writes cfg's non-default parameters to path (via path.tmp and rename). 1 if done, else 0
 * with a message on stderr. */
int node_params_save(const char *path, const app_config_t *cfg);

/* Removes the file (a missing one counts as removed). 1 if done. */
int node_params_erase(const char *path);

/* 32 hexadecimal digits -> 16 bytes. 1 if done. */
int node_parse_unique_id(const char *hex, uint8_t id[APP_UNIQUE_ID_BYTES]);

/* The machine's id (/etc/machine-id, 32 hexadecimal digits) as the node's unique id, with the
 * node id in its last byte so that several nodes on one machine differ. 1 if found. */
int node_machine_unique_id(uint8_t node_id, uint8_t id[APP_UNIQUE_ID_BYTES]);

#endif /* NODE_PARAMS_H */
