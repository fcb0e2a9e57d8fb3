/*
 * test_dcan.c - DroneCAN below the node: the transfer layer (dronecan/dcan_transfer.c: ids,
 * CRC, tail bytes, multi-frame reassembly and every refusal) and the frame conversions
 * (dronecan/dcan_frames.c), each against an independent computation: rotation matrices built
 * from their definition, and a numerical perturbation of the Euler angles.
 */
#include <math.h>
#include <string.h>

#include "dcan_frames.h"
#include "dcan_transfer.h"
#include "dsdl_bits.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static dcan_rx_t rx; /* the receiver under test */

/* ---- ids and CRC ----------------------------------------------------------------------- */
static void test_ids_round_trip(void)
{
    dcan_transfer_t t, u;
    memset(&t, 0, sizeof(t));
    t.kind = DCAN_MESSAGE;
    t.dtid = 1000u;
    t.source = 100u;
    t.priority = 16u;
    TEST_ASSERT_EQUAL_HEX32(HAL_FRAME_EXT | (16u << 24) | (1000u << 8) | 100u, dcan_make_id(&t));
    TEST_ASSERT_EQUAL_INT(1, dcan_parse_id(dcan_make_id(&t), &u));
    TEST_ASSERT_EQUAL_UINT8(DCAN_MESSAGE, u.kind);
    TEST_ASSERT_EQUAL_UINT16(1000u, u.dtid);
    TEST_ASSERT_EQUAL_UINT8(100u, u.source);
    TEST_ASSERT_EQUAL_UINT8(16u, u.priority);
    t.kind = DCAN_REQUEST;
    t.dtid = 11u;
    t.dest = 42u;
    t.source = 127u;
    t.priority = 30u;
    TEST_ASSERT_EQUAL_HEX32(HAL_FRAME_EXT | (30u << 24) | (11u << 16) | 0x8000u | (42u << 8) | 0x80u | 127u,
                            dcan_make_id(&t));
    TEST_ASSERT_EQUAL_INT(1, dcan_parse_id(dcan_make_id(&t), &u));
    TEST_ASSERT_EQUAL_UINT8(DCAN_REQUEST, u.kind);
    TEST_ASSERT_EQUAL_UINT16(11u, u.dtid);
    TEST_ASSERT_EQUAL_UINT8(42u, u.dest);
    TEST_ASSERT_EQUAL_UINT8(127u, u.source);
    t.kind = DCAN_RESPONSE;
    TEST_ASSERT_EQUAL_INT(1, dcan_parse_id(dcan_make_id(&t), &u));
    TEST_ASSERT_EQUAL_UINT8(DCAN_RESPONSE, u.kind);
    TEST_ASSERT_EQUAL_INT(0, dcan_parse_id(0x123u, &u)); /* an 11-bit frame is no DroneCAN */
    /* anonymous message: 2 bits of type id */
    TEST_ASSERT_EQUAL_INT(1, dcan_parse_id(HAL_FRAME_EXT | (1u << 24) | (0x2A5u << 10) | (2u << 8), &u));
    TEST_ASSERT_EQUAL_UINT8(0u, u.source);
    TEST_ASSERT_EQUAL_UINT16(2u, u.dtid);
}

static void test_crc(void)
{
    static const uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    uint8_t sig[8];
    const uint64_t s = 0x72A63A3C6F41FA9Bull;
    int i;
    TEST_ASSERT_EQUAL_HEX16(0x29B1u, dcan_crc16(0xFFFFu, check, sizeof(check))); /* CRC-16-CCITT-FALSE */
    for (i = 0; i < 8; ++i) {
        sig[i] = (uint8_t)(s >> (8 * i));
    }
    TEST_ASSERT_EQUAL_HEX16(dcan_crc16(0xFFFFu, sig, 8u), dcan_crc_start(s));
    TEST_ASSERT_EQUAL_HEX16(dcan_crc16(dcan_crc16(0xFFFFu, check, 4u), check + 4, 5u),
                            dcan_crc16(0xFFFFu, check, 9u)); /* continues */
}

