/*
 * test_app_dronecan.c - the node on a DroneCAN bus (firmware/app/app_dronecan.c) over the virtual
 * backend: RawIMU and MagneticFieldStrength2 in, ahrs.Solution out in DroneCAN's frames,
 * NodeStatus every second with its health, GetNodeInfo, param.GetSet (live and pending
 * parameters, refusals), param.ExecuteOpcode, RestartNode, and other nodes' traffic on the bus
 * counted as foreign, never as an error. The test speaks DroneCAN with the node's own transfer
 * layer and generated serialisation; tests/python/test_dronecan_node.py does the same with the
 * dronecan Python package.
 */
#include <math.h>
#include <string.h>

#include "app.h"
#include "app_param.h"
#include "dcan_transfer.h"
#include "dsdl_gen.h"
#include "hal_virtual.h"
#include "unity.h"

#define NODE 100u
#define IMU 21u
#define TOOL 127u
#define QLEN 4096
#define PERIOD_US 10000u

static hal_virtual_t v;
static hal_t hal;
static app_t app;
static hal_frame_t fqueue[QLEN];
static dcan_rx_t bus_rx;   /* reassembles what the node sends */
static int saves, erases;

/* What the node sent, reassembled. */
#define MAX_SEEN 2048
typedef struct {
    uint16_t dtid;
    uint8_t kind;
    uint8_t tid;
    uint8_t dest;
    uint64_t t_us;
    uint8_t payload[400];
    size_t len;
} seen_t;
static seen_t seen[MAX_SEEN];
static int n_seen;

static uint64_t signature_of(uint16_t dtid, uint8_t kind)
{
    if (kind == DCAN_MESSAGE) {
        return dtid == DSDL_AHRS_SOLUTION_ID ? DSDL_AHRS_SOLUTION_SIGNATURE : DSDL_PROTOCOL_NODE_STATUS_SIGNATURE;
    }
    switch (dtid) {
    case DSDL_PROTOCOL_GET_NODE_INFO_ID: return DSDL_PROTOCOL_GET_NODE_INFO_SIGNATURE;
    case DSDL_PROTOCOL_RESTART_NODE_ID: return DSDL_PROTOCOL_RESTART_NODE_SIGNATURE;
    case DSDL_PARAM_GET_SET_ID: return DSDL_PARAM_GET_SET_SIGNATURE;
    default: return DSDL_PARAM_EXECUTE_OPCODE_SIGNATURE;
    }
}

static void on_frame(void *user, const hal_frame_t *f)
{
    dcan_transfer_t t;
    (void)user;
    TEST_ASSERT_TRUE((f->id & HAL_FRAME_EXT) != 0u);
    TEST_ASSERT_EQUAL_INT(1, dcan_parse_id(f->id, &t));
    TEST_ASSERT_EQUAL_UINT8(NODE, t.source);
    if (dcan_rx_frame(&bus_rx, f, signature_of(t.dtid, t.kind), &t) == DCAN_RX_DONE && n_seen < MAX_SEEN) {
        seen_t *s = &seen[n_seen++];
        s->dtid = t.dtid;
        s->kind = t.kind;
        s->tid = t.tid;
        s->dest = t.dest;
        s->t_us = f->t_us;
        s->len = t.len;
        memcpy(s->payload, t.payload, t.len);
    }
}

static int save_hook(void *user, const app_config_t *cfg)
{
    (void)user;
    (void)cfg;
    ++saves;
    return 1;
}

static int erase_hook(void *user)
{
    (void)user;
    ++erases;
    return 1;
}

void setUp(void)
{
    n_seen = 0;
    saves = erases = 0;
    dcan_rx_init(&bus_rx);
    hal_virtual_init(&v, fqueue, QLEN, NULL, 0u, NULL, 0u);
    hal_virtual_set_sinks(&v, on_frame, NULL, NULL, NULL);
    hal_virtual_bind(&v, &hal);
}
void tearDown(void) {}

