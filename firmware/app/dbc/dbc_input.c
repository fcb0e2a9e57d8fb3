/*
 * dbc_input.c - the IMU input frames (IMU_GYRO, IMU_ACCEL, IMU_MAG, IMU_SYNC): one frame
 * decoded for the sample assembly (dbc_rx.c), a sample encoded as the IMU sends it.
 *
 * All bit layouts and scalings come from the cantools-generated canmsg_gen.c (from
 * firmware/app/dbc/attekf.dbc).
 */
#include "dbc_input.h"

#include <math.h>

/* The DBC's ids are consecutive from IMU_GYRO: the kinds are offsets from the base. */
typedef char dbc_input_ids_are_consecutive[(CANMSG_IMU_ACCEL_FRAME_ID == CANMSG_IMU_GYRO_FRAME_ID + 1 &&
                                            CANMSG_IMU_MAG_FRAME_ID == CANMSG_IMU_GYRO_FRAME_ID + 2 &&
                                            CANMSG_IMU_SYNC_FRAME_ID == CANMSG_IMU_GYRO_FRAME_ID + 3)
                                               ? 1
                                               : -1];

/* A raw 16-bit sensor value at either end of the signed range: the sender clamped it (the
 * DBC range is +-32767 LSB; -32768 is outside it and treated the same). */
static int raw_saturated(int16_t raw) { return raw >= INT16_MAX || raw <= -INT16_MAX; }

int dbc_decode_input(int kind, const uint8_t data[8], dbc_input_t *d)
{
    switch (kind) {
    case DBC_KIND_GYRO: {
        struct canmsg_imu_gyro_t m;
        if (canmsg_imu_gyro_unpack(&m, data, 8u) != 0) {
            return 0;
        }
        d->saturated = (uint8_t)(raw_saturated(m.gyro_x) || raw_saturated(m.gyro_y) ||
                                 raw_saturated(m.gyro_z));
        d->v[0] = canmsg_imu_gyro_gyro_x_decode(m.gyro_x);
        d->v[1] = canmsg_imu_gyro_gyro_y_decode(m.gyro_y);
        d->v[2] = canmsg_imu_gyro_gyro_z_decode(m.gyro_z);
        d->seq = m.seq;
        return 1;
    }
    case DBC_KIND_ACCEL: {
        struct canmsg_imu_accel_t m;
        if (canmsg_imu_accel_unpack(&m, data, 8u) != 0) {
            return 0;
        }
        d->saturated = (uint8_t)(raw_saturated(m.accel_x) || raw_saturated(m.accel_y) ||
                                 raw_saturated(m.accel_z));
        d->v[0] = canmsg_imu_accel_accel_x_decode(m.accel_x);
        d->v[1] = canmsg_imu_accel_accel_y_decode(m.accel_y);
        d->v[2] = canmsg_imu_accel_accel_z_decode(m.accel_z);
        d->seq = m.seq;
        return 1;
    }
    case DBC_KIND_MAG: {
        struct canmsg_imu_mag_t m;
        if (canmsg_imu_mag_unpack(&m, data, 8u) != 0) {
            return 0;
        }
        d->saturated = (uint8_t)(raw_saturated(m.mag_x) || raw_saturated(m.mag_y) ||
                                 raw_saturated(m.mag_z));
        d->v[0] = canmsg_imu_mag_mag_x_decode(m.mag_x);
        d->v[1] = canmsg_imu_mag_mag_y_decode(m.mag_y);
        d->v[2] = canmsg_imu_mag_mag_z_decode(m.mag_z);
        d->seq = m.seq;
        return 1;
    }
    case DBC_KIND_SYNC:
        if (canmsg_imu_sync_unpack(&d->sync, data, 8u) != 0) {
            return 0;
        }
        d->seq = d->sync.seq;
        d->saturated = 0u;
        return 1;
    default:
        return 0;
    }
}

/* v clamped to [lo, hi]; *sat set if it had to be (non-finite: 0). */
float dbc_clamp(float v, float lo, float hi, int *sat)
{
    if (!isfinite(v)) {
        *sat = 1;
        return 0.0f;
    }
    if (v > hi) {
        *sat = 1;
        return hi;
    }
    if (v < lo) {
        *sat = 1;
        return lo;
    }
    return v;
}

void dbc_put_frame(hal_frame_t *f, uint32_t id, uint64_t t_us)
{
    f->id = id;
    f->dlc = 8u;
    f->t_us = t_us;
}

