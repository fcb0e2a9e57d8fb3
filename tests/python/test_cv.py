"""Leave-one-group-out cross-validation (attekf/cv.py): folds, plateau choice, coverage choice."""

import json
import os

import pytest

from attekf import cv


def test_folds_partition_every_trial_once():
    groups = {"a": ["all_trials", "undisturbed", "rotation", "slow"], "b": ["undisturbed", "translation"],
              "c": ["disturbed", "tapping"], "d": ["undisturbed", "rotation", "fast"]}
    f = cv.folds(["a", "b", "c", "d"], groups)
    assert f == {"rotation": ["a", "d"], "translation": ["b"], "tapping": ["c"]}
    with pytest.raises(ValueError, match="trial e"):
        cv.folds(["e"], {"e": ["all_trials", "disturbed"]})


def test_broad_folds(broad_trial):
    with open(os.path.join(os.path.dirname(broad_trial), "trials.json"), encoding="utf-8") as fh:
        info = json.load(fh)
    groups = {t: v["groups"] for t, v in info["trials"].items()}
    f = cv.folds(sorted(groups), groups)
    assert sorted(t for m in f.values() for t in m) == sorted(groups)   # each trial exactly once


def test_smoothing_prefers_a_plateau():
    # 1-D grid: a sharp dip at index 1, a broad plateau at 3..5
    vals = [2.0, 1.0, 2.0, 1.2, 1.2, 1.2, 2.0]
    j = {(i,): v for i, v in enumerate(vals)}
    sm = cv.smoothed(j, (len(vals),))
    assert min(j, key=j.get) == (1,)
    assert min(sm, key=sm.get) == (4,)


def test_objective_is_the_mean_of_9d_and_6d():
    s9 = {"x": {"total": 1.0}, "y": {"total": 3.0}}
    s6 = {"x": {"total": 2.0}, "y": {"total": 2.0}}
    assert cv.objective(s9, s6, ["x", "y"]) == pytest.approx(2.0)
    assert cv.objective(s9, s6, ["x"]) == pytest.approx(1.5)


def test_consider_choice_is_the_cheapest_that_covers():
    # two combinations: (1,) covers everything with a larger sigma, (0,) fails one trial
    tables = {("t1", False): {(0,): ([99.0, 99.0, 90.0], [0.2, 0.2, 1.0]), (1,): ([99.9, 99.9, 99.0], [0.3, 0.3, 3.0])},
              ("t1", True): {(0,): ([99.0, 99.0], [0.2, 0.2]), (1,): ([99.9, 99.9], [0.3, 0.3])},
              ("t2", False): {(0,): ([99.0, 99.0, 99.0], [0.2, 0.2, 1.0]), (1,): ([99.9, 99.9, 99.9], [0.3, 0.3, 3.0])},
              ("t2", True): {(0,): ([99.0, 99.0], [0.2, 0.2]), (1,): ([99.9, 99.9], [0.3, 0.3])}}
    assert cv.choose_consider(tables, ["t1", "t2"]) == (1,)
    assert cv.choose_consider(tables, ["t2"]) == (0,)


# ---------------------------------------------------------------------------------------------
# Over rates (--decimate / --resample)
# ---------------------------------------------------------------------------------------------
def test_scores_and_coverage_over_rates():
    rows = [("a", {"total": 1.0, "heading": 2.0}), ("a", {"total": 3.0, "heading": 2.0}),
            ("b", {"total": 5.0, "heading": 1.0})]
    assert cv._per_trial_mean(rows) == {"a": {"total": 2.0, "heading": 2.0}, "b": {"total": 5.0, "heading": 1.0}}
    tables = [{(0,): ([99.0, 98.0], [0.2, 0.4])}, {(0,): ([97.0, 99.5], [0.4, 0.4])}]
    assert cv._merge_tables(tables) == {(0,): ([97.0, 98.0], [pytest.approx(0.3), pytest.approx(0.4)])}


