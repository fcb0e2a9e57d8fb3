/*
 * readme_main.c - runs the README's C snippet (readme_setup.inc / readme_step.inc, extracted
 * from README.md by CMakeLists.txt) on a fixed attitude at rest and checks its estimate.
 *
 * The sensor readings are those of a body at roll 10 deg, pitch -20 deg, yaw 120 deg (ZYX,
 * body to ENU), at rest, in a field of 50 uT with a dip of 60 deg, without noise: after 200
 * samples the snippet's quaternion must be within 0.5 deg of that attitude. Prints one line
 * (run.cmake compares it across the C, C++ and pkg-config builds) and exits 0 on success.
 * Also compiled as C++20 (readme_main.cpp): written in the common subset.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "att.h"

static void body_from_earth(const double R[3][3], const double e[3], float b[3])
{
    int i;
    for (i = 0; i < 3; ++i) { /* b = R^T e */
        b[i] = (float)(R[0][i] * e[0] + R[1][i] * e[1] + R[2][i] * e[2]);
    }
}

int main(void)
{
    const double pi = 3.14159265358979323846;
    const double roll = 10.0 * pi / 180.0, pitch = -20.0 * pi / 180.0, yaw = 120.0 * pi / 180.0;
    const double dip = 60.0 * pi / 180.0, field_uT = 50.0;
    const double sr = sin(roll), cr = cos(roll), sp = sin(pitch), cp = cos(pitch);
    const double sy = sin(yaw), cy = cos(yaw);
    /* R = Rz(yaw) Ry(pitch) Rx(roll): body to ENU */
    const double R[3][3] = {{cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr},
                            {sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr},
                            {-sp, cp * sr, cp * cr}};
    const double g_earth[3] = {0.0, 0.0, 9.81};
    const double m_earth[3] = {0.0, field_uT * cos(dip), -field_uT * sin(dip)};
    const double h[3] = {roll / 2.0, pitch / 2.0, yaw / 2.0};
    const double q_true[4] = {
        cos(h[2]) * cos(h[1]) * cos(h[0]) + sin(h[2]) * sin(h[1]) * sin(h[0]),
        cos(h[2]) * cos(h[1]) * sin(h[0]) - sin(h[2]) * sin(h[1]) * cos(h[0]),
        cos(h[2]) * sin(h[1]) * cos(h[0]) + sin(h[2]) * cos(h[1]) * sin(h[0]),
        sin(h[2]) * cos(h[1]) * cos(h[0]) - cos(h[2]) * sin(h[1]) * sin(h[0])};
    float acc[3], mag[3];
    float q_last[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    ekf_status_t last_status = EKF_ERR_NULL;
    double dot, err_deg;
    int i;

    body_from_earth(R, g_earth, acc);
    body_from_earth(R, m_earth, mag);
    {
        /* what the snippet reads: rad/s, m/s^2, uT */
        const float gx = 0.0f, gy = 0.0f, gz = 0.0f;
        const float ax = acc[0], ay = acc[1], az = acc[2];
        const float mx = mag[0], my = mag[1], mz = mag[2];
#include "readme_setup.inc"
        for (i = 0; i < 200; ++i) {
#include "readme_step.inc"
            last_status = st;
            memcpy(q_last, q, sizeof q_last);
        }
    }
    dot = fabs(q_last[0] * q_true[0] + q_last[1] * q_true[1] + q_last[2] * q_true[2] +
               q_last[3] * q_true[3]);
    err_deg = 2.0 * acos(dot > 1.0 ? 1.0 : dot) * 180.0 / pi;
    printf("readme snippet: q = %.7f %.7f %.7f %.7f, status %s, error %.4f deg\n", (double)q_last[0],
           (double)q_last[1], (double)q_last[2], (double)q_last[3], ekf_status_str(last_status),
           err_deg);
    if (last_status != EKF_OK || !(err_deg < 0.5)) {
        printf("FAIL: expected status EKF_OK and an error below 0.5 deg\n");
        return 1;
    }
    return 0;
}
