"""attekf.transform: recordings at other rates and with missing samples, checked against hand
computations and independent formulations (integrals, a linear signal, a known rotation)."""

from __future__ import annotations

import numpy as np
import pytest

from attekf import metrics as M
from attekf import transform as T
from attekf.io import Recording
from attekf.sim import SimConfig, simulate


def tiny(n=9, rate=10.0, mag_nan=()):
    """n samples at `rate` with sensor values that make every mean distinct."""
    t = np.arange(n) / rate
    k = np.arange(n, dtype=float)[:, None]
    mag = np.hstack([k, 2 * k, 3 * k]) + 20.0
    for i in mag_nan:
        mag[i] = np.nan
    q = M.quat_about_z(np.radians(10.0) * np.arange(n))
    return Recording(t=t, gyr=np.hstack([k, -k, k * k]), acc=np.hstack([k + 9, k, -k]), mag=mag, quat_ref=q,
                     movement=np.arange(n) % 2 == 0, rate_hz=rate)


def test_decimate_block_means_and_end_of_block_truth():
    r = tiny(9)
    d = T.decimate(r, 3)
    assert len(d) == 3 and d.rate_hz == pytest.approx(10.0 / 3)
    np.testing.assert_allclose(d.gyr[1], [4.0, -4.0, (9 + 16 + 25) / 3])     # samples 3, 4, 5
    np.testing.assert_allclose(d.acc[2], [7 + 9, 7, -7])
    np.testing.assert_array_equal(d.t, r.t[[2, 5, 8]])                     # the block's last instant
    np.testing.assert_array_equal(d.quat_ref, r.quat_ref[[2, 5, 8]])
    np.testing.assert_array_equal(d.movement, r.movement[[2, 5, 8]])
    assert len(T.decimate(tiny(10), 3)) == 3                                # an incomplete block is left out
    assert T.decimate(r, 1) is r
    with pytest.raises(ValueError, match="too few"):
        T.decimate(r, 5)


def test_decimate_magnetometer_rows_without_sample():
    d = T.decimate(tiny(9, mag_nan=(0, 1, 2, 4)), 3)
    assert np.isnan(d.mag[0]).all()                                         # no sample in the block
    np.testing.assert_allclose(d.mag[1], np.array([4.0, 8.0, 12.0]) + 20.0)  # rows 3 and 5
    np.testing.assert_allclose(d.mag[2], np.array([7.0, 14.0, 21.0]) + 20.0)


def test_decimate_weights_the_gyro_by_its_time_steps():
    r = tiny(6)
    r.t = np.array([0.0, 0.1, 0.3, 0.4, 0.5, 0.9])      # steps 0.1 (first = second), 0.1, 0.2, 0.1, 0.1, 0.4
    d = T.decimate(r, 3)
    np.testing.assert_allclose(d.gyr[:, 0], [(0 * 0.1 + 1 * 0.1 + 2 * 0.2) / 0.4, (3 * 0.1 + 4 * 0.1 + 5 * 0.4) / 0.6])
    np.testing.assert_allclose(d.acc[:, 1], [1.0, 4.0])                      # other sensors: plain means


def test_resample_by_an_integer_ratio_is_decimation():
    r = simulate(SimConfig(duration_s=6, rate_hz=300, seed=1))
    d, s = T.decimate(r, 3), T.resample(r, 100.0)
    assert len(d) == len(s)
    np.testing.assert_allclose(s.t, d.t, atol=1e-12)
    for name in ("gyr", "acc", "mag", "quat_ref"):
        np.testing.assert_allclose(getattr(s, name), getattr(d, name), atol=1e-9, err_msg=name)
    np.testing.assert_array_equal(s.movement, d.movement)


def test_resample_up_keeps_every_integral_and_a_linear_signal():
    r = simulate(SimConfig(duration_s=4, rate_hz=200, seed=2))
    u = T.resample(r, 600.0)
    ig = np.cumsum(r.gyr / 200.0, axis=0)
    iu = np.cumsum(u.gyr / 600.0, axis=0)
    np.testing.assert_allclose(u.t[2::3], r.t, atol=1e-12)
    np.testing.assert_allclose(iu[2::3], ig, atol=1e-12)                    # no rotation gained or lost
    # interval means of a linear signal: the cubic through the integral reproduces it exactly
    lin = Recording(t=np.arange(50) / 10.0, gyr=np.zeros((50, 3)), acc=np.zeros((50, 3)), rate_hz=10.0)
    a, b = 2.0, 0.7
    mean_over = lambda t0, t1: a + b * (t0 + t1) / 2              # noqa: E731
    lin.gyr[:, 0] = mean_over(lin.t - 0.1, lin.t)
    u = T.resample(lin, 40.0)
    inner = (u.t > 0.2) & (u.t < 4.7)
    np.testing.assert_allclose(u.gyr[inner, 0], mean_over(u.t[inner] - 0.025, u.t[inner]), atol=1e-12)