/* ---- frames of a transfer -------------------------------------------------------------- */
static void make_transfer(dcan_transfer_t *t, const uint8_t *payload, size_t len, uint8_t tid)
{
    memset(t, 0, sizeof(*t));
    t->kind = DCAN_MESSAGE;
    t->dtid = 1003u;
    t->source = 7u;
    t->priority = 8u;
    t->tid = tid;
    t->payload = payload;
    t->len = len;
    t->t_us = 5000u;
}

static void test_tail_bytes_and_crc_layout(void)
{
    uint8_t p[20];
    hal_frame_t f[DCAN_TX_FRAMES_MAX];
    dcan_transfer_t t;
    uint16_t crc;
    size_t i, n;
    for (i = 0; i < sizeof(p); ++i) {
        p[i] = (uint8_t)(3u * i + 1u);
    }
    make_transfer(&t, p, 7u, 9u);
    n = dcan_encode(&t, 0x1234u, f, DCAN_TX_FRAMES_MAX);
    TEST_ASSERT_EQUAL_UINT(1u, n); /* 7 bytes: one frame, no CRC */
    TEST_ASSERT_EQUAL_UINT8(8u, f[0].dlc);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(p, f[0].data, 7);
    TEST_ASSERT_EQUAL_HEX8(0x80u | 0x40u | 9u, f[0].data[7]);
    make_transfer(&t, p, 20u, 31u);
    n = dcan_encode(&t, 0x1234u, f, DCAN_TX_FRAMES_MAX);
    TEST_ASSERT_EQUAL_UINT(dcan_frames_needed(20u), n);
    TEST_ASSERT_EQUAL_UINT(4u, n); /* 2 + 20 = 22 bytes: 7 + 7 + 7 + 1 */
    crc = dcan_crc16(dcan_crc_start(0x1234u), p, 20u);
    TEST_ASSERT_EQUAL_HEX8(crc & 0xFFu, f[0].data[0]);
    TEST_ASSERT_EQUAL_HEX8(crc >> 8, f[0].data[1]);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(p, &f[0].data[2], 5);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(&p[5], f[1].data, 7);
    TEST_ASSERT_EQUAL_HEX8(0x80u | 31u, f[0].data[7]);       /* start, toggle 0 */
    TEST_ASSERT_EQUAL_HEX8(0x20u | 31u, f[1].data[7]);       /* toggle 1 */
    TEST_ASSERT_EQUAL_HEX8(0x00u | 31u, f[2].data[7]);       /* toggle 0 */
    TEST_ASSERT_EQUAL_UINT8(2u, f[3].dlc);                   /* the last byte and its tail */
    TEST_ASSERT_EQUAL_HEX8(p[19], f[3].data[0]);
    TEST_ASSERT_EQUAL_HEX8(0x40u | 0x20u | 31u, f[3].data[1]); /* end, toggle 1 */
    for (i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_HEX32(dcan_make_id(&t), f[i].id);
    }
    TEST_ASSERT_EQUAL_UINT(0u, dcan_encode(&t, 0x1234u, f, 3u)); /* does not fit */
    make_transfer(&t, p, 0u, 0u);
    TEST_ASSERT_EQUAL_UINT(1u, dcan_encode(&t, 0x1234u, f, 1u)); /* empty: the tail alone */
    TEST_ASSERT_EQUAL_UINT8(1u, f[0].dlc);
}

