/*
 * dbc_input.h - one IMU input frame of firmware/app/dbc/attekf.dbc at a time, and the helpers
 * the encoders share. Private to firmware/app/dbc (dbc_input.c, dbc_rx.c, dbc_output.c); the
 * interface is dbc.h.
 */
#ifndef DBC_INPUT_H
#define DBC_INPUT_H

#include <stdint.h>

#include "canmsg_gen.h"
#include "dbc.h"

/* Input frame kinds, in id order from the IMU base; a sensor kind k is the sample's bit
 * (1 << k) (HAL_HAS_*). */
enum { DBC_KIND_GYRO = 0, DBC_KIND_ACCEL = 1, DBC_KIND_MAG = 2, DBC_KIND_SYNC = 3 };

/* One decoded input frame. */
typedef struct {
    uint16_t seq;
    float v[3];                    /* sensor frames: rad/s, m/s^2 or uT */
    uint8_t saturated;             /* sensor frames: a raw value at the end of its range */
    struct canmsg_imu_sync_t sync; /* IMU_SYNC */
} dbc_input_t;

/* Unpacks the 8 data bytes of a frame of that kind. 1 if done, 0 if the kind is unknown or
 * the generated unpacker refused the bytes. */
int dbc_decode_input(int kind, const uint8_t data[8], dbc_input_t *d);

/* v clamped to [lo, hi]; *sat set if it had to be (non-finite: 0). */
float dbc_clamp(float v, float lo, float hi, int *sat);

/* Sets the id, an 8-byte length and the time of a frame about to be packed. */
void dbc_put_frame(hal_frame_t *f, uint32_t id, uint64_t t_us);

#endif /* DBC_INPUT_H */
