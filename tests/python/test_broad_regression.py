"""The headline figures, guarded: the mean total RMSE of this filter over the 22 BROAD trials
(docs/accuracy.md, "Latest result"), 9D and 6D, float build, through the binding, scored as
`attekf bench` scores `ours-9d` / `ours-6d`; and the coverage of its reported covariance (the
share of the scored samples within 3 sigma per angle, consistency.py) on every trial.

The bound is the measured mean plus a small margin: a change that costs more than that on the
development set is a regression to explain (or, if intended, a new measurement to record here
and in docs/accuracy.md). Only the C filter runs (about 20 s for the 44 runs); the pure-Python
baselines are `attekf bench`'s job. Without the data the test skips, under CI=true it fails
(prereq.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from attekf import bench as B
from attekf.io import read_recording

# Mean total RMSE over the 22 trials, deg, measured by this test (the table of
# docs/accuracy.md, from `attekf bench`, has the same figures to two decimals). Depends on the
# filter and its tuning: re-measure after a change of the estimator or its defaults.
MEASURED_DEG = {"ours-9d": 1.7089, "ours-6d": 1.6235}
MARGIN_DEG = 0.05  # about 3 % of the figure; the float build is deterministic on one machine
# Smallest coverage within 3 sigma of any trial, per angle, %, as measured (roll, pitch, yaw;
# 6D: roll and pitch). The bound allows three times the measured shortfall from 100 % (the
# target, 97 % on every trial and angle, is checked by attekf bench and docs/accuracy.md).
MEASURED_MIN_COVERAGE_PCT = {"ours-9d": (97.8, 99.7, 99.9), "ours-6d": (97.4, 99.7)}


@pytest.fixture(scope="module")
def broad_means(broad_dir):
    methods = B.all_methods()
    cfg = B.RunConfig()  # float build, att_default_settings, as attekf bench runs ours
    rows = {key: [] for key in MEASURED_DEG}
    for path in B.find_trials(str(broad_dir)):
        rec = read_recording(path)
        for key in rows:
            q, _sec, extra = B.run_method(rec, methods[key], cfg)
            r = B.score(rec, q, methods[key].six_d)
            cov = tuple(float(extra[f"cov_{a}"]) for a in ("roll", "pitch", "yaw"))
            rows[key].append((rec.name, float(r["total"]), int(extra["samples_refused"]), cov))
    return rows


@pytest.mark.parametrize("key", sorted(MEASURED_DEG))
def test_mean_total_rmse_over_the_22_trials(broad_means, key):
    rows = broad_means[key]
    assert len(rows) == 22, [r[0] for r in rows]
    totals = np.array([r[1] for r in rows])
    assert all(math.isfinite(v) for v in totals), rows
    assert sum(r[2] for r in rows) == 0          # no sample refused on real data
    mean = float(totals.mean())
    bound = MEASURED_DEG[key] + MARGIN_DEG
    worst = max(rows, key=lambda r: r[1])
    assert mean <= bound, (f"{key}: mean total RMSE {mean:.4f} deg over 22 trials > {bound:.4f} "
                           f"(measured {MEASURED_DEG[key]}); worst trial {worst[0]} {worst[1]:.3f} deg")


@pytest.mark.parametrize("key", sorted(MEASURED_MIN_COVERAGE_PCT))
def test_reported_covariance_covers_the_error_on_every_trial(broad_means, key):
    rows = broad_means[key]
    for i, measured in enumerate(MEASURED_MIN_COVERAGE_PCT[key]):
        bound = 100.0 - 3.0 * (100.0 - measured)
        worst = min(rows, key=lambda r: r[3][i])
        angle = ("roll", "pitch", "yaw")[i]
        assert worst[3][i] >= bound, (f"{key}: {angle} coverage within 3 sigma {worst[3][i]:.1f} % on "
                                      f"{worst[0]} < {bound:.1f} % (measured minimum {measured} %)")
