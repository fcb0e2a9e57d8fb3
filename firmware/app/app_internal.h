/*
 * app_internal.h - how the parts of the application call each other (not installed): the loop
 * (app.c) hands input to the protocol that takes it (app_dbc.c, app_dronecan.c, app_text.c),
 * the protocols hand samples to the sample path (app_sample.c), which publishes through
 * app_output.c, which encodes with the configured protocol.
 */
#ifndef APP_INTERNAL_H
#define APP_INTERNAL_H

#include "app.h"
#include "app_param.h"

/* app.c */
void app_log(const app_t *a, hal_level_t level, const char *event, int32_t detail);
/* A request served (ok) or refused: counted. */
void app_count_request(app_t *a, int ok);
/* The frame, sample and link error counters' changes since the last look, as status flags. */
void app_latch_errors(app_t *a);
/* Result of a parameter set as the text and the protocols report it. */
const char *app_param_result_name(app_param_result_t r);
/* Save and erase through the hooks: 1 if done. */
int app_save(app_t *a);
int app_erase(app_t *a);

/* app_sample.c: one IMU sample, whatever brought it. */
void app_process_sample(app_t *a, const hal_sample_t *s);

/* app_output.c */
void app_publish(app_t *a, app_output_kind_t kind);
/* Clock work after the input of a poll: staleness, heartbeats, DroneCAN status. */
void app_tick(app_t *a, uint64_t now);

/* app_dbc.c: frames of the DBC protocol; 1 if the frame completed a sample or a request. */
int app_dbc_frame(app_t *a, const hal_frame_t *f);
void app_dbc_end(app_t *a);
hal_status_t app_dbc_publish(app_t *a, const app_output_t *o);

/* app_dronecan.c */
int app_dcan_frame(app_t *a, const hal_frame_t *f);
hal_status_t app_dcan_publish(app_t *a, const app_output_t *o);
void app_dcan_start(app_t *a, uint64_t now);
void app_dcan_tick(app_t *a, uint64_t now);

/* app_text.c */
int app_text_line(app_t *a, const hal_line_t *line);
hal_status_t app_text_publish(app_t *a, const app_output_t *o);

#endif /* APP_INTERNAL_H */
