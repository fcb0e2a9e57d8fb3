"""Orientation errors with the BROAD benchmark's definitions, and the quaternion helpers
they need.

Quaternions are [w x y z] arrays (shape (4,) or (N, 4)), Hamilton product, rotating body to
ENU (the estimator's convention, firmware/att/att_defs.h). Euler angles are ZYX:
q = qz(yaw) * qy(pitch) * qx(roll).

BROAD (Laidig et al., Data 6(7), 2021) scores an estimate q_est against the truth q_ref with
the error quaternion expressed in the earth frame

    e = q_est * inv(q_ref)

and three angles of e:
    total        2 acos(|e_w|)                  the whole rotation between estimate and truth
    heading      2 atan(|e_z / e_w|)            its part about the vertical (earth z)
    inclination  2 acos(sqrt(e_w^2 + e_z^2))    its part about horizontal axes (tilt)
Each is an RMSE over the scored ("movement") samples, NaN (no truth) ignored, in degrees.

6D variant (no magnetometer): the heading is then not observable and any constant heading
offset is not the estimator's fault. remove_heading_offset() takes the signed heading angle
of e on every scored sample, delta_i = 2 atan2(e_z, e_w) (the rotation about earth z in the
swing-twist split of e), forms their circular mean delta = atan2(mean sin, mean cos), and
rotates the estimate by -delta about earth z (q_est <- qz(-delta) * q_est) before the errors
are computed. Heading *drift* (a varying offset) still counts. See docs/host_tools.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np

# ---------------------------------------------------------------------------------------------
# Quaternion helpers
# ---------------------------------------------------------------------------------------------


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b, row-wise (either may be a single quaternion)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate = inverse of a unit quaternion."""
    q = np.array(q, dtype=np.float64, copy=True)
    q[..., 1:] *= -1.0
    return q


