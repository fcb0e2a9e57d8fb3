"""The attitude estimator as a Python object: the same C code as on the target.

    import attekf
    f = attekf.Filter()                                   # defaults, float build
    for gyr, acc, mag in samples:                         # rad/s, m/s^2, uT
        est = f.update(gyr, acc, mag, dt=0.01)            # dt in s
    est.quaternion, est.euler, est.sigma, est.flags

    res = attekf.estimate(gyr, acc, mag, rate_hz=100.0)   # (N, 3) arrays, one C call
    res.quat, res.euler, res.sigma_euler
    res = attekf.smooth(gyr, acc, mag, rate_hz=100.0)     # the same, each sample given all of them

Units and frames (those of the C estimator):
  * inputs in the body frame: gyroscope rad/s, accelerometer m/s^2 (specific force, +9.81
    on the axis pointing up at rest), magnetometer uT (any unit used consistently with the
    settings mag_range and mag_ref_norm), time steps s. A sensor mounted rotated in the body
    gives Filter(mounting=R): R (3, 3) rotates sensor-frame vectors into the body frame;
  * the attitude rotates body-frame vectors into the earth frame ENU (x east, y north,
    z up): quaternion [w, x, y, z]; Euler angles roll, pitch, yaw in rad, ZYX
    (R = Rz(yaw) Ry(pitch) Rx(roll)), yaw 0 with the body x axis pointing east, positive
    counter-clockwise seen from above. Filter(frame="NED") gives the same attitude from NED
    (x north, y east, z down): R_ned = T R_enu with T = [[0 1 0], [1 0 0], [0 0 -1]], so a
    body whose z axis points up reads roll 180 deg; a body frame x forward, y right, z down
    reads roll = pitch = 0 when level;
  * sigmas: 1-sigma uncertainty of roll, pitch, yaw in rad (square roots of the diagonal of
    the filter's reported attitude covariance, Estimate.covariance).

Settings are given by name, or as a TOML or JSON file (attekf.load_settings);
attekf.setting_info() lists every one with its unit, range, default and meaning; the C
library checks them and an error names the setting at fault.

The first align_samples samples (default 10) align the filter: roll and pitch from the
averaged accelerometer, heading from the magnetometer. Until then Flag.ALIGNED is clear and
there is no estimate: quaternion and angles are NaN, sigmas infinite.

A Filter can be copied (copy.copy, copy.deepcopy: independent filters), pickled, and saved
and restored with get_state() / set_state(): the C filter's memory bit for bit, refused with
a clear error by a filter of another scalar build or another version.
"""

from __future__ import annotations

import os
import zlib
from typing import Mapping, Optional, Sequence, Union

import numpy as np

from . import native
from .native import NativeError, SettingsError
from .results import Estimate, Flag, Result
from .settings_file import load_settings

__all__ = ["Filter", "Estimate", "estimate", "smooth", "default_settings", "setting_info", "load_settings",
           "Flag", "Result", "SettingsError", "NativeError"]

ArrayLike3 = Union[Sequence[float], np.ndarray]
Settings = Union[Mapping[str, Union[float, int]], str, "os.PathLike[str]"]

STATE_FORMAT = "attekf.Filter state"
STATE_VERSION = 1
FRAMES = ("ENU", "NED")


def _settings_dict(settings) -> dict:
    if settings is None:
        return {}
    if isinstance(settings, (str, os.PathLike)):
        return load_settings(settings)
    if not isinstance(settings, Mapping):
        raise TypeError(f"settings: expected a mapping name -> value or a file name, "
                        f"not {type(settings).__name__}")
    return dict(settings)


def _check_dt(dt) -> Optional[float]:
    if dt is None:
        return None
    try:
        v = float(dt)
    except (TypeError, ValueError):
        raise TypeError(f"dt: {dt!r} is not a number (s)") from None
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"dt: {dt!r} is not a positive, finite time step (s)")
    return v


def _check_frame(frame) -> str:
    name = str(frame).upper()
    if name not in FRAMES:
        raise ValueError(f"frame: {frame!r} is not one of {', '.join(FRAMES)}")
    return name