/* Every payload length from 0 to the largest accepted reassembles to the same bytes. */
static void test_every_length_round_trips(void)
{
    static uint8_t p[DCAN_RX_PAYLOAD_MAX];
    static hal_frame_t f[DCAN_TX_FRAMES_MAX];
    size_t len, i, n;
    for (i = 0; i < sizeof(p); ++i) {
        p[i] = (uint8_t)(i * 7u + 3u);
    }
    dcan_rx_init(&rx);
    for (len = 0; len <= DCAN_RX_PAYLOAD_MAX; ++len) {
        dcan_transfer_t t, r;
        make_transfer(&t, p, len, (uint8_t)(len & 31u));
        n = dcan_encode(&t, 0xABCDEF0123456789ull, f, DCAN_TX_FRAMES_MAX);
        TEST_ASSERT_TRUE(n > 0u);
        for (i = 0; i < n; ++i) {
            dcan_rx_result_t res;
            TEST_ASSERT_EQUAL_INT(1, dcan_parse_id(f[i].id, &r));
            res = dcan_rx_frame(&rx, &f[i], 0xABCDEF0123456789ull, &r);
            TEST_ASSERT_EQUAL_INT(i + 1u == n ? DCAN_RX_DONE : DCAN_RX_MORE, res);
        }
        TEST_ASSERT_EQUAL_UINT(len, r.len);
        TEST_ASSERT_EQUAL_UINT8(len & 31u, r.tid);
        if (len > 0u) {
            TEST_ASSERT_EQUAL_HEX8_ARRAY(p, r.payload, len);
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0u, rx.errors);
}

/* Feeds frames[0..n) (ids parsed as the caller does); returns the result of the last one. */
static dcan_rx_result_t feed(const hal_frame_t *f, size_t n, uint64_t sig, dcan_transfer_t *r)
{
    dcan_rx_result_t res = DCAN_RX_MORE;
    size_t i;
    for (i = 0; i < n; ++i) {
        (void)dcan_parse_id(f[i].id, r);
        res = dcan_rx_frame(&rx, &f[i], sig, r);
    }
    return res;
}

static void test_broken_transfers_are_refused(void)
{
    uint8_t p[30];
    hal_frame_t f[8], g[8];
    dcan_transfer_t t, r;
    const uint64_t sig = 0x1122334455667788ull;
    size_t n, i;
    for (i = 0; i < sizeof(p); ++i) {
        p[i] = (uint8_t)i;
    }
    make_transfer(&t, p, sizeof(p), 4u);
    n = dcan_encode(&t, sig, f, 8u);
    TEST_ASSERT_EQUAL_UINT(5u, n);

    dcan_rx_init(&rx); /* the whole transfer, then each fault */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_DONE, feed(f, n, sig, &r));
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(&f[1], n - 1u, sig, &r)); /* no start */
    TEST_ASSERT_TRUE(rx.errors >= 1u);

    dcan_rx_init(&rx);
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(f, n, sig ^ 1u, &r));
    TEST_ASSERT_EQUAL_UINT32(1u, rx.errors); /* another data type's signature: CRC mismatch */

    dcan_rx_init(&rx);
    memcpy(g, f, sizeof(g));
    g[2].data[3] ^= 0x10u; /* a corrupted byte */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(g, n, sig, &r));
    TEST_ASSERT_EQUAL_UINT32(1u, rx.errors);

    dcan_rx_init(&rx);
    memcpy(g, f, sizeof(g));
    g[2].data[7] ^= 0x20u; /* a wrong toggle */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(g, 3u, sig, &r));
    TEST_ASSERT_EQUAL_UINT32(1u, rx.errors);

    dcan_rx_init(&rx);
    memcpy(g, f, sizeof(g));
    g[1].data[7] = (uint8_t)((g[1].data[7] & ~0x1Fu) | 5u); /* another transfer id */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(g, 2u, sig, &r));

    dcan_rx_init(&rx);
    memcpy(g, f, sizeof(g));
    g[1].dlc = 5u; /* a short frame before the end */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(g, 2u, sig, &r));

    dcan_rx_init(&rx);
    memcpy(g, f, sizeof(g));
    g[0].data[7] |= 0x20u; /* a start with the toggle set */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(g, 1u, sig, &r));

    dcan_rx_init(&rx); /* the transfer started again: the first try is lost, the second one taken */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_MORE, feed(f, 2u, sig, &r));
    TEST_ASSERT_EQUAL_INT(DCAN_RX_DONE, feed(f, n, sig, &r));
    TEST_ASSERT_EQUAL_UINT32(1u, rx.errors);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(p, r.payload, sizeof(p));

    dcan_rx_init(&rx); /* too slow: the rest comes after the transfer timeout */
    (void)feed(f, 2u, sig, &r);
    memcpy(g, f, sizeof(g));
    for (i = 2; i < n; ++i) {
        g[i].t_us = f[0].t_us + DCAN_TRANSFER_TIMEOUT_US + 1u;
    }
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(&g[2], n - 2u, sig, &r));
    TEST_ASSERT_TRUE(rx.errors >= 2u); /* the timed-out transfer and the orphan frames */

    dcan_rx_init(&rx);
    memcpy(g, f, sizeof(g));
    g[0].dlc = 0u; /* no tail byte */
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(g, 1u, sig, &r));
}

