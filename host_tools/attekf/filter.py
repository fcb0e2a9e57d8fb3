"""The attitude estimator as a Python object: the same C code as on the target.

    import attekf
    f = attekf.Filter()                                   # defaults, float build
    for gyr, acc, mag in samples:                         # rad/s, m/s^2, uT
        est = f.update(gyr, acc, mag, dt=0.01)            # dt in s
    est.quaternion, est.euler, est.sigma, est.flags

    res = attekf.estimate(gyr, acc, mag, rate_hz=100.0)   # (N, 3) arrays, one C call
    res.quat, res.euler, res.sigma_euler

Units and frames (those of the C estimator, firmware/att/att.h and att_defs.h):
  * inputs in the body frame: gyroscope rad/s, accelerometer m/s^2 (specific force, +9.81
    on the axis pointing up at rest), magnetometer uT (any unit used consistently with the
    settings mag_range and mag_ref_norm), time steps s;
  * the attitude rotates body-frame vectors into the earth frame ENU (x east, y north,
    z up): quaternion [w, x, y, z]; Euler angles roll, pitch, yaw in rad, ZYX
    (R = Rz(yaw) Ry(pitch) Rx(roll)), yaw 0 with the body x axis pointing east, positive
    counter-clockwise seen from above;
  * sigmas: 1-sigma uncertainty of roll, pitch, yaw in rad (square roots of the diagonal of
    the filter's covariance).

Settings are given by name (attekf.setting_info() lists every one with its unit, default
and meaning); the C library checks them and an error names the setting at fault.
The first align_samples samples (default 10) align the filter: roll and pitch from the
averaged accelerometer, heading from the magnetometer; until then Flag.ALIGNED is clear.
"""

from __future__ import annotations

from typing import Mapping, NamedTuple, Optional, Sequence, Union

import numpy as np

from . import native
from .native import Flag, NativeError, Result, SettingsError

__all__ = ["Filter", "Estimate", "estimate", "default_settings", "setting_info", "Flag",
           "Result", "SettingsError", "NativeError"]

ArrayLike3 = Union[Sequence[float], np.ndarray]
Settings = Mapping[str, Union[float, int]]


class Estimate(NamedTuple):
    """The filter's output after one sample (Filter.update).

    quaternion  (4,) [w, x, y, z], unit quaternion rotating body-frame vectors into ENU
    euler       (3,) rad: roll, pitch, yaw (ZYX, body to ENU; yaw 0 = body x east)
    sigma       (3,) rad: 1-sigma uncertainty of roll, pitch, yaw
    rate        (3,) rad/s: estimated body rates p, q, r (gyroscope offset removed)
    flags       Flag bits after the sample (Flag.ALIGNED, Flag.MAG_DISTURBED, ...)
    status      att_step's status: "EKF_OK"; "EKF_GATED" / "EKF_SKIPPED" (the sample was
                applied, a measurement was not fused); any "EKF_ERR_*" means the sample was
                refused (bad input, e.g. NaN or a time step above dt_max) and the filter is
                exactly as before it, except its rejection counter (Filter.diag)
    """

    quaternion: np.ndarray
    euler: np.ndarray
    sigma: np.ndarray
    rate: np.ndarray
    flags: Flag
    status: str

    @property
    def aligned(self) -> bool:
        """The filter has its initial attitude (before that the outputs are not an estimate)."""
        return bool(self.flags & Flag.ALIGNED)

    @property
    def euler_deg(self) -> np.ndarray:
        """(3,) roll, pitch, yaw in degrees."""
        return np.degrees(self.euler)

    @property
    def refused(self) -> bool:
        """att_step refused the sample (status EKF_ERR_*, the filter unchanged)."""
        return self.status.startswith("EKF_ERR")


def _put3(dst: np.ndarray, name: str, unit: str, v) -> None:
    """dst[:] = v for three numbers v (list, tuple or array), else an error naming the argument."""
    try:
        n = len(v)
    except TypeError:
        raise TypeError(f"{name}: {v!r} is not three numbers ({unit})") from None
    if n != 3:
        raise ValueError(f"{name}: expected three numbers ({unit}), got {n}")
    try:
        dst[:] = v
    except (TypeError, ValueError):
        raise TypeError(f"{name}: {v!r} is not three numbers ({unit})") from None


