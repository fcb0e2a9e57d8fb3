"""attekf.robustness (the measures), scorecard_report (rows, targets, pass/miss) and the
`attekf robustness` command on small generated data (no BROAD needed)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from attekf import metrics as M
from attekf import robustness as R
from attekf import scorecard as SC
from attekf import scorecard_report as SR
from attekf.cli import main
from attekf.transform import Transform


def test_heading_change_across_an_event():
    """Truth fixed; the estimate's heading steps by 7 deg in the middle of [2, 3] s over a
    constant offset of 40 deg (which cancels), with a tilt error that is not heading."""
    t = np.arange(0, 6, 0.01)
    ref = np.tile(M.euler_to_quat(np.array([0.2, -0.1, 1.0])), (len(t), 1))
    yaw = np.radians(40.0 + 7.0 * (t >= 2.5))
    est = M.quat_mul(M.quat_about_z(yaw), M.quat_mul(M.quat_from_rotvec(np.array([0.01, 0.0, 0.0])), ref))
    assert R.heading_change(t, est, ref, 2.0, 3.0) == pytest.approx(7.0, abs=1e-6)
    assert R.heading_change(t, est, ref, 3.6, 4.0) == pytest.approx(0.0, abs=1e-9)
    wrap = M.quat_mul(M.quat_about_z(np.radians(175.0 + 10.0 * (t >= 2.5))), ref)
    assert R.heading_change(t, wrap, ref, 2.0, 3.0) == pytest.approx(10.0, abs=1e-6)   # across +-180


def test_peak_recovery_and_window_means():
    t = np.arange(0, 10, 0.5)
    err = np.array([0, 0, 9, 8, 5, 3, 1, 2.5, 1, 0.5] + [0.2] * 10, float)
    assert R.peak(t, err, 1.0) == 9.0 and R.peak(t, err, 2.0, 3.0) == 5.0
    assert R.recovery_time(t, err, 1.0) == pytest.approx(3.0)          # last >= 2 at 3.5 s, below from 4.0
    assert R.recovery_time(t, err, 5.0) == 0.0
    assert R.recovery_time(t, np.r_[err[:-1], 3.0], 1.0) == math.inf
    nan = err.copy()
    nan[12] = np.nan                                                      # no estimate counts as not recovered
    assert R.recovery_time(t, nan, 1.0) == pytest.approx(5.5)
    assert R.window_means(t, err, [(0, 1.0, 2.0), (0, 6.0, 9.5)]) == [pytest.approx(22 / 3), pytest.approx(0.2)]


def test_quantiles_and_pooled_coverage():
    q = R.quantiles([1.0, 2.0, 3.0, 4.0, float("nan")])
    assert q["median"] == 3.0 and q["max"] == math.inf and q["n"] == 5    # no answer is never good
    assert R.quantiles([1, 2, 3, 4, 5, 6, 7, 8, 9, 10])["p90"] == pytest.approx(9.1)
    pooled = R.pool_coverage([{"roll": (90.0, 100)}, {"roll": (300.0, 300)}])
    assert pooled == {"roll": pytest.approx(97.5)}                        # samples weigh, not runs


def _broad(trial, tf, scores, post=None, role="set", rate=100.0):
    return {"kind": "broad", "role": role, "trial": trial, "transform": tf, "rate_hz": rate,
            "scores": {k: {"total": v} for k, v in scores.items()}, "post": post or {}}


def test_rate_rows_use_common_trials_and_targets():
    keys = ("ours-9d", "vqf-online-9d", "vqf-9d", "ours-6d", "vqf-online-6d", "vqf-6d")
    res = []
    for tf, ours in ((Transform(), 1.0), (Transform(decimate=3), 1.5)):
        res.append(_broad("a", tf, dict(zip(keys, [ours, 2.0, 2.0, ours, 1.2, 1.0])), rate=100.0 / tf.decimate))
        res.append(_broad("b", tf, dict(zip(keys[3:], [3.0, 3.0, 3.0])), rate=100.0 / tf.decimate))  # no 9D
    rows = {r.measure: r for r in SR.rate_rows(res)}
    r9 = rows["100.0 Hz (1/1) 9D, 1 trials"]
    assert (r9.ours, r9.online, r9.passed) == ("1.00", "2.00", True)
    r6 = rows["100.0 Hz (1/1) 6D, 2 trials"]
    assert (r6.ours, r6.online, r6.passed) == ("2.00", "2.10", True)
    assert rows["33.3 Hz (1/3) 6D, 2 trials"].passed is False             # 2.25 > 2.10
    d9 = rows["1/3 of the rate minus native, 9D"]
    assert d9.ours == "+0.50" and d9.passed is False                      # the 0.3 deg target


def test_motion_rows_pass_and_miss():
    def run(part, h, p, cov):
        per = {"ours-6d": {"heading_change": h, "coverage": {"roll": (cov, 100), "pitch": (100.0, 100)}},
               "vqf-online-6d": {"heading_change": 0.0},
               "ours-9d": {"peak": p, "coverage": {"roll": (100.0, 100)}}, "vqf-online-9d": {"peak": 0.1}}
        return {"kind": part, "rate_hz": 100.0, "peak": 720.0, "per": per}
    good = [run("flips", 0.1 * i, 1.0, 100.0) for i in range(10)]
    rows = SR.motion_rows(good)
    assert [r.passed for r in rows] == [True, True, True]
    bad = good + [run("flips", 4.0, 6.0, 50.0)]                            # one flip beyond max, coverage lost
    rows = SR.motion_rows(bad)
    assert [r.passed for r in rows] == [False, False, False]
    assert rows[0].ours == "0.50 / 0.90 / 4.00"


def test_scorecard_plan():
    plan = SC.Plan(trials=["a.hdf5", "b.hdf5"], drop_trial="c.hdf5", mc=2)
    kinds = [t[0] if t[0] == "broad" else t[1] for t in SC.tasks(plan)]
    assert kinds.count("broad") == 2 * 5 + 3                               # 5 rates x 2 trials; c alone, 2 drops
    assert kinds.count("flips") == kinds.count("tumbles") == 3 * 2 * 2
    assert kinds.count("glitch") == 3 * SC.SEEDS and kinds.count("gap") == SC.SEEDS
    approach = [t[2].approach_deg for t in SC.tasks(plan) if t[0] == "sim" and t[1] == "flips"][:2]
    assert approach == [1.25, 3.75]                                       # spread over 0-5 deg
    assert len(SC.tasks(SC.Plan(parts=("gap",)))) == SC.SEEDS


@pytest.fixture(scope="module")
def small_data(tmp_path_factory):
    """Two recordings in the BROAD layout: a rotation followed by 15 s of rest (a post-motion
    window), one without magnetometer."""
    from attekf import scenarios as S
    from attekf.io import write_recording_hdf5
    d = tmp_path_factory.mktemp("data")
    for name, mag in (("01_rot", True), ("02_nomag", False)):
        rec = S.build(S.ScenarioConfig.preset("rotation", rate_hz=100.0, after_s=15.0, spin_s=2.0, seed=3,
                                              with_mag=mag))
        write_recording_hdf5(str(d / f"{name}.hdf5"), rec)
    return d


def test_robustness_command_on_small_data(small_data, tmp_path, capsys):
    js = tmp_path / "r.json"
    rc = main(["robustness", "--data", str(small_data), "--drop-trial", "01", "--parts", "rates,post-motion,drops,gap",
               "--jobs", "2", "--json", str(js), "-q"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "25.0 Hz (1/4) 6D, 2 trials" in text and "1000.0 Hz (resampled) 9D, 1 trials" in text
    assert "pass" in text and "of 21 rows" in text          # 10 rates, 2 differences, 2 post-motion, 4 drops, 3 gap
    doc = json.loads(js.read_text())
    rows = {r["measure"]: r for r in doc["rows"]}
    assert rows["9D, 1 periods"]["values"]["n"] == 1 and rows["6D, 2 periods"]["values"]["n"] == 2
    assert rows["5% dropped, gyro own, 6D"]["passed"] in (True, False)
    assert doc["command"].startswith("attekf robustness") and doc["settings"] == {}
    assert {r["kind"] for r in doc["runs"]} == {"broad", "gap"}


def test_robustness_command_errors(tmp_path, capsys):
    assert main(["robustness", "--parts", "flips,loops"]) == 2
    assert "unknown part loops" in capsys.readouterr().err
    assert main(["robustness", "--data", str(tmp_path / "none"), "--parts", "rates"]) == 1
    assert "need no data" in capsys.readouterr().err
    assert main(["robustness", "--parts", "gap", "--set", "accel_noise=-1"]) == 2
