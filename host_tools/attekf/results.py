"""What the estimator returns: Flag (its status bits), Estimate (one sample, Filter.update)
and Result (N samples, Filter.update_batch and attekf.estimate).

Before the filter has aligned (Flag.ALIGNED clear: the first align_samples samples, default
10, or after reset()) there is no estimate: the quaternion, the Euler angles, the state and
the body rates are NaN, the sigmas and variances +inf (covariances between angles 0). The
gyroscope offset is reported throughout (0 until learned, with its initial sigma).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Dict, NamedTuple, Optional, Tuple, Union

import numpy as np

# The state vector of the filter, in the order of firmware/att/att_defs.h: body rates (rad/s),
# ZYX Euler angles body -> ENU (rad), Euler rates (rad/s).
STATE_NAMES = ("p", "q", "r", "phi", "theta", "psi", "phid", "thetad", "psid")

# ekf_status_t values that are not errors (firmware/ekf/ekf.h; checked by the tests).
_EKF_OK, _EKF_ERR_NOT_INITIALISED, _EKF_GATED, _EKF_SKIPPED = 0, 6, 11, 12


class Flag(enum.IntFlag):
    """Status flags of the filter (ATT_FLAG_* of the C library). "last" means the most
    recent sample of that sensor."""

    ALIGNED = 1 << 0            #: initial attitude set
    GIMBAL_LOCK = 1 << 1        #: |pitch| > gimbal_limit: kinematics clamped, heading held
    ACCEL_DEWEIGHTED = 1 << 2   #: last accel: linear acceleration or clipped, noise variance >= doubled
    ACCEL_REJECTED = 1 << 3     #: last accel: | |a| - g | beyond accel_reject, not fused
    MAG_DISTURBED = 1 << 4      #: last mag: norm or dip off the reference, not fused
    HEADING_HELD = 1 << 5       #: last mag: not fused because of gimbal lock
    GYRO_GATED = 1 << 6         #: last gyro: at least one axis gated
    ACCEL_GATED = 1 << 7        #: last accel: at least one axis gated
    MAG_GATED = 1 << 8          #: last mag: gated
    GATE_BYPASS = 1 << 9        #: a gate is bypassed after gate_timeout
    HEADING_LIMITED = 1 << 10   #: heading variance at heading_var_max, or no heading reference yet
    REMAPPED = 1 << 11          #: last predict: pitch passed +-90 deg, remapped
    COV_REPAIRED = 1 << 12      #: last call: P was loaded to stay positive definite
    AT_REST = 1 << 13           #: last sample: at rest, gyroscope offset learned


# ATT_FLAG_* by name, for readers of Result.flags.
ATT_FLAGS = {f.name: int(f) for f in Flag}


class Estimate(NamedTuple):
    """The filter's output after one sample (Filter.update). Frames: the quaternion and the
    Euler angles rotate body-frame vectors into the output frame (ENU: x east, y north, z up,
    the default; or NED, Filter(frame="NED")); the body frame is the sensor's, or the one the
    mounting rotation gives (Filter(mounting=...)). Before alignment: NaN and infinite sigma.

    quaternion  (4,) [w, x, y, z], unit quaternion rotating body-frame vectors into the
                output frame
    euler       (3,) rad: roll, pitch, yaw (ZYX; ENU: yaw 0 = body x east, counter-clockwise
                positive; NED: yaw 0 = body x north, clockwise positive)
    sigma       (3,) rad: 1-sigma uncertainty of roll, pitch, yaw
    rate        (3,) rad/s: estimated body rates p, q, r (gyroscope offset removed)
    flags       Flag bits after the sample (Flag.ALIGNED, Flag.MAG_DISTURBED, ...)
    status      att_step's status: "EKF_OK"; "EKF_GATED" / "EKF_SKIPPED" (the sample was
                applied, a measurement was not fused); any "EKF_ERR_*" means the sample was
                refused (bad input, e.g. NaN or a time step above dt_max) and the filter is
                exactly as before it, except its rejection counter (Filter.diag)
    covariance  (3, 3) rad^2: covariance of the roll, pitch, yaw errors (sigma**2 on its
                diagonal)
    gyro_bias   (3,) rad/s: the gyroscope offset the filter subtracts, body frame
    gyro_bias_sigma (3,) rad/s: its 1-sigma uncertainty per axis
    """

    quaternion: np.ndarray
    euler: np.ndarray
    sigma: np.ndarray
    rate: np.ndarray
    flags: Flag
    status: str
    covariance: np.ndarray
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray

    @property
    def aligned(self) -> bool:
        """The filter has its initial attitude (before that the outputs are NaN)."""
        return bool(self.flags & Flag.ALIGNED)

    @property
    def euler_deg(self) -> np.ndarray:
        """(3,) roll, pitch, yaw in degrees."""
        return np.degrees(self.euler)

    @property
    def refused(self) -> bool:
        """att_step refused the sample (status EKF_ERR_*, the filter unchanged)."""
        return self.status.startswith("EKF_ERR")


@dataclass
class Result:
    """Per-sample outputs of the C estimator (all after the sample was processed); NaN
    (angles, quaternion, state) and +inf (variances) before the filter aligned.

    t        (N,) s, the samples' times
    quat     (N, 4) [w x y z] body->ENU (or body->NED: frame)
    euler    (N, 3) rad, roll, pitch, yaw (ZYX) of the same rotation
    angle_cov (N, 6) the roll/pitch/yaw covariance, rad^2, packed (phi phi, theta theta,
             psi psi, phi theta, phi psi, theta psi); cov_euler gives it as (N, 3, 3)
    state    (N, 9) x = [p q r phi theta psi phid thetad psid] (rad/s, rad; the filter's own
             state, angles body->ENU whatever the frame)
    var      (N, 9) variances of x ((rad/s)^2, rad^2): the diagonal of P, for the angles
             that of the reported attitude covariance
    gyro_bias, gyro_bias_sigma  (N, 3) rad/s: the gyroscope offset and its 1-sigma (body)
    flags    (N,) uint32 ATT_FLAG_* bits (attekf.Flag)
    status   (N, 5) uint8 ekf_status_t of the step and of its stages (status_columns)
    diag     the filter's counters (att_diag_t) after the last sample
    diag_values  the other diagnostics of att_diag_t after the last sample (innovation test
             ratios, 1; accel_norm_error m/s^2; mag_norm_error, 1; mag_dip_error rad)
    settings the settings used, by name; scalar: "float", "double" or "fixed"; frame
    status_names code -> name of every code that occurs in status
    mag_absent samples given without magnetometer (no magnetometer, or an all-NaN row)
    c_seconds  CPU time (process) spent inside the C calls, s: the estimator's own cost
               without Python set-up (`attekf bench` per-sample cost)
    six_d    with attekf.estimate(..., with_6d=True): the same samples without the
             magnetometer (a Result), else None
    smoother from attekf.smooth: the smoother's counts (epochs, heading_cuts, rate_cuts,
             not_pd, branch_flips, recomputed, segment), else None
    """

    t: np.ndarray
    state: np.ndarray
    var: np.ndarray
    quat: np.ndarray
    euler: np.ndarray
    angle_cov: np.ndarray
    flags: np.ndarray
    status: np.ndarray
    gyro_bias: np.ndarray
    gyro_bias_sigma: np.ndarray
    diag: Dict[str, int]
    settings: Dict[str, Union[float, int]]
    scalar: str
    frame: str = "ENU"
    status_names: Dict[int, str] = field(default_factory=dict)
    mag_absent: int = 0
    c_seconds: float = 0.0
    diag_values: Dict[str, Union[float, tuple]] = field(default_factory=dict)
    status_columns: Tuple[str, ...] = ("step", "predict", "gyro", "accel", "mag")
    six_d: Optional["Result"] = None
    smoother: Optional[Dict[str, int]] = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def var_euler(self) -> np.ndarray:
        """(N, 3) variances of roll, pitch, yaw in rad^2."""
        return self.angle_cov[:, 0:3]

    @property
    def sigma_euler(self) -> np.ndarray:
        """(N, 3) 1-sigma uncertainty of roll, pitch, yaw in rad (sqrt of var_euler)."""
        return np.sqrt(self.angle_cov[:, 0:3])

    @property
    def cov_euler(self) -> np.ndarray:
        """(N, 3, 3) covariance of the roll, pitch, yaw errors, rad^2."""
        c = self.angle_cov
        rows = [[c[:, 0], c[:, 3], c[:, 4]], [c[:, 3], c[:, 1], c[:, 5]], [c[:, 4], c[:, 5], c[:, 2]]]
        return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)

    @property
    def rate(self) -> np.ndarray:
        """(N, 3) estimated body rates p, q, r in rad/s (body frame)."""
        return self.state[:, 0:3]

    @property
    def aligned(self) -> np.ndarray:
        """(N,) bool: the filter had its initial attitude after the sample."""
        return (self.flags & ATT_FLAGS["ALIGNED"]) != 0

    def refused(self, column: str = "step") -> np.ndarray:
        """(N,) bool: samples whose step (or stage) returned an error code, i.e. input
        refused or numerically refused; not counted: OK, gated, skipped by policy, and
        'not initialised' of a stage while the filter was still aligning."""
        s = self.status[:, self.status_columns.index(column)]
        return (s != _EKF_OK) & (s != _EKF_GATED) & (s != _EKF_SKIPPED) & (s != _EKF_ERR_NOT_INITIALISED)

    def summary(self) -> Dict[str, object]:
        """Counts of what happened to the samples: nothing is dropped without a count."""
        out: Dict[str, object] = {"samples": len(self), "aligned_samples": int(self.aligned.sum()),
                                  "mag_absent": int(self.mag_absent)}
        refused = {}
        for k, col in enumerate(self.status_columns):
            codes, counts = np.unique(self.status[:, k], return_counts=True)
            per = {self.status_names.get(int(c), str(int(c))): int(n)
                   for c, n in zip(codes, counts) if c != _EKF_OK}
            if per:
                refused[col] = per
        out["status_counts"] = refused
        out["samples_refused"] = int(self.refused().sum())
        out["diag"] = dict(self.diag)
        return out
