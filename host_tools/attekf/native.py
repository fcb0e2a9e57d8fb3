"""The C estimator from Python (ctypes over host_tools/native/attekf_native.c).

    from attekf.native import run_estimator, default_settings
    res = run_estimator(recording, {"accel_noise": 0.3}, scalar="float")
    res.euler, res.var_euler, res.quat, res.flags, res.status, res.summary()

The very same C code as on the target (firmware/att, att_step) runs over a whole recording
in one C call per block of samples (blocks only to drive a progress bar). Settings are set
by name through the C library's own table, so nothing here mirrors a C struct.

The libraries are built by CMake (build/host/host_tools/native/libattekf_native_{f,d}.so).
ATTEKF_LIB overrides where they are found: a directory holding them, or the path of one
library file (it then serves the scalar type it was built with).
"""

from __future__ import annotations

import ctypes
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Union

import numpy as np

from .io import Recording

API_VERSION = 1
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

# ATT_FLAG_* (firmware/att/att.h), for readers of Result.flags.
ATT_FLAGS = {
    "ALIGNED": 1 << 0, "GIMBAL_LOCK": 1 << 1, "ACCEL_DEWEIGHTED": 1 << 2, "ACCEL_REJECTED": 1 << 3,
    "MAG_DISTURBED": 1 << 4, "HEADING_HELD": 1 << 5, "GYRO_GATED": 1 << 6, "ACCEL_GATED": 1 << 7,
    "MAG_GATED": 1 << 8, "GATE_BYPASS": 1 << 9, "HEADING_LIMITED": 1 << 10, "REMAPPED": 1 << 11,
}

BLOCK = 20000  # samples per C call (progress granularity; ~10 ms of work)

_REPO = Path(__file__).resolve().parents[2]


class NativeError(RuntimeError):
    """The shared library is missing, of the wrong version, or refused the settings."""


class SettingsError(ValueError):
    """A setting name or value the C library refuses. str() names the setting."""


