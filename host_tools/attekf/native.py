"""The C estimator from Python (ctypes over host_tools/native/attekf_native.c).

    from attekf.native import run_estimator, default_settings
    res = run_estimator(recording, {"accel_noise": 0.3}, scalar="float")
    res.euler, res.var_euler, res.quat, res.flags, res.status, res.summary()

The very same C code as on the target (firmware/att, att_step) runs over a whole recording
in one C call (in blocks only when a progress callback asks for it). Settings are set by
name through the C library's own table, so nothing here mirrors a C struct. The stateful
API for users (attekf.Filter, attekf.estimate) is in attekf/filter.py.

Where the libraries (libattekf_native_{f,d,x}.so) are found, first match:
  1. ATTEKF_LIB: a directory holding them, or the path of one library file (it then serves
     the scalar type it was built with);
  2. the installed package (attekf/_native/, built by pip through host_tools/CMakeLists.txt);
  3. the source tree's build (build/host/host_tools/native/, scripts/setup.sh builds it;
     what an editable install uses).
"""

from __future__ import annotations

import ctypes
import enum
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Union

import numpy as np

from .io import Recording

API_VERSION = 2
SCALARS = {"float": "f", "double": "d", "fixed": "x"}  # fixed: Q-format (docs/fixed_point.md)

# Columns of the per-sample status array (attekf_native.h, ATTEKF_STATUS_*).
STATUS_COLUMNS = ("step", "predict", "gyro", "accel", "mag")
N_STATES = 9
STATE_NAMES = ("p", "q", "r", "phi", "theta", "psi", "phid", "thetad", "psid")

# ekf_status_t values the summary needs (firmware/ekf/ekf.h).
EKF_OK = 0
EKF_ERR_NOT_INITIALISED = 6
EKF_GATED = 11
EKF_SKIPPED = 12


class Flag(enum.IntFlag):
    """Status flags of the filter (ATT_FLAG_* of firmware/att/att.h). "last" means the most
    recent sample of that sensor."""

    ALIGNED = 1 << 0            #: initial attitude set
    GIMBAL_LOCK = 1 << 1        #: |pitch| > gimbal_limit: kinematics clamped, heading held
    ACCEL_DEWEIGHTED = 1 << 2   #: last accel: linear acceleration, noise variance >= doubled
    ACCEL_REJECTED = 1 << 3     #: last accel: | |a| - g | beyond accel_reject, not fused
    MAG_DISTURBED = 1 << 4      #: last mag: norm or dip off the reference, not fused
    HEADING_HELD = 1 << 5       #: last mag: not fused because of gimbal lock
    GYRO_GATED = 1 << 6         #: last gyro: at least one axis gated
    ACCEL_GATED = 1 << 7        #: last accel: at least one axis gated
    MAG_GATED = 1 << 8          #: last mag: gated
    GATE_BYPASS = 1 << 9        #: a gate is bypassed after gate_timeout
    HEADING_LIMITED = 1 << 10   #: heading variance at heading_var_max
    REMAPPED = 1 << 11          #: last predict: pitch passed +-90 deg, remapped
    COV_REPAIRED = 1 << 12      #: last call: P was loaded to stay positive definite
    AT_REST = 1 << 13           #: last sample: at rest, gyroscope offset learned


# ATT_FLAG_* by name, for readers of Result.flags.
ATT_FLAGS = {f.name: int(f) for f in Flag}

BLOCK = 20000  # samples per C call (progress granularity; ~10 ms of work)

_REPO = Path(__file__).resolve().parents[2]


class NativeError(RuntimeError):
    """The shared library is missing, of the wrong version, or refused the settings."""


class SettingsError(ValueError):
    """A setting name or value the C library refuses. str() names the setting."""


# ---------------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------------
def _packaged_dir() -> Path:
    """Where a pip-installed package keeps its libraries (host_tools/CMakeLists.txt)."""
    return Path(__file__).resolve().parent / "_native"


def _build_dir() -> Path:
    """The libraries of the source tree's build (scripts/setup.sh)."""
    return _REPO / "build" / "host" / "host_tools" / "native"