/* One vector frame (gyro, accelerometer or magnetometer) of a sample; *sat set if clamped. */
static void encode_vector(int kind, const float v[3], uint16_t seq, uint64_t rx_us, hal_frame_t *frame,
                          int *sat)
{
    float c[3];
    int i;
    if (kind == DBC_KIND_GYRO) {
        struct canmsg_imu_gyro_t m;
        const float lim = canmsg_imu_gyro_gyro_x_decode(INT16_MAX);
        for (i = 0; i < 3; ++i) {
            c[i] = dbc_clamp(v[i], -lim, lim, sat);
        }
        m.gyro_x = canmsg_imu_gyro_gyro_x_encode(c[0]);
        m.gyro_y = canmsg_imu_gyro_gyro_y_encode(c[1]);
        m.gyro_z = canmsg_imu_gyro_gyro_z_encode(c[2]);
        m.seq = seq;
        (void)canmsg_imu_gyro_pack(frame->data, &m, 8u);
        dbc_put_frame(frame, CANMSG_IMU_GYRO_FRAME_ID, rx_us);
    } else if (kind == DBC_KIND_ACCEL) {
        struct canmsg_imu_accel_t m;
        const float lim = canmsg_imu_accel_accel_x_decode(INT16_MAX);
        for (i = 0; i < 3; ++i) {
            c[i] = dbc_clamp(v[i], -lim, lim, sat);
        }
        m.accel_x = canmsg_imu_accel_accel_x_encode(c[0]);
        m.accel_y = canmsg_imu_accel_accel_y_encode(c[1]);
        m.accel_z = canmsg_imu_accel_accel_z_encode(c[2]);
        m.seq = seq;
        (void)canmsg_imu_accel_pack(frame->data, &m, 8u);
        dbc_put_frame(frame, CANMSG_IMU_ACCEL_FRAME_ID, rx_us);
    } else {
        struct canmsg_imu_mag_t m;
        const float lim = canmsg_imu_mag_mag_x_decode(INT16_MAX);
        for (i = 0; i < 3; ++i) {
            c[i] = dbc_clamp(v[i], -lim, lim, sat);
        }
        m.mag_x = canmsg_imu_mag_mag_x_encode(c[0]);
        m.mag_y = canmsg_imu_mag_mag_y_encode(c[1]);
        m.mag_z = canmsg_imu_mag_mag_z_encode(c[2]);
        m.seq = seq;
        (void)canmsg_imu_mag_pack(frame->data, &m, 8u);
        dbc_put_frame(frame, CANMSG_IMU_MAG_FRAME_ID, rx_us);
    }
}

size_t dbc_encode_sample(const hal_sample_t *s, hal_frame_t frames[DBC_SAMPLE_FRAMES])
{
    size_t n = 0;
    uint8_t valid = 0u;
    uint8_t satbits = 0u;
    struct canmsg_imu_sync_t m;
    int k;
    for (k = DBC_KIND_GYRO; k <= DBC_KIND_MAG; ++k) {
        const uint8_t bit = (uint8_t)(1u << k);
        const float *v = (k == DBC_KIND_GYRO) ? s->gyro : (k == DBC_KIND_ACCEL) ? s->accel : s->mag;
        int sat = 0;
        if ((s->valid & bit) == 0u || !isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2])) {
            continue;
        }
        encode_vector(k, v, s->seq, s->rx_us, &frames[n++], &sat);
        valid |= bit;
        if (sat || (s->saturated & bit) != 0u) {
            satbits |= bit;
        }
    }
    m.time_us = (uint32_t)(s->t_us & 0xFFFFFFFFu);
    m.seq = s->seq;
    m.has_gyro = (valid & HAL_HAS_GYRO) ? 1u : 0u;
    m.has_accel = (valid & HAL_HAS_ACCEL) ? 1u : 0u;
    m.has_mag = (valid & HAL_HAS_MAG) ? 1u : 0u;
    m.sat_gyro = (satbits & HAL_HAS_GYRO) ? 1u : 0u;
    m.sat_accel = (satbits & HAL_HAS_ACCEL) ? 1u : 0u;
    m.sat_mag = (satbits & HAL_HAS_MAG) ? 1u : 0u;
    (void)canmsg_imu_sync_pack(frames[n].data, &m, 8u);
    dbc_put_frame(&frames[n++], CANMSG_IMU_SYNC_FRAME_ID, s->rx_us);
    return n;
}
