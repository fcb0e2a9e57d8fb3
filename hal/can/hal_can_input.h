/*
 * hal_can_input.h - one IMU input frame of hal/can/attekf.dbc at a time, and the helpers the
 * encoders share. Private to hal/can (hal_can_input.c, hal_can_rx.c, hal_can_output.c); the
 * interface is hal_can.h.
 */
#ifndef HAL_CAN_INPUT_H
#define HAL_CAN_INPUT_H

#include <stdint.h>

#include "canmsg_gen.h"
#include "hal_can.h"

/* Input frame kinds; a sensor kind k is the sample's bit (1 << k) (HAL_HAS_*), IMU_SYNC is
 * HAL_CAN_HAVE_SYNC. */
enum { HAL_CAN_KIND_GYRO = 0, HAL_CAN_KIND_ACCEL = 1, HAL_CAN_KIND_MAG = 2, HAL_CAN_KIND_SYNC = 3 };

/* One decoded input frame. */
typedef struct {
    uint16_t seq;
    float v[3];                    /* sensor frames: rad/s, m/s^2 or uT */
    uint8_t saturated;             /* sensor frames: a raw value at the end of its range */
    struct canmsg_imu_sync_t sync; /* IMU_SYNC */
} hal_can_input_t;

/* HAL_CAN_KIND_* of an id, or -1 if it is not an input frame. */
int hal_can_input_kind(uint32_t id);

/* Unpacks the 8 data bytes of a frame of that kind. 1 if done, 0 if the kind is unknown or
 * the generated unpacker refused the bytes. */
int hal_can_decode_input(int kind, const uint8_t data[8], hal_can_input_t *d);

/* v clamped to [lo, hi]; *sat set if it had to be (non-finite: 0). */
float hal_can_clamp(float v, float lo, float hi, int *sat);

/* Sets the id, an 8-byte length and the time of a frame about to be packed. */
void hal_can_put_frame(hal_can_frame_t *f, uint32_t id, uint64_t t_us);

#endif /* HAL_CAN_INPUT_H */
