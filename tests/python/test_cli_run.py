"""`attekf run` (host_tools/attekf/commands/run.py, output_file.py) and what every command
says when the extra it needs is not installed (attekf/extras.py, cli.py)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import attekf
from attekf.cli import main as attekf_main
from attekf.io import read_output_csv, read_recording, write_recording_csv
from attekf.sim import SimConfig, simulate


@pytest.fixture(scope="module")
def rec_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("run") / "rec.csv"
    write_recording_csv(str(path), simulate(SimConfig(duration_s=15.0, rate_hz=100.0, seed=8)))
    return path


def test_run_writes_the_filter_output_per_sample(rec_csv, tmp_path):
    out = tmp_path / "o.csv"
    assert attekf_main(["run", "-q", str(rec_csv), "-o", str(out), "--set", "accel_noise=0.1"]) == 0
    rec = read_recording(str(rec_csv))
    res = attekf.estimate(rec.gyr, rec.acc, rec.mag, t=rec.t, settings={"accel_noise": 0.1})
    header = out.read_text().splitlines()[0].split(",")
    assert header[:8] == ["t_s", "quat_w", "quat_x", "quat_y", "quat_z", "roll_rad", "pitch_rad", "yaw_rad"]
    assert header[8:11] == ["sigma_roll_rad", "sigma_pitch_rad", "sigma_yaw_rad"] and header[-2:] == ["flags", "status"]
    got = read_output_csv(str(out))                 # the estimator-output reader takes it
    on = res.aligned
    np.testing.assert_array_equal(got.t, rec.t)
    np.testing.assert_allclose(got.euler[on], res.euler[on], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.stack([got.extra[c] for c in ("quat_w", "quat_x", "quat_y", "quat_z")], 1)[on],
                               res.quat[on], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.extra["sigma_yaw_rad"][on], res.sigma_euler[on, 2], rtol=1e-9)
    np.testing.assert_array_equal(got.flags, res.flags)
    assert np.isnan(got.euler[~on]).all() and np.isnan(got.extra["sigma_roll_rad"][~on]).all()
    # and `eval --output-csv` scores it like the run itself
    assert attekf_main(["eval", "-q", str(rec_csv), "--output-csv", str(out), "--set", "accel_noise=0.1"]) == 0


def test_run_hdf5_ned_and_mounting(rec_csv, tmp_path):
    import h5py
    out = tmp_path / "o.h5"
    m = "0,-1,0,1,0,0,0,0,1"
    assert attekf_main(["run", "-q", str(rec_csv), "-o", str(out), "--frame", "ned", "--mounting", m,
                        "--scalar", "double", "--no-mag"]) == 0
    rec = read_recording(str(rec_csv))
    res = attekf.estimate(rec.gyr, rec.acc, t=rec.t, frame="NED", scalar="double",
                          mounting=np.array([float(v) for v in m.split(",")]).reshape(3, 3))
    with h5py.File(out, "r") as fh:
        np.testing.assert_array_equal(fh["quat"][:], res.quat)
        np.testing.assert_array_equal(fh["cov"][:], res.cov_euler)
        np.testing.assert_array_equal(fh["status"][:], res.status)
        assert fh.attrs["frame"] == "NED" and fh.attrs["scalar"] == "double"


@pytest.mark.parametrize("args, fragment", [
    (["run", "REC"], "-o OUT is needed"),
    (["run"], "no recording given"),
    (["run", "REC", "-o", "x.txt"], "unknown output format '.txt'"),
    (["run", "REC", "-o", "x.csv", "--mounting", "1,0,0,0,1,0,0,0,-1"], "--mounting: not a rotation matrix"),
    (["run", "REC", "-o", "x.csv", "--mounting", "1,2"], "invalid rotation matrix (9 numbers) value"),
    (["run", "REC", "-o", "x.csv", "--set", "gimbal_limit=3"], "gimbal_limit: 3.0 is not in [0.1, 1.56]"),
])
def test_run_usage_errors(rec_csv, tmp_path, capsys, args, fragment):
    args = [str(rec_csv) if a == "REC" else str(tmp_path / a) if a.startswith("x.") else a for a in args]
    assert attekf_main(args) == 2
    err = capsys.readouterr().err.strip()
    assert fragment in err and len(err.splitlines()) == 1
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("hidden, args, extra", [
    ("tqdm", ["sim", "x.csv"], "tools"),
    ("tqdm", ["run", "REC", "-o", "x.csv"], "tools"),
    ("h5py", ["run", "REC", "-o", "x.h5"], "tools"),
    ("matplotlib", ["eval", "REC", "--out", "ev"], "plots"),
    ("cantools", ["replay", "REC", "--to-log", "x.log"], "can"),
    ("can", ["record", "--from-log", "x.log", "--csv", "x.csv"], "can"),
    ("h5py", ["bench", "--methods", "ours-9d"], "bench"),
])
def test_a_missing_extra_is_named(rec_csv, tmp_path, hidden, args, extra):
    """Without the package an extra brings (hidden here from the import system), a command
    says which extra to install: one line, exit 2, no traceback, nothing written."""
    args = [str(rec_csv) if a == "REC" else a for a in args]
    code = (f"import sys; sys.modules[{hidden!r}] = None\n"
            f"from attekf.cli import main\nsys.exit(main({args!r}))")
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, p.stderr
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr
    assert f"pip install 'attekf[{extra}]'" in p.stderr and args[0] in p.stderr
    assert not list(tmp_path.iterdir())


def test_the_filter_imports_with_numpy_only(tmp_path):
    """import attekf and the filter API load no optional package."""
    code = ("import sys\n"
            "for m in ('tqdm', 'h5py', 'matplotlib', 'can', 'cantools', 'vqf', 'imufusion', 'ahrs', 'sympy'):\n"
            "    sys.modules[m] = None\n"
            "import numpy as np, attekf\n"
            "f = attekf.Filter(dt=0.01)\n"
            "e = [f.update([0, 0, 0], [0, 0, 9.81]) for _ in range(20)][-1]\n"
            "r = attekf.estimate(np.zeros((50, 3)), np.tile([0, 0, 9.81], (50, 1)), rate_hz=100)\n"
            "assert e.aligned and r.aligned[-1]\n"
            "from attekf.cli import build_parser; build_parser()\n")   # --help needs no extra either
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
