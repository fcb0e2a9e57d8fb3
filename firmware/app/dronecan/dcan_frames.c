/*
 * dcan_frames.c - the filter's frames to DroneCAN's (dcan_frames.h).
 */
#include "dcan_frames.h"

#include <math.h>

void dcan_quat_to_ned(const float q[4], float xyzw[4])
{
    /* q_N = (0, s, s, 0), q_F = (0, 1, 0, 0), s = 1/sqrt(2): multiplied out,
     * q_N * q * q_F = -s (w + z, x + y, x - y, w - z) as (w, x, y, z). The sign is free. */
    const float s = 0.70710678118654752f;
    float w = s * (q[0] + q[3]);
    float x = s * (q[1] + q[2]);
    float y = s * (q[1] - q[2]);
    float z = s * (q[0] - q[3]);
    if (w < 0.0f) {
        w = -w;
        x = -x;
        y = -y;
        z = -z;
    }
    xyzw[0] = x;
    xyzw[1] = y;
    xyzw[2] = z;
    xyzw[3] = w;
}

void dcan_flip_body(const float v[3], float out[3])
{
    out[0] = v[0];
    out[1] = -v[1];
    out[2] = -v[2];
}

void dcan_angle_cov_to_ned(const float euler[3], const float c6[6], float out9[9])
{
    /* NED angles: roll phi, pitch -theta, yaw pi/2 - psi; sin and cos of those */
    const float sth = -sinf(euler[1]), cth = cosf(euler[1]);
    const float sps = cosf(euler[2]), cps = sinf(euler[2]);
    /* D C D: the cross terms of roll with pitch and yaw change sign */
    const float c[3][3] = {{c6[0], -c6[3], -c6[4]}, {-c6[3], c6[1], c6[5]}, {-c6[4], c6[5], c6[2]}};
    /* E: columns Rz Ry e_x, Rz e_y, e_z (the axes the NED roll, pitch, yaw turn about) */
    const float e[3][3] = {{cps * cth, -sps, 0.0f}, {sps * cth, cps, 0.0f}, {-sth, 0.0f, 1.0f}};
    float ec[3][3];
    int i, j, k;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            ec[i][j] = 0.0f;
            for (k = 0; k < 3; ++k) {
                ec[i][j] += e[i][k] * c[k][j];
            }
        }
    }
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            float v = 0.0f;
            for (k = 0; k < 3; ++k) {
                v += ec[i][k] * e[j][k];
            }
            out9[3 * i + j] = v;
        }
    }
}