def quat_normalize(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_about_z(angle_rad: np.ndarray) -> np.ndarray:
    """Rotation by angle (rad) about the z axis."""
    a = np.asarray(angle_rad, dtype=np.float64) / 2.0
    z = np.zeros_like(a)
    return np.stack([np.cos(a), z, z, np.sin(a)], axis=-1)


def quat_from_rotvec(v: np.ndarray) -> np.ndarray:
    """Quaternion of the rotation vector v (rad, axis * angle), row-wise; exact for small v."""
    v = np.asarray(v, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = angle / 2.0
    # sin(angle/2)/angle -> 1/2 as angle -> 0 (Taylor to 4th order below 1e-4 rad)
    k = np.where(angle > 1e-4, np.sin(half) / np.where(angle > 0, angle, 1.0),
                 0.5 - angle ** 2 / 48.0)
    return np.concatenate([np.cos(half), v * k], axis=-1)


def euler_to_quat(euler: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (rad; roll, pitch, yaw) -> [w x y z]; NaN rows stay NaN."""
    e = np.asarray(euler, dtype=np.float64)
    cr, sr = np.cos(e[..., 0] / 2), np.sin(e[..., 0] / 2)
    cp, sp = np.cos(e[..., 1] / 2), np.sin(e[..., 1] / 2)
    cy, sy = np.cos(e[..., 2] / 2), np.sin(e[..., 2] / 2)
    return np.stack([cy * cp * cr + sy * sp * sr,
                     cy * cp * sr - sy * sp * cr,
                     cy * sp * cr + sy * cp * sr,
                     sy * cp * cr - cy * sp * sr], axis=-1)


def quat_to_euler(q: np.ndarray) -> np.ndarray:
    """[w x y z] -> ZYX Euler angles (rad): roll, yaw in [-pi, pi], pitch in [-pi/2, pi/2]."""
    q = quat_normalize(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotates vectors v by q (v' = q v q^*), row-wise."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def wrap_pi(a: np.ndarray) -> np.ndarray:
    """Angles (rad) wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


# ---------------------------------------------------------------------------------------------
# BROAD errors
# ---------------------------------------------------------------------------------------------


def error_quat_earth(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """e = q_est * inv(q_ref), both normalised first; NaN rows propagate."""
    return quat_normalize(quat_mul(quat_normalize(q_est), quat_conj(quat_normalize(q_ref))))


def total_error(e: np.ndarray) -> np.ndarray:
    """Rotation angle of e, rad, in [0, pi]."""
    return 2.0 * np.arccos(np.clip(np.abs(e[..., 0]), 0.0, 1.0))


def heading_error(e: np.ndarray) -> np.ndarray:
    """Angle of e about earth z, rad, in [0, pi]. 2 atan(|e_z/e_w|), written with atan2 so
    that e_w = 0 gives pi instead of a division by zero."""
    return 2.0 * np.arctan2(np.abs(e[..., 3]), np.abs(e[..., 0]))


def inclination_error(e: np.ndarray) -> np.ndarray:
    """Angle of e about horizontal axes, rad, in [0, pi]."""
    return 2.0 * np.arccos(np.clip(np.sqrt(e[..., 0] ** 2 + e[..., 3] ** 2), 0.0, 1.0))


def rmse(x: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """Root mean square over mask (all if None), NaN ignored; NaN if nothing is left."""
    x = np.asarray(x, dtype=np.float64)
    if mask is not None:
        x = x[np.asarray(mask, bool)]
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def heading_offset(q_est: np.ndarray, q_ref: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """Circular mean (rad) of the signed heading angle 2 atan2(e_z, e_w) of the earth-frame
    error over mask (NaN rows ignored); NaN if no sample is usable."""
    e = error_quat_earth(q_est, q_ref)
    # e and -e are the same rotation: fix the sign so that the angle is within [-pi, pi]
    e = e * np.where(e[..., :1] < 0, -1.0, 1.0)
    delta = 2.0 * np.arctan2(e[..., 3], e[..., 0])
    ok = np.isfinite(delta) if mask is None else (np.asarray(mask, bool) & np.isfinite(delta))
    if not ok.any():
        return float("nan")
    return float(np.arctan2(np.mean(np.sin(delta[ok])), np.mean(np.cos(delta[ok]))))


def remove_heading_offset(q_est: np.ndarray, q_ref: np.ndarray,
                          mask: Optional[np.ndarray] = None) -> np.ndarray:
    """q_est rotated about earth z by minus its mean heading offset (6D evaluation)."""
    delta = heading_offset(q_est, q_ref, mask)
    if not np.isfinite(delta):
        return np.array(q_est, dtype=np.float64, copy=True)
    return quat_mul(quat_about_z(-delta), q_est)


@dataclass
class Errors:
    """Per-sample errors (rad) and their RMSE over the scored samples (deg)."""

    total: np.ndarray
    heading: np.ndarray
    inclination: np.ndarray
    scored: np.ndarray          # bool: movement & truth & estimate present
    heading_offset_rad: float   # removed before scoring (6D), 0.0 otherwise

    def rmse_deg(self) -> Dict[str, float]:
        return {name: float(np.degrees(rmse(getattr(self, name), self.scored)))
                for name in ("total", "heading", "inclination")}


def orientation_errors(q_est: np.ndarray, q_ref: np.ndarray, movement: Optional[np.ndarray] = None,
                       six_d: bool = False) -> Errors:
    """BROAD errors of q_est (N, 4) against q_ref (N, 4). movement: scored samples (None = all);
    samples without truth or without estimate (NaN rows) are never scored. six_d: remove the
    mean heading offset first (see the module docstring)."""
    q_est = np.asarray(q_est, dtype=np.float64)
    q_ref = np.asarray(q_ref, dtype=np.float64)
    if q_est.shape != q_ref.shape or q_est.ndim != 2 or q_est.shape[1] != 4:
        raise ValueError(f"q_est {q_est.shape} and q_ref {q_ref.shape} must both be (N, 4)")
    n = q_est.shape[0]
    scored = np.ones(n, bool) if movement is None else np.asarray(movement, bool).copy()
    scored &= np.all(np.isfinite(q_est), axis=1) & np.all(np.isfinite(q_ref), axis=1)
    offset = 0.0
    if six_d:
        offset = heading_offset(q_est, q_ref, scored)
        if np.isfinite(offset):
            q_est = quat_mul(quat_about_z(-offset), q_est)
        else:
            offset = 0.0
    e = error_quat_earth(q_est, q_ref)
    return Errors(total=total_error(e), heading=heading_error(e), inclination=inclination_error(e),
                  scored=scored, heading_offset_rad=float(offset))


def broad_rmse_deg(q_est: np.ndarray, q_ref: np.ndarray, movement: Optional[np.ndarray] = None,
                   six_d: bool = False) -> Dict[str, float]:
    """{'total', 'heading', 'inclination'}: RMSE in degrees (BROAD's calculateRMSE)."""
    return orientation_errors(q_est, q_ref, movement, six_d).rmse_deg()
