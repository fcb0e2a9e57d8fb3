/*
 * app_dbc.c - the node's own CAN protocol (dbc/) in the application: IMU frames to samples,
 * outputs to ATT_* frames, and the parameter frames (ATT_PARAM_REQ -> ATT_PARAM).
 */
#include "app_internal.h"

#include <math.h>

static dbc_result_t param_result(app_param_result_t r)
{
    switch (r) {
    case APP_PARAM_OK: return DBC_RESULT_OK;
    case APP_PARAM_PENDING: return DBC_RESULT_PENDING_RESTART;
    case APP_PARAM_NO_SUCH: return DBC_RESULT_NO_SUCH;
    case APP_PARAM_RANGE: return DBC_RESULT_RANGE;
    }
    return DBC_RESULT_BAD_REQUEST;
}

/* Serves one ATT_PARAM_REQ (malformed: its id with the wrong length) and answers. */
static void param_request(app_t *a, const dbc_param_req_t *req, int malformed, uint64_t t_us)
{
    dbc_result_t result = DBC_RESULT_BAD_REQUEST;
    float value = 0.0f;
    hal_frame_t answer;
    if (!malformed) {
        switch (req->op) {
        case DBC_OP_GET:
            result = app_param_get(a, req->index, &value) ? DBC_RESULT_OK : DBC_RESULT_NO_SUCH;
            break;
        case DBC_OP_SET:
            result = isfinite(req->value) ? param_result(app_param_set(a, req->index, req->value))
                                          : DBC_RESULT_BAD_REQUEST;
            (void)app_param_get(a, req->index, &value);
            break;
        case DBC_OP_SAVE: result = app_save(a) ? DBC_RESULT_OK : DBC_RESULT_FAILED; break;
        case DBC_OP_ERASE: result = app_erase(a) ? DBC_RESULT_OK : DBC_RESULT_FAILED; break;
        case DBC_OP_RESTART:
            result = DBC_RESULT_OK;
            a->restart_requested = 1u; /* after this poll, once the answer is out */
            break;
        default: break;
        }
    }
    app_count_request(a, result == DBC_RESULT_OK || result == DBC_RESULT_PENDING_RESTART);
    dbc_encode_param(&a->dbc_tx, malformed ? 0u : req->index, malformed ? 0u : req->op, (uint8_t)result, value,
                     t_us, &answer);
    (void)hal_send_frames(a->hal, &answer, 1u);
}

static int drain(app_t *a)
{
    hal_sample_t s;
    int n = 0;
    while (dbc_rx_pop(&a->dbc_rx, &s)) {
        app_process_sample(a, &s);
        n = 1;
    }
    return n;
}

int app_dbc_frame(app_t *a, const hal_frame_t *f)
{
    dbc_param_req_t req;
    int r;
    if (a->node.input == APP_PROTO_DBC && dbc_rx_takes(&a->dbc_rx, f->id)) {
        dbc_rx_frame(&a->dbc_rx, f);
        return drain(a);
    }
    if (a->node.protocol == APP_PROTO_DBC) {
        r = dbc_decode_param_req(&a->dbc_tx, f, &req);
        if (r != 0) {
            param_request(a, &req, r < 0, f->t_us);
            return 1;
        }
    }
    hal_count(&a->counters[APP_CNT_FOREIGN]);
    return 0;
}

void app_dbc_end(app_t *a)
{
    dbc_rx_flush(&a->dbc_rx);
    (void)drain(a);
}

hal_status_t app_dbc_publish(app_t *a, const app_output_t *o)
{
    hal_frame_t frames[DBC_MAX_OUT_FRAMES];
    const size_t n = dbc_encode_output(&a->dbc_tx, o, frames);
    return hal_send_frames(a->hal, frames, n);
}