class Filter:
    """The 9-state attitude EKF (firmware/att), fed sample by sample or in batches.

    Filter(settings=None, scalar="float", dt=None)
      settings  {name: value} changed from the defaults (units: attekf.setting_info());
                checked by the C library: an unknown name or a value out of range raises
                SettingsError naming the setting
      scalar    the C build: "float" (what runs on the microcontroller), "double" (the
                reference) or "fixed" (Q-format fixed point, docs/fixed_point.md)
      dt        s, default time step of update() when it is called without one (a fixed
                sample rate, like VQF's Ts)

    update(gyr, acc, mag=None, dt=...) -> Estimate     one sample
    update_batch(gyr, acc, mag=None, *, t= | rate_hz= | dt=) -> Result   N samples, one C call
    Both continue from the filter's state; reset() starts again from "not aligned".
    """

    def __init__(self, settings: Optional[Settings] = None, scalar: str = "float",
                 dt: Optional[float] = None):
        if settings is not None and not isinstance(settings, Mapping):
            raise TypeError(f"settings: expected a mapping name -> value, not {type(settings).__name__}")
        self._lib = native.load(scalar)
        self._sbuf = native._make_settings(self._lib, dict(settings or {}))
        self._fbuf = native._new_filter(self._lib, self._sbuf)
        self._dt = None if dt is None else float(dt)
        self._t_last: Optional[float] = None
        # one-sample buffers, allocated once (update() is called per sample)
        self._in = np.zeros((4, 3), np.float64)          # rows: dt (col 0), gyr, acc, mag
        self._state = np.zeros(native.N_STATES, np.float64)
        self._var = np.zeros(native.N_STATES, np.float64)
        self._quat = np.zeros(4, np.float64)
        self._flags = np.zeros(1, np.uint32)
        self._status = np.zeros(len(native.STATUS_COLUMNS), np.uint8)
        dp, u32p, u8p = native._dp, native._u32p, native._u8p
        self._p_in = [self._in[k].ctypes.data_as(dp) for k in range(4)]
        self._p_out = (self._state.ctypes.data_as(dp), self._var.ctypes.data_as(dp),
                       self._quat.ctypes.data_as(dp), self._flags.ctypes.data_as(u32p),
                       self._status.ctypes.data_as(u8p))
        self._status_names: dict = {}

    # ---- properties ---------------------------------------------------------------------
    @property
    def scalar(self) -> str:
        """The C build in use: "float", "double" or "fixed"."""
        return self._lib.scalar

    @property
    def settings(self) -> dict:
        """Every setting in use, by name (values as the C build stores them)."""
        return native._settings_to_dict(self._lib, self._sbuf)

    @property
    def diag(self) -> dict:
        """The filter's counters (att_diag_t), by name: steps, samples fused / gated /
        skipped per sensor, rejected (refused input), numeric, remaps, cov_repairs,
        heading_resets, gyro_saturated."""
        return self._lib.diag(self._fbuf)

    @property
    def diag_values(self) -> dict:
        """The other diagnostics of att_diag_t: innovation test ratios (gyro_ratio,
        accel_ratio per axis, mag_ratio; > 1 means gated), accel_norm_error m/s^2,
        mag_norm_error (fraction), mag_dip_error rad; of the last sample of each sensor."""
        return self._lib.diag_values(self._fbuf)

    # ---- running ------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to "not aligned" with the same settings (diagnostics cleared)."""
        self._fbuf = native._new_filter(self._lib, self._sbuf)
        self._t_last = None

    def update(self, gyr: ArrayLike3, acc: ArrayLike3, mag: Optional[ArrayLike3] = None,
               dt: Optional[float] = None) -> Estimate:
        """One IMU sample: gyr (3,) rad/s, acc (3,) m/s^2, mag (3,) uT or None (no
        magnetometer sample), dt s since the previous sample (default: the Filter's dt).
        Returns the Estimate after the sample (att_step: gyro update, predict over dt,
        accelerometer and magnetometer updates)."""
        if dt is None:
            if self._dt is None:
                raise ValueError("dt: give the time step in s (update(..., dt=0.01)) or "
                                 "Filter(dt=...) for a fixed sample rate")
            dt = self._dt
        try:
            self._in[0, 0] = float(dt)
        except (TypeError, ValueError):
            raise TypeError(f"dt: {dt!r} is not a number (s)") from None
        _put3(self._in[1], "gyr", "rad/s", gyr)
        _put3(self._in[2], "acc", "m/s^2", acc)
        p_mag = None
        if mag is not None:
            _put3(self._in[3], "mag", "uT", mag)
            p_mag = self._p_in[3]
        rc = self._lib.lib.attekf_run(self._fbuf, 1, self._p_in[0], self._p_in[1], self._p_in[2],
                                      p_mag, *self._p_out)
        if rc != 0:
            raise NativeError(f"attekf_run: {self._lib.status_name(rc)}")
        self._t_last = None
        code = int(self._status[0])
        status = self._status_names.get(code)
        if status is None:
            status = self._status_names[code] = self._lib.status_name(code)
        return Estimate(quaternion=self._quat.copy(), euler=self._state[3:6].copy(),
                        sigma=np.sqrt(self._var[3:6]), rate=self._state[0:3].copy(),
                        flags=Flag(int(self._flags[0])), status=status)

    def update_batch(self, gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None, *,
                     t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
                     dt: Union[None, float, np.ndarray] = None) -> Result:
        """N samples in one C call: gyr, acc (N, 3) rad/s, m/s^2; mag (N, 3) uT or None (a
        row of three NaN: no magnetometer sample at that time). Time from exactly one of
        t (N,) timestamps s, rate_hz (Hz) or dt (s, one value or (N,)); without any, the
        Filter's dt. Returns a Result with one row per sample (quat, euler, sigma_euler,
        rate, flags, status, ... : help(attekf.Result))."""
        gyr = np.asarray(gyr, dtype=np.float64)
        if gyr.ndim != 2 or gyr.shape[1] != 3:
            raise ValueError(f"gyr: shape {gyr.shape}, expected (N, 3)")
        n = gyr.shape[0]
        gyr = native._arr3("gyr", gyr, n)
        acc = native._arr3("acc", acc, n)
        mag = None if mag is None else native._arr3("mag", mag, n)
        if t is None and rate_hz is None and dt is None:
            if self._dt is None:
                raise ValueError("give t (timestamps, s), rate_hz (Hz) or dt (s), or Filter(dt=...)")
            dt = self._dt
        steps = native.time_steps(n, t=t, rate_hz=rate_hz, dt=dt, t_prev=self._t_last)
        if t is not None:
            times = np.ascontiguousarray(t, dtype=np.float64)
        elif rate_hz is not None:
            times = np.arange(n) / float(rate_hz)
        else:
            times = np.concatenate(([0.0], np.cumsum(steps[1:]))) if n else np.zeros(0)
        res = native._run(self._lib, self._fbuf, self._sbuf, times, steps, gyr, acc, mag)
        self._t_last = float(times[-1]) if (t is not None and n) else None
        return res


def estimate(gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None, *,
             t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
             dt: Union[None, float, np.ndarray] = None, settings: Optional[Settings] = None,
             scalar: str = "float") -> Result:
    """The estimator over whole arrays in one C call: Filter(settings, scalar).update_batch.

    gyr, acc (N, 3) rad/s and m/s^2, mag (N, 3) uT or None; time from exactly one of
    t (N,) timestamps s, rate_hz (Hz) or dt (s). Returns a Result (help(attekf.Result)):
    quat (N, 4), euler (N, 3) rad, sigma_euler (N, 3) rad, rate (N, 3) rad/s, flags,
    status per sample, diag counters after the last sample."""
    return Filter(settings, scalar).update_batch(gyr, acc, mag, t=t, rate_hz=rate_hz, dt=dt)


def default_settings(scalar: str = "float") -> dict:
    """Every setting's default value, by name (att_default_settings of the C build)."""
    return native.default_settings(scalar)


def setting_info(scalar: str = "float") -> dict:
    """name -> {"default", "unit", "help"} for every setting of the C library."""
    return native.setting_info(scalar)
