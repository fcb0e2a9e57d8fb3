"""The baselines `attekf bench` compares this estimator with, run as their authors recommend,
and the frame conversions that bring their outputs to ours (docs/accuracy.md explains the
choices; tests/python/test_bench.py checks every frame on a synthetic recording).

Every runner takes (recording, method, run configuration) and returns (quaternions [w x y z]
body->ENU (N, 4), seconds of the method's own computation, extra information). ENU is the
frame of the BROAD truth `opt_quat`.

* VQF (`vqf.offlineVQF`, the offline variant: acausal, it uses the whole recording for rest
  detection / bias estimation; `vqf-online` is the causal `vqf.VQF`): body->ENU by design
  (same authors as BROAD), quat9D / quat6D.
* Fusion (`imufusion.Ahrs`, x-io): CONVENTION_ENU -> body->ENU. Gyro in deg/s, accelerometer
  in g (divided by 9.81), magnetometer in uT (its rejection works on angles, units do not
  matter). Settings: FUSION_SETTINGS (the values of Fusion's own examples). Fusion's authors
  put their gyroscope bias correction (`imufusion.Bias`, called Offset in older releases) in
  front of the AHRS: it learns the gyroscope offset whenever the gyroscope stays below
  3 deg/s for 3 s (its defaults, FUSION_BIAS_SETTINGS). `fusion-9d` / `fusion-6d` run it so;
  `fusion-bare-9d` / `fusion-bare-6d` are the AHRS alone.
* Madgwick (`ahrs.filters.Madgwick`, gain = beta = 0.12): its MARG update uses gravity along
  +z and the horizontal field along +x, i.e. an NWU earth frame (x north, y west, z up);
  q_ENU = qz(+90 deg) * q_NWU, as BROAD's own process_data.py does. ahrs's batch mode would
  initialise it with ecompass(frame='NED'), inconsistent with its NWU update: so its update
  loop runs here, from the common start.
* Mahony (`ahrs.filters.Mahony`, k_P = 0.74, k_I = 0.0012): ahrs's MARG update references
  the field as [0, |h_xy|, h_z], i.e. ENU already; no conversion.

Fair start: Madgwick, Mahony and Fusion start from the same initial attitude, computed from
the mean accelerometer and magnetometer of the first `init_samples` samples (default 10, our
filter's align_samples) (6D: from the accelerometer only, heading 0). VQF initialises itself
(its first samples), our filter aligns itself from its first align_samples samples.

A magnetometer row of NaN (no sample at that instant, e.g. a slower magnetometer) is passed as
each method's own "no magnetometer sample": [0 0 0] for VQF online and Fusion (both skip a
zero vector), the magnetometer-free update for Madgwick and Mahony (ours: the binding clears
ATT_HAS_MAG). VQF offline
takes a heading from every row, so there such a row is interpolated between the nearest
samples.
"""

from __future__ import annotations

import math
import time
from typing import Dict, Optional

import numpy as np

from . import metrics as M
from .io import Recording

GRAVITY = 9.81

# The BROAD paper's best common ("trial-agnostic") parameters (example_code/out/*.json)
MADGWICK_BETA = 0.12
MAHONY_KP = 0.74
MAHONY_KI = 0.0012
# Fusion: the settings of x-io's examples (gain 0.5, 2000 deg/s, rejection 10 deg, 5 s)
FUSION_AHRS_SETTINGS = {"gain": 0.5, "gyroscope_range": 2000.0, "acceleration_rejection": 10.0,
                        "magnetic_rejection": 10.0, "rejection_timeout": 5.0}
# Fusion's gyroscope bias correction: imufusion.BiasSettings' defaults (deg/s, s)
FUSION_BIAS_SETTINGS = {"bias_stationary_threshold": 3.0, "bias_stationary_period": 3.0}
FUSION_SETTINGS = dict(FUSION_AHRS_SETTINGS, **FUSION_BIAS_SETTINGS)   # --fusion-set names


# ---------------------------------------------------------------------------------------------
# Frames
# ---------------------------------------------------------------------------------------------
Q_NWU_TO_ENU = M.quat_about_z(np.pi / 2)   # q_ENU = Q_NWU_TO_ENU * q_NWU