static void start(uint8_t imu_node)
{
    const app_hooks_t hooks = {save_hook, erase_hook, NULL, NULL};
    app_config_t cfg;
    int i;
    app_default_config(&cfg);
    cfg.node.protocol = APP_PROTO_DRONECAN;
    cfg.node.input = APP_PROTO_DRONECAN;
    cfg.node.node_id = NODE;
    cfg.node.imu_node = imu_node;
    for (i = 0; i < APP_UNIQUE_ID_BYTES; ++i) {
        cfg.node.unique_id[i] = (uint8_t)(0xA0 + i);
    }
    TEST_ASSERT_EQUAL_INT(EKF_OK, app_init(&app, &cfg, &hal));
    app_set_hooks(&app, &hooks);
}

static void push_transfer(uint8_t kind, uint16_t dtid, uint64_t sig, uint8_t source, uint8_t dest, uint8_t tid,
                          const uint8_t *payload, int len, uint64_t t_us)
{
    hal_frame_t f[DCAN_TX_FRAMES_MAX];
    dcan_transfer_t t;
    size_t n, i;
    TEST_ASSERT_TRUE(len >= 0);
    memset(&t, 0, sizeof(t));
    t.kind = kind;
    t.dtid = dtid;
    t.source = source;
    t.dest = dest;
    t.priority = 8u;
    t.tid = tid;
    t.t_us = t_us;
    t.payload = payload;
    t.len = (size_t)len;
    n = dcan_encode(&t, sig, f, DCAN_TX_FRAMES_MAX);
    TEST_ASSERT_TRUE(n > 0u);
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f[i]));
    }
}

/* Level, facing north, at rest: the sensors in DroneCAN's body frame (FRD). */
static void push_imu(uint8_t source, uint8_t tid, uint64_t t_us, int with_mag)
{
    dsdl_ahrs_raw_imu_t m;
    uint8_t buf[DSDL_AHRS_RAW_IMU_MAX_BYTES];
    memset(&m, 0, sizeof(m));
    if (with_mag) {
        dsdl_ahrs_magnetic_field_strength2_t g;
        uint8_t gb[DSDL_AHRS_MAGNETIC_FIELD_STRENGTH2_MAX_BYTES];
        memset(&g, 0, sizeof(g));
        g.magnetic_field_ga[0] = 0.2f; /* north */
        g.magnetic_field_ga[2] = 0.4f; /* down */
        push_transfer(DCAN_MESSAGE, DSDL_AHRS_MAGNETIC_FIELD_STRENGTH2_ID, DSDL_AHRS_MAGNETIC_FIELD_STRENGTH2_SIGNATURE,
                      source, 0u, tid, gb, dsdl_ahrs_magnetic_field_strength2_encode(&g, gb, sizeof(gb)), t_us);
    }
    m.timestamp.usec = t_us;
    m.accelerometer_latest[2] = -9.81f; /* the specific force points up: -z in FRD */
    push_transfer(DCAN_MESSAGE, DSDL_AHRS_RAW_IMU_ID, DSDL_AHRS_RAW_IMU_SIGNATURE, source, 0u, tid, buf,
                  dsdl_ahrs_raw_imu_encode(&m, buf, sizeof(buf)), t_us);
}

static void push_stream(uint8_t source, int n, uint64_t t0)
{
    int k;
    for (k = 0; k < n; ++k) {
        push_imu(source, (uint8_t)(k & 31), t0 + PERIOD_US * (uint64_t)k, 1);
    }
}

/* Polls until every queued frame is taken (the input stays open: the clock can go on). */
static void run(void)
{
    int polls = 0;
    while (v.frames_n > 0u) {
        (void)app_poll(&app, 10000u);
        TEST_ASSERT_TRUE(++polls < 200000);
    }
    (void)app_poll(&app, 0u);
}

/* Polls until the clock reaches t_us (no input needed). */
static void run_until(uint64_t t_us)
{
    int polls = 0;
    while (hal_virtual_now_us(&v) < t_us) {
        (void)app_poll(&app, 10000u);
        TEST_ASSERT_TRUE(++polls < 200000);
    }
}

static uint32_t counter(app_counter_id_t id)
{
    uint32_t c[APP_CNT_COUNT];
    app_get_counters(&app, c);
    return c[id];
}

static int count_seen(uint8_t kind, uint16_t dtid)
{
    int i, n = 0;
    for (i = 0; i < n_seen; ++i) {
        n += (seen[i].kind == kind && seen[i].dtid == dtid);
    }
    return n;
}

