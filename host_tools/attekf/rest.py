"""Rest and motion from the ground truth's angular rate: what "at rest" means for `attekf bench
--oracle-bias` and for the post-motion inclination of `attekf robustness` (docs/accuracy.md,
"How the robustness targets are measured").

    truth rate     at sample k: the angle of the rotation between the truth at the two truth
                   samples that enclose [t_k - HALF_WINDOW_S, t_k + HALF_WINDOW_S] most tightly
                   (the last at or before the start, the first at or after the end; samples
                   without truth are skipped), divided by the time between them, rad/s. The
                   window averages the optical truth's noise (its rate from one sample to the
                   next is several deg/s at rest).
    rest           truth rate below RATE_MAX; a stretch of not-rest shorter than TWITCH_S
                   between two rest samples is taken as rest (a twitch of the table); then
                   only rest stretches of at least MIN_REST_S count. No truth rate (the start
                   and end of the recording, where the window does not fit): not rest.
    motion period  a stretch between two rest periods (the recording's start, before its first
                   rest period, is none).
"""

from __future__ import annotations

from typing import List, Tuple

import numpy as np

from .metrics import quat_conj, quat_mul

HALF_WINDOW_S = 0.25
RATE_MAX = np.radians(2.0)     # rad/s
TWITCH_S = 0.5
MIN_REST_S = 1.0


def rotation_angle(q: np.ndarray) -> np.ndarray:
    """Angle (rad, 0..pi) of unit quaternions [w x y z], accurate for small angles."""
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def truth_rate(t: np.ndarray, q: np.ndarray, half_window_s: float = HALF_WINDOW_S) -> np.ndarray:
    """(N,) the truth's mean angular rate around each sample, rad/s (module docstring); NaN where
    the window does not fit between truth samples."""
    t = np.asarray(t, dtype=np.float64)
    ok = np.flatnonzero(np.all(np.isfinite(q), axis=1))
    out = np.full(len(t), np.nan)
    if len(ok) < 2:
        return out
    tv = t[ok]
    left = np.searchsorted(tv, t - half_window_s + 1e-9, side="right") - 1
    right = np.searchsorted(tv, t + half_window_s - 1e-9, side="left")
    good = (left >= 0) & (right < len(ok))
    li, ri = ok[left[good]], ok[right[good]]
    out[good] = rotation_angle(quat_mul(quat_conj(q[li]), q[ri])) / (t[ri] - t[li])
    return out


def runs(mask: np.ndarray) -> List[Tuple[int, int]]:
    """[start, stop) index pairs of the True stretches of mask."""
    d = np.diff(np.concatenate([[0], np.asarray(mask, bool).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def rest_mask(t: np.ndarray, q: np.ndarray, rate_max: float = RATE_MAX, twitch_s: float = TWITCH_S,
              min_rest_s: float = MIN_REST_S) -> np.ndarray:
    """(N,) bool: the samples at rest by the truth (module docstring)."""
    t = np.asarray(t, dtype=np.float64)
    rate = truth_rate(t, q)
    rest = np.isfinite(rate) & (rate < rate_max)
    for a, b in runs(~rest):            # short not-rest stretches between rest samples: rest
        if a > 0 and b < len(t) and t[b] - t[a - 1] <= twitch_s and np.isfinite(rate[a:b]).all():
            rest[a:b] = True
    for a, b in runs(rest):             # short rest stretches: not rest
        if t[b - 1] - t[a] < min_rest_s:
            rest[a:b] = False
    return rest


def post_motion_windows(t: np.ndarray, q: np.ndarray, min_rest_s: float = 12.0, start_s: float = 2.0,
                        stop_s: float = 12.0) -> List[Tuple[float, float, float]]:
    """(motion end, window start, window stop) in s for every motion period that ends in at
    least min_rest_s of rest: the window is [end + start_s, end + stop_s] (the issue's 2-12 s
    after the motion ends)."""
    t = np.asarray(t, dtype=np.float64)
    rest = rest_mask(t, q)
    periods = runs(rest)
    out = []
    for i, (a, b) in enumerate(periods):
        if i == 0:
            continue                    # the first rest period follows no motion period
        if t[b - 1] - t[a] >= min_rest_s:
            out.append((float(t[a]), float(t[a] + start_s), float(t[a] + stop_s)))
    return out