def nwu_to_enu(q_nwu: np.ndarray) -> np.ndarray:
    """Body->NWU quaternions to body->ENU (ENU is NWU turned by +90 deg about up)."""
    return M.quat_mul(Q_NWU_TO_ENU, q_nwu)


def enu_to_nwu(q_enu: np.ndarray) -> np.ndarray:
    return M.quat_mul(M.quat_conj(Q_NWU_TO_ENU), q_enu)


def quat_from_matrix(r: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) -> [w x y z] with w >= 0 (Shepperd: the largest of the four
    candidates, so no division by a small number)."""
    r = np.asarray(r, dtype=np.float64)
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    cand = np.array([tr, r[0, 0], r[1, 1], r[2, 2]])
    k = int(np.argmax(cand))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = [s / 4, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [(r[2, 1] - r[1, 2]) / s, s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def initial_quat_enu(acc: np.ndarray, mag: Optional[np.ndarray]) -> np.ndarray:
    """Body->ENU attitude from one accelerometer (specific force, up at rest) and magnetometer
    vector (None: heading 0, i.e. body x in the east-up plane). Raises ValueError if the
    vectors are zero or parallel."""
    up = np.asarray(acc, dtype=np.float64)
    if not np.linalg.norm(up) > 0:
        raise ValueError("zero accelerometer vector")
    up = up / np.linalg.norm(up)
    if mag is None:
        # heading is arbitrary (6D): take north along the horizontal part of body y (body x if
        # body y is near vertical)
        ref = np.array([0.0, 1.0, 0.0]) if abs(up[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        north = ref - np.dot(ref, up) * up
    else:
        m = np.asarray(mag, dtype=np.float64)
        north = m - np.dot(m, up) * up            # horizontal part of the field points north
    if not np.linalg.norm(north) > 1e-9:
        raise ValueError("magnetometer parallel to gravity")
    north = north / np.linalg.norm(north)
    east = np.cross(north, up)
    # rows = earth axes in body coordinates: maps body vectors to ENU
    return quat_from_matrix(np.vstack([east, north, up]))


def start_quat(rec: Recording, n: int, use_mag: bool) -> np.ndarray:
    """The common initial attitude (body->ENU) of the baselines: mean of the first n samples."""
    n = max(1, min(int(n), len(rec)))
    acc = rec.acc[:n].mean(axis=0)
    mag = None
    if use_mag and rec.mag is not None:
        rows = rec.mag[:n][np.all(np.isfinite(rec.mag[:n]), axis=1)]
        mag = rows.mean(axis=0) if len(rows) else None
    return initial_quat_enu(acc, mag)


# ---------------------------------------------------------------------------------------------
# Runners
# ---------------------------------------------------------------------------------------------
def _run_vqf(rec: Recording, m, cfg):
    import vqf
    ts = 1.0 / rec.rate_hz
    gyr = np.ascontiguousarray(rec.gyr, dtype=np.float64)
    acc = np.ascontiguousarray(rec.acc, dtype=np.float64)
    mag = None
    online = m.key.startswith("vqf-online")
    if not (m.six_d or rec.mag is None):
        mag = np.ascontiguousarray(_vqf_mag(rec.mag, online), dtype=np.float64)
    t0 = time.process_time()
    if online:
        f = vqf.VQF(ts)
        out = f.updateBatch(gyr, acc, mag) if mag is not None else f.updateBatch(gyr, acc)
    else:
        out = vqf.offlineVQF(gyr, acc, mag, ts)
    sec = time.process_time() - t0
    return np.asarray(out["quat6D" if m.six_d else "quat9D"], dtype=np.float64), sec, {}


def _vqf_mag(mag: np.ndarray, online: bool) -> np.ndarray:
    """Magnetometer rows for VQF: a NaN row (no sample) is [0 0 0], which VQF's causal filter
    skips; its offline variant uses every row (a heading from each), so there a missing row is
    interpolated linearly between the nearest samples (held at the ends)."""
    ok = np.isfinite(mag).all(axis=1)
    if ok.all():
        return mag
    if online or not ok.any():
        return np.where(ok[:, None], mag, 0.0)
    idx = np.arange(len(mag))
    return np.stack([np.interp(idx, idx[ok], mag[ok, i]) for i in range(3)], axis=1)


def _run_fusion(rec: Recording, m, cfg):
    """Fusion's AHRS; with its gyroscope bias correction (imufusion.Bias) in front, as x-io's
    examples run it, unless the method is a fusion-bare variant."""
    import imufusion
    # set as attributes: imufusion 1.3.3's AhrsSettings(convention=...) keyword is silently
    # ignored (stays NWU, which gave a 90 deg heading error); read back to be sure
    ahrs_settings = {k: v for k, v in cfg.fusion.items() if not k.startswith("bias_")}
    s = _fusion_settings(imufusion.AhrsSettings(),
                         dict(ahrs_settings, sample_rate=float(rec.rate_hz),
                              convention=imufusion.CONVENTION_ENU))
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(s)
    ahrs.set_quaternion(start_quat(rec, cfg.init_samples, use_mag=not m.six_d))
    bias = None
    if not m.key.startswith("fusion-bare"):
        bias = imufusion.Bias()
        bias.set_settings(_fusion_settings(imufusion.BiasSettings(), {
            "sample_rate": float(rec.rate_hz),
            "stationary_threshold": float(cfg.fusion.get("bias_stationary_threshold",
                                                         FUSION_BIAS_SETTINGS["bias_stationary_threshold"])),
            "stationary_period": float(cfg.fusion.get("bias_stationary_period",
                                                      FUSION_BIAS_SETTINGS["bias_stationary_period"]))}))
    gyr = np.degrees(rec.gyr)
    acc = rec.acc / GRAVITY
    mag = None if m.six_d else rec.mag
    n = len(rec)
    q = np.empty((n, 4))
    t0 = time.process_time()
    if mag is not None:
        # no sample (NaN row): a zero vector, which Fusion's update skips (its magnetometer-free
        # update would reset the heading to 0 while the filter initialises)
        mag = np.where(np.isfinite(mag), mag, 0.0)
    for i in range(n):
        g = bias.update(gyr[i]) if bias is not None else gyr[i]
        if mag is None:
            ahrs.update_no_magnetometer(g, acc[i])
        else:
            ahrs.update(g, acc[i], mag[i])
        q[i] = ahrs.get_quaternion()
    sec = time.process_time() - t0
    extra = {"fusion_bias_deg_s": np.asarray(bias.get_offset(), float).tolist()} if bias is not None else {}
    return q, sec, extra


def _fusion_settings(obj, wanted: Dict[str, float]):
    """Sets imufusion settings as attributes and reads them back (RuntimeError if one did not
    take: imufusion stores floats as float32, hence the tolerance)."""
    for k, v in wanted.items():
        setattr(obj, k, v)
    for k, v in wanted.items():
        if not math.isclose(float(getattr(obj, k)), float(v), rel_tol=1e-6):
            raise RuntimeError(f"imufusion did not take setting {k}={v} (reads {getattr(obj, k)})")
    return obj


def _run_ahrs(rec: Recording, m, cfg):
    from ahrs.filters import Madgwick, Mahony
    rate = float(rec.rate_hz)
    q0 = start_quat(rec, cfg.init_samples, use_mag=not m.six_d)
    if m.family == "madgwick":
        f = Madgwick(gain=MADGWICK_BETA, frequency=rate)
        q0 = enu_to_nwu(q0)    # Madgwick's earth frame is NWU (see the module docstring)
    else:
        f = Mahony(k_P=MAHONY_KP, k_I=MAHONY_KI, frequency=rate)
    n = len(rec)
    q = np.empty((n, 4))
    q[0] = q0
    gyr, acc, mag = rec.gyr, rec.acc, rec.mag
    t0 = time.process_time()
    if m.six_d or mag is None:
        upd = f.updateIMU
        for i in range(1, n):
            q[i] = upd(q[i - 1], gyr[i], acc[i])
    else:
        has_mag = np.isfinite(mag).all(axis=1)   # a NaN row: no magnetometer sample
        for i in range(1, n):
            q[i] = (f.updateMARG(q[i - 1], gyr[i], acc[i], mag[i]) if has_mag[i]
                    else f.updateIMU(q[i - 1], gyr[i], acc[i]))
    sec = time.process_time() - t0
    if m.family == "madgwick":
        q = nwu_to_enu(q)
    return q, sec, {}


# Python package each family needs
PACKAGES = {"vqf": "vqf", "fusion": "imufusion", "madgwick": "ahrs", "mahony": "ahrs"}
