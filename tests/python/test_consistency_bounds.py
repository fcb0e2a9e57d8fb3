"""Two-sided bounds on the reported covariance, on simulated recordings the project generates
(attekf.sim): the share of the scored samples outside 1, 2 and 3 reported sigma per angle and
the mean NEES per degree of freedom (consistency.py), pooled over six 60 s recordings, float
build, 9D and 6D; clean, and with linear-acceleration and magnetic-disturbance episodes.

Two-sided, because an over-stated covariance is as wrong as an under-stated one: the gates
and the fusion weights follow it, and a user trusts it; a lower bound on the coverage alone
passes any inflation. The bands are not drawn around the Gaussian nominal (68.3 / 95.4 /
99.7 %, NEES 1): the reported covariance deliberately carries error sources the simulation
does not have (the considered errors, docs/derivation.md), so it is far from nominal on
clean data (NEES about 0.1) and a band of three times the deviation from nominal would never
bind from above. Each figure is held within a factor of about 3 of its measured value
instead, both ways: a share outside k sigma measured as u must stay in [u / 3, 3 u], the
NEES m in [m / 3, 3 m]. A share below 0.5 % (under about 170 of the 34,000 scored samples)
is too small to bound from below and is bounded from above only, by 1.5 %. The recordings
are deterministic: re-measure (the figures below) after a change of the estimator or its
defaults, with `pytest tests/python/test_consistency_bounds.py -s`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from attekf import consistency as C
from attekf import native
from attekf.sim import SimConfig, simulate

SEEDS = range(1, 7)
CONFIGS = {"clean": {}, "disturbed": {"lin_acc_m_s2": 2.0, "mag_disturbance_uT": 20.0}}
SMALL_PCT = 0.5       # a share below this is bounded from above only, by 3 * SMALL_PCT
FACTOR = 3.0

# Measured by this test (pooled share outside k sigma, %, roll / pitch / yaw; 6D: roll /
# pitch) and the pooled NEES per degree of freedom.
MEASURED_OUTSIDE_PCT = {
    ("clean", "9d"): {1: (4.06, 0.85, 0.03), 2: (0.04, 0.0, 0.0), 3: (0.0, 0.0, 0.0)},
    ("clean", "6d"): {1: (4.00, 0.79), 2: (0.04, 0.0), 3: (0.0, 0.0)},
    ("disturbed", "9d"): {1: (10.88, 9.47, 12.06), 2: (6.24, 4.74, 4.72), 3: (3.50, 2.43, 0.30)},
    ("disturbed", "6d"): {1: (11.96, 10.93), 2: (7.25, 6.65), 3: (5.05, 3.48)},
}
MEASURED_NEES = {("clean", "9d"): 0.098, ("clean", "6d"): 0.134, ("disturbed", "9d"): 0.82,
                 ("disturbed", "6d"): 1.308}


def pooled(config: str, six_d: bool):
    """Share of the scored samples outside k sigma (k = 1, 2, 3; %, per angle) and the NEES per
    degree of freedom, each pooled over the recordings."""
    outside = {k: np.zeros(3) for k in (1, 2, 3)}
    samples = nees_sum = nees_samples = 0
    for seed in SEEDS:
        rec = simulate(SimConfig(duration_s=60.0, seed=seed, **CONFIGS[config]))
        res = native.run_arrays(rec.t, rec.gyr, rec.acc, None if six_d else rec.mag, {}, "float")
        q = res.quat.copy()
        cov = res.angle_cov.copy()
        q[~res.aligned] = np.nan
        cov[~res.aligned] = np.nan
        c = C.consistency(q, rec.quat_ref, angle_cov=cov, movement=rec.movement, six_d=six_d)
        for k in outside:
            outside[k] += (100.0 - np.array([c["coverage_k_pct"][k][a] for a in C.ANGLES])) * c["samples"]
        samples += c["samples"]
        nees_sum += c["nees"] * c["nees_samples"]
        nees_samples += c["nees_samples"]
    return {k: v / samples for k, v in outside.items()}, nees_sum / nees_samples


def within(measured: float, got: float) -> bool:
    if measured < SMALL_PCT:
        return got <= FACTOR * SMALL_PCT
    return measured / FACTOR <= got <= FACTOR * measured


@pytest.mark.parametrize("config, dims", sorted(MEASURED_OUTSIDE_PCT))
def test_reported_covariance_neither_over_nor_under_stated(config, dims):
    outside, nees = pooled(config, dims == "6d")
    print(f"\n{config} {dims}: outside 1/2/3 sigma %: "
          + "; ".join(", ".join(f"{v:.2f}" for v in outside[k][: 2 if dims == "6d" else 3]) for k in (1, 2, 3))
          + f"; NEES/dof {nees:.3f}")
    bad = []
    for k, want in MEASURED_OUTSIDE_PCT[(config, dims)].items():
        for angle, measured, got in zip(C.ANGLES, want, outside[k]):
            if not within(measured, float(got)):
                bad.append(f"{angle} outside {k} sigma {got:.2f} % (measured {measured} %)")
    m = MEASURED_NEES[(config, dims)]
    if not (math.isfinite(nees) and m / FACTOR <= nees <= FACTOR * m):
        bad.append(f"NEES/dof {nees:.3f} (measured {m})")
    assert not bad, f"{config} {dims}: " + "; ".join(bad) + " (bounds: a factor 3 either way)"


def test_the_bands_can_fail_both_ways():
    """The rule of the bands, on the figures it is given: a covariance twice too large or too
    small in sigma moves a share outside 1 sigma of a Gaussian error beyond a factor 3."""
    nominal = 100.0 - C.COVERAGE_NOMINAL_PCT[1]                        # 31.7 % outside 1 sigma
    over = 100.0 * math.erfc(2.0 / math.sqrt(2.0))                     # sigma doubled: 4.6 %
    under = 100.0 * math.erfc(0.5 / math.sqrt(2.0))                    # sigma halved: 61.7 %
    assert within(nominal, nominal)
    assert not within(nominal, over)
    assert within(nominal, under)          # a factor 3 is loose for under-statement at 1 sigma,
    outside3 = 100.0 - C.COVERAGE_NOMINAL_PCT[3]                       # 0.27 %: below SMALL_PCT
    assert not within(outside3, 100.0 * math.erfc(1.5 / math.sqrt(2.0)))  # but 3 sigma catches it (13 %)
