"""The C estimator from Python: the extension modules of host_tools/native (CPython C API).

    from attekf.native import run_estimator, default_settings
    res = run_estimator(recording, {"accel_noise": 0.3}, scalar="float")
    res.euler, res.var_euler, res.quat, res.flags, res.status, res.summary()

The very same C code as on the target (firmware/att, att_step) runs over a whole recording
in one C call (in blocks only when a progress callback asks for it). Settings are set by
name through the C library's own table, so nothing here mirrors a C struct. The stateful
API for users (attekf.Filter, attekf.estimate) is in attekf/filter.py; the result types
(Flag, Estimate, Result) in attekf/results.py.

Where the modules (_core_f, _core_d, _core_x with the interpreter's suffix, e.g.
_core_f.cpython-311-x86_64-linux-gnu.so) are found, first match:
  1. ATTEKF_LIB: a directory holding them, or the path of one module file (it then serves
     the scalar type it was built for);
  2. the installed package (attekf/, built by pip through host_tools/CMakeLists.txt);
  3. the source tree's build (build/host/host_tools/native/, scripts/setup.sh builds it;
     what an editable install uses).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import os
import time
from pathlib import Path
from typing import Callable, Dict, List, Optional, Union

import numpy as np

from .results import ATT_FLAGS, Estimate, Flag, Result, STATE_NAMES  # noqa: F401 (re-exported)

API_VERSION = 3
SCALARS = {"float": "f", "double": "d", "fixed": "x"}  # fixed: Q-format (docs/fixed_point.md)
N_STATES = len(STATE_NAMES)

# ekf_status_t values the summary needs (firmware/ekf/ekf.h; checked by the tests).
EKF_OK = 0
EKF_ERR_NOT_INITIALISED = 6
EKF_ERR_SETTINGS = 7
EKF_GATED = 11
EKF_SKIPPED = 12

BLOCK = 20000  # samples per C call when a progress callback is given (~20 ms of work)

_REPO = Path(__file__).resolve().parents[2]


class NativeError(RuntimeError):
    """The extension module is missing, of the wrong version, or failed."""


class SettingsError(ValueError):
    """A setting name or value the C library refuses. str() names the setting."""


# ---------------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------------
def build_dir() -> Path:
    """The source tree's build of the modules and of the attekf_vectors programs
    (scripts/setup.sh)."""
    return _REPO / "build" / "host" / "host_tools" / "native"


def _module_file(directory: Path, scalar: str) -> Optional[Path]:
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        p = directory / f"_core_{SCALARS[scalar]}{suffix}"
        if p.is_file():
            return p
    return None


def module_path(scalar: str) -> Path:
    """The extension module file of a scalar build (ATTEKF_LIB, the package, the build)."""
    if scalar not in SCALARS:
        raise ValueError(f"scalar must be one of {', '.join(SCALARS)}, not {scalar!r}")
    expected = f"_core_{SCALARS[scalar]}{importlib.machinery.EXTENSION_SUFFIXES[0]}"
    env = os.environ.get("ATTEKF_LIB")
    if env:
        p = Path(env)
        return (_module_file(p, scalar) or p / expected) if p.is_dir() else p
    for directory in (Path(__file__).resolve().parent, build_dir()):
        found = _module_file(directory, scalar)
        if found is not None:
            return found
    return Path(__file__).resolve().parent / expected


def _not_built(path: Path) -> NativeError:
    if (_REPO / "firmware" / "CMakeLists.txt").exists():   # a source checkout
        how = "build it with scripts/setup.sh (or cmake --build build/host), "
    else:
        how = "reinstall the package (pip install --force-reinstall attekf), "
    return NativeError(f"{path}: the estimator's extension module is not there: {how}or point "
                       "ATTEKF_LIB at a directory holding _core_f / _core_d / _core_x")


class Library:
    """One loaded extension module with its tables (settings, diagnostics, status names)."""

    def __init__(self, path: Path, scalar: str):
        if not path.is_file():
            raise _not_built(path)
        name = "attekf." + path.name.split(".")[0]   # the module's own name (its PyInit_ function)
        try:
            spec = importlib.util.spec_from_file_location(name, path)
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
        except (ImportError, OSError) as exc:
            raise NativeError(f"{path}: cannot load: {exc}") from None
        self.path = path
        self.module = mod
        if getattr(mod, "API_VERSION", None) != API_VERSION:
            raise NativeError(f"{path}: API version {getattr(mod, 'API_VERSION', '?')}, this package "
                              f"expects {API_VERSION}; rebuild")
        if mod.SCALAR != scalar:
            raise NativeError(f"{path}: built for scalar '{mod.SCALAR}', asked for '{scalar}'")
        if mod.ESTIMATE_FIELDS != Estimate._fields or mod.N_STATES != N_STATES:
            raise NativeError(f"{path}: its Estimate fields or state size differ from this package's; rebuild")
        self.scalar = scalar
        self.layout = mod.LAYOUT
        self.state_size = int(mod.STATE_SIZE)
        self.status_columns = tuple(mod.STATUS_COLUMNS)
        table = mod.settings_table()
        self.setting_names: List[str] = [row[0] for row in table]
        self.setting_units = {row[0]: row[1] for row in table}
        self.setting_help = {row[0]: row[2] for row in table}
        self.setting_is_int = {row[0]: bool(row[3]) for row in table}
        self.setting_range = {row[0]: (self._shown(row[4]), self._shown(row[5])) for row in table}
        self.setting_live = {row[0]: bool(row[6]) for row in table}
        self._index = {n: i for i, n in enumerate(self.setting_names)}
        counters, values = mod.diag_tables()
        self.diag_names: List[str] = list(counters)
        self.diag_value_names: List[str] = [v[0] for v in values]
        self.diag_value_units = {v[0]: v[1] for v in values}
        self.diag_value_lens = [int(v[2]) for v in values]
        names = []
        while len(names) < 256 and mod.status_name(len(names)) != "EKF_STATUS_UNKNOWN":
            names.append(mod.status_name(len(names)))
        self.status_names = tuple(names)

    def tables_complete(self) -> bool:
        """The settings and diagnostics tables cover att_settings_t and att_diag_t."""
        return all(self.module.tables_complete())

    def status_name(self, code: int) -> str:
        code = int(code)
        return self.status_names[code] if 0 <= code < len(self.status_names) else self.module.status_name(code)

    def _shown(self, v: float) -> float:
        """A value of the build as a short decimal: the float build's 0.001 (not
        0.0010000000474974513), the others as they are."""
        return float(str(np.float32(v))) if self.scalar == "float" else float(v)

    # ---- settings ----------------------------------------------------------------------
    def settings_dict(self, s) -> Dict[str, Union[float, int]]:
        """Every setting of a Settings object, by name (values as the C build stores them)."""
        out: Dict[str, Union[float, int]] = {}
        for i, name in enumerate(self.setting_names):
            v = s.get(i)
            out[name] = int(v) if self.setting_is_int[name] else self._shown(v)
        return out

    def make_settings(self, settings: Optional[Dict[str, float]] = None):
        """A Settings object: the defaults with `settings` {name: value} changed, each checked
        by the C library (att_setting_set: its own range; att_settings_check: the bounds
        between settings). SettingsError names the setting at fault."""
        s = self.module.Settings()
        for name, value in (settings or {}).items():
            i = self._index.get(str(name))
            if i is None:
                raise SettingsError(f"unknown setting '{name}' (known: {', '.join(self.setting_names)})")
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise SettingsError(f"setting {name}: {value!r} is not a number") from None
            largest = float(np.finfo(np.float32).max) if self.scalar == "float" else float("inf")
            if not abs(v) <= largest:
                raise SettingsError(f"setting {name}: {value!r} is not a finite {self.scalar}")
            if s.set(i, v) != EKF_OK:
                lo, hi = self.setting_range[name]
                whole = "a whole number " if self.setting_is_int[name] else ""
                raise SettingsError(f"setting {name}: {value!r} is not {whole}in [{lo:g}, {hi:g}] "
                                    f"({self.setting_units[name]})")
        st = s.check()
        if st != EKF_OK:
            changed = ", ".join(f"{k}={v!r}" for k, v in (settings or {}).items())
            raise SettingsError(f"settings refused by att_settings_check ({self.status_name(st)}): "
                                f"{changed}: settings that bound each other do not fit (accel_range >= "
                                "gravity, heading_var_max >= var_floor, rest.bias_max and bias.sigma_init "
                                "<= gyro_range), or a derived variance is not representable in the "
                                f"{self.scalar} build; attekf.setting_info() gives every setting's range")
        return s

    def new_core(self, settings):
        """A Core (one att_ekf_t, initialised with the Settings) ready for update()."""
        core = self.module.Core(settings)
        core.bind(Estimate, Flag, self.status_names)
        return core


_LIBS: Dict[str, Library] = {}


def load(scalar: str = "float") -> Library:
    """The extension module for a scalar type ("float", "double" or "fixed"), loaded once."""
    path = module_path(scalar)
    key = f"{scalar}:{path}"
    if key not in _LIBS:
        _LIBS[key] = Library(path, scalar)
    return _LIBS[key]


def _make_settings(lib: Library, settings: Optional[Dict[str, float]]):
    """lib.make_settings (the name the commands use)."""
    return lib.make_settings(settings)


# ---------------------------------------------------------------------------------------------
# Settings
# ---------------------------------------------------------------------------------------------
def default_settings(scalar: str = "float") -> Dict[str, Union[float, int]]:
    """att_default_settings by name (values as the C build stores them)."""
    lib = load(scalar)
    return lib.settings_dict(lib.module.Settings())


def setting_info(scalar: str = "float") -> Dict[str, Dict[str, object]]:
    """name -> {'default', 'unit', 'help', 'range' (lo, hi), 'live'} for every setting of the
    C library (live: may change while the filter runs)."""
    lib = load(scalar)
    defaults = default_settings(scalar)
    return {n: {"default": defaults[n], "unit": lib.setting_units[n], "help": lib.setting_help[n],
                "range": lib.setting_range[n], "live": lib.setting_live[n]}
            for n in lib.setting_names}


# ---------------------------------------------------------------------------------------------
# Checking array arguments and time
# ---------------------------------------------------------------------------------------------
def rows3(name: str, a, unit: str, n: Optional[int] = None, layout_known: bool = False) -> np.ndarray:
    """a as a C-contiguous float64 (N, 3) array of samples; ValueError naming the argument
    for any other shape and, unless layout_known (a recording read from a file), for the
    ambiguous (3, 3) and a transposed (3, N)."""
    try:
        arr = np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: not an array of numbers ({unit})") from None
    shape = arr.shape
    if not layout_known and arr.ndim == 2 and shape == (3, 3):
        raise ValueError(f"{name}: shape (3, 3) is ambiguous (three samples as rows, or one per "
                         "column?): give samples as the rows of an (N, 3) array with N other than 3, "
                         "or call Filter.update() per sample")
    if not layout_known and arr.ndim == 2 and shape[0] == 3 and shape[1] != 3:
        raise ValueError(f"{name}: shape {shape}, expected (N, 3): samples are rows ({name}.T?)")
    if arr.ndim == 1 and shape == (3,):
        raise ValueError(f"{name}: shape (3,), expected (N, 3): one sample goes to Filter.update()")
    if arr.ndim != 2 or shape[1] != 3 or (n is not None and shape[0] != n):
        want = "(N, 3)" if n is None else f"({n}, 3)"
        raise ValueError(f"{name}: shape {shape}, expected {want} ({unit})")
    return arr


def time_steps(n: int, t: Optional[np.ndarray] = None, rate_hz: Optional[float] = None,
               dt: Union[None, float, np.ndarray] = None, t_prev: Optional[float] = None,
               first: Optional[float] = None) -> np.ndarray:
    """(n,) time steps in s from exactly one of: timestamps t (n,) s, a sample rate rate_hz
    (Hz), or dt (s, one value or (n,)). With timestamps the first step is t[0] - t_prev
    when the time of the previous sample is known, else `first`, else the next step (a new
    filter aligns on its first samples and does not use it). Every step must be a positive
    finite number (timestamps strictly increasing): ValueError naming the argument and
    sample otherwise."""
    if (t is not None) + (rate_hz is not None) + (dt is not None) != 1:
        raise ValueError("give exactly one of t (timestamps, s), rate_hz (Hz) or dt (s)")
    if t is not None:
        try:
            t = np.ascontiguousarray(t, dtype=np.float64)
        except (TypeError, ValueError):
            raise TypeError("t: not an array of numbers (s)") from None
        if t.shape != (n,):
            raise ValueError(f"t: shape {t.shape}, expected ({n},)")
        if not np.isfinite(t).all():
            k = int(np.argmin(np.isfinite(t)))
            raise ValueError(f"t: sample {k}: {float(t[k])!r} is not a finite time (s)")
        out = np.empty(n, np.float64)
        if n:
            out[1:] = np.diff(t)
            if t_prev is not None:
                out[0] = t[0] - t_prev
            elif first is not None:
                out[0] = first
            elif n > 1:
                out[0] = out[1]
            else:
                raise ValueError("t: one timestamp and no earlier one gives no time step: give dt (s)")
        bad = ~(out > 0)
        if bad.any():
            k = int(np.argmax(bad))
            before = f"t[{k - 1}] = {float(t[k - 1])!r}" if k else f"the previous batch's last time {t_prev!r}"
            raise ValueError(f"t: not strictly increasing: t[{k}] = {float(t[k])!r} after {before}")
        return out
    if rate_hz is not None:
        try:
            rate = float(rate_hz)
        except (TypeError, ValueError):
            raise TypeError(f"rate_hz: {rate_hz!r} is not a number (Hz)") from None
        if not np.isfinite(rate) or rate <= 0.0 or not np.isfinite(1.0 / rate):
            raise ValueError(f"rate_hz: {rate_hz!r} is not a positive sample rate in Hz")
        return np.full(n, 1.0 / rate)
    try:
        steps = np.asarray(dt, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"dt: {dt!r} is not a number (s) or an array of them") from None
    if steps.ndim == 0:
        if not (np.isfinite(steps) and steps > 0):
            raise ValueError(f"dt: {dt!r} is not a positive, finite time step (s)")
        return np.full(n, float(steps))
    if steps.shape != (n,):
        raise ValueError(f"dt: shape {steps.shape}, expected ({n},) or one value")
    bad = ~(np.isfinite(steps) & (steps > 0))
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(f"dt: sample {k}: {float(steps[k])!r} is not a positive, finite time step (s)")
    return np.ascontiguousarray(steps)


# ---------------------------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------------------------
def run_core(lib: Library, core, t: np.ndarray, dt: np.ndarray, gyr: np.ndarray, acc: np.ndarray,
             mag: Optional[np.ndarray], progress: Optional[Callable[[int], None]] = None,
             frame: str = "ENU") -> Result:
    """att_step over checked arrays (rows3, time_steps) on the Core, continuing from its state:
    one C call for all samples, or blocks of BLOCK samples with a progress callback."""
    n = dt.shape[0]
    out = {"state": np.empty((n, N_STATES)), "var": np.empty((n, N_STATES)), "quat": np.empty((n, 4)),
           "euler": np.empty((n, 3)), "angle_cov": np.empty((n, 6)), "flags": np.empty(n, np.uint32),
           "status": np.empty((n, len(lib.status_columns)), np.uint8), "gyro_bias": np.empty((n, 3)),
           "gyro_bias_sigma": np.empty((n, 3))}
    order = ("state", "var", "quat", "euler", "angle_cov", "flags", "status", "gyro_bias", "gyro_bias_sigma")
    block = BLOCK if progress is not None else max(n, 1)
    c_seconds = 0.0
    for start in range(0, n, block):
        rows = slice(start, min(n, start + block))
        t0 = time.process_time()
        core.run(dt[rows], gyr[rows], acc[rows], None if mag is None else mag[rows],
                 *(out[k][rows] for k in order))
        c_seconds += time.process_time() - t0
        if progress is not None:
            progress(rows.stop - rows.start)
    codes = np.flatnonzero(np.bincount(out["status"].ravel(), minlength=1))   # the codes that occur
    mag_absent = n if mag is None else int(np.all(np.isnan(mag), axis=1).sum())
    return Result(t=t, scalar=lib.scalar, frame=frame, settings=lib.settings_dict(core.settings()),
                  diag=dict(zip(lib.diag_names, core.diag())), diag_values=_diag_values(lib, core),
                  status_names={int(c): lib.status_name(int(c)) for c in codes}, mag_absent=mag_absent,
                  c_seconds=c_seconds, status_columns=lib.status_columns, **out)


def _diag_values(lib: Library, core) -> Dict[str, Union[float, tuple]]:
    """The other diagnostics of att_diag_t (test ratios, norm and dip errors), by name: a float,
    or a tuple for an array field."""
    flat = core.diag_values()
    values: Dict[str, Union[float, tuple]] = {}
    k = 0
    for name, n in zip(lib.diag_value_names, lib.diag_value_lens):
        values[name] = float(flat[k]) if n == 1 else tuple(float(v) for v in flat[k:k + n])
        k += n
    return values


def run_arrays(t: np.ndarray, gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray] = None,
               settings: Optional[Dict[str, float]] = None, scalar: str = "float",
               progress: Optional[Callable[[int], None]] = None) -> Result:
    """Runs the C estimator on arrays: t (N,) s, gyr/acc/mag (N, 3) (mag None or all-NaN rows
    for no magnetometer). One C call, or blocks when progress(k) is given: it is called with
    the number of samples just done."""
    lib = load(scalar)
    t = np.ascontiguousarray(t, dtype=np.float64)
    n = t.shape[0]
    gyr = rows3("gyr", gyr, "rad/s", n, layout_known=True)
    acc = rows3("acc", acc, "m/s^2", n, layout_known=True)
    mag = None if mag is None else rows3("mag", mag, "uT", n, layout_known=True)
    core = lib.new_core(lib.make_settings(settings))
    # the first step of a new filter is an alignment sample's, which the filter does not use
    return run_core(lib, core, t, time_steps(n, t=t, first=1.0 if n == 1 else None), gyr, acc, mag, progress)


def run_estimator(recording, settings: Optional[Dict[str, float]] = None,
                  scalar: str = "float", use_mag: bool = True,
                  progress: Optional[Callable[[int], None]] = None) -> Result:
    """Runs the C estimator over a recording (attekf.io.Recording; use_mag=False: as if it had
    no magnetometer)."""
    return run_arrays(recording.t, recording.gyr, recording.acc,
                      recording.mag if use_mag else None, settings, scalar, progress)
