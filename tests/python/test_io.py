"""attekf.io: recordings and estimator outputs, round trips and every bad-input error."""

from __future__ import annotations

import json

import numpy as np
import pytest

from attekf import io
from attekf.io import InputError, read_output_csv, read_recording, write_output_csv, write_recording

HEADER = "t_s,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2"
ROW = "0.01,0.1,0.2,0.3,0,0,9.81"


def _write(tmp_path, text, name="rec.csv"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def _rows(n, t0=0.0, dt=0.01):
    return "\n".join(f"{t0 + i * dt:.4f},0.1,0.2,0.3,0,0,9.81" for i in range(n))


# --- round trips ----------------------------------------------------------------------------
def test_csv_round_trip(tmp_path, sim_recording):
    rec = sim_recording.slice(0, 500)
    rec.mag[5] = np.nan            # magnetometer absent at one sample
    rec.quat_ref[7] = np.nan       # no truth at another
    path = str(tmp_path / "r.csv")
    write_recording(path, rec)
    back = read_recording(path)
    assert len(back) == len(rec)
    np.testing.assert_array_equal(back.t, rec.t)           # 17 digits: exact
    for name in ("gyr", "acc", "mag", "quat_ref"):
        np.testing.assert_allclose(getattr(back, name), getattr(rec, name), rtol=1e-9, atol=1e-12,
                                   err_msg=name)
    assert np.isnan(back.mag[5]).all() and np.isnan(back.quat_ref[7]).all()
    np.testing.assert_array_equal(back.movement, rec.movement)
    assert back.rate_hz == pytest.approx(100.0)
    # the simulator's metadata goes into '# key: value' lines before the header, and back
    lines = open(path).read().splitlines()
    first = int(back.where(0).split()[1])
    assert lines[first - 2].startswith("t_s,") and float(lines[first - 1].split(",")[0]) == rec.t[0]
    assert back.meta["generator"] == "attekf sim" and "gyro_bias_rad_s" in back.meta


def test_metadata_lines_stay_short(tmp_path):
    """Many episodes, long settings: every comment line fits the firmware reader's line."""
    from attekf.csvtext import COMMENT_MAX
    from attekf.evaluate import recording_episodes
    from attekf.sim import SimConfig, simulate
    rec = simulate(SimConfig(duration_s=400.0, rate_hz=10.0, lin_acc_m_s2=2.0, mag_disturbance_uT=20.0,
                             disturbance_every_s=5.0))
    path = str(tmp_path / "many.csv")
    write_recording(path, rec)
    comments = [ln for ln in open(path).read().splitlines() if ln.startswith("#")]
    assert len(comments) > 100 and max(len(ln) for ln in comments) <= COMMENT_MAX
    assert len(recording_episodes(read_recording(path))) == len(json.loads(rec.meta["episodes"]))


def test_hdf5_round_trip_broad_layout(tmp_path, sim_recording):
    import h5py
    path = str(tmp_path / "r.hdf5")
    write_recording(path, sim_recording)
    with h5py.File(path, "r") as fh:
        assert {"imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement"} <= set(fh.keys())
        assert "t" not in fh  # uniform sampling: t is i / sampling_rate, as in BROAD
        assert fh.attrs["sampling_rate"] == 100.0
    back = read_recording(path)
    np.testing.assert_array_equal(back.gyr, sim_recording.gyr)
    np.testing.assert_array_equal(back.quat_ref, sim_recording.quat_ref)
    np.testing.assert_allclose(back.t, sim_recording.t, rtol=0, atol=1e-12)
    assert "sim_config" in back.meta


def test_hdf5_keeps_nonuniform_time(tmp_path, sim_recording):
    rec = sim_recording.slice(0, 100)
    rec.t = rec.t + np.linspace(0, 1e-4, 100)
    path = str(tmp_path / "r.h5")
    write_recording(path, rec)
    np.testing.assert_array_equal(read_recording(path).t, rec.t)


def test_reads_real_broad_trial(broad_trial):
    rec = read_recording(str(broad_trial))
    assert rec.rate_hz == pytest.approx(285.714, rel=1e-5)
    assert rec.mag is not None and rec.quat_ref is not None and rec.movement.dtype == bool
    assert np.isnan(rec.quat_ref).any()          # camera dropouts are kept as NaN rows
    assert rec.t[1] - rec.t[0] == pytest.approx(1 / rec.rate_hz)


def test_csv_optional_columns_and_comments(tmp_path):
    p = _write(tmp_path, "# a comment line\n" + HEADER + "\n" + _rows(3) + "\n\n")
    rec = read_recording(p)
    assert rec.mag is None and rec.quat_ref is None and rec.movement is None
    assert len(rec) == 3 and rec.where(0) == "line 3"


# --- bad recordings -------------------------------------------------------------------------
@pytest.mark.parametrize("text, fragment", [
    ("", "empty file"),
    (ROW + "\n", "no header"),
    ("t_s,gyr_x_rad_s\n0,1\n", "missing column(s) gyr_y_rad_s"),
    (HEADER + "\n", "no data rows"),
    (HEADER + "\n0.00,0.1,0.2,0.3,0,0,9.81\n0.01,0.1,abc,0.3,0,0,9.81\n",
     "line 3: column gyr_y_rad_s: 'abc' is not a number"),
    (HEADER + "\n0.00,0.1,0.2,0.3,0,0,9.81\n0.01,0.1,nan,0.3,0,0,9.81\n",
     "line 3: column gyr_y_rad_s: 'nan' is not finite"),
    (HEADER + "\n0.00,0.1,0.2,0.3,0,0,9.81\n0.01,0.1,,0.3,0,0,9.81\n", "line 3: column gyr_y_rad_s: empty cell"),
    (HEADER + "\n0.00,0.1,0.2,0.3,0,0\n", "line 2: 6 fields, header has 7"),
    (HEADER + "\n0.02,0.1,0.2,0.3,0,0,9.81\n0.01,0.1,0.2,0.3,0,0,9.81\n", "line 3: t_s 0.01 is not after"),
    (HEADER + "\n0.01,0.1,0.2,0.3,0,0,9.81\n0.01,0.1,0.2,0.3,0,0,9.81\n", "timestamps must increase"),
    (HEADER + ",t_s\n", "duplicate column(s) t_s"),
    (HEADER + ",mag_x_uT\n", "mag_y_uT, mag_z_uT missing"),
    (HEADER + ",movement\n0,0,0,0,0,0,9.81,2\n", "column movement: 2"),
])
def test_bad_csv(tmp_path, text, fragment):
    p = _write(tmp_path, text)
    with pytest.raises(InputError) as err:
        read_recording(p)
    msg = str(err.value)
    assert fragment in msg and p in msg and "\n" not in msg


def test_gyro_in_deg_s_detected(tmp_path):
    rows = [f"{i * 0.01:.2f},0,0,{90.0 if i == 4 else 0.0},0,0,9.81" for i in range(10)]
    p = _write(tmp_path, HEADER + "\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match=r"line 6: .*looks like deg/s"):
        read_recording(p)
    assert len(read_recording(p, check_units=False)) == 10


def test_accel_in_g_detected(tmp_path):
    rows = [f"{i * 0.01:.2f},0,0,0,0,0,1.0" for i in range(10)]
    p = _write(tmp_path, HEADER + "\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match="looks like g"):
        read_recording(p)


def test_mag_in_gauss_detected(tmp_path):
    rows = [f"{i * 0.01:.2f},0,0,0,0,0,9.81,0.2,0.1,-0.4" for i in range(10)]
    p = _write(tmp_path, HEADER + ",mag_x_uT,mag_y_uT,mag_z_uT\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match="magnetometer: median"):
        read_recording(p)


def test_partial_mag_row_and_bad_quaternion(tmp_path):
    h = HEADER + ",mag_x_uT,mag_y_uT,mag_z_uT"
    p = _write(tmp_path, h + "\n0,0,0,0,0,0,9.81,20,,-40\n")
    with pytest.raises(InputError, match="line 2: column mag_y_uT: empty cell while other magnetometer"):
        read_recording(p)
    h = HEADER + ",quat_w,quat_x,quat_y,quat_z"
    p = _write(tmp_path, h + "\n0,0,0,0,0,0,9.81,1,0,0,0\n0.01,0,0,0,0,0,9.81,2,0,0,0\n")
    with pytest.raises(InputError, match="line 3: norm 2"):
        read_recording(p)


def test_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_recording(str(tmp_path / "missing.csv"))
    with pytest.raises(InputError, match="is a directory"):
        read_recording(str(tmp_path))
    with pytest.raises(InputError, match="unknown recording format '.txt'"):
        read_recording(_write(tmp_path, "x", "r.txt"))
    bad = tmp_path / "bin.csv"
    bad.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(InputError, match="not a text file"):
        read_recording(str(bad))
    fake = tmp_path / "fake.hdf5"
    fake.write_text("not hdf5")
    with pytest.raises(InputError, match="cannot read as HDF5"):
        read_recording(str(fake))


def test_bad_hdf5(tmp_path):
    import h5py
    p = str(tmp_path / "bad.hdf5")
    gyr = np.zeros((5, 3))
    acc = np.tile([0, 0, 9.81], (5, 1))
    with h5py.File(p, "w") as fh:
        fh.create_dataset("imu_gyr", data=gyr)
    with pytest.raises(InputError, match="missing dataset 'imu_acc'"):
        read_recording(p)
    with h5py.File(p, "w") as fh:
        fh.create_dataset("imu_gyr", data=gyr)
        fh.create_dataset("imu_acc", data=acc)
    with pytest.raises(InputError, match="missing attribute 'sampling_rate'"):
        read_recording(p)
    gyr[3, 1] = np.nan
    with h5py.File(p, "w") as fh:
        fh.create_dataset("imu_gyr", data=gyr)
        fh.create_dataset("imu_acc", data=acc)
        fh.attrs["sampling_rate"] = 100.0
    with pytest.raises(InputError, match="imu_gyr: sample 3: .* is not finite"):
        read_recording(p)
    with h5py.File(p, "w") as fh:
        fh.create_dataset("imu_gyr", data=np.zeros((5, 3)))
        fh.create_dataset("imu_acc", data=acc[:4])
        fh.attrs["sampling_rate"] = 100.0
    with pytest.raises(InputError, match="'imu_acc' has 4 rows, imu_gyr has 5"):
        read_recording(p)


# --- estimator output CSV -------------------------------------------------------------------
def test_output_csv_round_trip(tmp_path):
    n = 6
    t = np.arange(n) * 0.01
    euler = np.random.default_rng(0).uniform(-3, 3, (n, 3))
    euler[0] = np.nan  # no estimate yet (not aligned)
    var = np.full((n, 3), 1e-4)
    var[0] = np.nan
    flags = np.array([0, 1, 1, 17, 1, 2 ** 31 + 1], np.uint32)
    status = np.array([0, 0, 11, 12, 2, 0], np.uint8)
    p = str(tmp_path / "out.csv")
    write_output_csv(p, t, euler, var, flags, status, extra={"frame": np.arange(n)})
    out = read_output_csv(p)
    np.testing.assert_array_equal(out.t, t)
    np.testing.assert_allclose(out.euler, euler, rtol=1e-9)
    assert np.isnan(out.euler[0]).all() and np.isnan(out.var[0]).all()
    np.testing.assert_array_equal(out.flags, flags)
    np.testing.assert_array_equal(out.status, status)
    np.testing.assert_array_equal(out.extra["frame"], np.arange(n))
    # minimal file: only the required columns
    write_output_csv(p, t, np.zeros((n, 3)))
    out = read_output_csv(p)
    assert out.var is None and out.flags is None and out.status is None


def test_bad_output_csv(tmp_path):
    head = "t_s,roll_rad,pitch_rad,yaw_rad,var_roll_rad2,var_pitch_rad2,var_yaw_rad2,flags\n"
    p = _write(tmp_path, head + "0,0,0,0,1e-4,-1e-4,1e-4,1\n", "o.csv")
    with pytest.raises(InputError, match="line 2: negative variance"):
        read_output_csv(p)
    p = _write(tmp_path, head + "0,0,0,0,1e-4,1e-4,1e-4,1.5\n", "o.csv")
    with pytest.raises(InputError, match="line 2: column flags: 1.5"):
        read_output_csv(p)
    p = _write(tmp_path, "t_s,roll_rad,pitch_rad\n0,0,0\n", "o.csv")
    with pytest.raises(InputError, match="missing column.*yaw_rad"):
        read_output_csv(p)


def test_documented_columns_match_the_code(repo_root):
    """docs/host_tools.md names every column the reader accepts."""
    doc = (repo_root / "docs" / "host_tools.md").read_text()
    for col in (io.COL_T, *io.COLS_GYR, *io.COLS_ACC, *io.COLS_MAG, *io.COLS_QUAT, io.COL_MOVEMENT,
                *io.COLS_EULER, *io.COLS_VAR, io.COL_FLAGS, io.COL_STATUS):
        assert f"`{col}`" in doc, col


def test_unknown_recording_columns_are_ignored(tmp_path):
    p = _write(tmp_path, HEADER + ",note\n" + "0,0,0,0,0,0,9.81,hello\n")
    assert len(read_recording(p)) == 1