static void test_interleaved_sources_and_no_room(void)
{
    uint8_t p[12];
    hal_frame_t f[DCAN_RX_SLOTS + 1u][3];
    dcan_transfer_t t, r;
    size_t k;
    memset(p, 0x5A, sizeof(p));
    dcan_rx_init(&rx);
    for (k = 0; k <= DCAN_RX_SLOTS; ++k) {
        make_transfer(&t, p, sizeof(p), 1u);
        t.source = (uint8_t)(10u + k);
        TEST_ASSERT_EQUAL_UINT(2u, dcan_encode(&t, 1u, f[k], 3u));
    }
    for (k = 0; k < DCAN_RX_SLOTS; ++k) { /* DCAN_RX_SLOTS transfers at once: all taken */
        TEST_ASSERT_EQUAL_INT(DCAN_RX_MORE, feed(&f[k][0], 1u, 1u, &r));
    }
    TEST_ASSERT_EQUAL_INT(DCAN_RX_REFUSED, feed(&f[DCAN_RX_SLOTS][0], 1u, 1u, &r)); /* one more: no room */
    for (k = 0; k < DCAN_RX_SLOTS; ++k) {
        TEST_ASSERT_EQUAL_INT(DCAN_RX_DONE, feed(&f[k][1], 1u, 1u, &r));
        TEST_ASSERT_EQUAL_UINT8(10u + k, r.source);
        TEST_ASSERT_EQUAL_UINT(sizeof(p), r.len);
    }
}

/* ---- frames ---------------------------------------------------------------------------- */
static void mat_mul(const double a[9], const double b[9], double c[9])
{
    int i, j, k;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            c[3 * i + j] = 0.0;
            for (k = 0; k < 3; ++k) {
                c[3 * i + j] += a[3 * i + k] * b[3 * k + j];
            }
        }
    }
}

/* R = Rz(psi) Ry(theta) Rx(phi), from the elementary rotations. */
static void euler_matrix(double phi, double theta, double psi, double r[9])
{
    const double rot_x[9] = {1, 0, 0, 0, cos(phi), -sin(phi), 0, sin(phi), cos(phi)};
    const double rot_y[9] = {cos(theta), 0, sin(theta), 0, 1, 0, -sin(theta), 0, cos(theta)};
    const double rot_z[9] = {cos(psi), -sin(psi), 0, sin(psi), cos(psi), 0, 0, 0, 1};
    double t[9];
    mat_mul(rot_y, rot_x, t);
    mat_mul(rot_z, t, r);
}

static void quat_matrix(const double q[4] /* w x y z */, double r[9])
{
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    r[0] = 1 - 2 * (y * y + z * z);
    r[1] = 2 * (x * y - w * z);
    r[2] = 2 * (x * z + w * y);
    r[3] = 2 * (x * y + w * z);
    r[4] = 1 - 2 * (x * x + z * z);
    r[5] = 2 * (y * z - w * x);
    r[6] = 2 * (x * z - w * y);
    r[7] = 2 * (y * z + w * x);
    r[8] = 1 - 2 * (x * x + y * y);
}

/* The unit quaternion (w x y z) of a rotation matrix (Shepperd's method). */
static void matrix_quat(const double r[9], double q[4])
{
    const double tr = r[0] + r[4] + r[8];
    if (tr > 0.0) {
        const double s = 2.0 * sqrt(tr + 1.0);
        q[0] = s / 4.0;
        q[1] = (r[7] - r[5]) / s;
        q[2] = (r[2] - r[6]) / s;
        q[3] = (r[3] - r[1]) / s;
    } else if (r[0] > r[4] && r[0] > r[8]) {
        const double s = 2.0 * sqrt(1.0 + r[0] - r[4] - r[8]);
        q[0] = (r[7] - r[5]) / s;
        q[1] = s / 4.0;
        q[2] = (r[1] + r[3]) / s;
        q[3] = (r[2] + r[6]) / s;
    } else if (r[4] > r[8]) {
        const double s = 2.0 * sqrt(1.0 + r[4] - r[0] - r[8]);
        q[0] = (r[2] - r[6]) / s;
        q[1] = (r[1] + r[3]) / s;
        q[2] = s / 4.0;
        q[3] = (r[5] + r[7]) / s;
    } else {
        const double s = 2.0 * sqrt(1.0 + r[8] - r[0] - r[4]);
        q[0] = (r[3] - r[1]) / s;
        q[1] = (r[2] + r[6]) / s;
        q[2] = (r[5] + r[7]) / s;
        q[3] = s / 4.0;
    }
}