@pytest.fixture(scope="module")
def two_groups(tmp_path_factory):
    """Two simulated trials in two folds (rotation, translation), BROAD layout with trials.json."""
    from attekf.io import write_recording_hdf5
    from attekf.sim import SimConfig, simulate
    d = tmp_path_factory.mktemp("cvdata")
    groups = {}
    for name, fold, seed in (("01_r", "rotation", 1), ("02_t", "translation", 2)):
        write_recording_hdf5(str(d / f"{name}.hdf5"), simulate(SimConfig(duration_s=20.0, rate_hz=100.0, seed=seed)))
        groups[name] = {"groups": ["all_trials", "undisturbed", fold]}
    (d / "trials.json").write_text(json.dumps({"groups": [{"name": g} for g in
                                                          ("all_trials", "undisturbed", "rotation", "translation")],
                                               "trials": groups}))
    return d


def test_cv_over_rates_averages_each_trial_over_them(two_groups):
    """The cross-validated score of a trial is the mean of its runs at each rate, each run made
    independently here (the task the pool runs, on the transformed recording)."""
    from attekf import bench as B
    from attekf.transform import Transform
    paths = B.find_trials(str(two_groups))
    tfs = [Transform(), Transform(decimate=2)]
    grid = [("accel_noise", [0.5, 0.7])]
    r = cv.run_cv(paths, str(two_groups), grid, {}, transforms=tfs)
    assert r["rates"] == ["native", "x2"]
    for trial, path in zip(r["trials"], paths):
        chosen = r["chosen"]["rotation" if trial == "01_r" else "translation"]["accuracy"]["accel_noise"]
        want = [cv._accuracy_task((path, {"accel_noise": chosen}, False, "float", tf))[1]["total"] for tf in tfs]
        assert r["cv"]["9d"][trial]["total"] == pytest.approx(sum(want) / 2, rel=1e-12)
        assert want[0] != pytest.approx(want[1], rel=1e-3)      # the rates do differ
    one = cv.run_cv(paths, str(two_groups), grid, {})
    assert one["rates"] == ["native"] and one["in"]["9d"]["01_r"] != r["in"]["9d"]["01_r"]


def test_cv_command_rates_options(two_groups, capsys):
    from attekf.cli import main
    rc = main(["cv", "--data", str(two_groups), "--grid", "accel_noise=0.5", "--decimate", "1,3", "--resample", "250",
               "--no-vqf", "--jobs", "1", "-q"])
    assert rc == 0
    assert "at the rates: native, x3, 250 Hz" in capsys.readouterr().out
    assert main(["cv", "--data", str(two_groups), "--decimate", "0", "-q"]) == 2
    assert "decimate must be an integer >= 1" in capsys.readouterr().err
    assert main(["cv", "--data", str(two_groups), "--decimate", "1,1", "-q"]) == 2
    assert "given twice" in capsys.readouterr().err
    assert main(["cv", "--data", str(two_groups), "--decimate", "5000", "-q"]) == 1
    assert capsys.readouterr().err.endswith("01_r.hdf5: 2001 samples, too few to decimate by 5000\n")


def test_reported_covariance_settings_stay_at_the_shipped_values_unless_tuned(two_groups):
    """The reported-covariance settings describe the device and the place: by default every
    fold keeps the shipped ones (a left-out trial's coverage is theirs); tune_covariance picks
    the cheapest covering combination per fold instead; values off the grid are refused."""
    from attekf import bench as B
    from attekf import native
    paths = B.find_trials(str(two_groups))
    grid = [("accel_noise", [0.0414])]
    shipped = cv.shipped_covariance(native.default_settings("float"), {})
    fixed = cv.run_cv(paths, str(two_groups), grid, {})
    assert not fixed["covariance_tuned"]
    for ch in list(fixed["chosen"].values()) + [fixed["in_sample"]]:
        assert tuple(ch["reported_covariance"].values()) == shipped
    tuned = cv.run_cv(paths, str(two_groups), grid, {}, tune_covariance=True)
    # two clean simulations need no reference terms: tuning takes the cheapest combination
    assert tuple(tuned["in_sample"]["reported_covariance"].values()) != shipped
    assert cv.shipped_covariance({}, {"angle_walk_rate": 0.001, "accel_ref_sigma": 0.0,
                                      "mag_ref_sigma": 0.02}) == (0.001, 0.0, 0.02)
    with pytest.raises(ValueError, match="mag_ref_sigma = 0.033: not one of"):
        cv.shipped_covariance(native.default_settings("float"), {"mag_ref_sigma": 0.033})
