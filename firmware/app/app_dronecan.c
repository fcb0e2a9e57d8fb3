/*
 * app_dronecan.c - the node on a DroneCAN bus (docs/can_protocol.md, "DroneCAN"):
 *   out   uavcan.equipment.ahrs.Solution with every attitude output (once aligned), in
 *         DroneCAN's frames (dcan_frames.h), with the covariance of the filter;
 *         uavcan.protocol.NodeStatus every second, its health from the filter and the node;
 *   in    uavcan.equipment.ahrs.RawIMU (+ MagneticFieldStrength2) as IMU samples;
 *         the services GetNodeInfo, RestartNode, param.GetSet and param.ExecuteOpcode.
 * Serialisation: dsdl_gen.c, generated from the DSDL of the pinned dronecan package; frames:
 * dcan_transfer.c. Everything else on the bus is foreign: counted, never an error.
 */
#include "app_internal.h"

#include <math.h>
#include <string.h>

#include "dcan_frames.h"
#include "dsdl_gen.h"

/* Priorities (0 highest .. 31): the attitude ahead of the status; answers at the request's. */
#define PRIO_SOLUTION 16u
#define PRIO_STATUS 24u
#define STATUS_PERIOD_US 1000000u /* NodeStatus.MAX_BROADCASTING_PERIOD_MS */
#define NODE_NAME "org.attekf.ahrs"
#define SOFTWARE_MAJOR 0u
#define SOFTWARE_MINOR 1u
#define RESTART_MAGIC 0xACCE551B1Eull /* RestartNode.MAGIC_NUMBER */
#define OPCODE_SAVE 0u
#define OPCODE_ERASE 1u
#define GAUSS_TO_UT 100.0f
#define F16_MAX 65504.0f /* largest finite float16: a reading at or beyond it saturated */
/* NodeStatus fields (DSDL constants) */
enum { HEALTH_OK = 0, HEALTH_WARNING = 1, HEALTH_ERROR = 2 };
enum { MODE_OPERATIONAL = 0, MODE_INITIALIZATION = 1 };

/* NodeStatus.vendor_specific_status_code: the ATT_FLAG_* word in bits 0..14, bit 15 set while a
 * parameter waits for a restart. The filter's flags must leave bit 15 free. */
#define VENDOR_CONFIG_PENDING 0x8000u
typedef char app_dcan_att_flags_fit[(ATT_FLAG_AT_REST < VENDOR_CONFIG_PENDING) ? 1 : -1];

/* Events that make the health a warning, and the filter flags that do. */
#define WARN_EVENTS (APP_FLAG_GAP | APP_FLAG_IN_SATURATED | APP_FLAG_FRAME_ERROR | APP_FLAG_INCOMPLETE | \
                     APP_FLAG_EKF_REJECT | APP_FLAG_TIME_ERROR | APP_FLAG_RESTARTED | APP_FLAG_OUT_SATURATED)
#define WARN_ATT (ATT_FLAG_ACCEL_REJECTED | ATT_FLAG_MAG_DISTURBED | ATT_FLAG_GATE_BYPASS | ATT_FLAG_COV_REPAIRED | \
                  ATT_FLAG_GIMBAL_LOCK)

void app_dcan_start(app_t *a, uint64_t now)
{
    memset(&a->dcan, 0, sizeof(a->dcan));
    dcan_rx_init(&a->dcan.rx);
    a->dcan.start_us = now;
    a->dcan.next_status_us = now;
}

static void node_status(const app_t *a, uint64_t now, dsdl_protocol_node_status_t *m)
{
    const uint32_t att = att_flags(&a->ekf);
    const uint16_t events = (uint16_t)(a->dcan.status_flags | a->latched);
    const uint64_t up = (now - a->dcan.start_us) / 1000000u;
    m->uptime_sec = (up > UINT32_MAX) ? UINT32_MAX : (uint32_t)up;
    if (a->stale || (events & APP_FLAG_LINK_ERROR) != 0u) {
        m->health = HEALTH_ERROR; /* no IMU input, or the bus is failing */
    } else if ((events & WARN_EVENTS) != 0u || (att & WARN_ATT) != 0u) {
        m->health = HEALTH_WARNING;
    } else {
        m->health = HEALTH_OK;
    }
    m->mode = (att & ATT_FLAG_ALIGNED) != 0u ? MODE_OPERATIONAL : MODE_INITIALIZATION;
    m->sub_mode = 0u;
    m->vendor_specific_status_code =
        (uint16_t)((att & (VENDOR_CONFIG_PENDING - 1u)) | (a->n_pending > 0u ? VENDOR_CONFIG_PENDING : 0u));
}