static const seen_t *last_seen(uint8_t kind, uint16_t dtid)
{
    int i;
    for (i = n_seen - 1; i >= 0; --i) {
        if (seen[i].kind == kind && seen[i].dtid == dtid) {
            return &seen[i];
        }
    }
    TEST_FAIL_MESSAGE("the node sent no such transfer");
    return NULL;
}

static void test_raw_imu_in_solution_out(void)
{
    dsdl_ahrs_solution_t s;
    const seen_t *last;
    int i;
    start(0u);
    push_stream(IMU, 200, 1000000u);
    run();
    TEST_ASSERT_EQUAL_UINT32(200u, counter(APP_CNT_SAMPLES));
    TEST_ASSERT_EQUAL_UINT32(200u, counter(APP_CNT_OUTPUTS)); /* 100 Hz output on a 100 Hz stream */
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_TRANSFER_ERRORS) + counter(APP_CNT_GAPS) + counter(APP_CNT_FOREIGN) +
                                     counter(APP_CNT_EKF_REJECTED));
    /* one Solution per aligned output (the first align_samples samples align the filter) */
    TEST_ASSERT_EQUAL_INT(200 - (int)att_default_settings.align_samples + 1,
                          count_seen(DCAN_MESSAGE, DSDL_AHRS_SOLUTION_ID));
    last = last_seen(DCAN_MESSAGE, DSDL_AHRS_SOLUTION_ID);
    TEST_ASSERT_EQUAL_INT(0, dsdl_ahrs_solution_decode(&s, last->payload, last->len));
    /* level, facing north: DroneCAN's identity (float16 resolution around 1: 5e-4) */
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 0.0f, s.orientation_xyzw[0]);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 0.0f, s.orientation_xyzw[1]);
    TEST_ASSERT_FLOAT_WITHIN(0.02f, 0.0f, s.orientation_xyzw[2]);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 1.0f, s.orientation_xyzw[3]);
    TEST_ASSERT_EQUAL_UINT8(9u, s.orientation_covariance_len);
    for (i = 0; i < 3; ++i) {
        TEST_ASSERT_TRUE(s.orientation_covariance[4 * i] > 0.0f && s.orientation_covariance[4 * i] < 0.1f);
        TEST_ASSERT_FLOAT_WITHIN(0.01f, 0.0f, s.angular_velocity[i]);
    }
    TEST_ASSERT_EQUAL_FLOAT(s.orientation_covariance[1], s.orientation_covariance[3]); /* symmetric */
    TEST_ASSERT_EQUAL_UINT8(3u, s.angular_velocity_covariance_len);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, -9.81f, s.linear_acceleration[2]); /* back in FRD */
    TEST_ASSERT_EQUAL_UINT8(0u, s.linear_acceleration_covariance_len);
    TEST_ASSERT_EQUAL_UINT64(1000000u + 199u * PERIOD_US, s.timestamp.usec);
    /* transfer ids count up by one per Solution, modulo 32 */
    TEST_ASSERT_EQUAL_UINT8((uint8_t)((count_seen(DCAN_MESSAGE, DSDL_AHRS_SOLUTION_ID) - 1) & 31), last->tid);
}

static void test_lost_and_repeated_imu_messages(void)
{
    int k;
    start(0u);
    for (k = 0; k < 40; ++k) {
        if (k == 20 || k == 21) {
            continue; /* two lost: a gap of 2 */
        }
        push_imu(IMU, (uint8_t)(k & 31), 1000000u + PERIOD_US * (uint64_t)k, 0);
        if (k == 30) {
            push_imu(IMU, (uint8_t)(k & 31), 1000000u + PERIOD_US * (uint64_t)k, 0); /* repeated */
        }
    }
    run();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_GAPS));
    TEST_ASSERT_EQUAL_UINT32(2u, counter(APP_CNT_MISSING));
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_DUPLICATE));
    TEST_ASSERT_EQUAL_UINT32(38u, counter(APP_CNT_SAMPLES));
}