# ---------------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------------
def library_dir() -> Path:
    """Directory of the shared libraries (and of the attekf_vectors programs)."""
    env = os.environ.get("ATTEKF_LIB")
    if env:
        p = Path(env)
        return p if p.is_dir() else p.parent
    return _REPO / "build" / "host" / "host_tools" / "native"


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
            raise NativeError(
                f"{path}: the estimator library is not built. Build it with\n"
                f"  cmake -S {_REPO} -B {_REPO / 'build/host'} -G Ninja && cmake --build {_REPO / 'build/host'}\n"
                "(scripts/setup.sh does this), or point ATTEKF_LIB at a directory holding "
                "libattekf_native_f.so / _d.so.")
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
            ("attekf_run", c.c_int, [c.c_void_p, c.c_size_t, _dp, _dp, _dp, _dp,
                                     _dp, _dp, _dp, _u32p, _u8p]),
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

    # opaque, 8-byte aligned buffers of the C structs
    def new_settings(self):
        return (ctypes.c_double * ((self.settings_size + 7) // 8))()

    def new_filter(self):
        return (ctypes.c_double * ((self.filter_size + 7) // 8))()

    def status_name(self, code: int) -> str:
        return self.lib.attekf_status_name(int(code)).decode()


_LIBS: Dict[str, _Lib] = {}


def load(scalar: str = "float") -> _Lib:
    """The library for a scalar type ("float" or "double"), loaded once."""
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
                            f"{which} out of range (see firmware/att/att.h)")
    return buf


# ---------------------------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------------------------
@dataclass
class Result:
    """Per-sample outputs of the C estimator (all after the sample was processed).

    t        (N,) s, the recording's timestamps
    state    (N, 9) x = [p q r phi theta psi phid thetad psid] (rad/s, rad)
    var      (N, 9) diagonal of P (same order; (rad/s)^2, rad^2)
    quat     (N, 4) [w x y z] body->ENU
    flags    (N,) uint32 ATT_FLAG_* bits
    status   (N, 5) uint8 ekf_status_t of the step and of its stages (STATUS_COLUMNS)
    diag     the filter's counters (att_diag_t) after the last sample
    settings the settings used, by name; scalar: "float" or "double"
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


def run_arrays(t: np.ndarray, gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None,
               settings: Optional[Dict[str, float]] = None, scalar: str = "float",
               progress: Optional[Callable[[int], None]] = None) -> Result:
    """Runs the C estimator on arrays: t (N,) s, gyr/acc/mag (N, 3) (mag None or all-NaN rows
    for no magnetometer). progress(k) is called with the number of samples just done."""
    lib = load(scalar)
    t = np.ascontiguousarray(t, dtype=np.float64)
    n = t.shape[0]

    def arr3(name, a):
        a = np.ascontiguousarray(a, dtype=np.float64)
        if a.shape != (n, 3):
            raise ValueError(f"{name}: shape {a.shape}, expected ({n}, 3)")
        return a

    gyr = arr3("gyr", gyr)
    acc = arr3("acc", acc)
    mag = None if mag is None else arr3("mag", mag)
    sbuf = _make_settings(lib, settings)
    fbuf = lib.new_filter()
    st = lib.lib.attekf_filter_init(fbuf, sbuf)
    if st != 0:
        raise NativeError(f"att_init: {lib.status_name(st)}")
    # dt[0] is ignored by the filter (it aligns first); the nominal step is a harmless value.
    dt = np.empty(n, np.float64)
    if n:
        dt[1:] = np.diff(t)
        dt[0] = dt[1] if n > 1 else 0.01
    state = np.empty((n, N_STATES), np.float64)
    var = np.empty((n, N_STATES), np.float64)
    quat = np.empty((n, 4), np.float64)
    flags = np.empty(n, np.uint32)
    status = np.empty((n, len(STATUS_COLUMNS)), np.uint8)

    def ptr(a, typ, start):
        # rows from 'start' of a C-contiguous array; the view keeps the array alive
        return None if a is None else a[start:].ctypes.data_as(typ)

    c_seconds = 0.0
    for start in range(0, n, BLOCK):
        stop = min(n, start + BLOCK)
        t0 = time.process_time()
        rc = lib.lib.attekf_run(
            fbuf, stop - start, ptr(dt, _dp, start), ptr(gyr, _dp, start), ptr(acc, _dp, start),
            ptr(mag, _dp, start), ptr(state, _dp, start), ptr(var, _dp, start),
            ptr(quat, _dp, start), ptr(flags, _u32p, start), ptr(status, _u8p, start))
        c_seconds += time.process_time() - t0
        if rc != 0:
            raise NativeError(f"attekf_run: {lib.status_name(rc)}")
        if progress is not None:
            progress(stop - start)
    counters = (ctypes.c_uint32 * len(lib.diag_names))()
    lib.lib.attekf_diag_get(fbuf, counters)
    codes = np.unique(status)
    mag_absent = n if mag is None else int(np.all(np.isnan(mag), axis=1).sum())
    return Result(t=t, state=state, var=var, quat=quat, flags=flags, status=status,
                  diag={name: int(v) for name, v in zip(lib.diag_names, counters)},
                  settings=_settings_to_dict(lib, sbuf), scalar=scalar,
                  status_names={int(c): lib.status_name(int(c)) for c in codes},
                  mag_absent=mag_absent, c_seconds=c_seconds)


def run_estimator(recording: Recording, settings: Optional[Dict[str, float]] = None,
                  scalar: str = "float", use_mag: bool = True,
                  progress: Optional[Callable[[int], None]] = None) -> Result:
    """Runs the C estimator over a recording (use_mag=False: as if it had no magnetometer)."""
    return run_arrays(recording.t, recording.gyr, recording.acc,
                      recording.mag if use_mag else None, settings, scalar, progress)