static hal_status_t send(app_t *a, const dcan_transfer_t *t, uint64_t signature)
{
    hal_frame_t frames[DCAN_TX_FRAMES_MAX];
    const size_t n = dcan_encode(t, signature, frames, DCAN_TX_FRAMES_MAX);
    return (n == 0u) ? HAL_ERR_ARG : hal_send_frames(a->hal, frames, n);
}

static hal_status_t publish_message(app_t *a, uint16_t dtid, uint64_t signature, uint8_t priority, uint8_t *tid,
                                    const uint8_t *payload, int len, uint64_t t_us)
{
    dcan_transfer_t t;
    if (len < 0) {
        return HAL_ERR_ARG;
    }
    memset(&t, 0, sizeof(t));
    t.dtid = dtid;
    t.kind = DCAN_MESSAGE;
    t.source = a->node.node_id;
    t.priority = priority;
    t.tid = *tid;
    t.t_us = t_us;
    t.payload = payload;
    t.len = (size_t)len;
    *tid = (uint8_t)((*tid + 1u) & 0x1Fu);
    return send(a, &t, signature);
}

static void respond(app_t *a, const dcan_transfer_t *req, uint64_t signature, const uint8_t *payload, int len)
{
    dcan_transfer_t t = *req;
    if (len < 0) {
        return;
    }
    t.kind = DCAN_RESPONSE;
    t.dest = req->source;
    t.source = a->node.node_id;
    t.payload = payload;
    t.len = (size_t)len;
    (void)send(a, &t, signature);
}

/* ---- services ----------------------------------------------------------------------- */
static void get_node_info(app_t *a, const dcan_transfer_t *req)
{
    static const char name[] = NODE_NAME;
    dsdl_protocol_get_node_info_resp_t r;
    uint8_t buf[DSDL_PROTOCOL_GET_NODE_INFO_RESP_MAX_BYTES];
    memset(&r, 0, sizeof(r));
    node_status(a, hal_now_us(a->hal), &r.status);
    r.software_version.major = SOFTWARE_MAJOR;
    r.software_version.minor = SOFTWARE_MINOR;
    memcpy(r.hardware_version.unique_id, a->node.unique_id, APP_UNIQUE_ID_BYTES);
    r.name_len = (uint8_t)(sizeof(name) - 1u);
    memcpy(r.name, name, sizeof(name) - 1u);
    app_count_request(a, 1);
    respond(a, req, DSDL_PROTOCOL_GET_NODE_INFO_SIGNATURE, buf,
            dsdl_protocol_get_node_info_resp_encode(&r, buf, sizeof(buf)));
}

static void restart_node(app_t *a, const dcan_transfer_t *req)
{
    dsdl_protocol_restart_node_req_t q;
    dsdl_protocol_restart_node_resp_t r;
    uint8_t buf[DSDL_PROTOCOL_RESTART_NODE_RESP_MAX_BYTES];
    if (dsdl_protocol_restart_node_req_decode(&q, req->payload, req->len) != 0) {
        hal_count(&a->counters[APP_CNT_TRANSFER_ERRORS]);
        return;
    }
    r.ok = (uint8_t)(q.magic_number == RESTART_MAGIC);
    app_count_request(a, r.ok);
    respond(a, req, DSDL_PROTOCOL_RESTART_NODE_SIGNATURE, buf,
            dsdl_protocol_restart_node_resp_encode(&r, buf, sizeof(buf)));
    if (r.ok) {
        a->restart_requested = 1u; /* after this poll, once the answer is out */
    }
}

static void execute_opcode(app_t *a, const dcan_transfer_t *req)
{
    dsdl_param_execute_opcode_req_t q;
    dsdl_param_execute_opcode_resp_t r;
    uint8_t buf[DSDL_PARAM_EXECUTE_OPCODE_RESP_MAX_BYTES];
    if (dsdl_param_execute_opcode_req_decode(&q, req->payload, req->len) != 0) {
        hal_count(&a->counters[APP_CNT_TRANSFER_ERRORS]);
        return;
    }
    r.argument = 0;
    r.ok = (uint8_t)((q.opcode == OPCODE_SAVE && app_save(a)) || (q.opcode == OPCODE_ERASE && app_erase(a)));
    app_count_request(a, r.ok);
    respond(a, req, DSDL_PARAM_EXECUTE_OPCODE_SIGNATURE, buf,
            dsdl_param_execute_opcode_resp_encode(&r, buf, sizeof(buf)));
}