static void node_status_at(int i, dsdl_protocol_node_status_t *m)
{
    int k, n = -1;
    for (k = 0; k < n_seen; ++k) {
        if (seen[k].kind == DCAN_MESSAGE && seen[k].dtid == DSDL_PROTOCOL_NODE_STATUS_ID && ++n == i) {
            TEST_ASSERT_EQUAL_INT(0, dsdl_protocol_node_status_decode(m, seen[k].payload, seen[k].len));
            return;
        }
    }
    TEST_FAIL_MESSAGE("no such NodeStatus");
}

/* NodeStatus every second on the node's clock: uptime, mode initialisation until aligned, health
 * error while no IMU sample comes, ok with a clean stream, the filter's flags. */
static void test_node_status_every_second(void)
{
    dsdl_protocol_node_status_t m;
    hal_virtual_set_clock(&v, 1000000u);
    start(0u);
    run_until(3500000u); /* 2.5 s without input */
    push_stream(IMU, 300, 3500000u);
    run();
    run_until(8200000u);
    TEST_ASSERT_EQUAL_INT(8, count_seen(DCAN_MESSAGE, DSDL_PROTOCOL_NODE_STATUS_ID)); /* at 1.0 .. 8.0 s */
    node_status_at(0, &m);
    TEST_ASSERT_EQUAL_UINT32(0u, m.uptime_sec);
    TEST_ASSERT_EQUAL_UINT8(1u, m.mode);   /* initialisation */
    TEST_ASSERT_EQUAL_UINT8(0u, m.health); /* not stale yet */
    node_status_at(2, &m);
    TEST_ASSERT_EQUAL_UINT32(2u, m.uptime_sec);
    TEST_ASSERT_EQUAL_UINT8(2u, m.health); /* no input: error */
    node_status_at(5, &m);                 /* 6.0 s: 2.5 s into the stream */
    TEST_ASSERT_EQUAL_UINT32(5u, m.uptime_sec);
    TEST_ASSERT_EQUAL_UINT8(0u, m.mode);   /* operational */
    TEST_ASSERT_EQUAL_UINT8(0u, m.health);
    TEST_ASSERT_EQUAL_HEX16((uint16_t)att_flags(app_filter(&app)) & 0x7FFFu, m.vendor_specific_status_code & 0x7FFFu);
    TEST_ASSERT_TRUE((m.vendor_specific_status_code & 0x0001u) != 0u); /* ATT_FLAG_ALIGNED */
    node_status_at(7, &m);                 /* 8.0 s: the stream ended at 6.5 s */
    TEST_ASSERT_EQUAL_UINT8(2u, m.health);
}

static void request(uint16_t dtid, uint64_t sig, uint8_t tid, const uint8_t *payload, int len, uint64_t t_us)
{
    push_transfer(DCAN_REQUEST, dtid, sig, TOOL, NODE, tid, payload, len, t_us);
}

static const seen_t *response(uint16_t dtid, uint8_t tid)
{
    const seen_t *r = last_seen(DCAN_RESPONSE, dtid);
    TEST_ASSERT_EQUAL_UINT8(TOOL, r->dest);
    TEST_ASSERT_EQUAL_UINT8(tid, r->tid); /* answers carry the request's transfer id */
    return r;
}

static void test_get_node_info(void)
{
    dsdl_protocol_get_node_info_resp_t r;
    const seen_t *s;
    int i;
    start(0u);
    request(DSDL_PROTOCOL_GET_NODE_INFO_ID, DSDL_PROTOCOL_GET_NODE_INFO_SIGNATURE, 3u, NULL, 0, 2000u);
    run();
    s = response(DSDL_PROTOCOL_GET_NODE_INFO_ID, 3u);
    TEST_ASSERT_EQUAL_INT(0, dsdl_protocol_get_node_info_resp_decode(&r, s->payload, s->len));
    TEST_ASSERT_EQUAL_UINT8(15u, r.name_len);
    TEST_ASSERT_EQUAL_MEMORY("org.attekf.ahrs", r.name, 15u);
    for (i = 0; i < APP_UNIQUE_ID_BYTES; ++i) {
        TEST_ASSERT_EQUAL_UINT8(0xA0 + i, r.hardware_version.unique_id[i]);
    }
    TEST_ASSERT_EQUAL_UINT8(1u, r.status.mode);
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_REQUESTS));
}