def _check_mounting(mounting) -> Optional[np.ndarray]:
    """A 3x3 rotation matrix (sensor -> body), or None."""
    if mounting is None:
        return None
    try:
        m = np.array(mounting, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("mounting: not a 3x3 matrix of numbers") from None
    if m.shape != (3, 3) or not np.isfinite(m).all():
        raise ValueError(f"mounting: expected a finite 3x3 rotation matrix, got shape {m.shape}")
    if np.abs(m @ m.T - np.eye(3)).max() > 1e-6 or np.linalg.det(m) < 0:
        raise ValueError("mounting: not a rotation matrix (R R^T = I and det R = +1, to 1e-6)")
    return m


class Filter:
    """The 9-state attitude EKF (the C library), fed sample by sample or in batches.

    Filter(settings=None, scalar="float", dt=None, *, frame="ENU", mounting=None)
      settings  {name: value} changed from the defaults (units: attekf.setting_info()), or
                the name of a TOML or JSON file of them (attekf.load_settings); checked by
                the C library: an unknown name or a value out of range raises SettingsError
                naming the setting
      scalar    the C build: "float" (what runs on the microcontroller), "double" (the
                reference) or "fixed" (Q-format fixed point)
      dt        s, default time step of update() when it is called without one (a fixed
                sample rate, like VQF's Ts)
      frame     "ENU" (the filter's own) or "NED": the earth frame of the outputs
      mounting  (3, 3) rotation matrix sensor -> body applied to every input (None: the
                sensor frame is the body frame)

    update(gyr, acc, mag=None, dt=...) -> Estimate     one sample
    update_batch(gyr, acc, mag=None, *, t= | rate_hz= | dt=) -> Result   N samples, one C call
    Both continue from the filter's state; reset() starts again from "not aligned".
    get_state() / set_state(state), copy.copy, copy.deepcopy and pickle keep everything.
    """

    def __init__(self, settings: Optional[Settings] = None, scalar: str = "float",
                 dt: Optional[float] = None, *, frame: str = "ENU", mounting=None):
        changes = _settings_dict(settings)
        self._lib = native.load(scalar)
        self._core = self._lib.new_core(self._lib.make_settings(changes))
        self._configure(_check_dt(dt), _check_frame(frame), _check_mounting(mounting))
        self._t_last: Optional[float] = None

    def _configure(self, dt: Optional[float], frame: str, mounting: Optional[np.ndarray]) -> None:
        self._dt, self._frame, self._mounting = dt, frame, mounting
        mount = None if mounting is None else tuple(float(v) for v in mounting.ravel())
        self._core.configure(dt or 0.0, mount, frame == "NED")

    # ---- properties ---------------------------------------------------------------------
    @property
    def scalar(self) -> str:
        """The C build in use: "float", "double" or "fixed"."""
        return self._lib.scalar

    @property
    def dt(self) -> Optional[float]:
        """The default time step of update(), s (None: every call gives one)."""
        return self._dt

    @property
    def frame(self) -> str:
        """The earth frame of the outputs: "ENU" or "NED"."""
        return self._frame

    @property
    def mounting(self) -> Optional[np.ndarray]:
        """The sensor -> body rotation applied to the inputs (a copy), or None."""
        return None if self._mounting is None else self._mounting.copy()

    @property
    def settings(self) -> dict:
        """Every setting in use, by name (values as the C build stores them)."""
        return self._lib.settings_dict(self._core.settings())

    @property
    def diag(self) -> dict:
        """The filter's counters (att_diag_t), by name: steps, samples fused / gated /
        skipped per sensor, rejected (refused input), numeric, remaps, cov_repairs,
        heading_resets, gyro_saturated."""
        return dict(zip(self._lib.diag_names, self._core.diag()))

    @property
    def diag_values(self) -> dict:
        """The other diagnostics of att_diag_t: innovation test ratios (gyro_ratio,
        accel_ratio per axis, mag_ratio; > 1 means gated), accel_norm_error m/s^2,
        mag_norm_error (fraction), mag_dip_error rad; of the last sample of each sensor."""
        return native._diag_values(self._lib, self._core)

    # ---- running ------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to "not aligned" with the same settings (diagnostics cleared)."""
        self._core.reset()
        self._t_last = None

    def update(self, gyr: ArrayLike3, acc: ArrayLike3, mag: Optional[ArrayLike3] = None,
               dt: Optional[float] = None) -> Estimate:
        """One IMU sample: gyr (3,) rad/s, acc (3,) m/s^2, mag (3,) uT or None (no
        magnetometer sample; three NaN mean the same), dt s since the previous sample
        (default: the Filter's dt; a positive finite number, else ValueError). Returns the
        Estimate after the sample (att_step: gyro update, predict over dt, accelerometer and
        magnetometer updates)."""
        self._t_last = None
        return self._core.update(gyr, acc, mag, dt)

    def update_batch(self, gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None, *,
                     t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
                     dt: Union[None, float, np.ndarray] = None, progress=None) -> Result:
        """N samples in one C call: gyr, acc (N, 3) rad/s, m/s^2; mag (N, 3) uT or None (a
        row of three NaN: no magnetometer sample at that time). Time from exactly one of
        t (N,) timestamps s, rate_hz (Hz) or dt (s, one value or (N,)); without any, the
        Filter's dt. Steps must be positive and finite (timestamps strictly increasing).
        Returns a Result with one row per sample (quat, euler, sigma_euler, cov_euler, rate,
        gyro_bias, flags, status, ... : help(attekf.Result)). progress(k), if given, is
        called after each block of samples with their number (blocks of 20000 C steps: the
        same filter, the same results)."""
        times, steps, gyr, acc, mag = self._batch_inputs(gyr, acc, mag, t, rate_hz, dt)
        return self._run(times, steps, gyr, acc, mag, t is not None, progress)

    def _batch_inputs(self, gyr, acc, mag, t, rate_hz, dt):
        """update_batch's and smooth_batch's arguments checked: (times s, steps s, gyr, acc,
        mag) as the C run takes them."""
        gyr = native.rows3("gyr", gyr, "rad/s")
        n = gyr.shape[0]
        acc = native.rows3("acc", acc, "m/s^2", n)
        mag = None if mag is None else native.rows3("mag", mag, "uT", n)
        if t is None and rate_hz is None and dt is None:
            if self._dt is None:
                raise ValueError("give t (timestamps, s), rate_hz (Hz) or dt (s), or Filter(dt=...)")
            dt = self._dt
        steps = native.time_steps(n, t=t, rate_hz=rate_hz, dt=dt, t_prev=self._t_last, first=self._dt)
        if t is not None:
            times = np.ascontiguousarray(t, dtype=np.float64)
        elif rate_hz is not None:
            times = np.arange(n) / float(rate_hz)
        else:
            times = np.concatenate(([0.0], np.cumsum(steps[1:]))) if n else np.zeros(0)
        return times, steps, gyr, acc, mag

    def smooth_batch(self, gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None, *,
                     t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
                     dt: Union[None, float, np.ndarray] = None, progress=None,
                     segment: Optional[int] = None) -> Result:
        """update_batch, then the Rauch-Tung-Striebel smoother over those samples
        (docs/derivation.md, "Smoother"): the same arguments, and a Result whose attitude,
        state, variances and covariance are the smoothed estimate, each sample's given all N
        samples (flags, status, gyro_bias: the filter's). The filter ends as update_batch would
        leave it. progress(k), if given, is called with the samples done, 2 N in all (the
        forward pass, then the backward pass). segment: samples per segment of the smoother's
        memory (default: 64 MiB of traces; docs/host_tools.md, "Smoothing")."""
        times, steps, gyr, acc, mag = self._batch_inputs(gyr, acc, mag, t, rate_hz, dt)
        return self._run(times, steps, gyr, acc, mag, t is not None, progress, _segment(segment))

    def smooth_recording(self, rec, use_mag: bool = True, progress=None, segment: Optional[int] = None) -> Result:
        """run_recording with the smoother (smooth_batch)."""
        return self._run(*self._recording_inputs(rec, use_mag), True, progress, _segment(segment))

    def run_recording(self, rec, use_mag: bool = True, progress=None) -> Result:
        """update_batch over a recording read by attekf.io.read_recording (its timestamps;
        use_mag=False: as if it had no magnetometer). progress(k) as in update_batch."""
        return self._run(*self._recording_inputs(rec, use_mag), True, progress)

    def _recording_inputs(self, rec, use_mag: bool):
        """run_recording's and smooth_recording's inputs from a recording: (times s, steps s,
        gyr, acc, mag) as the C run takes them."""
        n = len(rec.t)
        gyr = native.rows3("gyr", rec.gyr, "rad/s", n, layout_known=True)
        acc = native.rows3("acc", rec.acc, "m/s^2", n, layout_known=True)
        mag = native.rows3("mag", rec.mag, "uT", n, layout_known=True) if use_mag and rec.mag is not None else None
        steps = native.time_steps(n, t=rec.t, t_prev=self._t_last, first=self._dt or (1.0 if n == 1 else None))
        return np.ascontiguousarray(rec.t, dtype=np.float64), steps, gyr, acc, mag

    def _run(self, times, steps, gyr, acc, mag, timestamps: bool, progress, segment: Union[None, bool, int] = False
             ) -> Result:
        """The batch on the Core; segment False: the filter alone, else the smoother with that
        segment length (None: the default)."""
        if segment is False:
            res = native.run_core(self._lib, self._core, times, steps, gyr, acc, mag, progress, self._frame)
        else:
            res = native.smooth_core(self._lib, self._core, times, steps, gyr, acc, mag, progress, self._frame,
                                     segment)
        self._t_last = float(times[-1]) if (timestamps and len(times)) else None
        return res

    # ---- state --------------------------------------------------------------------------
    def get_state(self) -> dict:
        """Everything this filter is, to restore it later with set_state() (a dict of plain
        values, picklable): the C filter's memory (att_ekf_t: settings, state, covariance,
        counters) as bytes, tagged with the scalar build and the layout of this version of
        the library, and the Python-side options (dt, frame, mounting)."""
        data = self._core.state_bytes()
        return {"format": STATE_FORMAT, "version": STATE_VERSION, "scalar": self.scalar,
                "layout": self._lib.layout, "c_state": data, "crc32": zlib.crc32(data),
                "dt": self._dt, "frame": self._frame,
                "mounting": None if self._mounting is None else self._mounting.tolist(),
                "t_last": self._t_last}

    def set_state(self, state: dict) -> None:
        """Makes this filter exactly the one get_state() saved. ValueError (this filter
        unchanged) for anything else: not such a state, another scalar build, another
        version of the library, or damaged bytes."""
        if not isinstance(state, Mapping) or state.get("format") != STATE_FORMAT:
            raise ValueError("state: not a state saved by attekf.Filter.get_state()")
        if state.get("version") != STATE_VERSION:
            raise ValueError(f"state: format version {state.get('version')!r}, this attekf reads "
                             f"version {STATE_VERSION}")
        if state.get("scalar") != self.scalar:
            raise ValueError(f"state: saved by a {state.get('scalar')!r} filter, this one is "
                             f"{self.scalar!r} (use Filter(scalar={state.get('scalar')!r}))")
        if state.get("layout") != self._lib.layout:
            raise ValueError(f"state: saved by another version of the estimator (layout "
                             f"{state.get('layout')!r}, this one {self._lib.layout!r}): its memory "
                             "cannot be read by this one")
        data = state.get("c_state")
        if not isinstance(data, (bytes, bytearray)) or zlib.crc32(data) != state.get("crc32"):
            raise ValueError("state: the filter's bytes are damaged (checksum mismatch)")
        options = (_check_dt(state.get("dt")), _check_frame(state.get("frame")),
                   _check_mounting(state.get("mounting")))
        t_last = state.get("t_last")
        self._core.load_state(bytes(data))   # ValueError if the C library refuses them
        self._configure(*options)
        self._t_last = None if t_last is None else float(t_last)

    def __copy__(self) -> "Filter":
        new = Filter.__new__(Filter)
        new._lib, new._core = self._lib, self._core.copy()
        new._dt, new._frame, new._mounting, new._t_last = self._dt, self._frame, self.mounting, self._t_last
        return new

    def __deepcopy__(self, memo) -> "Filter":
        return self.__copy__()   # nothing is shared: the C filter is copied, the rest immutable

    def __reduce__(self):
        return (_filter_from_state, (self.get_state(),))

    def __repr__(self) -> str:
        mounting = "None" if self._mounting is None else self._mounting.tolist()
        return (f"<attekf.Filter scalar={self.scalar!r} dt={self._dt!r} frame={self._frame!r} "
                f"mounting={mounting}>")


def _filter_from_state(state: dict) -> Filter:
    """Unpickling: a Filter of the state's scalar build, set to the state."""
    f = Filter(scalar=state.get("scalar", "float") if isinstance(state, Mapping) else "float")
    f.set_state(state)
    return f


def estimate(gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None, *,
             t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
             dt: Union[None, float, np.ndarray] = None, settings: Optional[Settings] = None,
             scalar: str = "float", frame: str = "ENU", mounting=None, with_6d: bool = False) -> Result:
    """The estimator over whole arrays in one C call: Filter(settings, scalar, frame=...,
    mounting=...).update_batch.

    gyr, acc (N, 3) rad/s and m/s^2, mag (N, 3) uT or None; time from exactly one of
    t (N,) timestamps s, rate_hz (Hz) or dt (s). Returns a Result (help(attekf.Result)):
    quat (N, 4), euler (N, 3) rad, sigma_euler (N, 3) rad, cov_euler (N, 3, 3) rad^2, rate
    (N, 3) rad/s, gyro_bias (N, 3) rad/s, flags, status per sample, diag counters after the
    last sample. with_6d=True also runs the samples without the magnetometer (a second
    filter, the same settings): its Result is res.six_d, so one call gives 9D and 6D."""
    def run(m):
        return Filter(settings, scalar, frame=frame, mounting=mounting).update_batch(
            gyr, acc, m, t=t, rate_hz=rate_hz, dt=dt)
    if with_6d and mag is None:
        raise ValueError("with_6d: without a magnetometer (mag=None) the result is 6D already")
    res = run(mag)
    if with_6d:
        res.six_d = run(None)
    return res


def smooth(gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None, *,
           t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
           dt: Union[None, float, np.ndarray] = None, settings: Optional[Settings] = None,
           scalar: str = "float", frame: str = "ENU", mounting=None, with_6d: bool = False,
           progress=None, segment: Optional[int] = None) -> Result:
    """The estimate of every sample given the whole recording: estimate's arguments and result,
    from the filter (exactly the one estimate runs, any scalar build) and its Rauch-Tung-
    Striebel smoother in double precision (Filter.smooth_batch; docs/derivation.md,
    "Smoother"). quat, euler, sigma_euler, cov_euler, rate, state and var are smoothed; flags,
    status, diag and gyro_bias are the filter's. progress(k): called with the samples done
    (2 N per filter: forward, then backward; with_6d runs two). segment: samples per segment of
    the smoother's memory (default: 64 MiB of traces)."""
    def run(m):
        return Filter(settings, scalar, frame=frame, mounting=mounting).smooth_batch(
            gyr, acc, m, t=t, rate_hz=rate_hz, dt=dt, progress=progress, segment=segment)
    if with_6d and mag is None:
        raise ValueError("with_6d: without a magnetometer (mag=None) the result is 6D already")
    res = run(mag)
    if with_6d:
        res.six_d = run(None)
    return res


def _segment(segment) -> Optional[int]:
    """The smoother's segment length: None (the default) or a whole number >= 1 of samples."""
    if segment is None:
        return None
    if isinstance(segment, bool) or not isinstance(segment, (int, np.integer)) or segment < 1:
        raise ValueError(f"segment: {segment!r} is not a whole number of samples >= 1")
    return int(segment)


def default_settings(scalar: str = "float") -> dict:
    """Every setting's default value, by name (att_default_settings of the C build)."""
    return native.default_settings(scalar)


def setting_info(scalar: str = "float") -> dict:
    """name -> {"default", "unit", "help", "range" (lo, hi), "live"} for every setting of the
    C library ("live": may change while the filter runs)."""
    return native.setting_info(scalar)
