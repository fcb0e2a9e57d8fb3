/*
 * peer_fusion.c - Fusion's AHRS (xioTechnologies, imufusion source distribution) behind
 * peers.h: FusionAhrsUpdate with gyroscope, accelerometer and magnetometer.
 */
#include "Fusion.h"
#include "peers.h"

static FusionAhrs ahrs;

static void fusion_init(float dt_s)
{
    /* x-io's example settings (the same as attekf bench's): gain 0.5, 2000 deg/s,
     * rejection 10 deg, 5 s; NWU (earth z up, like the other peers' output) */
    const FusionAhrsSettings settings = {
        .sampleRate = 1.0f / dt_s,
        .convention = FusionConventionNwu,
        .gain = 0.5f,
        .gyroscopeRange = 2000.0f,
        .accelerationRejection = 10.0f,
        .magneticRejection = 10.0f,
        .rejectionTimeout = 5.0f,
    };
    FusionAhrsInitialise(&ahrs);
    FusionAhrsSetSettings(&ahrs, &settings);
}

static void fusion_step(const float gyro_rad_s[3], const float accel_m_s2[3], const float mag_ut[3])
{
    /* Fusion's units: deg/s, g */
    const FusionVector g = {.axis = {gyro_rad_s[0] * 57.2957795f, gyro_rad_s[1] * 57.2957795f,
                                     gyro_rad_s[2] * 57.2957795f}};
    const FusionVector a = {.axis = {accel_m_s2[0] * (1.0f / 9.80665f), accel_m_s2[1] * (1.0f / 9.80665f),
                                     accel_m_s2[2] * (1.0f / 9.80665f)}};
    const FusionVector m = {.axis = {mag_ut[0], mag_ut[1], mag_ut[2]}};
    FusionAhrsUpdate(&ahrs, g, a, m);
}

static void fusion_quaternion(float q[4])
{
    const FusionQuaternion f = FusionAhrsGetQuaternion(&ahrs);
    q[0] = f.element.w;
    q[1] = f.element.x;
    q[2] = f.element.y;
    q[3] = f.element.z;
}

const peer_t peer_fusion = {"Fusion", fusion_init, fusion_step, fusion_quaternion, sizeof(FusionAhrs)};