/* A GetSet request by name (value: REAL, INTEGER or none) or by index. */
static void get_set(const char *name, uint16_t index, uint8_t tag, float value, uint8_t tid, uint64_t t_us)
{
    dsdl_param_get_set_req_t q;
    uint8_t buf[DSDL_PARAM_GET_SET_REQ_MAX_BYTES];
    memset(&q, 0, sizeof(q));
    q.index = index;
    q.value.tag = tag;
    q.value.real_value = value;
    q.value.integer_value = (int64_t)value;
    if (name != NULL) {
        q.name_len = (uint8_t)strlen(name);
        memcpy(q.name, name, q.name_len);
    }
    request(DSDL_PARAM_GET_SET_ID, DSDL_PARAM_GET_SET_SIGNATURE, tid, buf,
            dsdl_param_get_set_req_encode(&q, buf, sizeof(buf)), t_us);
}

static void get_set_answer(uint8_t tid, dsdl_param_get_set_resp_t *r)
{
    const seen_t *s;
    run();
    s = response(DSDL_PARAM_GET_SET_ID, tid);
    TEST_ASSERT_EQUAL_INT(0, dsdl_param_get_set_resp_decode(r, s->payload, s->len));
    hal_virtual_init(&v, fqueue, QLEN, NULL, 0u, NULL, 0u); /* a fresh input queue, same clock: */
    hal_virtual_set_sinks(&v, on_frame, NULL, NULL, NULL);
    hal_virtual_set_clock(&v, s->t_us);
}

static void test_param_get_set(void)
{
    dsdl_param_get_set_resp_t r;
    app_param_info_t info;
    const int decl = app_param_index("mag_declination");
    const int lpf = app_param_index("accel_lpf_order");
    TEST_ASSERT_TRUE(decl >= 0 && lpf >= 0);
    start(0u);
    /* by index: the first parameter, with its default, range and name */
    get_set(NULL, 0u, DSDL_PARAM_VALUE_EMPTY, 0.0f, 1u, 1000u);
    get_set_answer(1u, &r);
    TEST_ASSERT_EQUAL_INT(1, app_param_info(0u, &info));
    TEST_ASSERT_EQUAL_MEMORY(info.name, r.name, strlen(info.name));
    TEST_ASSERT_EQUAL_UINT8(DSDL_PARAM_VALUE_REAL_VALUE, r.value.tag);
    TEST_ASSERT_EQUAL_FLOAT(info.def, r.default_value.real_value);
    TEST_ASSERT_EQUAL_FLOAT(info.lo, r.min_value.real_value);
    TEST_ASSERT_EQUAL_FLOAT(info.hi, r.max_value.real_value);
    /* a live one by name: in force at once */
    get_set("mag_declination", 0u, DSDL_PARAM_VALUE_REAL_VALUE, 0.25f, 2u, 2000u);
    get_set_answer(2u, &r);
    TEST_ASSERT_EQUAL_FLOAT(0.25f, r.value.real_value);
    TEST_ASSERT_EQUAL_FLOAT(0.25f, app_filter(&app)->settings.mag_declination);
    /* one that needs a restart: kept, said so (pending flag), not in force */
    get_set("accel_lpf_order", 0u, DSDL_PARAM_VALUE_INTEGER_VALUE, 1.0f, 3u, 3000u);
    get_set_answer(3u, &r);
    TEST_ASSERT_EQUAL_UINT8(DSDL_PARAM_VALUE_INTEGER_VALUE, r.value.tag);
    TEST_ASSERT_EQUAL_INT64(1, r.value.integer_value);
    TEST_ASSERT_EQUAL_INT64(2, r.default_value.integer_value);
    TEST_ASSERT_EQUAL_UINT16(2u, app_filter(&app)->settings.accel_lpf_order);
    TEST_ASSERT_EQUAL_UINT8(1u, app.n_pending);
    /* refused: out of range, and a string; the answer carries the value in force */
    get_set("mag_declination", 0u, DSDL_PARAM_VALUE_REAL_VALUE, 7.0f, 4u, 4000u);
    get_set_answer(4u, &r);
    TEST_ASSERT_EQUAL_FLOAT(0.25f, r.value.real_value);
    get_set("mag_declination", 0u, DSDL_PARAM_VALUE_STRING_VALUE, 0.0f, 5u, 5000u);
    get_set_answer(5u, &r);
    TEST_ASSERT_EQUAL_FLOAT(0.25f, r.value.real_value);
    TEST_ASSERT_EQUAL_UINT32(2u, counter(APP_CNT_REFUSED));
    /* no such parameter: empty name and value */
    get_set("no.such", 0u, DSDL_PARAM_VALUE_EMPTY, 0.0f, 6u, 6000u);
    get_set_answer(6u, &r);
    TEST_ASSERT_EQUAL_UINT8(0u, r.name_len);
    TEST_ASSERT_EQUAL_UINT8(DSDL_PARAM_VALUE_EMPTY, r.value.tag);
    get_set(NULL, (uint16_t)app_param_count(), DSDL_PARAM_VALUE_EMPTY, 0.0f, 7u, 7000u);
    get_set_answer(7u, &r);
    TEST_ASSERT_EQUAL_UINT8(0u, r.name_len);
    /* the last parameter by index exists */
    get_set(NULL, (uint16_t)(app_param_count() - 1u), DSDL_PARAM_VALUE_EMPTY, 0.0f, 8u, 8000u);
    get_set_answer(8u, &r);
    TEST_ASSERT_TRUE(r.name_len > 0u);
    TEST_ASSERT_EQUAL_UINT32(4u, counter(APP_CNT_REFUSED));
}

