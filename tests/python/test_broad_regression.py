"""The headline figures, guarded: the mean total RMSE of this filter over the 22 BROAD trials
(docs/accuracy.md, "Latest result"), 9D and 6D, float build, through the binding, scored as
`attekf bench` scores `ours-9d` / `ours-6d`; and the consistency of its reported covariance
(consistency.py): the share of the scored samples within 3 sigma per angle on every trial, and,
two-sided, the mean over the trials of the share outside 1, 2 and 3 sigma and of the NEES.

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
# Two-sided: an over-stated covariance is as wrong as an under-stated one, and the minimum
# coverage above passes any inflation. Mean over the 22 trials of the share of the scored
# samples outside k sigma (k = 1, 2, 3; %, roll / pitch / yaw) and of the NEES per degree of
# freedom, as measured; each held within a factor of 3 of its value both ways (a share below
# 0.5 % from above only, by 1.5 %). Not a band around the Gaussian nominal (31.7 / 4.6 / 0.3 %
# outside, NEES 1): the reported covariance deliberately carries error sources the filter does
# not estimate, so it is conservative here (NEES about 0.5) and three times its deviation from
# nominal would not bound it from above (tests/python/test_consistency_bounds.py has the same
# rule on simulated data).
MEASURED_MEAN_OUTSIDE_PCT = {"ours-9d": {1: (21.79, 7.89, 6.83), 2: (2.52, 0.22, 4.14), 3: (0.22, 0.0, 0.01)},
                             "ours-6d": {1: (21.88, 8.15), 2: (2.58, 0.27), 3: (0.23, 0.0)}}
MEASURED_MEAN_NEES = {"ours-9d": 0.488, "ours-6d": 0.523}


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
            cov12 = {k: tuple(float(extra[f"cov{k}_{a}"]) for a in ("roll", "pitch", "yaw")) for k in (1, 2)}
            rows[key].append((rec.name, float(r["total"]), int(extra["samples_refused"]), cov,
                              {**cov12, 3: cov}, float(extra["nees"])))
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


@pytest.mark.parametrize("key", sorted(MEASURED_MEAN_OUTSIDE_PCT))
def test_reported_covariance_neither_over_nor_under_stated(broad_means, key):
    rows = broad_means[key]
    bad = []
    for k, measured_pct in MEASURED_MEAN_OUTSIDE_PCT[key].items():
        for i, measured in enumerate(measured_pct):
            got = float(np.mean([100.0 - r[4][k][i] for r in rows]))
            lo, hi = (0.0, 1.5) if measured < 0.5 else (measured / 3.0, 3.0 * measured)
            if not lo <= got <= hi:
                bad.append(f"{('roll', 'pitch', 'yaw')[i]} outside {k} sigma {got:.2f} % (measured {measured} %)")
    nees = float(np.mean([r[5] for r in rows]))
    m = MEASURED_MEAN_NEES[key]
    if not m / 3.0 <= nees <= 3.0 * m:
        bad.append(f"NEES/dof {nees:.3f} (measured {m})")
    assert not bad, f"{key}, mean over the 22 trials: " + "; ".join(bad) + " (bounds: a factor 3 either way)"