static void put_value(dsdl_param_value_t *v, float x, int integer)
{
    v->tag = integer ? DSDL_PARAM_VALUE_INTEGER_VALUE : DSDL_PARAM_VALUE_REAL_VALUE;
    v->integer_value = integer ? (int64_t)x : 0;
    v->real_value = integer ? 0.0f : x;
}

static void put_numeric(dsdl_param_numeric_value_t *v, float x, int integer)
{
    v->tag = integer ? DSDL_PARAM_NUMERIC_VALUE_INTEGER_VALUE : DSDL_PARAM_NUMERIC_VALUE_REAL_VALUE;
    v->integer_value = integer ? (int64_t)x : 0;
    v->real_value = integer ? 0.0f : x;
}

/* The parameter a GetSet request names (by name if it has one, else by index), or -1. */
static int requested_param(const dsdl_param_get_set_req_t *q)
{
    char name[sizeof(q->name) + 1u];
    if (q->name_len == 0u) {
        return (q->index < app_param_count()) ? (int)q->index : -1;
    }
    memcpy(name, q->name, q->name_len);
    name[q->name_len] = '\0';
    return app_param_index(name);
}

/* A set request's value as a number: 1 and *x, or 0 (a string, or not finite). */
static int requested_value(const dsdl_param_value_t *v, float *x)
{
    switch (v->tag) {
    case DSDL_PARAM_VALUE_INTEGER_VALUE: *x = (float)v->integer_value; return 1;
    case DSDL_PARAM_VALUE_REAL_VALUE: *x = v->real_value; return isfinite(v->real_value);
    case DSDL_PARAM_VALUE_BOOLEAN_VALUE: *x = (v->boolean_value != 0u) ? 1.0f : 0.0f; return 1;
    default: return 0;
    }
}

static void get_set(app_t *a, const dcan_transfer_t *req)
{
    dsdl_param_get_set_req_t q;
    dsdl_param_get_set_resp_t r;
    uint8_t buf[DSDL_PARAM_GET_SET_RESP_MAX_BYTES];
    app_param_info_t info;
    int i, ok = 1;
    float x = 0.0f;
    if (dsdl_param_get_set_req_decode(&q, req->payload, req->len) != 0) {
        hal_count(&a->counters[APP_CNT_TRANSFER_ERRORS]);
        return;
    }
    memset(&r, 0, sizeof(r)); /* empty value and name: no such parameter */
    i = requested_param(&q);
    if (i >= 0 && app_param_info((size_t)i, &info)) {
        if (q.value.tag != DSDL_PARAM_VALUE_EMPTY) {
            const app_param_result_t res =
                requested_value(&q.value, &x) ? app_param_set(a, (size_t)i, x) : APP_PARAM_RANGE;
            ok = (res == APP_PARAM_OK || res == APP_PARAM_PENDING);
            app_log(a, HAL_LOG_INFO, ok ? "param_set" : "param_refused", i);
        }
        (void)app_param_get(a, (size_t)i, &x);
        put_value(&r.value, x, info.integer);
        put_value(&r.default_value, info.def, info.integer);
        put_numeric(&r.max_value, info.hi, info.integer);
        put_numeric(&r.min_value, info.lo, info.integer);
        r.name_len = (uint8_t)strlen(info.name);
        memcpy(r.name, info.name, r.name_len);
    } else {
        ok = 0;
    }
    app_count_request(a, ok);
    respond(a, req, DSDL_PARAM_GET_SET_SIGNATURE, buf, dsdl_param_get_set_resp_encode(&r, buf, sizeof(buf)));
}

/* ---- IMU input ---------------------------------------------------------------------- */
/* Whether a message of this source is taken: the configured node, or the first one heard. */
static int from_source(uint8_t configured, uint8_t *current, uint8_t source)
{
    if (configured != 0u) {
        return source == configured;
    }
    if (*current == 0u) {
        *current = source;
    }
    return source == *current;
}

