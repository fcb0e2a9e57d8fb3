/*
 * att_predict.h - the prediction stage. Not part of the public API.
 */
#ifndef ATT_PREDICT_H
#define ATT_PREDICT_H

#include "att.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A stage runs on the filter's variables v under the settings s, after its caller (att.c)
 * has validated its inputs and saved v. It returns EKF_OK, EKF_GATED or EKF_SKIPPED, or
 * EKF_ERR_NUMERIC after which the caller puts the saved v back (v may be half-updated). */

/* The prediction over dt (s) in (0, dt_max], aligned filter; trace (may be NULL) receives what the
 * prediction did (att_trace_t). */
ekf_status_t att_stage_predict(att_vars_t *v, const att_settings_t *s, ekf_scalar_t dt, att_trace_t *trace);

#ifdef __cplusplus
}
#endif

#endif /* ATT_PREDICT_H */
