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