def library_dir() -> Path:
    """Directory of the shared libraries (in the source tree's build, also of the
    attekf_vectors programs): ATTEKF_LIB, else the installed package's, else the build's."""
    env = os.environ.get("ATTEKF_LIB")
    if env:
        p = Path(env)
        return p if p.is_dir() else p.parent
    packaged = _packaged_dir()
    if (packaged / "libattekf_native_f.so").exists():
        return packaged
    return _build_dir()


def _library_path(scalar: str) -> Path:
    if scalar not in SCALARS:
        raise ValueError(f"scalar must be one of {', '.join(SCALARS)}, not {scalar!r}")
    env = os.environ.get("ATTEKF_LIB")
    if env and not Path(env).is_dir():
        return Path(env)
    return library_dir() / f"libattekf_native_{SCALARS[scalar]}.so"


_u8p = ctypes.POINTER(ctypes.c_uint8)
_u32p = ctypes.POINTER(ctypes.c_uint32)
_dp = ctypes.POINTER(ctypes.c_double)


class _Lib:
    """One loaded library with its prototypes and its tables (settings, counters)."""

    def __init__(self, path: Path, scalar: str):
        if not path.exists():
            if (_REPO / "firmware" / "CMakeLists.txt").exists():  # a source checkout
                how = (f"build it with scripts/setup.sh (or cmake -S {_REPO} -B {_REPO / 'build/host'} "
                       f"-G Ninja && cmake --build {_REPO / 'build/host'}), ")
            else:
                how = "reinstall the package (pip install attekf builds the libraries), "
            raise NativeError(
                f"{path}: the estimator library is not built: {how}or point ATTEKF_LIB at a "
                "directory holding libattekf_native_f.so / _d.so / _x.so.")
        try:
            lib = ctypes.CDLL(str(path))
        except OSError as exc:
            raise NativeError(f"{path}: cannot load: {exc}") from None
        self.path = path
        self.lib = lib
        c = ctypes
        for name, res, args in (
            ("attekf_api_version", c.c_int, []),
            ("attekf_scalar_name", c.c_char_p, []),
            ("attekf_settings_size", c.c_size_t, []),
            ("attekf_filter_size", c.c_size_t, []),
            ("attekf_settings_default", None, [c.c_void_p]),
            ("attekf_setting_count", c.c_size_t, []),
            ("attekf_setting_name", c.c_char_p, [c.c_size_t]),
            ("attekf_setting_unit", c.c_char_p, [c.c_size_t]),
            ("attekf_setting_help", c.c_char_p, [c.c_size_t]),
            ("attekf_setting_type", c.c_int, [c.c_size_t]),
            ("attekf_setting_set", c.c_int, [c.c_void_p, c.c_char_p, c.c_double]),
            ("attekf_setting_get", c.c_int, [c.c_void_p, c.c_char_p, _dp]),
            ("attekf_settings_table_complete", c.c_int, []),
            ("attekf_settings_check", c.c_int, [c.c_void_p]),
            ("attekf_filter_init", c.c_int, [c.c_void_p, c.c_void_p]),
            ("attekf_status_name", c.c_char_p, [c.c_int]),
            ("attekf_diag_count", c.c_size_t, []),
            ("attekf_diag_name", c.c_char_p, [c.c_size_t]),
            ("attekf_diag_get", None, [c.c_void_p, _u32p]),
            ("attekf_diag_value_count", c.c_size_t, []),
            ("attekf_diag_value_name", c.c_char_p, [c.c_size_t]),
            ("attekf_diag_value_unit", c.c_char_p, [c.c_size_t]),
            ("attekf_diag_value_len", c.c_size_t, [c.c_size_t]),
            ("attekf_diag_values_get", None, [c.c_void_p, _dp]),
            ("attekf_diag_table_complete", c.c_int, []),
            ("attekf_run", c.c_int, [c.c_void_p, c.c_size_t, _dp, _dp, _dp, _dp,
                                     _dp, _dp, _dp, _u32p, _u8p]),
            ("attekf_run_cov", c.c_int, [c.c_void_p, c.c_size_t, _dp, _dp, _dp, _dp,
                                         _dp, _dp, _dp, _u32p, _u8p, _dp]),
        ):
            try:
                fn = getattr(lib, name)
            except AttributeError:
                raise NativeError(f"{path}: missing symbol {name} (stale build? rebuild)") from None
            fn.restype = res
            fn.argtypes = args
        version = lib.attekf_api_version()
        if version != API_VERSION:
            raise NativeError(f"{path}: API version {version}, this package expects {API_VERSION}; rebuild")
        built = lib.attekf_scalar_name().decode()
        if built != scalar:
            raise NativeError(f"{path}: built for scalar '{built}', asked for '{scalar}'")
        self.scalar = scalar
        self.settings_size = int(lib.attekf_settings_size())
        self.filter_size = int(lib.attekf_filter_size())
        n = int(lib.attekf_setting_count())
        self.setting_names: List[str] = [lib.attekf_setting_name(i).decode() for i in range(n)]
        self.setting_units = {nm: lib.attekf_setting_unit(i).decode() for i, nm in enumerate(self.setting_names)}
        self.setting_help = {nm: lib.attekf_setting_help(i).decode() for i, nm in enumerate(self.setting_names)}
        self.setting_is_int = {nm: lib.attekf_setting_type(i) == 1 for i, nm in enumerate(self.setting_names)}
        self.diag_names: List[str] = [lib.attekf_diag_name(i).decode() for i in range(int(lib.attekf_diag_count()))]
        nv = int(lib.attekf_diag_value_count())
        self.diag_value_names: List[str] = [lib.attekf_diag_value_name(i).decode() for i in range(nv)]
        self.diag_value_units = {nm: lib.attekf_diag_value_unit(i).decode()
                                 for i, nm in enumerate(self.diag_value_names)}
        self.diag_value_lens = [int(lib.attekf_diag_value_len(i)) for i in range(nv)]

    # opaque, 8-byte aligned buffers of the C structs
    def new_settings(self):
        return (ctypes.c_double * ((self.settings_size + 7) // 8))()

    def new_filter(self):
        return (ctypes.c_double * ((self.filter_size + 7) // 8))()

    def status_name(self, code: int) -> str:
        return self.lib.attekf_status_name(int(code)).decode()

    def diag(self, fbuf) -> Dict[str, int]:
        """The counters of att_diag_t of a filter buffer, by name."""
        counters = (ctypes.c_uint32 * len(self.diag_names))()
        self.lib.attekf_diag_get(fbuf, counters)
        return {name: int(v) for name, v in zip(self.diag_names, counters)}

    def diag_values(self, fbuf) -> Dict[str, Union[float, tuple]]:
        """The other diagnostics of att_diag_t (test ratios, norm and dip errors), by name:
        a float, or a tuple for an array field."""
        out = (ctypes.c_double * sum(self.diag_value_lens))()
        self.lib.attekf_diag_values_get(fbuf, out)
        values: Dict[str, Union[float, tuple]] = {}
        k = 0
        for name, n in zip(self.diag_value_names, self.diag_value_lens):
            values[name] = float(out[k]) if n == 1 else tuple(float(v) for v in out[k:k + n])
            k += n
        return values


_LIBS: Dict[str, _Lib] = {}


def load(scalar: str = "float") -> _Lib:
    """The library for a scalar type ("float", "double" or "fixed"), loaded once."""
    path = _library_path(scalar)
    key = f"{scalar}:{path}"
    if key not in _LIBS:
        _LIBS[key] = _Lib(path, scalar)
    return _LIBS[key]


# ---------------------------------------------------------------------------------------------
# Settings
# ---------------------------------------------------------------------------------------------
def default_settings(scalar: str = "float") -> Dict[str, Union[float, int]]:
    """att_default_settings by name (values as the C build stores them)."""
    lib = load(scalar)
    buf = lib.new_settings()
    lib.lib.attekf_settings_default(buf)
    return _settings_to_dict(lib, buf)


def setting_info(scalar: str = "float") -> Dict[str, Dict[str, object]]:
    """name -> {'default', 'unit', 'help'} for every setting of the C library."""
    lib = load(scalar)
    defaults = default_settings(scalar)
    return {n: {"default": defaults[n], "unit": lib.setting_units[n], "help": lib.setting_help[n]}
            for n in lib.setting_names}


def _settings_to_dict(lib: _Lib, buf) -> Dict[str, Union[float, int]]:
    out: Dict[str, Union[float, int]] = {}
    v = ctypes.c_double()
    for name in lib.setting_names:
        rc = lib.lib.attekf_setting_get(buf, name.encode(), ctypes.byref(v))
        if rc != 0:
            raise NativeError(f"attekf_setting_get({name}) failed ({rc})")
        if lib.setting_is_int[name]:
            out[name] = int(v.value)
        elif lib.scalar == "float":
            # the shortest decimal that reads back as the same float (0.001, not 0.0010000000474...)
            out[name] = float(str(np.float32(v.value)))
        else:
            out[name] = float(v.value)
    return out


def _make_settings(lib: _Lib, settings: Optional[Dict[str, float]]):
    buf = lib.new_settings()
    lib.lib.attekf_settings_default(buf)
    for name, value in (settings or {}).items():
        try:
            fvalue = float(value)
        except (TypeError, ValueError):
            raise SettingsError(f"setting {name}: {value!r} is not a number") from None
        rc = lib.lib.attekf_setting_set(buf, str(name).encode(), fvalue)
        if rc == -1:
            raise SettingsError(f"unknown setting '{name}' (known: {', '.join(lib.setting_names)})")
        if rc != 0:
            kind = "a non-negative integer <= 65535" if lib.setting_is_int.get(name) else \
                f"a finite {lib.scalar}"
            raise SettingsError(f"setting {name}: {value!r} is not {kind}")
    st = lib.lib.attekf_settings_check(buf)
    if st != 0:
        # att_settings_check does not say which field is wrong: find it by applying the
        # changed settings one at a time to the defaults.
        culprits = []
        for name, value in (settings or {}).items():
            one = lib.new_settings()
            lib.lib.attekf_settings_default(one)
            lib.lib.attekf_setting_set(one, str(name).encode(), float(value))
            if lib.lib.attekf_settings_check(one) != 0:
                culprits.append(f"{name}={value!r}")
        which = ", ".join(culprits) if culprits else "a combination of " + ", ".join(
            f"{k}={v!r}" for k, v in (settings or {}).items())
        raise SettingsError(f"settings refused by att_settings_check ({lib.status_name(st)}): "
                            f"{which} out of range (the ranges: firmware/att/att.h)")
    return buf


# ---------------------------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------------------------
@dataclass
class Result:
    """Per-sample outputs of the C estimator (all after the sample was processed).

    t        (N,) s, the recording's timestamps
    state    (N, 9) x = [p q r phi theta psi phid thetad psid] (rad/s, rad)
    var      (N, 9) att_get_variances (same order; (rad/s)^2, rad^2): the diagonal of P, for
             the angles that of the reported attitude covariance
    angle_cov (N, 6) the reported roll/pitch/yaw covariance, rad^2 (att_get_angle_covariance:
             phi phi, theta theta, psi psi, phi theta, phi psi, theta psi)
    quat     (N, 4) [w x y z] body->ENU
    flags    (N,) uint32 ATT_FLAG_* bits
    status   (N, 5) uint8 ekf_status_t of the step and of its stages (STATUS_COLUMNS)
    diag     the filter's counters (att_diag_t) after the last sample
    diag_values  the other diagnostics of att_diag_t after the last sample (innovation test
             ratios, 1; accel_norm_error m/s^2; mag_norm_error, 1; mag_dip_error rad)
    settings the settings used, by name; scalar: "float", "double" or "fixed"
    status_names code -> name of every code that occurs in status
    mag_absent samples given without magnetometer (no magnetometer, or an all-NaN row)
    c_seconds  CPU time (process) spent inside the C calls (attekf_run), s: the estimator's
               own cost without Python set-up (`attekf bench` per-sample cost)
    """

    t: np.ndarray
    state: np.ndarray
    var: np.ndarray
    quat: np.ndarray
    flags: np.ndarray
    status: np.ndarray
    diag: Dict[str, int]
    settings: Dict[str, Union[float, int]]
    scalar: str
    status_names: Dict[int, str] = field(default_factory=dict)
    mag_absent: int = 0
    c_seconds: float = 0.0  # CPU time inside the attekf_run calls (the C loop), s
    diag_values: Dict[str, Union[float, tuple]] = field(default_factory=dict)
    angle_cov: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def euler(self) -> np.ndarray:
        """(N, 3) roll, pitch, yaw in rad (ZYX, body->ENU)."""
        return self.state[:, 3:6]

    @property
    def var_euler(self) -> np.ndarray:
        """(N, 3) variances of roll, pitch, yaw in rad^2."""
        return self.var[:, 3:6]

    @property
    def sigma_euler(self) -> np.ndarray:
        """(N, 3) 1-sigma uncertainty of roll, pitch, yaw in rad (sqrt of var_euler)."""
        return np.sqrt(self.var[:, 3:6])

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
        s = self.status[:, STATUS_COLUMNS.index(column)]
        return (s != EKF_OK) & (s != EKF_GATED) & (s != EKF_SKIPPED) & (s != EKF_ERR_NOT_INITIALISED)

    def summary(self) -> Dict[str, object]:
        """Counts of what happened to the samples: nothing is dropped without a count."""
        out: Dict[str, object] = {"samples": len(self), "aligned_samples": int(self.aligned.sum()),
                                  "mag_absent": int(self.mag_absent)}
        refused = {}
        for k, col in enumerate(STATUS_COLUMNS):
            codes, counts = np.unique(self.status[:, k], return_counts=True)
            per = {self.status_names.get(int(c), str(int(c))): int(n)
                   for c, n in zip(codes, counts) if c != EKF_OK}
            if per:
                refused[col] = per
        out["status_counts"] = refused
        out["samples_refused"] = int(self.refused().sum())
        out["diag"] = dict(self.diag)
        return out


def time_steps(n: int, t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
               dt: Union[None, float, np.ndarray] = None, t_prev: Optional[float] = None
               ) -> np.ndarray:
    """(n,) time steps in s from exactly one of: timestamps t (n,) s, a sample rate rate_hz
    (Hz), or dt (s, one value or (n,)). With timestamps the first step is t[0] - t_prev
    when the time of the previous sample is known, else the next step (the filter aligns on
    the first samples and does not use it)."""
    if (t is not None) + (rate_hz is not None) + (dt is not None) != 1:
        raise ValueError("give exactly one of t (timestamps, s), rate_hz (Hz) or dt (s)")
    if t is not None:
        t = np.ascontiguousarray(t, dtype=np.float64)
        if t.shape != (n,):
            raise ValueError(f"t: shape {t.shape}, expected ({n},)")
        out = np.empty(n, np.float64)
        if n:
            out[1:] = np.diff(t)
            if t_prev is not None:
                out[0] = t[0] - t_prev
            else:
                out[0] = out[1] if n > 1 else 0.01
        return out
    if rate_hz is not None:
        rate = float(rate_hz)
        if not np.isfinite(rate) or rate <= 0.0:
            raise ValueError(f"rate_hz: {rate_hz!r} is not a positive sample rate in Hz")
        return np.full(n, 1.0 / rate)
    steps = np.asarray(dt, dtype=np.float64)
    if steps.ndim == 0:
        return np.full(n, float(steps))
    if steps.shape != (n,):
        raise ValueError(f"dt: shape {steps.shape}, expected ({n},) or one value")
    return np.ascontiguousarray(steps)


def _arr3(name: str, a, n: int) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.shape != (n, 3):
        raise ValueError(f"{name}: shape {a.shape}, expected ({n}, 3)")
    return a


def _run(lib: _Lib, fbuf, sbuf, t: np.ndarray, dt: np.ndarray, gyr: np.ndarray,
         acc: np.ndarray, mag: Optional[np.ndarray],
         progress: Optional[Callable[[int], None]] = None) -> Result:
    """att_step over the arrays on the filter fbuf, continuing from its state: one C call
    for all samples, or blocks of BLOCK samples with a progress callback."""
    n = dt.shape[0]
    state = np.empty((n, N_STATES), np.float64)
    var = np.empty((n, N_STATES), np.float64)
    quat = np.empty((n, 4), np.float64)
    flags = np.empty(n, np.uint32)
    status = np.empty((n, len(STATUS_COLUMNS)), np.uint8)
    cov = np.empty((n, 6), np.float64)

    def ptr(a, typ, start):
        # rows from 'start' of a C-contiguous array; the view keeps the array alive
        return None if a is None else a[start:].ctypes.data_as(typ)

    block = BLOCK if progress is not None else max(n, 1)
    c_seconds = 0.0
    for start in range(0, n, block):
        stop = min(n, start + block)
        t0 = time.process_time()
        rc = lib.lib.attekf_run_cov(
            fbuf, stop - start, ptr(dt, _dp, start), ptr(gyr, _dp, start), ptr(acc, _dp, start),
            ptr(mag, _dp, start), ptr(state, _dp, start), ptr(var, _dp, start),
            ptr(quat, _dp, start), ptr(flags, _u32p, start), ptr(status, _u8p, start),
            ptr(cov, _dp, start))
        c_seconds += time.process_time() - t0
        if rc != 0:
            raise NativeError(f"attekf_run: {lib.status_name(rc)}")
        if progress is not None:
            progress(stop - start)
    codes = np.unique(status)
    mag_absent = n if mag is None else int(np.all(np.isnan(mag), axis=1).sum())
    return Result(t=t, state=state, var=var, quat=quat, flags=flags, status=status,
                  diag=lib.diag(fbuf), settings=_settings_to_dict(lib, sbuf), scalar=lib.scalar,
                  status_names={int(c): lib.status_name(int(c)) for c in codes},
                  mag_absent=mag_absent, c_seconds=c_seconds, diag_values=lib.diag_values(fbuf),
                  angle_cov=cov)


def _new_filter(lib: _Lib, sbuf):
    fbuf = lib.new_filter()
    st = lib.lib.attekf_filter_init(fbuf, sbuf)
    if st != 0:
        raise NativeError(f"att_init: {lib.status_name(st)}")
    return fbuf


def run_arrays(t: np.ndarray, gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None,
               settings: Optional[Dict[str, float]] = None, scalar: str = "float",
               progress: Optional[Callable[[int], None]] = None) -> Result:
    """Runs the C estimator on arrays: t (N,) s, gyr/acc/mag (N, 3) (mag None or all-NaN rows
    for no magnetometer). One C call, or blocks when progress(k) is given: it is called with
    the number of samples just done."""
    lib = load(scalar)
    t = np.ascontiguousarray(t, dtype=np.float64)
    n = t.shape[0]
    gyr = _arr3("gyr", gyr, n)
    acc = _arr3("acc", acc, n)
    mag = None if mag is None else _arr3("mag", mag, n)
    sbuf = _make_settings(lib, settings)
    fbuf = _new_filter(lib, sbuf)
    return _run(lib, fbuf, sbuf, t, time_steps(n, t=t), gyr, acc, mag, progress)


def run_estimator(recording: Recording, settings: Optional[Dict[str, float]] = None,
                  scalar: str = "float", use_mag: bool = True,
                  progress: Optional[Callable[[int], None]] = None) -> Result:
    """Runs the C estimator over a recording (use_mag=False: as if it had no magnetometer)."""
    return run_arrays(recording.t, recording.gyr, recording.acc,
                      recording.mag if use_mag else None, settings, scalar, progress)