def test_resample_truth_by_slerp_and_rows_without_magnetometer():
    r = tiny(9, mag_nan=(4,))
    u = T.resample(r, 20.0)                       # new instants halfway between the old ones too
    k = int(np.argmin(np.abs(u.t - 0.25)))
    assert u.t[k] == pytest.approx(0.25)
    e = M.quat_mul(M.quat_conj(u.quat_ref[k]), M.quat_about_z(np.radians(25.0)))
    assert np.degrees(M.total_error(e)) == pytest.approx(0.0, abs=1e-9)      # 10 deg/sample, halfway: 25
    assert np.isnan(u.quat_ref[0]).all()          # before the first truth sample
    bad = np.isnan(u.mag).any(axis=1)
    # the new intervals (0.3, 0.35] and (0.35, 0.4] overlap the missing sample's (0.3, 0.4]
    np.testing.assert_array_equal(np.flatnonzero(bad), np.flatnonzero((u.t > 0.3 + 1e-9) & (u.t < 0.4 + 1e-9)))


def test_drop_keeps_the_rotation_and_is_seeded():
    r = simulate(SimConfig(duration_s=20, rate_hz=100, seed=3))
    d = T.drop_samples(r, 0.1, seed=5)
    assert len(d) == len(r) - round(0.1 * (len(r) - 2))
    assert d.t[0] == r.t[0] and d.t[-1] == r.t[-1]
    np.testing.assert_array_equal(d.t, T.drop_samples(r, 0.1, seed=5).t)
    assert not np.array_equal(d.t, T.drop_samples(r, 0.1, seed=6).t)
    dt = np.diff(d.t)
    np.testing.assert_allclose(np.sum(d.gyr[1:] * dt[:, None], axis=0),
                               np.sum(r.gyr[1:] / 100.0, axis=0), atol=1e-12)   # mean rate x the longer step
    keep = np.searchsorted(r.t, d.t)
    np.testing.assert_array_equal(d.acc, r.acc[keep])
    np.testing.assert_array_equal(d.quat_ref, r.quat_ref[keep])
    own = T.drop_samples(r, 0.1, seed=5, gyro="own")
    np.testing.assert_array_equal(own.gyr, r.gyr[keep])
    with pytest.raises(ValueError, match="fraction"):
        T.drop_samples(r, 1.0)


def test_regular_feed_fills_a_gap_with_the_next_sample():
    r = tiny(8)
    d = T.remove_samples(r, np.isin(np.arange(8), [3, 4]))
    feed, slots = T.regular_feed(d)
    np.testing.assert_array_equal(slots, [0, 1, 2, 5, 6, 7])
    assert len(feed) == 8
    np.testing.assert_array_equal(feed.gyr[3], d.gyr[3])         # slots 3, 4 get the sample of slot 5
    np.testing.assert_array_equal(feed.gyr[4], d.gyr[3])
    np.testing.assert_allclose(d.gyr[3], [4.0, -4.0, (9 + 16 + 25) / 3])   # its mean over the gap
    assert T.regular_feed(r) == (r, None)
    r.t = r.t + np.array([0, 0, 0, 0.04, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="not on a grid"):
        T.regular_feed(r)


def test_transform_options_are_checked():
    assert T.Transform().identity and T.Transform(decimate=3).label() == "x3"
    assert T.Transform(resample_hz=1000, drop=0.05, seed=2).label() == "1000 Hz, 5% dropped (seed 2)"
    for bad in (dict(decimate=0), dict(decimate=2, resample_hz=100.0), dict(resample_hz=-1.0), dict(drop=1.0),
                dict(seed=-1), dict(drop_gyro="nearest")):
        with pytest.raises(ValueError):
            T.Transform(**bad)


def test_decimated_real_trial_is_the_resampled_one(broad_trial):
    """On a real BROAD trial, decimate(3) and resample(rate / 3) agree (two formulations)."""
    from attekf.io import read_recording
    r = read_recording(str(broad_trial)).slice(0, 30000)
    d, s = T.decimate(r, 3), T.resample(r, r.rate_hz / 3)
    assert len(d) == len(s) == 10000
    np.testing.assert_allclose(s.gyr, d.gyr, atol=1e-9)
    np.testing.assert_allclose(s.mag, d.mag, atol=1e-7)
    ok = np.isfinite(d.quat_ref).all(axis=1)
    np.testing.assert_allclose(np.abs(np.sum(s.quat_ref[ok] * d.quat_ref[ok], axis=1)), 1.0, atol=1e-9)