/* Body vector FRD -> the filter's frame; saturation bit if a component is at float16's end. */
static uint8_t take_vector(const float frd[3], float out[3], uint8_t bit)
{
    uint8_t sat = 0u;
    int i;
    dcan_flip_body(frd, out);
    for (i = 0; i < 3; ++i) {
        if (fabsf(out[i]) >= F16_MAX) {
            sat = bit;
        }
    }
    return sat;
}

static void magnetometer(app_t *a, const dcan_transfer_t *t)
{
    dsdl_ahrs_magnetic_field_strength2_t m;
    float ut[3];
    int i;
    if (dsdl_ahrs_magnetic_field_strength2_decode(&m, t->payload, t->len) != 0) {
        hal_count(&a->counters[APP_CNT_TRANSFER_ERRORS]);
        return;
    }
    a->dcan.mag_saturated = take_vector(m.magnetic_field_ga, ut, HAL_HAS_MAG);
    for (i = 0; i < 3; ++i) {
        a->dcan.mag[i] = ut[i] * GAUSS_TO_UT;
    }
    a->dcan.have_mag = 1u;
}

/* A RawIMU message: one sample (with the newest magnetometer reading since the previous one).
 * Its sequence number counts transfer ids, so up to 31 lost messages show as a gap; a repeated
 * transfer id is a duplicate. The sample time is the message's timestamp, or the local
 * receive time where the sender leaves it 0 (unknown). */
static int raw_imu(app_t *a, const dcan_transfer_t *t, uint64_t rx_us)
{
    dsdl_ahrs_raw_imu_t m;
    hal_sample_t s;
    const uint8_t step = (uint8_t)((t->tid - a->dcan.imu_tid) & 0x1Fu);
    if (dsdl_ahrs_raw_imu_decode(&m, t->payload, t->len) != 0) {
        hal_count(&a->counters[APP_CNT_TRANSFER_ERRORS]);
        return 0;
    }
    if (a->dcan.have_imu && step == 0u) {
        hal_count(&a->counters[APP_CNT_DUPLICATE]);
        return 0;
    }
    a->dcan.imu_seq = a->dcan.have_imu ? (uint16_t)(a->dcan.imu_seq + step) : 0u;
    a->dcan.imu_tid = t->tid;
    a->dcan.have_imu = 1u;
    memset(&s, 0, sizeof(s));
    s.seq = a->dcan.imu_seq;
    s.t_us = (m.timestamp.usec != 0u) ? m.timestamp.usec : rx_us;
    s.rx_us = rx_us;
    s.saturated = (uint8_t)(take_vector(m.rate_gyro_latest, s.gyro, HAL_HAS_GYRO) |
                            take_vector(m.accelerometer_latest, s.accel, HAL_HAS_ACCEL));
    s.valid = HAL_HAS_GYRO | HAL_HAS_ACCEL;
    if (a->dcan.have_mag) {
        memcpy(s.mag, a->dcan.mag, sizeof(s.mag));
        s.valid |= HAL_HAS_MAG;
        s.saturated |= a->dcan.mag_saturated;
        a->dcan.have_mag = 0u;
    }
    app_process_sample(a, &s);
    return 1;
}

/* ---- frames ------------------------------------------------------------------------- */
/* 1 and the signature if the node takes this transfer. */
static int wanted(app_t *a, const dcan_transfer_t *t, uint64_t *signature)
{
    if (t->kind == DCAN_REQUEST) {
        if (a->node.protocol != APP_PROTO_DRONECAN || t->dest != a->node.node_id || t->source == 0u) {
            return 0;
        }
        switch (t->dtid) {
        case DSDL_PROTOCOL_GET_NODE_INFO_ID: *signature = DSDL_PROTOCOL_GET_NODE_INFO_SIGNATURE; return 1;
        case DSDL_PROTOCOL_RESTART_NODE_ID: *signature = DSDL_PROTOCOL_RESTART_NODE_SIGNATURE; return 1;
        case DSDL_PARAM_GET_SET_ID: *signature = DSDL_PARAM_GET_SET_SIGNATURE; return 1;
        case DSDL_PARAM_EXECUTE_OPCODE_ID: *signature = DSDL_PARAM_EXECUTE_OPCODE_SIGNATURE; return 1;
        default: return 0;
        }
    }
    if (t->kind != DCAN_MESSAGE || t->source == 0u || a->node.input != APP_PROTO_DRONECAN) {
        return 0;
    }
    if (t->dtid == DSDL_AHRS_RAW_IMU_ID && from_source(a->node.imu_node, &a->dcan.imu_source, t->source)) {
        *signature = DSDL_AHRS_RAW_IMU_SIGNATURE;
        return 1;
    }
    if (t->dtid == DSDL_AHRS_MAGNETIC_FIELD_STRENGTH2_ID &&
        from_source(a->node.mag_node, &a->dcan.mag_source, t->source)) {
        *signature = DSDL_AHRS_MAGNETIC_FIELD_STRENGTH2_SIGNATURE;
        return 1;
    }
    return 0;
}

