"""The measures of `attekf robustness` (docs/accuracy.md, "How the robustness targets are
measured"): what a flip does to the heading, how far the error goes, how long a filter takes
to recover, the inclination after motion stops, and the coverage of the reported covariance
pooled over many runs. Pure functions of the estimate, the truth and the time axis; the runs
and the table are in scorecard.py.

Errors are those of metrics.py: e = q_est * inv(q_ref) in the earth frame, its total angle and
its inclination part; the signed heading of e is the rotation about earth z in its swing-twist
split, 2 atan2(e_z, e_w).
"""

from __future__ import annotations

import math
from typing import Dict, List, Sequence, Tuple

import numpy as np

from . import metrics as M

# windows around an event [t0, t1] (a flip, a tumble) for the heading change, s
BEFORE_S = (1.0, 0.0)      # [t0 - 1.0, t0)
AFTER_S = (0.5, 1.5)       # [t1 + 0.5, t1 + 1.5]: half a second for the filter to settle
RECOVERY_DEG = 2.0


def signed_heading(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """(N,) signed heading angle of the earth-frame error, rad in (-pi, pi]; NaN where either
    quaternion is NaN."""
    e = M.error_quat_earth(q_est, q_ref)
    e = e * np.where(e[..., :1] < 0, -1.0, 1.0)
    return 2.0 * np.arctan2(e[..., 3], e[..., 0])


def circular_mean(a: np.ndarray) -> float:
    """Circular mean of angles (rad), NaN ignored; NaN if none is left."""
    a = a[np.isfinite(a)]
    return float(np.arctan2(np.mean(np.sin(a)), np.mean(np.cos(a)))) if a.size else float("nan")


def heading_change(t: np.ndarray, q_est: np.ndarray, q_ref: np.ndarray, t0: float, t1: float,
                   before: Tuple[float, float] = BEFORE_S, after: Tuple[float, float] = AFTER_S) -> float:
    """|change| of the signed heading error across an event [t0, t1], deg: the circular mean
    over [t1 + after[0], t1 + after[1]] minus that over [t0 - before[0], t0 - before[1]),
    wrapped to +-180. A constant heading offset (6D) cancels."""
    h = signed_heading(q_est, q_ref)
    pre = (t >= t0 - before[0]) & (t < t0 - before[1])
    post = (t >= t1 + after[0]) & (t <= t1 + after[1])
    d = circular_mean(h[post]) - circular_mean(h[pre])
    return float(abs(np.degrees(M.wrap_pi(d)))) if math.isfinite(d) else float("nan")


def total_error_deg(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    return np.degrees(M.total_error(M.error_quat_earth(q_est, q_ref)))


def inclination_error_deg(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    return np.degrees(M.inclination_error(M.error_quat_earth(q_est, q_ref)))


def peak(t: np.ndarray, err: np.ndarray, start: float, stop: float = math.inf) -> float:
    """Largest error over [start, stop]; NaN (no estimate) counts as 180 deg, never as fine."""
    sel = (t >= start) & (t <= stop)
    if not sel.any():
        return float("nan")
    return float(np.max(np.where(np.isfinite(err[sel]), err[sel], 180.0)))


def value_at(t: np.ndarray, x: np.ndarray, when: float) -> np.ndarray:
    """x at the first sample at or after `when` (NaN rows of the right width if none)."""
    k = int(np.searchsorted(t, when - 1e-9, side="left"))
    if k >= len(t):
        return np.full(np.shape(x)[1:], np.nan)
    return x[k]


def recovery_time(t: np.ndarray, err: np.ndarray, start: float, threshold: float = RECOVERY_DEG) -> float:
    """Seconds from `start` until err falls below threshold and stays below to the end of the
    recording: 0 if it never exceeds it after start, inf if it is still above at the end. NaN
    (no estimate) counts as above."""
    sel = t >= start
    tt, ee = t[sel], err[sel]
    if not tt.size:
        return float("nan")
    above = ~(np.isfinite(ee) & (ee < threshold))
    if not above.any():
        return 0.0
    last = int(np.flatnonzero(above)[-1])
    if last == len(tt) - 1:
        return math.inf
    return float(tt[last + 1] - start)


def window_means(t: np.ndarray, err: np.ndarray, windows: Sequence[Tuple[float, float, float]]) -> List[float]:
    """Mean of err over each window (end of motion, start, stop) (the post-motion
    inclination); NaN for a window without a finite value."""
    out = []
    for _, a, b in windows:
        sel = (t >= a) & (t <= b) & np.isfinite(err)
        out.append(float(np.mean(err[sel])) if sel.any() else float("nan"))
    return out


def coverage_counts(cons: Dict[str, object]) -> Dict[str, Tuple[float, int]]:
    """{angle: (samples inside 3 sigma, samples)} from a consistency() result, for pooling."""
    n = int(cons["samples"])
    return {a: (float(c) * n / 100.0, n) for a, c in cons["coverage_pct"].items() if math.isfinite(c)}


def pool_coverage(counts: Sequence[Dict[str, Tuple[float, int]]]) -> Dict[str, float]:
    """Coverage (%) per angle over all runs together (every sample weighs the same)."""
    inside: Dict[str, float] = {}
    total: Dict[str, int] = {}
    for c in counts:
        for a, (k, n) in c.items():
            inside[a] = inside.get(a, 0.0) + k
            total[a] = total.get(a, 0) + n
    return {a: 100.0 * inside[a] / total[a] for a in inside if total[a] > 0}


def quantiles(values: Sequence[float]) -> Dict[str, float]:
    """median, p90 (linear interpolation) and max of the finite values (NaN counts as inf: a
    run without an answer is never a good one)."""
    big = 1e300     # inf as a finite stand-in, so that interpolation next to it stays defined
    v = np.array([x if math.isfinite(x) else big for x in values if x is not None], float)
    if not v.size:
        return {"median": float("nan"), "p90": float("nan"), "max": float("nan"), "n": 0}

    def back(x):
        return math.inf if x >= 1e288 else float(x)   # any share of the stand-in: inf

    return {"median": back(np.percentile(v, 50)), "p90": back(np.percentile(v, 90)), "max": back(np.max(v)),
            "n": int(v.size)}
