/*
 * dcan_frames.h - the filter's frames to DroneCAN's and back (docs/can_protocol.md,
 * "DroneCAN: frames").
 *
 * The filter: body axes with z up at rest (x forward, y left: FLU), earth frame ENU,
 * R = Rz(psi) Ry(theta) Rx(phi) maps body to earth (firmware/att/att_defs.h).
 * DroneCAN (uavcan.equipment.ahrs, following the aerospace convention of the UAVCAN v0
 * specification): body axes x forward, y right, z down (FRD), earth frame NED; RawIMU's
 * comments name the FRD axes, and the Solution's quaternion maps body to NED.
 *
 *   body:   v_frd = F v_flu, F = diag(1, -1, -1) = Rx(pi)
 *   earth:  v_ned = N v_enu, N = [[0 1 0] [1 0 0] [0 0 -1]] = Rz(pi/2) Rx(pi)
 *   so      R_ned_frd = N R F = Rz(pi/2 - psi) Ry(-theta) Rx(phi): the same roll, pitch
 *           negated, yaw = pi/2 - psi, and as quaternions q_ned_frd = q_N * q * q_F.
 */
#ifndef DCAN_FRAMES_H
#define DCAN_FRAMES_H

#ifdef __cplusplus
extern "C" {
#endif

/* q (w, x, y, z; body FLU to ENU, unit) -> the DroneCAN orientation (x, y, z, w; body FRD to
 * NED), w >= 0. */
void dcan_quat_to_ned(const float q_wxyz[4], float xyzw[4]);

/* A body vector FLU -> FRD, or FRD -> FLU (the same map: y and z change sign). */
void dcan_flip_body(const float v[3], float out[3]);

/* The covariance of the filter's roll, pitch and yaw errors (rad^2, packed as
 * att_get_angle_covariance: phi phi, theta theta, psi psi, phi theta, phi psi, theta psi) at
 * the Euler angles euler (rad, ENU) -> the covariance of the attitude error as a small rotation
 * about the NED axes (rad^2, 3x3 row-major): C = E D C_euler D E^T, where D maps the errors of
 * the filter's angles to those of the NED angles (roll, -pitch, -yaw) and E maps errors of
 * the NED angles to a rotation vector in NED. */
void dcan_angle_cov_to_ned(const float euler[3], const float cov6[6], float out9[9]);

#ifdef __cplusplus
}
#endif

#endif /* DCAN_FRAMES_H */