int app_dcan_frame(app_t *a, const hal_frame_t *f)
{
    dcan_transfer_t t;
    uint64_t signature = 0u;
    if (!dcan_parse_id(f->id, &t) || !wanted(a, &t, &signature)) {
        hal_count(&a->counters[APP_CNT_FOREIGN]);
        return 0;
    }
    if (dcan_rx_frame(&a->dcan.rx, f, signature, &t) != DCAN_RX_DONE) {
        return 0;
    }
    switch (t.kind == DCAN_MESSAGE ? 1000u + t.dtid : t.dtid) {
    case 1000u + DSDL_AHRS_RAW_IMU_ID: return raw_imu(a, &t, f->t_us);
    case 1000u + DSDL_AHRS_MAGNETIC_FIELD_STRENGTH2_ID: magnetometer(a, &t); return 0;
    case DSDL_PROTOCOL_GET_NODE_INFO_ID: get_node_info(a, &t); return 1;
    case DSDL_PROTOCOL_RESTART_NODE_ID: restart_node(a, &t); return 1;
    case DSDL_PARAM_GET_SET_ID: get_set(a, &t); return 1;
    default: execute_opcode(a, &t); return 1; /* the last service wanted() takes */
    }
}

/* ---- outputs ------------------------------------------------------------------------ */
hal_status_t app_dcan_publish(app_t *a, const app_output_t *o)
{
    dsdl_ahrs_solution_t m;
    uint8_t buf[DSDL_AHRS_SOLUTION_MAX_BYTES];
    int i;
    if (o->kind != APP_OUT_ATTITUDE || (o->flags & APP_FLAG_ALIGNED) == 0u) {
        return HAL_OK; /* no attitude yet: the NodeStatus says so (mode initialization) */
    }
    memset(&m, 0, sizeof(m));
    m.timestamp.usec = o->t_us & 0xFFFFFFFFFFFFFFull; /* 56 bits */
    dcan_quat_to_ned(o->quat, m.orientation_xyzw);
    dcan_angle_cov_to_ned(o->euler, o->angle_cov, m.orientation_covariance);
    m.orientation_covariance_len = 9u;
    dcan_flip_body(o->rates, m.angular_velocity);
    for (i = 0; i < 3; ++i) {
        m.angular_velocity_covariance[i] = o->rate_var[i]; /* diagonal; a flip keeps variances */
    }
    m.angular_velocity_covariance_len = 3u;
    dcan_flip_body(o->accel, m.linear_acceleration);
    m.linear_acceleration_covariance_len = 0u; /* not estimated: unknown */
    return publish_message(a, DSDL_AHRS_SOLUTION_ID, DSDL_AHRS_SOLUTION_SIGNATURE, PRIO_SOLUTION, &a->dcan.tid_solution,
                           buf, dsdl_ahrs_solution_encode(&m, buf, sizeof(buf)), o->rx_us);
}

void app_dcan_tick(app_t *a, uint64_t now)
{
    dsdl_protocol_node_status_t m;
    uint8_t buf[DSDL_PROTOCOL_NODE_STATUS_MAX_BYTES];
    if (now < a->dcan.next_status_us) {
        return;
    }
    /* on a 1 s grid; after a long stall the next one second from now */
    a->dcan.next_status_us += STATUS_PERIOD_US;
    if (a->dcan.next_status_us <= now) {
        a->dcan.next_status_us = now + STATUS_PERIOD_US;
    }
    node_status(a, now, &m);
    a->dcan.status_flags = 0u;
    (void)publish_message(a, DSDL_PROTOCOL_NODE_STATUS_ID, DSDL_PROTOCOL_NODE_STATUS_SIGNATURE, PRIO_STATUS,
                          &a->dcan.tid_status, buf, dsdl_protocol_node_status_encode(&m, buf, sizeof(buf)), now);
}