/* The filter's attitude -> DroneCAN's, against the matrices: R_ned_frd = N R F with N mapping ENU
 * to NED ((e, n, u) -> (n, e, -u)) and F mapping FRD to FLU ((f, r, d) -> (f, -r, -d)). */
static void test_quaternion_to_ned_matches_the_matrices(void)
{
    static const double n_mat[9] = {0, 1, 0, 1, 0, 0, 0, 0, -1};
    static const double f_mat[9] = {1, 0, 0, 0, -1, 0, 0, 0, -1};
    int k;
    for (k = 0; k < 500; ++k) {
        /* a grid through every quadrant and near the poles */
        const double phi = -3.1 + 6.2 * (double)((k * 37) % 500) / 500.0;
        const double theta = -1.55 + 3.1 * (double)((k * 91) % 500) / 500.0;
        const double psi = -3.1 + 6.2 * (double)((k * 53) % 500) / 500.0;
        double r[9], t[9], want[9], got[9], q[4], qd[4];
        float qf[4], xyzw[4];
        int i;
        euler_matrix(phi, theta, psi, r);
        matrix_quat(r, q);
        for (i = 0; i < 4; ++i) {
            qf[i] = (float)q[i];
        }
        dcan_quat_to_ned(qf, xyzw);
        qd[0] = (double)xyzw[3];
        qd[1] = (double)xyzw[0];
        qd[2] = (double)xyzw[1];
        qd[3] = (double)xyzw[2];
        TEST_ASSERT_TRUE(qd[0] >= 0.0);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, 1.0, qd[0] * qd[0] + qd[1] * qd[1] + qd[2] * qd[2] + qd[3] * qd[3]);
        mat_mul(r, f_mat, t);
        mat_mul(n_mat, t, want);
        quat_matrix(qd, got);
        for (i = 0; i < 9; ++i) {
            TEST_ASSERT_DOUBLE_WITHIN(1e-6, want[i], got[i]);
        }
    }
}

/* Physical cases: level facing north is DroneCAN's identity; facing east is yaw +90 deg about
 * down; the nose 30 deg up is pitch +30 deg in NED (negative pitch in the filter's frame, whose
 * y axis points left). */
static void test_quaternion_physical_cases(void)
{
    const double d = 3.14159265358979323846 / 180.0;
    struct {
        double phi, theta, psi;      /* the filter's angles */
        double roll, pitch, yaw;     /* what an aerospace user expects, NED */
    } c[] = {{0, 0, 90 * d, 0, 0, 0}, {0, 0, 0, 0, 0, 90 * d}, {0, -30 * d, 90 * d, 0, 30 * d, 0},
             {20 * d, 0, 90 * d, 20 * d, 0, 0}, {10 * d, -20 * d, 180 * d, 10 * d, 20 * d, -90 * d}};
    size_t k;
    for (k = 0; k < sizeof(c) / sizeof(c[0]); ++k) {
        double r[9], q[4];
        float qf[4], xyzw[4];
        /* the aerospace ZYX quaternion of (roll, pitch, yaw) */
        const double cr = cos(c[k].roll / 2), sr = sin(c[k].roll / 2), cp = cos(c[k].pitch / 2),
                     sp = sin(c[k].pitch / 2), cy = cos(c[k].yaw / 2), sy = sin(c[k].yaw / 2);
        double want[4];
        int i;
        want[0] = cr * cp * cy + sr * sp * sy; /* w */
        want[1] = sr * cp * cy - cr * sp * sy; /* x */
        want[2] = cr * sp * cy + sr * cp * sy; /* y */
        want[3] = cr * cp * sy - sr * sp * cy; /* z */
        if (want[0] < 0) {
            for (i = 0; i < 4; ++i) {
                want[i] = -want[i];
            }
        }
        euler_matrix(c[k].phi, c[k].theta, c[k].psi, r);
        matrix_quat(r, q);
        for (i = 0; i < 4; ++i) {
            qf[i] = (float)q[i];
        }
        dcan_quat_to_ned(qf, xyzw);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, want[1], (double)xyzw[0]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, want[2], (double)xyzw[1]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, want[3], (double)xyzw[2]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, want[0], (double)xyzw[3]);
    }
}

