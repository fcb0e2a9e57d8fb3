"""Recordings at other sample rates and with missing samples: what `attekf bench --decimate /
--resample / --drop`, `attekf cv --decimate / --resample` and `attekf robustness` score on
(docs/host_tools.md, "Other rates and dropped samples").

The sample convention is the estimator's (att_step): sample k at time t_k carries the mean of
each sensor over the interval (t_{k-1}, t_k] that ends at it, the gyroscope above all (the
rotation over the interval is its mean rate times dt). Every transform keeps that convention:

decimate(rec, K)      each sensor: mean of K consecutive samples (the gyroscope weighted by its
                      time steps, i.e. the mean rate over the block); time, truth and movement
                      mask of the LAST sample of the block, the instant at which the averaged
                      interval ends (its gyro integral is the rotation up to that instant).
                      An incomplete block at the end is left out.
resample(rec, hz)     any rate, up or down. Each sensor is integrated over time, that integral
                      interpolated by a cubic Hermite curve through its exact values at the
                      original sample instants (slopes: the three-point estimate from the two
                      adjacent samples), and differenced over the new intervals: every new
                      sample is the mean of that curve over its interval. The integral over any
                      original interval is kept exactly, so no rotation is gained or lost; going
                      down the mean over the new interval is the anti-alias (box) filter and an
                      integer ratio gives decimate()'s values; going up the rate varies smoothly
                      inside an original interval instead of in steps. Truth by slerp between
                      the truth samples around the new instant; movement of the original sample
                      whose interval holds the new instant.
drop_samples(rec, p)  removes a random fraction p of the samples (first and last kept). A kept
                      sample's time step is then the time since the previous kept sample. Its
                      gyroscope, two sensors (gyro=...):
                        "mean"  the mean rate over that whole interval (the time-weighted mean
                                of the samples it now stands for): an integrating sensor (delta
                                angles), the rotation is preserved, as the convention requires;
                        "own"   its own reading: a rate sensor whose missed reads are lost; the
                                filter then spreads that one rate over the longer step.
                      Accelerometer and magnetometer are its own reading either way.
remove_samples(rec, mask)  the same for a given mask (a gap of `attekf sim`).

Methods that need a fixed rate (VQF, Fusion, Madgwick, Mahony) cannot take a time step per
sample: regular_feed() gives them the recording on its nominal grid, each missing slot filled
with the next present sample. Their gyroscope integral over a gap is then exactly what our
filter integrates over its longer step (the same mean rate times the same total time), the
accelerometer and magnetometer are that sample's reading repeated; both are scored on the
present samples only.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from .io import Recording
from .metrics import quat_conj, quat_from_rotvec, quat_mul, quat_normalize


GYRO_AFTER_DROP = ("mean", "own")


@dataclass(frozen=True)
class Transform:
    """What to do to a recording before it is scored: decimate by K or resample to
    resample_hz (not both), then drop a fraction `drop` of the samples (random, seeded)."""

    decimate: int = 1
    resample_hz: Optional[float] = None
    drop: float = 0.0
    seed: int = 0
    drop_gyro: str = "mean"     # gyroscope of a sample after a drop: "mean" or "own" (docstring)

    def __post_init__(self):
        if isinstance(self.decimate, bool) or int(self.decimate) != self.decimate or self.decimate < 1:
            raise ValueError(f"decimate must be an integer >= 1 (got {self.decimate})")
        if self.resample_hz is not None:
            if not (math.isfinite(self.resample_hz) and self.resample_hz > 0):
                raise ValueError(f"resample rate must be > 0 Hz (got {self.resample_hz})")
            if self.decimate != 1:
                raise ValueError("decimate and resample are exclusive (both set the rate)")
        if not (0.0 <= self.drop < 1.0):
            raise ValueError(f"drop fraction must be in [0, 1) (got {self.drop})")
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0 (got {self.seed})")
        if self.drop_gyro not in GYRO_AFTER_DROP:
            raise ValueError(f"drop_gyro must be one of {', '.join(GYRO_AFTER_DROP)} (got {self.drop_gyro!r})")

    @property
    def identity(self) -> bool:
        return self.decimate == 1 and self.resample_hz is None and self.drop == 0.0

    def label(self) -> str:
        """Short text for tables: 'native', 'x3', '1000 Hz', 'x1, 5% dropped (seed 1)'."""
        parts = []
        if self.resample_hz is not None:
            parts.append(f"{self.resample_hz:g} Hz")
        elif self.decimate != 1:
            parts.append(f"x{self.decimate}")
        if self.drop > 0:
            gyro = "" if self.drop_gyro == "mean" else f", gyro {self.drop_gyro}"
            parts.append(f"{100 * self.drop:g}% dropped (seed {self.seed}{gyro})")
        return ", ".join(parts) or "native"

    def apply(self, rec: Recording) -> Recording:
        out = rec
        if self.resample_hz is not None:
            out = resample(out, self.resample_hz)
        elif self.decimate != 1:
            out = decimate(out, self.decimate)
        if self.drop > 0:
            out = drop_samples(out, self.drop, self.seed, self.drop_gyro)
        return out


def _with_note(meta: dict, note: str) -> dict:
    out = dict(meta)
    prev = out.get("transform")
    out["transform"] = f"{prev}; {note}" if prev else note
    return out


def time_steps(t: np.ndarray) -> np.ndarray:
    """(N,) interval lengths, s: t_k - t_{k-1}, the first one equal to the second (the
    binding's convention for a first sample without a predecessor)."""
    dt = np.empty_like(t)
    dt[1:] = np.diff(t)
    dt[0] = dt[1] if len(t) > 1 else 0.0
    return dt


def _block_mean(x: np.ndarray, k: int, n_out: int, w: Optional[np.ndarray] = None) -> np.ndarray:
    """Mean of each block of k rows (weighted by w), rows with NaN left out; a block with only
    NaN rows gives NaN."""
    x = x[:n_out * k].reshape(n_out, k, -1)
    ok = np.all(np.isfinite(x), axis=2, keepdims=True)
    wt = np.ones((n_out, k, 1)) if w is None else w[:n_out * k].reshape(n_out, k, 1)
    wt = wt * ok
    tot = wt.sum(axis=1)
    s = np.where(ok, x, 0.0) * wt
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(tot > 0, s.sum(axis=1) / np.where(tot > 0, tot, 1.0), np.nan)


def decimate(rec: Recording, k: int) -> Recording:
    """Every sensor averaged over blocks of k samples; time, truth, movement of each block's last
    sample (module docstring)."""
    k = int(k)
    if k < 1:
        raise ValueError(f"decimate must be >= 1 (got {k})")
    if k == 1:
        return rec
    n_out = len(rec) // k
    if n_out < 2:
        raise ValueError(f"{rec.source or 'recording'}: {len(rec)} samples, too few to decimate by {k}")
    last = np.arange(n_out) * k + k - 1
    dt = time_steps(rec.t)

    def pick(a):
        return None if a is None else a[last].copy()

    return Recording(t=rec.t[last].copy(), gyr=_block_mean(rec.gyr, k, n_out, dt),
                     acc=_block_mean(rec.acc, k, n_out),
                     mag=None if rec.mag is None else _block_mean(rec.mag, k, n_out),
                     quat_ref=pick(rec.quat_ref), movement=pick(rec.movement),
                     rate_hz=rec.rate_hz / k, source=rec.source,
                     meta=_with_note(rec.meta, f"decimate {k}"))


# ---------------------------------------------------------------------------------------------
# Resampling
# ---------------------------------------------------------------------------------------------
def _hermite_integral(knots: np.ndarray, means: np.ndarray, tau: np.ndarray, smooth: bool) -> np.ndarray:
    """Integral of a signal whose mean over (knots[j], knots[j+1]] is means[j], at times tau:
    exact at the knots; between them a cubic Hermite curve (smooth) or a straight line (the
    signal held constant over each interval)."""
    h = np.diff(knots)                                    # (M,)
    theta = np.concatenate([np.zeros((1, means.shape[1])), np.cumsum(means * h[:, None], axis=0)])
    j = np.clip(np.searchsorted(knots, tau, side="right") - 1, 0, len(h) - 1)
    u = np.clip((tau - knots[j]) / h[j], 0.0, 1.0)[:, None]
    if not smooth:
        return theta[j] + u * (theta[j + 1] - theta[j])
    slope = np.empty((len(knots), means.shape[1]))
    slope[0] = means[0]
    slope[-1] = means[-1]
    # three-point derivative at an inner knot: exact for a quadratic integral (linear signal)
    slope[1:-1] = (h[1:, None] * means[:-1] + h[:-1, None] * means[1:]) / (h[:-1] + h[1:])[:, None]
    u2, u3 = u * u, u * u * u
    hj = h[j][:, None]
    return ((2 * u3 - 3 * u2 + 1) * theta[j] + (u3 - 2 * u2 + u) * hj * slope[j]
            + (-2 * u3 + 3 * u2) * theta[j + 1] + (u3 - u2) * hj * slope[j + 1])


def _resample_means(knots: np.ndarray, x: np.ndarray, tau_knots: np.ndarray) -> np.ndarray:
    """New interval means of x (original interval means, NaN rows = no sample) over the new
    intervals (tau_knots[m], tau_knots[m+1]]; NaN where a new interval overlaps a missing
    sample (then the signal is taken as held, so that the NaN stays local)."""
    bad = ~np.all(np.isfinite(x), axis=1)
    smooth = not bad.any()
    xf = np.where(bad[:, None], 0.0, x)
    th = _hermite_integral(knots, xf, tau_knots, smooth)
    out = np.diff(th, axis=0) / np.diff(tau_knots)[:, None]
    if not smooth:
        miss = _hermite_integral(knots, bad[:, None].astype(float), tau_knots, False)
        out[np.diff(miss[:, 0]) > 1e-12] = np.nan
    return out


def slerp_truth(t: np.ndarray, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Truth at times tau by spherical interpolation between the truth samples around each
    instant (q at times t); NaN where a neighbour is NaN or tau is outside [t_0, t_-1]."""
    n = len(t)
    i = np.clip(np.searchsorted(t, tau, side="right") - 1, 0, n - 2)
    u = np.clip((tau - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)[:, None]
    q0, q1 = q[i], q[i + 1]
    q1 = q1 * np.where(np.sum(q0 * q1, axis=1, keepdims=True) < 0, -1.0, 1.0)   # shorter way
    rel = quat_mul(quat_conj(q0), q1)
    w = np.clip(rel[:, :1], -1.0, 1.0)
    s = np.linalg.norm(rel[:, 1:], axis=1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    axis = np.where(s > 0, rel[:, 1:] / np.where(s > 0, s, 1.0), 0.0)
    out = quat_normalize(quat_mul(q0, quat_from_rotvec(axis * angle * u)))
    # on a truth instant: that sample, whatever its neighbour holds
    at0 = (u[:, 0] < 1e-9) & np.isfinite(q[i]).all(axis=1)
    at1 = (u[:, 0] > 1 - 1e-9) & np.isfinite(q[i + 1]).all(axis=1)
    out[at0] = q[i][at0]
    out[at1] = q[i + 1][at1]
    outside = (tau < t[0] - 1e-12) | (tau > t[-1] + 1e-12)
    out[outside] = np.nan
    return out


def resample(rec: Recording, rate_hz: float) -> Recording:
    """The recording at rate_hz (module docstring). The first original sample's interval is
    taken as long as the second's; the new grid starts where that interval starts, so that
    an integer ratio lands on the original instants."""
    rate_hz = float(rate_hz)
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"resample rate must be > 0 Hz (got {rate_hz})")
    if len(rec) < 2:
        raise ValueError(f"{rec.source or 'recording'}: too few samples to resample")
    dt = time_steps(rec.t)
    knots = np.concatenate([[rec.t[0] - dt[0]], rec.t])
    span = knots[-1] - knots[0]
    m = int(math.floor(span * rate_hz + 1e-6))
    if m < 2:
        raise ValueError(f"{rec.source or 'recording'}: {span:.3g} s is too short for {rate_hz:g} Hz")
    tau_knots = knots[0] + np.arange(m + 1) / rate_hz
    tau = tau_knots[1:]
    movement = None
    if rec.movement is not None:
        movement = rec.movement[np.clip(np.searchsorted(rec.t, tau - 1e-6 / rate_hz, side="left"), 0,
                                        len(rec) - 1)].copy()
    return Recording(t=tau, gyr=_resample_means(knots, rec.gyr, tau_knots),
                     acc=_resample_means(knots, rec.acc, tau_knots),
                     mag=None if rec.mag is None else _resample_means(knots, rec.mag, tau_knots),
                     quat_ref=None if rec.quat_ref is None else slerp_truth(rec.t, rec.quat_ref, tau),
                     movement=movement, rate_hz=rate_hz, source=rec.source,
                     meta=_with_note(rec.meta, f"resample {rate_hz:g} Hz"))


# ---------------------------------------------------------------------------------------------
# Missing samples
# ---------------------------------------------------------------------------------------------
def remove_samples(rec: Recording, remove: np.ndarray, note: str = "samples removed",
                   gyro: str = "mean") -> Recording:
    """The recording without the samples where `remove` is true; each kept sample's gyroscope
    the mean rate over the interval since the previous kept sample (gyro="mean") or its own
    reading ("own") (module docstring). The first sample is always kept."""
    if gyro not in GYRO_AFTER_DROP:
        raise ValueError(f"gyro must be one of {', '.join(GYRO_AFTER_DROP)} (got {gyro!r})")
    remove = np.asarray(remove, bool).copy()
    if remove.shape != (len(rec),):
        raise ValueError(f"remove: shape {remove.shape}, expected ({len(rec)},)")
    remove[0] = False
    keep = np.flatnonzero(~remove)
    dt = time_steps(rec.t)
    # group of each original sample = the kept sample that ends its interval
    group = np.searchsorted(keep, np.arange(len(rec)), side="left")
    tail = group >= len(keep)          # removed samples after the last kept one: lost
    w = np.where(tail, 0.0, dt)
    g = np.clip(group, 0, len(keep) - 1)
    num = np.zeros((len(keep), 3))
    den = np.zeros(len(keep))
    np.add.at(num, g, rec.gyr * w[:, None])
    np.add.at(den, g, w)
    gyr = num / den[:, None] if gyro == "mean" else rec.gyr[keep].copy()

    def pick(a):
        return None if a is None else a[keep].copy()

    return Recording(t=rec.t[keep].copy(), gyr=gyr, acc=rec.acc[keep].copy(), mag=pick(rec.mag),
                     quat_ref=pick(rec.quat_ref), movement=pick(rec.movement), rate_hz=rec.rate_hz,
                     source=rec.source, meta=_with_note(rec.meta, note))


def drop_samples(rec: Recording, fraction: float, seed: int = 0, gyro: str = "mean") -> Recording:
    """Removes round(fraction * (N - 2)) samples chosen at random (numpy default_rng(seed)),
    never the first or the last; gyro: see remove_samples."""
    if not (0.0 <= fraction < 1.0):
        raise ValueError(f"drop fraction must be in [0, 1) (got {fraction})")
    n = len(rec)
    count = int(round(fraction * max(n - 2, 0)))
    remove = np.zeros(n, bool)
    if count:
        rng = np.random.default_rng(seed)
        remove[1 + rng.choice(n - 2, size=count, replace=False)] = True
    out = remove_samples(rec, remove, f"drop {fraction:g} seed {seed} gyro {gyro}", gyro)
    out.meta["dropped_samples"] = json.dumps(int(count))
    return out


def regular_feed(rec: Recording, tolerance: float = 0.25) -> Tuple[Recording, Optional[np.ndarray]]:
    """(recording on the nominal grid of rec.rate_hz, index of each of rec's samples in it);
    (rec, None) when rec is on its grid already. A missing slot gets the next present sample
    (module docstring). ValueError when the timestamps are not on a grid of the rate (within
    tolerance x the period)."""
    rate = float(rec.rate_hz)
    if not rate > 0:
        raise ValueError(f"{rec.source or 'recording'}: no nominal sample rate")
    pos = (rec.t - rec.t[0]) * rate
    slots = np.rint(pos).astype(np.int64)
    if np.any(np.abs(pos - slots) > tolerance) or np.any(np.diff(slots) < 1):
        raise ValueError(f"{rec.source or 'recording'}: timestamps are not on a grid of {rate:g} Hz "
                         "(a fixed-rate method cannot run on it)")
    if np.array_equal(slots, np.arange(len(rec))):
        return rec, None
    src = np.searchsorted(slots, np.arange(slots[-1] + 1), side="left")

    def pick(a):
        return None if a is None else a[src]

    feed = Recording(t=rec.t[0] + np.arange(slots[-1] + 1) / rate, gyr=rec.gyr[src], acc=rec.acc[src],
                     mag=pick(rec.mag), quat_ref=pick(rec.quat_ref), movement=pick(rec.movement),
                     rate_hz=rate, source=rec.source, meta=rec.meta)
    return feed, slots