static void opcode(uint8_t code, uint8_t tid, uint64_t t_us, int *ok)
{
    dsdl_param_execute_opcode_req_t q;
    dsdl_param_execute_opcode_resp_t r;
    uint8_t buf[DSDL_PARAM_EXECUTE_OPCODE_REQ_MAX_BYTES];
    const seen_t *s;
    q.opcode = code;
    q.argument = 0;
    request(DSDL_PARAM_EXECUTE_OPCODE_ID, DSDL_PARAM_EXECUTE_OPCODE_SIGNATURE, tid, buf,
            dsdl_param_execute_opcode_req_encode(&q, buf, sizeof(buf)), t_us);
    run();
    s = response(DSDL_PARAM_EXECUTE_OPCODE_ID, tid);
    TEST_ASSERT_EQUAL_INT(0, dsdl_param_execute_opcode_resp_decode(&r, s->payload, s->len));
    *ok = r.ok;
    hal_virtual_init(&v, fqueue, QLEN, NULL, 0u, NULL, 0u);
    hal_virtual_set_sinks(&v, on_frame, NULL, NULL, NULL);
    hal_virtual_set_clock(&v, s->t_us);
}

static void test_execute_opcode(void)
{
    int ok = 0;
    start(0u);
    opcode(0u, 1u, 1000u, &ok); /* save */
    TEST_ASSERT_EQUAL_INT(1, ok);
    TEST_ASSERT_EQUAL_INT(1, saves);
    opcode(1u, 2u, 2000u, &ok); /* erase */
    TEST_ASSERT_EQUAL_INT(1, ok);
    TEST_ASSERT_EQUAL_INT(1, erases);
    opcode(7u, 3u, 3000u, &ok); /* no such opcode */
    TEST_ASSERT_EQUAL_INT(0, ok);
    app_set_hooks(&app, NULL); /* no storage: refused */
    opcode(0u, 4u, 4000u, &ok);
    TEST_ASSERT_EQUAL_INT(0, ok);
    TEST_ASSERT_EQUAL_UINT32(2u, counter(APP_CNT_REFUSED));
}

static void restart_request(uint64_t magic, uint8_t tid, uint64_t t_us, int *ok)
{
    dsdl_protocol_restart_node_req_t q;
    dsdl_protocol_restart_node_resp_t r;
    uint8_t buf[DSDL_PROTOCOL_RESTART_NODE_REQ_MAX_BYTES];
    const seen_t *s;
    q.magic_number = magic;
    request(DSDL_PROTOCOL_RESTART_NODE_ID, DSDL_PROTOCOL_RESTART_NODE_SIGNATURE, tid, buf,
            dsdl_protocol_restart_node_req_encode(&q, buf, sizeof(buf)), t_us);
    run();
    s = response(DSDL_PROTOCOL_RESTART_NODE_ID, tid);
    TEST_ASSERT_EQUAL_INT(0, dsdl_protocol_restart_node_resp_decode(&r, s->payload, s->len));
    *ok = r.ok;
}

