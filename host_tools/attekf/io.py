"""Reading and writing IMU recordings and estimator outputs.

Two kinds of file:

* a *recording* (sensor samples, optionally ground truth): CSV with a header, or HDF5 in the
  layout of the BROAD benchmark (``imu_gyr``, ``imu_acc``, ``imu_mag``, ``opt_quat``,
  ``movement``, attribute ``sampling_rate``) -> :class:`Recording`;
* an *estimator output* (what the filter produced per sample): CSV -> :class:`EstimatorOutput`.

Column names carry their units; docs/host_tools.md lists them. Every problem with a file raises
:class:`InputError` whose message is one line naming the file and the row or field, so the
command-line tools print it and exit non-zero. Nothing is dropped or repaired silently: a row
that cannot be read is an error, not a skipped row.

Conventions (those of the C estimator, firmware/att/att_defs.h): body frame sensors, SI units
(rad/s, m/s^2) and uT for the magnetometer; quaternions [w x y z] rotating body to ENU; Euler
angles ZYX (roll, pitch, yaw) of the same rotation.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from .csvtext import PROGRESS_ROWS, comment_lines, parse_csv
from .errors import InputError, OutputError
from .outputs import atomic_path

# ---------------------------------------------------------------------------------------------
# Column names (CSV). Units are part of the name so that a file documents itself.
# ---------------------------------------------------------------------------------------------
COL_T = "t_s"
COLS_GYR = ("gyr_x_rad_s", "gyr_y_rad_s", "gyr_z_rad_s")
COLS_ACC = ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2")
COLS_MAG = ("mag_x_uT", "mag_y_uT", "mag_z_uT")
COLS_QUAT = ("quat_w", "quat_x", "quat_y", "quat_z")
COL_MOVEMENT = "movement"

COLS_EULER = ("roll_rad", "pitch_rad", "yaw_rad")
COLS_VAR = ("var_roll_rad2", "var_pitch_rad2", "var_yaw_rad2")
COL_FLAGS = "flags"
COL_STATUS = "status"

# Plausibility limits used to catch unit mistakes (by magnitude; docs/host_tools.md).
GYRO_MAX_RAD_S = 70.0        # 4000 deg/s, the largest full scale of common MEMS gyroscopes
ACC_MEDIAN_RANGE_M_S2 = (2.0, 30.0)   # |a| at rest is 9.81; in g it would be ~1, in mg ~1000
MAG_MEDIAN_RANGE_UT = (5.0, 200.0)    # Earth: 25..66 uT; gauss would be ~0.5, nT or mG ~1e3..1e4


__all__ = ["InputError", "OutputError", "Recording", "EstimatorOutput", "read_recording",
           "read_output_csv", "read_settings_json", "write_recording", "write_recording_csv",
           "write_recording_hdf5", "write_output_csv", "validate_recording"]


# ---------------------------------------------------------------------------------------------
# Data classes
# ---------------------------------------------------------------------------------------------
@dataclass
class Recording:
    """IMU samples of one trial, body frame.

    t         (N,) s, strictly increasing (for HDF5 files without timestamps: i / rate_hz)
    gyr       (N, 3) rad/s
    acc       (N, 3) m/s^2, specific force (+9.81 on the axis pointing up at rest)
    mag       (N, 3) uT, or None without magnetometer; a row of three NaN = no magnetometer
              sample at that time (lower-rate magnetometer), never a partially NaN row
    quat_ref  (N, 4) ground truth [w x y z] body->ENU, or None; NaN rows = no truth there
    movement  (N,) bool, the samples on which errors are scored, or None (= all samples)
    rate_hz   nominal sampling rate, Hz (file attribute, or from the median time step)
    source    path the recording was read from ("" if built in memory)
    meta      free-form attributes (e.g. the simulator's settings)
    lines     (N,) line number of each sample in a CSV file, or None (then errors name the
              0-based sample index)
    """

    t: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    mag: Optional[np.ndarray] = None
    quat_ref: Optional[np.ndarray] = None
    movement: Optional[np.ndarray] = None
    rate_hz: float = 0.0
    source: str = ""
    meta: Dict[str, object] = field(default_factory=dict)
    lines: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def where(self, k: int) -> str:
        """Where sample k is in the source file, for error messages."""
        return f"line {self.lines[k]}" if self.lines is not None else f"sample {k}"

    @property
    def name(self) -> str:
        """File name without directory and extension (a trial's name in tables)."""
        return os.path.splitext(os.path.basename(self.source))[0] if self.source else "recording"

    @property
    def has_truth(self) -> bool:
        return self.quat_ref is not None

    def scored_mask(self) -> np.ndarray:
        """Samples on which errors are scored: movement (all if absent) and truth present."""
        n = len(self)
        mask = np.ones(n, bool) if self.movement is None else self.movement.astype(bool).copy()
        if self.quat_ref is None:
            return np.zeros(n, bool)
        return mask & np.all(np.isfinite(self.quat_ref), axis=1)

    def slice(self, start: int, stop: int) -> "Recording":
        """Samples [start, stop) as a new recording (arrays copied)."""
        def cut(a):
            return None if a is None else a[start:stop].copy()
        return Recording(t=cut(self.t), gyr=cut(self.gyr), acc=cut(self.acc), mag=cut(self.mag),
                         quat_ref=cut(self.quat_ref), movement=cut(self.movement),
                         rate_hz=self.rate_hz, source=self.source, meta=dict(self.meta),
                         lines=cut(self.lines))


@dataclass
class EstimatorOutput:
    """What an estimator produced, one row per sample.

    t        (N,) s (the time of the input sample the row belongs to)
    euler    (N, 3) rad: roll, pitch, yaw (ZYX, body->ENU); NaN = no estimate for that row
    var      (N, 3) rad^2 variances of roll, pitch, yaw, or None
    flags    (N,) uint32 ATT_FLAG_* bits (firmware/att/att.h), or None
    status   (N,) uint8 ekf_status_t of the step that produced the row, or None
    extra    further columns of the file, by name (float arrays), kept as read
    source   path read from
    """

    t: np.ndarray
    euler: np.ndarray
    var: Optional[np.ndarray] = None
    flags: Optional[np.ndarray] = None
    status: Optional[np.ndarray] = None
    extra: Dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""

    def __len__(self) -> int:
        return int(self.t.shape[0])


# ---------------------------------------------------------------------------------------------
# Reading recordings
# ---------------------------------------------------------------------------------------------
def read_settings_json(path: str) -> Dict[str, float]:
    """Estimator settings {name: number} from a JSON or TOML file (the commands' --settings;
    attekf.settings_file.load_settings); InputError naming the file and the line or the
    setting otherwise. Whether the names and values are ones the filter accepts is the C
    library's to say."""
    from .settings_file import load_settings
    return load_settings(path)


def read_recording(path: str, check_units: bool = True,
                   progress: Optional[Callable[[int], None]] = None) -> Recording:
    """Reads a recording; the format follows the extension (.csv, .hdf5/.h5).

    check_units: reject data whose magnitudes look like another unit (gyro in deg/s,
    accelerometer in g, magnetometer in gauss or nT). progress(k): called with the number
    of CSV lines just parsed (for a progress bar). Raises InputError.
    """
    ext = os.path.splitext(path)[1].lower()
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a directory, expected a .csv or .hdf5 recording")
    if ext == ".csv":
        rec = _read_recording_csv(path, progress)
    elif ext in (".hdf5", ".h5"):
        rec = _read_recording_hdf5(path)
    else:
        raise InputError(f"{path}: unknown recording format '{ext or '(none)'}' "
                         "(expected .csv, .hdf5 or .h5)")
    validate_recording(rec, check_units=check_units)
    return rec


def _read_recording_csv(path: str, progress=None) -> Recording:
    optional_empty = {c: "magnetometer" for c in COLS_MAG}
    optional_empty.update({c: "quaternion" for c in COLS_QUAT})
    known = (COL_T,) + COLS_GYR + COLS_ACC + COLS_MAG + COLS_QUAT + (COL_MOVEMENT,)
    cols, header, lines, comments = parse_csv(path, (COL_T,) + COLS_GYR + COLS_ACC,
                                              (COLS_MAG, COLS_QUAT), optional_empty, only_known=known,
                                              progress=progress)
    meta = _meta_from_comments(comments)
    t = cols[COL_T]
    _check_time(path, t, lambda k: f"line {lines[k]}")
    rec = Recording(t=t, gyr=np.stack([cols[c] for c in COLS_GYR], axis=1),
                    acc=np.stack([cols[c] for c in COLS_ACC], axis=1), source=path, meta=meta)
    if COLS_MAG[0] in cols:
        rec.mag = np.stack([cols[c] for c in COLS_MAG], axis=1)
    if COLS_QUAT[0] in cols:
        rec.quat_ref = np.stack([cols[c] for c in COLS_QUAT], axis=1)
    if COL_MOVEMENT in cols:
        mv = cols[COL_MOVEMENT]
        bad = ~np.isin(mv, (0.0, 1.0))
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError(f"{path}: line {lines[k]}: column {COL_MOVEMENT}: {mv[k]:g} "
                             "(expected 0 or 1)")
        rec.movement = mv.astype(bool)
    rec.rate_hz = _rate_from_time(t)
    _check_quaternions(path, rec.quat_ref, lambda k: f"line {lines[k]}")
    rec.lines = lines
    return rec


def _meta_from_comments(comments) -> Dict[str, object]:
    """'# key: value' lines -> metadata; '# episode: KIND START_S STOP_S' lines (one per
    disturbance episode) -> meta['episodes'], a JSON list as in HDF5 files."""
    meta: Dict[str, object] = {}
    episodes = []
    for key, value in comments:
        if key == "episode":
            parts = value.split()
            try:
                episodes.append([parts[0], float(parts[1]), float(parts[2])])
            except (IndexError, ValueError):
                continue   # a comment is not data: one that does not parse is left alone
        else:
            meta[key] = value
    if episodes:
        meta["episodes"] = json.dumps(episodes)
    return meta


def _comment_lines(meta: Dict[str, object]) -> List[str]:
    """The '# ...' lines write_recording_csv puts before the header."""
    out = []
    rest = dict(meta)
    raw = rest.pop("episodes", None)
    for key, value in comment_lines(rest):
        out.append(f"# {key}: {value}")
    if raw is not None:
        try:
            items = json.loads(raw) if isinstance(raw, (str, bytes)) else raw
            out += [f"# episode: {k} {float(a)!r} {float(b)!r}" for k, a, b in items]
        except (TypeError, ValueError):
            pass
    return out


def _h5():
    from .extras import require
    require("h5py", "HDF5 files")
    import h5py  # imported lazily: only HDF5 users pay for it
    return h5py


def _read_recording_hdf5(path: str) -> Recording:
    h5py = _h5()
    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"{path}: cannot read as HDF5: {exc}") from None
    with fh:
        for name in ("imu_gyr", "imu_acc"):
            if name not in fh:
                raise InputError(f"{path}: missing dataset '{name}' "
                                 f"(file has: {', '.join(sorted(fh.keys())) or 'nothing'})")

        def dataset(name: str, width: Optional[int]) -> np.ndarray:
            try:
                a = np.asarray(fh[name][()])
            except Exception as exc:  # h5py raises many types for corrupt data
                raise InputError(f"{path}: dataset '{name}': cannot read: {exc}") from None
            if a.dtype.kind not in "biuf":
                raise InputError(f"{path}: dataset '{name}': values of type {a.dtype} "
                                 "(expected real numbers)")
            if width is None:
                if a.ndim != 1:
                    raise InputError(f"{path}: dataset '{name}': shape {a.shape}, expected (N,)")
            elif a.ndim != 2 or a.shape[1] != width:
                raise InputError(f"{path}: dataset '{name}': shape {a.shape}, expected (N, {width})")
            return a

        gyr = dataset("imu_gyr", 3).astype(np.float64)
        acc = dataset("imu_acc", 3).astype(np.float64)
        n = gyr.shape[0]
        mag = dataset("imu_mag", 3).astype(np.float64) if "imu_mag" in fh else None
        quat = dataset("opt_quat", 4).astype(np.float64) if "opt_quat" in fh else None
        mov = dataset("movement", None) if "movement" in fh else None
        t = dataset("t", None).astype(np.float64) if "t" in fh else None
        rate = fh.attrs.get("sampling_rate")
        meta = {}
        for k, v in fh.attrs.items():
            if k != "sampling_rate":
                meta[k] = v.decode() if isinstance(v, bytes) else (v.tolist() if hasattr(v, "tolist") else v)
    for name, a in (("imu_acc", acc), ("imu_mag", mag), ("opt_quat", quat), ("movement", mov), ("t", t)):
        if a is not None and a.shape[0] != n:
            raise InputError(f"{path}: dataset '{name}' has {a.shape[0]} rows, imu_gyr has {n}")
    if n == 0:
        raise InputError(f"{path}: no samples (imu_gyr is empty)")
    where = lambda k: f"sample {k}"  # noqa: E731 - 0-based index into the datasets
    if t is None:
        if rate is None:
            raise InputError(f"{path}: missing attribute 'sampling_rate' (and no 't' dataset)")
        try:
            rate = float(np.asarray(rate).reshape(-1)[0])
        except (TypeError, ValueError, IndexError):
            raise InputError(f"{path}: attribute 'sampling_rate': not a number") from None
        if not (math.isfinite(rate) and rate > 0):
            raise InputError(f"{path}: attribute 'sampling_rate': {rate} (expected > 0 Hz)")
        t = np.arange(n, dtype=np.float64) / rate
    else:
        _check_finite(path, "t", t[:, None], where)
        _check_time(path, t, where)
        rate = float(rate) if rate is not None else _rate_from_time(t)
    for name, a in (("imu_gyr", gyr), ("imu_acc", acc)):
        _check_finite(path, name, a, where)
    if mag is not None:
        nan = np.isnan(mag)
        partial = np.any(nan, axis=1) & ~np.all(nan, axis=1)
        bad = partial | np.any(np.isinf(mag), axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError(f"{path}: dataset 'imu_mag': {where(k)}: {mag[k].tolist()} "
                             "(a row is all finite, or all NaN for 'no sample')")
    if mov is not None:
        if mov.dtype != bool:
            bad = ~np.isin(mov, (0, 1))
            if bad.any():
                k = int(np.argmax(bad))
                raise InputError(f"{path}: dataset 'movement': {where(k)}: {mov[k]} (expected 0/1)")
        mov = mov.astype(bool)
    _check_quaternions(path, quat, where, field_name="dataset 'opt_quat'")
    rec = Recording(t=t, gyr=gyr, acc=acc, mag=mag, quat_ref=quat, movement=mov,
                    rate_hz=float(rate), source=path, meta=meta)
    return rec


def _check_finite(path: str, name: str, a: np.ndarray, where) -> None:
    bad = ~np.all(np.isfinite(a), axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(f"{path}: {name}: {where(k)}: {a[k].tolist()} is not finite")


def _check_time(path: str, t: np.ndarray, where) -> None:
    if t.shape[0] >= 2:
        dt = np.diff(t)
        bad = ~(dt > 0)
        if bad.any():
            k = int(np.argmax(bad)) + 1
            raise InputError(f"{path}: {where(k)}: {COL_T} {float(t[k])!r} is not after the previous "
                             f"sample's {float(t[k - 1])!r} (timestamps must increase strictly)")


def _check_quaternions(path: str, q: Optional[np.ndarray], where,
                       field_name: str = "columns quat_w..quat_z") -> None:
    """Truth rows are unit quaternions or entirely NaN (no truth); anything else is an error."""
    if q is None:
        return
    nan = np.isnan(q)
    partial = np.any(nan, axis=1) & ~np.all(nan, axis=1)
    if partial.any() or np.isinf(q).any():
        k = int(np.argmax(partial | np.any(np.isinf(q), axis=1)))
        raise InputError(f"{path}: {field_name}: {where(k)}: {q[k].tolist()} "
                         "(a truth row is a full quaternion, or all empty/NaN for 'no truth')")
    norm = np.linalg.norm(q, axis=1)
    bad = np.isfinite(norm) & (np.abs(norm - 1.0) > 1e-3)
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(f"{path}: {field_name}: {where(k)}: norm {norm[k]:.6g} "
                         "(expected a unit quaternion [w x y z])")


def _rate_from_time(t: np.ndarray) -> float:
    if t.shape[0] < 2:
        return 0.0
    return float(1.0 / np.median(np.diff(t)))


def validate_recording(rec: Recording, check_units: bool = True) -> None:
    """Shapes, finiteness and (check_units) plausible magnitudes. Raises InputError."""
    path = rec.source or "<recording>"
    where = rec.where
    n = len(rec)
    if n == 0:
        raise InputError(f"{path}: no samples")
    for name, a, w in (("gyro", rec.gyr, 3), ("accelerometer", rec.acc, 3), ("magnetometer", rec.mag, 3),
                       ("truth quaternion", rec.quat_ref, 4)):
        if a is not None and a.shape != (n, w):
            raise InputError(f"{path}: {name}: shape {a.shape}, expected ({n}, {w})")
    if rec.movement is not None and rec.movement.shape != (n,):
        raise InputError(f"{path}: movement: shape {rec.movement.shape}, expected ({n},)")
    _check_time(path, rec.t, where)
    if not check_units:
        return
    gmax = np.abs(rec.gyr).max(axis=1)
    if gmax.max() > GYRO_MAX_RAD_S:
        k = int(np.argmax(gmax > GYRO_MAX_RAD_S))
        raise InputError(f"{path}: gyro: {where(k)}: |{gmax[k]:.4g}| rad/s exceeds {GYRO_MAX_RAD_S:g} rad/s "
                         "(4000 deg/s): the gyroscope looks like deg/s, expected rad/s "
                         "(convert, or pass --no-unit-check if this is real)")
    acc_med = float(np.median(np.linalg.norm(rec.acc, axis=1)))
    lo, hi = ACC_MEDIAN_RANGE_M_S2
    if not (lo <= acc_med <= hi):
        hint = " (looks like g: multiply by 9.81)" if 0.5 < acc_med < 2 else ""
        raise InputError(f"{path}: accelerometer: median |a| = {acc_med:.4g}, expected about 9.81 m/s^2"
                         f"{hint}")
    if rec.mag is not None:
        norms = np.linalg.norm(rec.mag, axis=1)
        norms = norms[np.isfinite(norms)]
        if norms.size:
            mag_med = float(np.median(norms))
            lo, hi = MAG_MEDIAN_RANGE_UT
            if not (lo <= mag_med <= hi):
                raise InputError(f"{path}: magnetometer: median |m| = {mag_med:.4g}, expected uT "
                                 f"(Earth's field is 25..66 uT; gauss would read ~0.5, nT ~5e4)")


# ---------------------------------------------------------------------------------------------
# Writing recordings
# ---------------------------------------------------------------------------------------------
def _fmt(v: float, digits: int) -> str:
    return "" if math.isnan(v) else f"{v:.{digits}g}"


def write_recording_csv(path: str, rec: Recording,
                        progress: Optional[Callable[[int], None]] = None) -> None:
    """CSV with the columns of docs/host_tools.md; absent magnetometer samples and absent
    truth are written as empty cells. 17 significant digits for time, 10 for the rest
    (round trip within 1e-10 relative)."""
    header = [COL_T, *COLS_GYR, *COLS_ACC]
    blocks = [rec.t[:, None], rec.gyr, rec.acc]
    if rec.mag is not None:
        header += COLS_MAG
        blocks.append(rec.mag)
    if rec.quat_ref is not None:
        header += COLS_QUAT
        blocks.append(rec.quat_ref)
    if rec.movement is not None:
        header.append(COL_MOVEMENT)
        blocks.append(rec.movement.astype(np.float64)[:, None])
    data = np.concatenate(blocks, axis=1)
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        for line in _comment_lines(rec.meta):
            fh.write(line + "\n")
        fh.write(",".join(header) + "\n")
        for k, row in enumerate(data):
            if progress is not None and k % PROGRESS_ROWS == PROGRESS_ROWS - 1:
                progress(PROGRESS_ROWS)
            cells = [_fmt(row[0], 17)] + [_fmt(v, 10) for v in row[1:]]
            if rec.movement is not None:
                cells[-1] = str(int(row[-1]))
            fh.write(",".join(cells) + "\n")


def write_recording_hdf5(path: str, rec: Recording) -> None:
    """BROAD layout: imu_gyr, imu_acc, [imu_mag], [opt_quat], [movement], attribute
    sampling_rate; plus dataset 't' when the timestamps are not i / sampling_rate, and the
    entries of rec.meta as attributes."""
    h5py = _h5()
    rate = rec.rate_hz or _rate_from_time(rec.t)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as fh:
        fh.create_dataset("imu_gyr", data=rec.gyr)
        fh.create_dataset("imu_acc", data=rec.acc)
        if rec.mag is not None:
            fh.create_dataset("imu_mag", data=rec.mag)
        if rec.quat_ref is not None:
            fh.create_dataset("opt_quat", data=rec.quat_ref)
        if rec.movement is not None:
            fh.create_dataset("movement", data=rec.movement.astype(bool))
        fh.attrs["sampling_rate"] = float(rate)
        uniform = np.arange(len(rec), dtype=np.float64) / rate
        if not np.array_equal(uniform, rec.t):
            fh.create_dataset("t", data=rec.t)
        for k, v in rec.meta.items():
            fh.attrs[k] = v


def write_recording(path: str, rec: Recording, progress: Optional[Callable[[int], None]] = None) -> None:
    """Writes CSV or HDF5 according to the extension."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".csv":
        write_recording_csv(path, rec, progress)
    elif ext in (".hdf5", ".h5"):
        write_recording_hdf5(path, rec)
    else:
        from .errors import UsageError
        raise UsageError(f"{path}: unknown recording format '{ext or '(none)'}' "
                         "(expected .csv, .hdf5 or .h5)")


# ---------------------------------------------------------------------------------------------
# Estimator output CSV
# ---------------------------------------------------------------------------------------------
def write_output_csv(path: str, t: np.ndarray, euler: np.ndarray, var: Optional[np.ndarray] = None,
                     flags: Optional[np.ndarray] = None, status: Optional[np.ndarray] = None,
                     extra: Optional[Dict[str, np.ndarray]] = None,
                     progress: Optional[Callable[[int], None]] = None,
                     order: Optional[List[str]] = None, full_precision: Sequence[str] = ()) -> None:
    """Estimator output: t_s, roll_rad, pitch_rad, yaw_rad, [var_roll_rad2, var_pitch_rad2,
    var_yaw_rad2], [flags], [status], [extra columns], or the columns in `order` (every
    column once). NaN (no estimate) is an empty cell; no value may be infinite. Values have
    10 significant digits, t_s and the extra columns named in full_precision 17 (every digit
    of a double: epoch times keep their fraction). progress(k): called with the number of
    rows just written."""
    n = t.shape[0]
    euler = np.asarray(euler, dtype=np.float64)
    if euler.shape != (n, 3):
        raise ValueError(f"euler: shape {euler.shape}, expected ({n}, 3)")
    header = [COL_T, *COLS_EULER]
    cols: List[np.ndarray] = [np.asarray(t, np.float64), euler[:, 0], euler[:, 1], euler[:, 2]]
    kinds = ["t", "f", "f", "f"]
    if var is not None:
        var = np.asarray(var, dtype=np.float64)
        if var.shape != (n, 3):
            raise ValueError(f"var: shape {var.shape}, expected ({n}, 3)")
        header += COLS_VAR
        cols += [var[:, 0], var[:, 1], var[:, 2]]
        kinds += ["f", "f", "f"]
    for name, a in ((COL_FLAGS, flags), (COL_STATUS, status)):
        if a is not None:
            a = np.asarray(a)
            if a.shape != (n,):
                raise ValueError(f"{name}: shape {a.shape}, expected ({n},)")
            header.append(name)
            cols.append(a.astype(np.int64))
            kinds.append("i")
    for name, a in (extra or {}).items():
        a = np.asarray(a)
        if a.shape != (n,):
            raise ValueError(f"{name}: shape {a.shape}, expected ({n},)")
        header.append(name)
        cols.append(a)
        kinds.append("i" if np.issubdtype(a.dtype, np.integer) else "t" if name in full_precision else "f")
    if order is not None:
        if sorted(order) != sorted(header):
            raise ValueError(f"order: {order} is not a permutation of the columns {header}")
        at = [header.index(c) for c in order]
        header, cols, kinds = order, [cols[k] for k in at], [kinds[k] for k in at]
    for name, a, kind in zip(header, cols, kinds):
        if kind != "i" and np.isinf(a).any():
            raise ValueError(f"{name}: infinite value at row {int(np.argmax(np.isinf(a)))} (NaN = no value)")
    # one format per row ("%.17g" time, "%.10g" floats, "%d" integers); NaN is an empty cell
    # (no number's text contains "nan")
    row = ",".join({"t": "%.17g", "f": "%.10g", "i": "%d"}[k] for k in kinds)
    values = [a.tolist() if k != "i" else np.asarray(a, np.int64).tolist() for a, k in zip(cols, kinds)]
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        fh.write(",".join(header) + "\n")
        for k, cells in enumerate(zip(*values)):
            if progress is not None and k % PROGRESS_ROWS == PROGRESS_ROWS - 1:
                progress(PROGRESS_ROWS)
            fh.write((row % cells).replace("nan", "") + "\n")


def read_output_csv(path: str) -> EstimatorOutput:
    """Reads an estimator output CSV (write_output_csv's format). Raises InputError."""
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    optional_empty = {c: "estimate" for c in COLS_EULER}
    optional_empty.update({c: "variance" for c in COLS_VAR})
    cols, header, lines, _meta = parse_csv(path, (COL_T,) + COLS_EULER,
                                           (COLS_VAR, (COL_FLAGS,), (COL_STATUS,)), optional_empty,
                                           keep_other=True)
    t = cols[COL_T]
    _check_time(path, t, lambda k: f"line {lines[k]}")
    out = EstimatorOutput(t=t, euler=np.stack([cols[c] for c in COLS_EULER], axis=1), source=path)
    if COLS_VAR[0] in cols:
        out.var = np.stack([cols[c] for c in COLS_VAR], axis=1)
        bad = out.var < 0
        if bad.any():
            k = int(np.argmax(np.any(bad, axis=1)))
            raise InputError(f"{path}: line {lines[k]}: negative variance {out.var[k].tolist()}")
    for name, limit in ((COL_FLAGS, 2 ** 32), (COL_STATUS, 256)):
        if name in cols:
            a = cols[name]
            bad = (a != np.floor(a)) | (a < 0) | (a >= limit)
            if bad.any():
                k = int(np.argmax(bad))
                raise InputError(f"{path}: line {lines[k]}: column {name}: {a[k]:g} "
                                 f"(expected an integer in 0..{limit - 1})")
            setattr(out, name, a.astype(np.uint32 if name == COL_FLAGS else np.uint8))
    known = {COL_T, *COLS_EULER, *COLS_VAR, COL_FLAGS, COL_STATUS}
    out.extra = {c: cols[c] for c in header if c and c not in known and c in cols}
    return out
