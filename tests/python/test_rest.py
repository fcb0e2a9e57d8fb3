"""attekf.rest: rest and motion from the truth's angular rate (the oracle offset of bench and
the post-motion windows of the scorecard)."""

from __future__ import annotations

import numpy as np
import pytest

from attekf import metrics as M
from attekf import rest as R


def yaw_truth(rate_hz, pieces):
    """Truth turning about earth z: pieces of (seconds, deg/s)."""
    t, yaw, now, ang = [], [], 0.0, 0.0
    for seconds, w in pieces:
        n = int(round(seconds * rate_hz))
        tt = now + np.arange(n) / rate_hz
        t.append(tt)
        yaw.append(ang + np.radians(w) * (tt - now))
        now += n / rate_hz
        ang += np.radians(w) * n / rate_hz
    t, yaw = np.concatenate(t), np.concatenate(yaw)
    return t, M.quat_about_z(yaw)


def test_truth_rate_over_its_window_and_across_missing_truth():
    t, q = yaw_truth(100.0, [(5, 0.0), (5, 30.0)])
    q[250:260] = np.nan                                     # no truth for 0.1 s at rest
    rate = np.degrees(R.truth_rate(t, q))
    assert np.isnan(rate[:25]).all() and np.isnan(rate[-25:]).all()   # the window does not fit
    assert rate[100] == pytest.approx(0.0, abs=1e-9)
    assert rate[255] == pytest.approx(0.0, abs=1e-9)        # bridged by the truth around the hole
    assert rate[800] == pytest.approx(30.0, rel=1e-9)
    assert 0 < rate[500] < 30.0                             # the window straddles the start


def test_rest_mask_twitches_and_short_rests():
    # rest 4 s, a twitch of 1.2 deg in 0.1 s (above 2 deg/s over the window for about 0.43 s),
    # rest 4 s, motion 3 s, rest 0.6 s, motion 3 s, rest 4 s
    t, q = yaw_truth(100.0, [(4, 0), (0.1, 12), (4, 0), (3, 40), (0.6, 0), (3, 40), (4, 0)])
    rate = np.degrees(R.truth_rate(t, q))
    assert 0.3 < np.sum(rate[:700] >= 2.0) / 100.0 < 0.5     # the twitch does exceed the threshold
    rest = R.rest_mask(t, q)
    periods = [(round(t[a], 2), round(t[b - 1], 2)) for a, b in R.runs(rest)]
    # the twitch is rest (merged), the 0.6 s pause is too short to count. Edges: the 0.5 s window
    # reads 2 deg/s of a 40 deg/s motion when 0.025 s of the motion is inside it
    assert len(periods) == 2
    assert periods[0][0] == pytest.approx(0.25) and periods[0][1] == pytest.approx(8.1 - 0.25 + 0.025, abs=0.011)
    assert periods[1][0] == pytest.approx(14.7 + 0.25 - 0.025, abs=0.011)
    assert not rest[int(11.4 * 100)]                         # inside the short pause
    assert R.rest_mask(t, q, twitch_s=0.0)[400:410].sum() == 0   # without the rule the twitch splits the rest


def test_post_motion_windows_need_twelve_seconds_of_rest():
    t, q = yaw_truth(50.0, [(5, 0), (3, 60), (15, 0), (2, 60), (8, 0), (2, 60), (13, 0)])
    w = R.post_motion_windows(t, q)
    assert len(w) == 2                                       # after the first and the last motion
    end, a, b = w[0]
    assert end == pytest.approx(8.0 + 0.25, abs=0.03) and a == pytest.approx(end + 2) and b == pytest.approx(end + 12)
    assert w[1][0] == pytest.approx(35.0 + 0.25, abs=0.03)


def test_broad_post_motion_windows(broad_dir):
    """Every BROAD trial ends with a rest of more than 12 s after its motion: at least one
    window each (some have more, after a long break)."""
    from attekf.io import read_recording
    counts = [len(R.post_motion_windows(r.t, r.quat_ref))
              for r in (read_recording(str(p)) for p in sorted(broad_dir.glob("*.hdf5")))]
    assert len(counts) == 22 and min(counts) >= 1 and 22 <= sum(counts) <= 30