/* A restart puts the pending parameters in force and starts the uptime again; a request with
 * the wrong magic number is refused. */
static void test_restart_node(void)
{
    dsdl_param_get_set_resp_t r;
    dsdl_protocol_node_status_t m;
    int ok = 1, n_status;
    hal_virtual_set_clock(&v, 1000000u);
    start(0u);
    get_set("accel_lpf_order", 0u, DSDL_PARAM_VALUE_INTEGER_VALUE, 1.0f, 1u, 4500000u);
    get_set_answer(1u, &r);
    restart_request(0x123u, 2u, 4600000u, &ok);
    TEST_ASSERT_EQUAL_INT(0, ok);
    TEST_ASSERT_EQUAL_UINT16(2u, app_filter(&app)->settings.accel_lpf_order);
    hal_virtual_init(&v, fqueue, QLEN, NULL, 0u, NULL, 0u);
    hal_virtual_set_sinks(&v, on_frame, NULL, NULL, NULL);
    hal_virtual_set_clock(&v, 4650000u);
    n_status = count_seen(DCAN_MESSAGE, DSDL_PROTOCOL_NODE_STATUS_ID);
    restart_request(0xACCE551B1Eull, 3u, 4700000u, &ok);
    TEST_ASSERT_EQUAL_INT(1, ok);
    TEST_ASSERT_EQUAL_UINT16(1u, app_filter(&app)->settings.accel_lpf_order);
    TEST_ASSERT_EQUAL_UINT8(0u, app.n_pending);
    run_until(6000000u);
    TEST_ASSERT_TRUE(count_seen(DCAN_MESSAGE, DSDL_PROTOCOL_NODE_STATUS_ID) > n_status);
    node_status_at(n_status, &m); /* the first status after the restart: at once */
    TEST_ASSERT_EQUAL_UINT32(0u, m.uptime_sec);
    TEST_ASSERT_EQUAL_UINT64(4700000u, seen[n_seen - 2].t_us); /* ... and one second later */
    node_status_at(n_status + 1, &m);
    TEST_ASSERT_EQUAL_UINT32(1u, m.uptime_sec);
    node_status_at(n_status - 1, &m); /* the last before it */
    TEST_ASSERT_EQUAL_UINT32(3u, m.uptime_sec);
}

/* Other nodes' traffic between the IMU's messages: their messages (single- and multi-frame),
 * services between them, anonymous frames, 11-bit frames, a second IMU when the node is told
 * which one to use. All foreign, no error, the same outputs as without them. */
