"""Coverage and NEES of the reported covariance (attekf/consistency.py)."""

import math

import numpy as np
import pytest

from attekf import consistency as C
from attekf import metrics as M


def _attitudes(n, rng, max_pitch=1.2):
    e = np.stack([rng.uniform(-math.pi, math.pi, n), rng.uniform(-max_pitch, max_pitch, n),
                  rng.uniform(-math.pi, math.pi, n)], axis=1)
    return e


def test_euler_errors_are_the_euler_differences_to_first_order():
    rng = np.random.default_rng(1)
    truth = _attitudes(500, rng)
    d = rng.normal(0.0, 0.01, (500, 3))            # rad
    err = C.euler_errors(M.euler_to_quat(truth + d), M.euler_to_quat(truth))
    # second-order terms ~ |d|^2 sec(theta)
    assert np.max(np.abs(err - d)) < 2e-3
    assert np.median(np.abs(err - d)) < 2e-4


def test_euler_errors_continuous_across_wraps():
    truth = np.array([[math.pi - 1e-3, 0.2, -math.pi + 1e-3]])
    est = truth + np.array([[2e-3, 0.0, -2e-3]])   # wraps past +-pi: still a 2 mrad error
    err = C.euler_errors(M.euler_to_quat(est), M.euler_to_quat(truth))
    assert np.allclose(err, [[2e-3, 0.0, -2e-3]], atol=1e-5)   # second order: |d|^2


def test_six_d_removes_the_heading_offset():
    rng = np.random.default_rng(2)
    truth = _attitudes(300, rng, 0.5)
    est = truth.copy()
    est[:, 2] += 0.7                                # a constant heading offset
    q_est = M.quat_mul(M.quat_about_z(0.7), M.euler_to_quat(truth))
    err = C.euler_errors(q_est, M.euler_to_quat(truth), six_d=True)
    assert np.max(np.abs(err)) < 1e-9


def test_coverage_and_nees_of_a_consistent_gaussian_error():
    rng = np.random.default_rng(3)
    n = 20000
    truth = _attitudes(n, rng, 1.0)
    # a correlated 3x3 covariance per sample
    a = rng.normal(0.0, 0.004, (n, 3, 3))
    cov = np.einsum("nij,nkj->nik", a, a) + np.eye(3) * 1e-6
    d = np.einsum("nij,nj->ni", np.linalg.cholesky(cov), rng.normal(size=(n, 3)))
    q_est = M.euler_to_quat(truth + d)
    packed = np.stack([cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2], cov[:, 0, 1], cov[:, 0, 2], cov[:, 1, 2]], axis=1)
    c = C.consistency(q_est, M.euler_to_quat(truth), angle_cov=packed)
    for ang in C.ANGLES:
        assert c["coverage_pct"][ang] == pytest.approx(99.73, abs=0.2)
    assert c["nees"] == pytest.approx(1.0, abs=0.05)
    assert c["dof"] == 3
    for k, nominal in ((1, 68.27), (2, 95.45), (3, 99.73)):          # erf(k / sqrt 2)
        assert C.COVERAGE_NOMINAL_PCT[k] == pytest.approx(nominal, abs=0.005)
        for ang in C.ANGLES:
            assert c["coverage_k_pct"][k][ang] == pytest.approx(nominal, abs=1.0), (k, ang)
    assert c["coverage_k_pct"][3] == c["coverage_pct"]
    # the same errors against half the sigma: coverage and NEES say so
    c2 = C.consistency(q_est, M.euler_to_quat(truth), angle_cov=packed / 4.0)
    assert c2["coverage_pct"]["roll"] == pytest.approx(86.64, abs=0.6)   # 3 half-sigmas = 1.5 sigma
    assert c2["coverage_k_pct"][2]["roll"] == pytest.approx(68.27, abs=1.0)  # 2 half-sigmas = 1 sigma
    assert c2["nees"] == pytest.approx(4.0, rel=0.05)
    # and against twice the sigma (over-stated): more inside than nominal, NEES a quarter
    c3 = C.consistency(q_est, M.euler_to_quat(truth), angle_cov=packed * 4.0)
    assert c3["coverage_k_pct"][1]["roll"] == pytest.approx(95.45, abs=0.6)  # 1 double sigma = 2 sigma
    assert c3["nees"] == pytest.approx(0.25, rel=0.05)
    flat = C.flat(c)
    assert flat["cov1_pitch"] == c["coverage_k_pct"][1]["pitch"] and flat["cov2_yaw"] == c["coverage_k_pct"][2]["yaw"]


def test_six_d_leaves_yaw_out():
    rng = np.random.default_rng(4)
    truth = _attitudes(1000, rng, 0.5)
    q = M.euler_to_quat(truth)
    var = np.full((1000, 3), 1e-4)
    c = C.consistency(q, q, var=var, six_d=True)
    assert math.isnan(c["coverage_pct"]["yaw"]) and c["dof"] == 2
    assert c["coverage_pct"]["roll"] == 100.0
    assert math.isnan(c["nees"])                      # no covariance, no NEES


def test_aggregate_counts_trials_below_target():
    rows = {"a": {"cov_roll": 99.0, "cov_pitch": 98.0, "cov_yaw": 96.0, "sigma_roll_deg": 0.5,
                  "sigma_pitch_deg": 0.5, "sigma_yaw_deg": 2.0, "nees": 0.8},
            "b": {"cov_roll": 100.0, "cov_pitch": 99.5, "cov_yaw": 99.0, "sigma_roll_deg": 0.3,
                  "sigma_pitch_deg": 0.3, "sigma_yaw_deg": 1.0, "nees": 0.4}}
    agg = C.aggregate(rows)
    assert agg["cov_min_yaw"] == 96.0 and agg["trials_below_97"] == 1
    assert agg["sigma_yaw_deg"] == pytest.approx(1.5) and agg["nees"] == pytest.approx(0.6)
