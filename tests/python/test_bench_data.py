"""attekf bench on other data and at other rates: the same trials for every method (9D not run
without a magnetometer, a trial without a score left out of every mean), names for both
dimensions, --decimate / --resample / --drop for every method (ours with each sample's time
step, the fixed-rate methods on the regular feed), the oracle offset from the truth's rest.
Small generated recordings only."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from attekf import bench as B
from attekf import scenarios as S
from attekf import transform as T
from attekf.cli import main
from attekf.io import write_recording_hdf5
from attekf.sim import SimConfig, simulate


def test_names_without_dimension_select_both():
    assert [m.key for m in B.select_methods("vqf-online")] == ["vqf-online-9d", "vqf-online-6d"]
    assert [m.key for m in B.select_methods("ours,fusion-bare")] == ["ours-9d", "ours-6d", "fusion-bare-9d",
                                                                     "fusion-bare-6d"]
    assert [m.key for m in B.select_methods("madgwick")] == ["madgwick-9d", "madgwick-6d"]
    assert [m.key for m in B.select_methods("vqf-online-6d,vqf")] == ["vqf-online-6d", "vqf-9d", "vqf-6d"]


def test_means_over_the_trials_every_method_has():
    ms = [B.Method(k, "ours", k.endswith("6d"), k) for k in ("a-9d", "b-9d", "a-6d")]
    rows = [dict(method=m, trial=t, total=v, heading=v, inclination=v, samples=1, seconds=0.0)
            for m, t, v in (("a-9d", "t1", 1.0), ("b-9d", "t1", 3.0), ("a-9d", "t2", 5.0), ("b-9d", "t2", math.nan),
                            ("a-6d", "t1", 2.0), ("a-6d", "t2", 4.0), ("a-6d", "t3", 6.0))]
    used, excluded = B.common_trials(rows, ms, ["t1", "t2", "t3"], {("t3", "9D"): "no magnetometer"})
    assert used == {"9D": ["t1"], "6D": ["t1", "t2", "t3"]}
    assert excluded == [{"trial": "t2", "dim": "9D", "reason": "no score from b-9d"},
                        {"trial": "t3", "dim": "9D", "reason": "not run: no magnetometer"}]
    agg = B.aggregate(rows, ms, ["t1", "t2", "t3"], ["all_trials"], {})
    assert agg["a-9d"]["overall"]["total"] == 1.0 and agg["a-9d"]["n_trials"] == 1   # t2 left out for a too
    assert agg["a-6d"]["overall"]["total"] == 4.0 and agg["a-6d"]["groups"]["all_trials"]["n"] == 3


@pytest.fixture(scope="module")
def other_data(tmp_path_factory):
    """Three short trials in the BROAD layout: with magnetometer, without imu_mag, with every
    magnetometer row NaN."""
    d = tmp_path_factory.mktemp("other")
    for name in ("a_full", "b_nomag", "c_nanmag"):
        rec = simulate(SimConfig(duration_s=15.0, rate_hz=100.0, seed=7, with_mag=name != "b_nomag"))
        if name == "c_nanmag":
            rec.mag[:] = np.nan
        write_recording_hdf5(str(d / f"{name}.hdf5"), rec)
    return d


def test_bench_on_trials_without_magnetometer(other_data, tmp_path, capsys):
    js = tmp_path / "r.json"
    rc = main(["bench", "--data", str(other_data), "--methods", "ours,vqf-online", "--jobs", "2", "--json", str(js),
               "--decimate", "2", "-q"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "note: 9D means over 1 of 3 trial(s)" in text and "imu_mag all NaN" in text and "x2" in text
    res = json.loads(js.read_text())
    assert sorted((e["trial"], e["dim"]) for e in res["excluded"]) == [("b_nomag", "9D"), ("c_nanmag", "9D")]
    r = res["results"]
    assert set(r["ours-9d"]["trials"]) == {"a_full"} and r["ours-9d"]["n_trials"] == 1
    assert r["vqf-online-6d"]["n_trials"] == 3 and r["ours-6d"]["trials"]["b_nomag"]["samples"] == 750
    assert r["ours-9d"]["overall"]["total"] == r["ours-9d"]["trials"]["a_full"]["total"]
    assert res["transform"]["decimate"] == 2


def test_every_method_runs_on_dropped_samples_with_their_time_steps():
    """A noise-free 90 deg/s rotation with 20 % of the samples dropped: ours integrates each
    kept sample over its own time step, VQF over the regular feed; both stay on the truth. With
    the nominal step instead, a fifth of the rotation (about 50 deg) would be lost."""
    quiet = dict(gyro_noise_density=0.0, gyro_bias_rad_s=0.0, acc_noise_density=0.0, mag_noise_density=0.0)
    rec = S.build(S.ScenarioConfig.preset("rotation", rate_hz=100.0, peak_rate_deg_s=90.0, axis=(0.0, 0.0, 1.0),
                                          seed=1, **quiet))
    cfg = B.RunConfig(transform=T.Transform(drop=0.2, seed=3))
    dropped = cfg.transform.apply(rec)
    assert np.diff(dropped.t).max() > 0.015
    for key in ("ours-6d", "vqf-online-6d"):
        q, _, _ = B.run_method(dropped, B.all_methods()[key], cfg)
        assert len(q) == len(dropped)
        assert B.score(dropped, q, True)["total"] < 2.0, key


def test_oracle_offset_from_the_truth_at_rest():
    """The movement mask of this recording marks a moving stretch as not scored: "not movement"
    would average the gyro while it turns; rest by the truth's rate does not."""
    rec = simulate(SimConfig(duration_s=30.0, rate_hz=100.0, seed=2, gyro_bias_rad_s=0.02, initial_rest_s=8.0))
    rec.movement = rec.t >= 12.0                              # 3..12 s: moving but not scored
    bias = np.array(json.loads(rec.meta["gyro_bias_rad_s"]))
    np.testing.assert_allclose(B.oracle_gyro_bias(rec), bias, atol=1e-3)
    assert np.abs(rec.gyr[~rec.movement].mean(axis=0) - bias).max() > 5e-3   # what "not movement" gave


def test_baselines_take_rows_without_magnetometer_sample(other_data):
    """Every other magnetometer row NaN (a slower magnetometer): VQF, Fusion and Mahony still
    give finite 9D estimates close to those with every row."""
    rec = simulate(SimConfig(duration_s=10.0, rate_hz=100.0, seed=5))
    half = T.Transform()   # unchanged, then every other row emptied
    sparse = half.apply(rec)
    sparse.mag = rec.mag.copy()
    sparse.mag[1::2] = np.nan
    for key in ("vqf-online-9d", "vqf-9d", "fusion-9d", "mahony-9d"):
        m = B.all_methods()[key]
        q, _, _ = B.run_method(sparse, m, B.RunConfig())
        assert np.isfinite(q[-1]).all(), key
        assert B.score(sparse, q, False)["total"] < 8.0, key