static void test_body_vectors_flip(void)
{
    const float flu[3] = {1.0f, 2.0f, 9.81f}, frd[3] = {1.0f, -2.0f, -9.81f};
    float out[3], back[3];
    dcan_flip_body(flu, out);
    TEST_ASSERT_EQUAL_FLOAT_ARRAY(frd, out, 3);
    dcan_flip_body(out, back);
    TEST_ASSERT_EQUAL_FLOAT_ARRAY(flu, back, 3);
}

/* The covariance conversion against a perturbation: for a small change d of the filter's Euler
 * angles, the rotation R_ned(e + d) R_ned(e)^T is a small rotation w about the NED axes; the
 * conversion of the rank-one covariance d d^T must be w w^T. */
static void test_angle_covariance_matches_a_perturbation(void)
{
    static const double n_mat[9] = {0, 1, 0, 1, 0, 0, 0, 0, -1};
    static const double f_mat[9] = {1, 0, 0, 0, -1, 0, 0, 0, -1};
    int k;
    for (k = 0; k < 200; ++k) {
        const double e[3] = {-2.5 + 5.0 * (double)((k * 31) % 200) / 200.0,
                             -1.2 + 2.4 * (double)((k * 17) % 200) / 200.0,
                             -3.0 + 6.0 * (double)((k * 59) % 200) / 200.0};
        const double dl[3] = {1e-4 * (1 + k % 3), -2e-4 * (1 + k % 5), 1.5e-4 * (1 + k % 7)};
        const double d2 = dl[0] * dl[0] + dl[1] * dl[1] + dl[2] * dl[2];
        double r0[9], r1[9], t[9], a[9], b[9], bt[9], m[9], w[3];
        float ef[3], c6[6], out[9];
        int i, j;
        euler_matrix(e[0], e[1], e[2], r0);
        euler_matrix(e[0] + dl[0], e[1] + dl[1], e[2] + dl[2], r1);
        mat_mul(r0, f_mat, t);
        mat_mul(n_mat, t, a); /* R_ned(e) */
        mat_mul(r1, f_mat, t);
        mat_mul(n_mat, t, b); /* R_ned(e + d) */
        for (i = 0; i < 3; ++i) {
            for (j = 0; j < 3; ++j) {
                bt[3 * i + j] = a[3 * j + i];
            }
        }
        mat_mul(b, bt, m);
        w[0] = 0.5 * (m[7] - m[5]);
        w[1] = 0.5 * (m[2] - m[6]);
        w[2] = 0.5 * (m[3] - m[1]);
        for (i = 0; i < 3; ++i) {
            ef[i] = (float)e[i];
        }
        c6[0] = (float)(dl[0] * dl[0]);
        c6[1] = (float)(dl[1] * dl[1]);
        c6[2] = (float)(dl[2] * dl[2]);
        c6[3] = (float)(dl[0] * dl[1]);
        c6[4] = (float)(dl[0] * dl[2]);
        c6[5] = (float)(dl[1] * dl[2]);
        dcan_angle_cov_to_ned(ef, c6, out);
        for (i = 0; i < 3; ++i) {
            for (j = 0; j < 3; ++j) {
                /* the perturbation's second-order terms and float rounding: 0.5 % of |d|^2 */
                TEST_ASSERT_DOUBLE_WITHIN(5e-3 * d2, w[i] * w[j], (double)out[3 * i + j]);
            }
        }
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_ids_round_trip);
    RUN_TEST(test_crc);
    RUN_TEST(test_tail_bytes_and_crc_layout);
    RUN_TEST(test_every_length_round_trips);
    RUN_TEST(test_broken_transfers_are_refused);
    RUN_TEST(test_interleaved_sources_and_no_room);
    RUN_TEST(test_quaternion_to_ned_matches_the_matrices);
    RUN_TEST(test_quaternion_physical_cases);
    RUN_TEST(test_body_vectors_flip);
    RUN_TEST(test_angle_covariance_matches_a_perturbation);
    return UNITY_END();
}
