"""The smoother through Python (attekf.smooth, Filter.smooth_batch, attekf run/eval --smooth,
the ours-smooth methods of attekf bench): the filter's own outputs kept, the smoothed ones
closer to the truth, memory segments invisible in the result, errors and interruption. The
smoother's mathematics is checked in C (tests/c/test_rts.c against batch least squares,
tests/c/test_smooth.c on simulated recordings)."""

from __future__ import annotations

import numpy as np
import pytest

import attekf
from attekf import bench as B
from attekf import metrics as M
from attekf.cli import main
from attekf.sim import SimConfig, simulate


@pytest.fixture(scope="module")
def rec():
    """60 s of the simulator's motion with linear-acceleration episodes (truth known)."""
    return simulate(SimConfig(duration_s=60.0, rate_hz=100.0, seed=11, lin_acc_m_s2=2.0,
                              disturbance_every_s=15.0, disturbance_s=4.0))


def _rmse(res, rec, six_d=False):
    q = res.quat.copy()
    q[~res.aligned] = np.nan
    return M.orientation_errors(q, rec.quat_ref, rec.movement, six_d=six_d).rmse_deg()


@pytest.mark.parametrize("scalar", ["float", "double", "fixed"])
def test_smooth_keeps_the_filters_outputs_and_beats_it(rec, scalar):
    f = attekf.estimate(rec.gyr, rec.acc, rec.mag, t=rec.t, scalar=scalar)
    s = attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t, scalar=scalar)
    # the same filter forward: its flags, status, offset and counters
    np.testing.assert_array_equal(s.flags, f.flags)
    np.testing.assert_array_equal(s.status, f.status)
    np.testing.assert_array_equal(s.gyro_bias, f.gyro_bias)
    assert s.diag == f.diag and s.scalar == scalar
    for name in ("quat", "euler", "angle_cov", "state", "var", "sigma_euler", "cov_euler", "rate"):
        assert getattr(s, name).shape == getattr(f, name).shape
    # no estimate before alignment, an estimate and a finite covariance after
    assert np.isnan(s.quat[~s.aligned]).all() and np.isinf(s.sigma_euler[~s.aligned]).all()
    assert np.isfinite(s.quat[s.aligned]).all() and (s.sigma_euler[s.aligned] > 0).all()
    assert np.allclose(np.linalg.norm(s.quat[s.aligned], axis=1), 1.0)
    ef, es = _rmse(f, rec), _rmse(s, rec)
    assert es["inclination"] < 0.9 * ef["inclination"]
    assert es["total"] < ef["total"]
    assert s.smoother["epochs"] == f.diag["steps"] and s.smoother["not_pd"] == 0


def test_segments_change_nothing_but_memory(rec):
    a = attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t)
    b = attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t, segment=777)
    assert a.smoother["recomputed"] == 0 and b.smoother["recomputed"] == 777 * (len(rec.t) // 777)
    for name in ("quat", "angle_cov", "state", "var", "flags"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_with_6d_and_the_filter_api(rec):
    s = attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t, with_6d=True)
    six = attekf.smooth(rec.gyr, rec.acc, None, t=rec.t)
    np.testing.assert_array_equal(s.six_d.quat, six.quat)
    assert s.six_d.smoother["heading_cuts"] == s.six_d.smoother["epochs"]   # no heading measured
    f = attekf.Filter(dt=0.01)
    r = f.smooth_batch(rec.gyr, rec.acc, rec.mag)
    g = attekf.Filter(dt=0.01)
    g.update_batch(rec.gyr, rec.acc, rec.mag)
    assert f.get_state()["c_state"] == g.get_state()["c_state"]   # the filter ends as the forward pass
    assert r.aligned.sum() == len(rec.t) - 9


def test_progress_counts_both_passes_and_can_stop(rec):
    done = []
    attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t, progress=done.append)
    assert sum(done) == 2 * len(rec.t) and len(done) > 1

    f = attekf.Filter()
    f.update_batch(rec.gyr[:500], rec.acc[:500], rec.mag[:500], t=rec.t[:500])
    before = f.get_state()["c_state"]

    def stop(k):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        f.smooth_batch(rec.gyr[500:], rec.acc[500:], rec.mag[500:], t=rec.t[500:], progress=stop)
    assert f.get_state()["c_state"] == before   # the filter as it was


def test_bad_arguments(rec):
    with pytest.raises(ValueError, match="segment"):
        attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t, segment=0)
    with pytest.raises(ValueError, match="segment"):
        attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t, segment=2.5)
    with pytest.raises(ValueError, match="shape"):
        attekf.smooth(rec.gyr[:, :2], rec.acc, rec.mag, t=rec.t)
    with pytest.raises(ValueError, match="not strictly increasing"):
        attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t[::-1])
    with pytest.raises(ValueError, match="with_6d"):
        attekf.smooth(rec.gyr, rec.acc, None, t=rec.t, with_6d=True)
    # refused samples are the filter's business, as for estimate
    gyr = rec.gyr.copy()
    gyr[1000] = np.nan
    s = attekf.smooth(gyr, rec.acc, rec.mag, t=rec.t)
    assert s.summary()["samples_refused"] == 1
    np.testing.assert_array_equal(s.quat[1000], s.quat[999])


def test_run_and_eval_commands(rec, tmp_path, capsys):
    from attekf.io import write_recording_hdf5
    path = tmp_path / "sim.h5"
    write_recording_hdf5(str(path), rec)
    out = tmp_path / "out.csv"
    assert main(["run", str(path), "-o", str(out), "--smooth", "-q"]) == 0
    rows = out.read_text().splitlines()
    assert len(rows) == len(rec.t) + 1 and rows[0].startswith("t_s")
    assert main(["eval", str(path), "--smooth", "--no-plot", "--json", str(tmp_path / "e.json"), "-q"]) == 0
    smoothed = capsys.readouterr().out
    assert main(["eval", str(path), "--no-plot", "-q"]) == 0
    filtered = capsys.readouterr().out
    assert smoothed != filtered
    assert main(["eval", str(path), "--smooth", "--output-csv", str(out)]) == 2


def test_bench_methods():
    keys = [m.key for m in B.select_methods("ours-smooth")]
    assert keys == ["ours-smooth-9d", "ours-smooth-6d"]
    assert all(m.family in B.OURS for m in B.select_methods("ours-smooth,ours"))
    assert "ours-smooth-9d" not in [m.key for m in B.select_methods(None)]   # not in the default set
