"""Atheris (libFuzzer for Python) target: the host tools' file parsers.

    .venv/bin/python tests/fuzz/fuzz_parsers.py [libFuzzer options] [corpus dirs]

Each input picks a parser and becomes one file for it:

* recording CSV      attekf.io.read_recording (``.csv``)
* output CSV         attekf.io.read_output_csv
* recording HDF5     attekf.io.read_recording (``.hdf5``): the input chooses datasets, shapes,
                     dtypes and values (random bytes are never a valid HDF5 file)
* CAN log            attekf.commands.replay.load_frames (``.log`` candump, ``.asc``, ``.blf``)

Invariant: a parser returns a well-formed object (arrays of the declared shapes, finite
values where the format requires them, strictly increasing time) or raises its documented
error (InputError / ReplayError) with a one-line message naming the file. Any other
exception is a finding: atheris reports it and writes the input.
"""

import glob
import os
import shutil
import sys
import tempfile
import warnings

import atheris
import numpy as np  # not instrumented: the coverage that matters is the project's

with atheris.instrument_imports(include=["attekf"]):
    from attekf import io as aio
    from attekf.commands import replay

warnings.simplefilter("ignore")
# One scratch directory per process (libFuzzer exits without running atexit handlers, so
# directories of processes that are gone are removed here instead).
_PREFIX = os.path.join(tempfile.gettempdir(), "attekf-fuzz-parsers-")
for _d in glob.glob(_PREFIX + "*"):
    try:
        os.kill(int(_d[len(_PREFIX):]), 0)
    except (ValueError, ProcessLookupError):
        shutil.rmtree(_d, ignore_errors=True)
    except PermissionError:
        pass
TMP = _PREFIX + str(os.getpid())
os.makedirs(TMP, exist_ok=True)
CSV_REC = os.path.join(TMP, "rec.csv")
CSV_OUT = os.path.join(TMP, "out.csv")
H5 = os.path.join(TMP, "rec.hdf5")
LOGS = {0: os.path.join(TMP, "frames.log"), 1: os.path.join(TMP, "frames.asc"), 2: os.path.join(TMP, "frames.blf")}

HEADERS = [
    "t_s,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2",
    "t_s,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2,mag_x_uT,mag_y_uT,mag_z_uT,"
    "quat_w,quat_x,quat_y,quat_z,movement",
    "t_s,roll_rad,pitch_rad,yaw_rad,var_roll_rad2,var_pitch_rad2,var_yaw_rad2,flags,status",
]


def _one_line(msg: str, path: str) -> None:
    assert "\n" not in msg, f"error message spans lines: {msg!r}"
    assert path in msg, f"error message does not name the file: {msg!r}"


def _check_recording(rec) -> None:
    n = len(rec)
    assert n > 0
    assert rec.t.shape == (n,) and np.all(np.isfinite(rec.t)) and np.all(np.diff(rec.t) > 0)
    assert rec.gyr.shape == (n, 3) and np.all(np.isfinite(rec.gyr))
    assert rec.acc.shape == (n, 3) and np.all(np.isfinite(rec.acc))
    if rec.mag is not None:
        assert rec.mag.shape == (n, 3)
    if rec.quat_ref is not None:
        assert rec.quat_ref.shape == (n, 4) and not np.any(np.isinf(rec.quat_ref))


def _csv_bytes(fdp: atheris.FuzzedDataProvider) -> bytes:
    if fdp.ConsumeBool():  # a known header, then free text: rows get past the header checks
        head = HEADERS[fdp.ConsumeIntInRange(0, len(HEADERS) - 1)].encode()
        return head + b"\n" + fdp.ConsumeBytes(fdp.remaining_bytes())
    return fdp.ConsumeBytes(fdp.remaining_bytes())


def _h5_file(fdp: atheris.FuzzedDataProvider) -> None:
    import h5py
    dtypes = [np.float64, np.float32, np.int16, np.uint8, np.complex64, "S4", np.bool_]
    with h5py.File(H5, "w") as fh:
        for name in ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement"):
            if not fdp.ConsumeBool() and name not in ("imu_gyr", "imu_acc"):
                continue
            if fdp.ConsumeIntInRange(0, 15) == 0:
                continue  # even a required one missing
            n = fdp.ConsumeIntInRange(0, 6)
            shape = [(n, 3), (n, 4), (n,), (n, 3, 1), ()][fdp.ConsumeIntInRange(0, 4)]
            dt = dtypes[fdp.ConsumeIntInRange(0, len(dtypes) - 1)]
            count = int(np.prod(shape)) if shape else 1
            vals = np.array(fdp.ConsumeRegularFloatList(count) if fdp.ConsumeBool()
                            else fdp.ConsumeFloatList(count), dtype=np.float64)
            if vals.size < count:
                vals = np.concatenate([vals, np.zeros(count - vals.size)])
            with np.errstate(all="ignore"):
                arr = vals.reshape(shape) if shape else vals[0]
                fh.create_dataset(name, data=np.asarray(arr).astype(dt))
        if fdp.ConsumeBool():
            fh.attrs["sampling_rate"] = fdp.ConsumeFloat()


def TestOneInput(data: bytes) -> None:
    fdp = atheris.FuzzedDataProvider(data)
    kind = fdp.ConsumeIntInRange(0, 3)
    if kind in (0, 2):  # a recording: CSV or HDF5
        if kind == 0:
            path = CSV_REC
            with open(path, "wb") as fh:
                fh.write(_csv_bytes(fdp))
        else:
            path = H5
            _h5_file(fdp)
        try:
            rec = aio.read_recording(path, check_units=fdp.ConsumeBool())
        except aio.InputError as e:
            _one_line(str(e), path)
            return
        _check_recording(rec)
    elif kind == 1:
        path = CSV_OUT
        with open(path, "wb") as fh:
            fh.write(_csv_bytes(fdp))
        try:
            out = aio.read_output_csv(path)
        except aio.InputError as e:
            _one_line(str(e), path)
            return
        n = out.t.shape[0]
        assert n > 0 and out.euler.shape == (n, 3) and np.all(np.diff(out.t) > 0)
        if out.var is not None:
            assert out.var.shape == (n, 3) and not np.any(out.var < 0)
    else:
        path = LOGS[fdp.ConsumeIntInRange(0, 2)]
        with open(path, "wb") as fh:
            fh.write(fdp.ConsumeBytes(fdp.remaining_bytes()))
        try:
            fr = replay.load_frames(path)
        except replay.ReplayError as e:
            _one_line(str(e), path)
            return
        n = len(fr)
        assert n > 0 and fr.t.shape == (n,) and fr.ids.shape == (n,) and np.all(np.diff(fr.t) >= 0)
        assert all(isinstance(d, bytes) and len(d) <= 64 for d in fr.data)


def main() -> None:
    atheris.Setup(sys.argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