static void test_other_nodes_are_foreign(void)
{
    static seen_t clean[4];
    dsdl_protocol_node_status_t st;
    uint8_t p[40], ns[DSDL_PROTOCOL_NODE_STATUS_MAX_BYTES];
    int round, k, solutions[2];
    memset(p, 0x33, sizeof(p));
    memset(&st, 0, sizeof(st));
    for (round = 0; round < 2; ++round) {
        setUp();
        start(IMU);
        for (k = 0; k < 100; ++k) {
            const uint64_t t = 1000000u + PERIOD_US * (uint64_t)k;
            push_imu(IMU, (uint8_t)(k & 31), t, 1);
            if (round == 1) {
                hal_frame_t f;
                push_transfer(DCAN_MESSAGE, DSDL_PROTOCOL_NODE_STATUS_ID, DSDL_PROTOCOL_NODE_STATUS_SIGNATURE, 30u, 0u,
                              (uint8_t)(k & 31), ns, dsdl_protocol_node_status_encode(&st, ns, sizeof(ns)), t);
                push_transfer(DCAN_MESSAGE, 1034u, 0x1234u, 31u, 0u, (uint8_t)(k & 31), p, 14, t); /* ESC status */
                push_transfer(DCAN_MESSAGE, 1063u, 0x5678u, 32u, 0u, (uint8_t)(k & 31), p, 40, t); /* GNSS Fix2 */
                push_transfer(DCAN_REQUEST, DSDL_PARAM_GET_SET_ID, DSDL_PARAM_GET_SET_SIGNATURE, 33u, 34u,
                              (uint8_t)(k & 31), p, 20, t); /* between two other nodes */
                push_transfer(DCAN_MESSAGE, DSDL_AHRS_RAW_IMU_ID, DSDL_AHRS_RAW_IMU_SIGNATURE, 35u, 0u,
                              (uint8_t)(k & 31), p, 30, t); /* a second IMU */
                memset(&f, 0, sizeof(f));
                f.t_us = t;
                f.id = HAL_FRAME_EXT | (1u << 24) | (0x155u << 10) | (1u << 8); /* anonymous */
                f.dlc = 8u;
                TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f));
                f.id = 0x123u; /* 11-bit */
                TEST_ASSERT_EQUAL_INT(HAL_OK, hal_virtual_push_frame(&v, &f));
            }
        }
        run();
        solutions[round] = count_seen(DCAN_MESSAGE, DSDL_AHRS_SOLUTION_ID);
        if (round == 0) {
            memcpy(clean, &seen[n_seen - 4], sizeof(clean));
        }
    }
    TEST_ASSERT_EQUAL_INT(solutions[0], solutions[1]);
    TEST_ASSERT_EQUAL_MEMORY(clean[3].payload, seen[n_seen - 1].payload, clean[3].len);
    TEST_ASSERT_EQUAL_UINT32(100u, counter(APP_CNT_SAMPLES));
    TEST_ASSERT_EQUAL_UINT32(0u, counter(APP_CNT_TRANSFER_ERRORS) + counter(APP_CNT_DUPLICATE) + counter(APP_CNT_GAPS));
    TEST_ASSERT_TRUE(counter(APP_CNT_FOREIGN) >= 100u * 7u);
    TEST_ASSERT_TRUE((app_last_output(&app)->flags & APP_FLAG_FRAME_ERROR) == 0u);
}

/* A broken transfer of a message the node takes is an error: counted, flagged, the health a
 * warning. */
static void test_broken_transfer_is_an_error(void)
{
    dsdl_ahrs_raw_imu_t m;
    dsdl_protocol_node_status_t st;
    uint8_t buf[DSDL_AHRS_RAW_IMU_MAX_BYTES];
    hal_frame_t f[DCAN_TX_FRAMES_MAX];
    dcan_transfer_t t;
    size_t n, i;
    int k, flagged = 0;
    hal_virtual_set_clock(&v, 1000000u);
    start(0u);
    push_stream(IMU, 100, 1000000u);
    memset(&m, 0, sizeof(m));
    memset(&t, 0, sizeof(t));
    t.kind = DCAN_MESSAGE;
    t.dtid = DSDL_AHRS_RAW_IMU_ID;
    t.source = IMU;
    t.tid = 4u;
    t.t_us = 2000000u;
    t.payload = buf;
    t.len = (size_t)dsdl_ahrs_raw_imu_encode(&m, buf, sizeof(buf));
    n = dcan_encode(&t, DSDL_AHRS_RAW_IMU_SIGNATURE, f, DCAN_TX_FRAMES_MAX);
    f[1].data[0] ^= 1u; /* CRC mismatch */
    for (i = 0; i < n; ++i) {
        hal_virtual_push_frame(&v, &f[i]);
    }
    for (k = 100; k < 150; ++k) {
        push_imu(IMU, (uint8_t)(k & 31), 1000000u + PERIOD_US * (uint64_t)k, 1);
    }
    run();
    TEST_ASSERT_EQUAL_UINT32(1u, counter(APP_CNT_TRANSFER_ERRORS));
    for (k = 0; k < count_seen(DCAN_MESSAGE, DSDL_PROTOCOL_NODE_STATUS_ID); ++k) {
        node_status_at(k, &st);
        flagged |= (st.health == 1u);
    }
    TEST_ASSERT_TRUE(flagged);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_raw_imu_in_solution_out);
    RUN_TEST(test_lost_and_repeated_imu_messages);
    RUN_TEST(test_node_status_every_second);
    RUN_TEST(test_get_node_info);
    RUN_TEST(test_param_get_set);
    RUN_TEST(test_execute_opcode);
    RUN_TEST(test_restart_node);
    RUN_TEST(test_other_nodes_are_foreign);
    RUN_TEST(test_broken_transfer_is_an_error);
    return UNITY_END();
}
