/*
 * smooth_att.h - the attitude filter's fixed-interval (Rauch-Tung-Striebel) smoother over a
 * recording: the forward filter exactly as shipped (att_step_traced, any scalar build), then a
 * backward pass in double over what each prediction did (docs/derivation.md, "Smoother").
 *
 * Memory is bounded by checkpoints and recomputation: the forward pass keeps the filter's
 * memory (att_ekf_t) at the start of every segment of seg_len samples and the traces of the
 * current segment only; the backward pass runs the segments from the last to the first,
 * recomputing each earlier segment's traces from its checkpoint (the same calls on the same
 * memory give the same traces, bit for bit) before smoothing it. What the caller provides:
 * seg_len traces, their sample numbers and events, and smooth_checkpoints(n, seg_len) filters.
 *
 * Outputs (core_run_io_t, every output array required): flags, status, gyro_bias and
 * gyro_bias_sigma are the forward filter's; state, var, quat, euler and cov the smoothed
 * estimate, in the output frame, with the reported covariance of docs/derivation.md
 * ("Smoother", "Reported covariance"); before the filter has aligned what the forward filter
 * gives (no estimate). Host-side C99, no allocation.
 */
#ifndef SMOOTH_ATT_H
#define SMOOTH_ATT_H

#include <stddef.h>
#include <stdint.h>

#include "att.h"
#include "core_io.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Events of a step that the backward pass must not smooth across as if continuous. */
#define SMOOTH_EVENT_HEADING_RESET 1u /* the magnetometer reset the heading (diag.heading_resets) */
#define SMOOTH_EVENT_GYRO_SATURATED 2u /* the gyro stage raised the rate variances (diag.gyro_saturated) */
#define SMOOTH_EVENT_NO_MAGNETOMETER 4u /* no magnetometer sample has reached the aligned filter yet */

/* Memory the caller owns. */
typedef struct {
    size_t seg_len;       /* samples per segment, >= 1 */
    att_trace_t *trace;   /* [seg_len]: the traces of one segment */
    size_t *trace_sample; /* [seg_len]: the sample of each trace */
    uint8_t *trace_event; /* [seg_len]: SMOOTH_EVENT_* of each trace's step */
    att_ekf_t *ckpt;      /* [smooth_checkpoints(n, seg_len)]: the filter at each segment's start
                             (ckpt[0]: the filter as it was before the run) */
} smooth_buffers_t;

/* What the backward pass met (counts over the recording). */
typedef struct {
    uint32_t epochs;        /* steps that ran a prediction: the smoothed steps */
    uint32_t heading_cuts;  /* steps across which the heading was not smoothed (reset or capped) */
    uint32_t rate_cuts;     /* steps across which the rates were not smoothed (saturation) */
    uint32_t not_pd;        /* steps whose predicted covariance was not positive definite (not smoothed across) */
    uint32_t branch_flips;  /* steps compared across the two Euler representations (over +-90 deg pitch) */
    uint32_t recomputed;    /* samples run forward a second time (segments before the last) */
} smooth_report_t;

/* Called with the number of samples done since the last call (the forward pass, then the
 * backward pass: 2 n in all); a non-zero return stops the run (smooth_run returns 1). */
typedef int (*smooth_progress_fn)(void *ctx, size_t done);

/* Number of checkpoints for n samples in segments of seg_len. */
size_t smooth_checkpoints(size_t n, size_t seg_len);

/* Runs the filter f (initialised; it continues from its state, and ends as the forward filter
 * ends) over the n samples of io and writes the smoothed outputs. Returns 0, or 1 if progress
 * stopped it (the outputs are then incomplete). */
int smooth_run(att_ekf_t *f, const core_frame_t *fr, size_t n, const core_run_io_t *io, const smooth_buffers_t *buf,
               smooth_progress_fn progress, void *ctx, smooth_report_t *report);

#ifdef __cplusplus
}
#endif

#endif /* SMOOTH_ATT_H */
