"""Evaluation of an estimate against a recording's ground truth (used by `attekf eval`).

An estimate comes either from the C estimator run through the binding (evaluate_run) or from
an estimator output file (evaluate_output, e.g. what `attekf record` decoded from the bus).
Errors follow the BROAD definitions of metrics.py; in addition the per-angle Euler errors are
set against the filter's own 3-sigma bounds and its covariance (coverage and NEES,
consistency.py: about 99.7 % of the samples inside and NEES/dof about 1 if the reported
covariance is right).

Every sample is accounted for: the trial reports how many were scored, how many movement
samples had no truth, how many had no estimate (filter not aligned yet, or no output row),
and what the estimator refused (status counts).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from . import consistency as C
from .io import EstimatorOutput, InputError, Recording
from .metrics import euler_to_quat, orientation_errors, quat_to_euler

ANGLES = ("roll", "pitch", "yaw")
METRICS = ("total", "heading", "inclination")


@dataclass
class TrialEval:
    """The evaluation of one trial (arrays are per recording sample)."""

    name: str
    source: str
    estimator: str                      # what produced the estimate
    t: np.ndarray                       # (N,) s
    euler_est: np.ndarray               # (N, 3) rad, NaN = no estimate
    var_euler: Optional[np.ndarray]     # (N, 3) rad^2, or None
    euler_ref: Optional[np.ndarray]     # (N, 3) rad, NaN = no truth; None without truth
    err_total: Optional[np.ndarray]     # (N,) rad (BROAD errors), None without truth
    err_heading: Optional[np.ndarray]
    err_inclination: Optional[np.ndarray]
    err_euler: Optional[np.ndarray]     # (N, 3) rad, Euler-angle errors (consistency.euler_errors)
    scored: np.ndarray                  # (N,) bool
    movement: np.ndarray                # (N,) bool
    six_d: bool
    heading_offset_deg: float
    rmse_deg: Dict[str, float]
    within_3sigma_pct: Dict[str, float]
    counts: Dict[str, int]
    estimator_summary: Dict[str, object] = field(default_factory=dict)
    episodes: List[Tuple[str, float, float]] = field(default_factory=list)  # (kind, start s, stop s)
    flags: Optional[np.ndarray] = None  # (N,) ATT_FLAG_* per sample (0 where no output row), or None
    nees: float = float("nan")          # mean NEES / dof (consistency.py), NaN without a covariance

    @property
    def has_truth(self) -> bool:
        return self.euler_ref is not None

    def to_json(self) -> Dict[str, object]:
        def clean(v):
            return None if isinstance(v, float) and not math.isfinite(v) else v
        return {
            "name": self.name,
            "source": self.source,
            "estimator": self.estimator,
            "scoring": "6D (mean heading offset removed)" if self.six_d else "9D",
            "heading_offset_removed_deg": clean(self.heading_offset_deg),
            "rmse_deg": {k: clean(v) for k, v in self.rmse_deg.items()},
            "within_3sigma_pct": {k: clean(v) for k, v in self.within_3sigma_pct.items()},
            "nees_per_dof": clean(self.nees),
            "counts": dict(self.counts),
            "estimator_summary": self.estimator_summary,
        }


def recording_episodes(rec: Recording) -> List[Tuple[str, float, float]]:
    """Disturbance episodes the recording declares (attekf sim's 'episodes' metadata: a JSON
    list of [kind, start_s, stop_s]); [] when absent or not in that form."""
    raw = rec.meta.get("episodes")
    if raw is None:
        return []
    try:
        items = json.loads(raw) if isinstance(raw, (str, bytes)) else raw
        return [(str(k), float(a), float(b)) for k, a, b in items
                if math.isfinite(float(a)) and math.isfinite(float(b)) and float(b) > float(a)]
    except (TypeError, ValueError):
        return []


def _score(rec: Recording, name: str, estimator: str, euler_est: np.ndarray,
           var_euler: Optional[np.ndarray], six_d: bool, counts: Dict[str, int],
           summary: Dict[str, object], angle_cov: Optional[np.ndarray] = None) -> TrialEval:
    n = len(rec)
    movement = np.ones(n, bool) if rec.movement is None else rec.movement.astype(bool)
    have_est = np.all(np.isfinite(euler_est), axis=1)
    counts = dict(counts)
    counts.update(samples=n, movement=int(movement.sum()),
                  movement_without_estimate=int((movement & ~have_est).sum()))
    nan3 = {k: float("nan") for k in METRICS}
    if rec.quat_ref is None:
        counts.update(scored=0, movement_without_truth=int(movement.sum()))
        return TrialEval(name=name, source=rec.source, estimator=estimator, t=rec.t, euler_est=euler_est,
                         var_euler=var_euler, euler_ref=None, err_total=None, err_heading=None,
                         err_inclination=None, err_euler=None, scored=np.zeros(n, bool), movement=movement,
                         six_d=six_d, heading_offset_deg=0.0, rmse_deg=nan3,
                         within_3sigma_pct={k: float("nan") for k in ANGLES}, counts=counts,
                         estimator_summary=summary, episodes=recording_episodes(rec))
    have_ref = np.all(np.isfinite(rec.quat_ref), axis=1)
    counts["movement_without_truth"] = int((movement & ~have_ref).sum())
    q_est = euler_to_quat(euler_est)
    errs = orientation_errors(q_est, rec.quat_ref, movement, six_d=six_d)
    counts["scored"] = int(errs.scored.sum())
    euler_ref = np.full((n, 3), np.nan)
    euler_ref[have_ref] = quat_to_euler(rec.quat_ref[have_ref])
    err_euler = C.euler_errors(q_est, rec.quat_ref, six_d, errs.scored)
    within = {k: float("nan") for k in ANGLES}
    nees = float("nan")
    if (var_euler is not None or angle_cov is not None) and counts["scored"] > 0:
        # 6D: yaw is not judged, its variance describes an unobservable heading
        cons = C.consistency(q_est, rec.quat_ref, var=var_euler, angle_cov=angle_cov,
                             movement=movement, six_d=six_d)
        within = dict(cons["coverage_pct"])
        nees = float(cons["nees"])
    return TrialEval(name=name, source=rec.source, estimator=estimator, t=rec.t, euler_est=euler_est,
                     var_euler=var_euler, euler_ref=euler_ref, err_total=errs.total,
                     err_heading=errs.heading, err_inclination=errs.inclination, err_euler=err_euler,
                     scored=errs.scored, movement=movement, six_d=six_d,
                     heading_offset_deg=float(np.degrees(errs.heading_offset_rad)),
                     rmse_deg=errs.rmse_deg(), within_3sigma_pct=within, counts=counts,
                     estimator_summary=summary, episodes=recording_episodes(rec), nees=nees)


def evaluate_run(rec: Recording, settings: Optional[Dict[str, float]] = None, scalar: str = "float",
                 use_mag: bool = True, six_d: Optional[bool] = None, progress=None, smooth: bool = False):
    """Runs the C estimator over rec (smooth: and its smoother) and scores it. Returns
    (TrialEval, native.Result). six_d defaults to 'no magnetometer used'. Samples before
    alignment have no estimate."""
    from . import native  # the binding needs the built library; import only when used

    res = native.run_estimator(rec, settings, scalar=scalar, use_mag=use_mag, progress=progress, smooth=smooth)
    euler = res.euler.copy()
    var = res.var_euler.copy()
    not_aligned = ~res.aligned
    euler[not_aligned] = np.nan
    var[not_aligned] = np.nan
    mag_used = use_mag and rec.mag is not None
    if six_d is None:
        six_d = not mag_used
    summary = res.summary()
    counts = {"not_aligned": int(not_aligned.sum()), "refused": int(summary["samples_refused"])}
    estimator = (f"C estimator ({scalar}, binding){', smoothed' if smooth else ''}"
                 f"{'' if mag_used else ', no magnetometer'}")
    cov = None
    if res.angle_cov is not None:
        cov = res.angle_cov.copy()
        cov[not_aligned] = np.nan
    tr = _score(rec, rec.name, estimator, euler, var, six_d, counts, summary, cov)
    tr.flags = np.asarray(res.flags, dtype=np.uint32)
    return tr, res


def align_output(rec: Recording, out: EstimatorOutput, time_offset_s: float = 0.0):
    """Places output rows on recording samples: each row goes to the sample nearest to its
    time (t + time_offset_s) if within half a sample period. Returns (euler (N,3), var (N,3)
    or None, counts). Rows that match no sample, or a sample already taken, are counted."""
    euler, var, counts, _rows = _align(rec, out, time_offset_s)
    return euler, var, counts


def _align(rec: Recording, out: EstimatorOutput, time_offset_s: float):
    """align_output, plus the output row placed on each sample (-1: none)."""
    n = len(rec)
    t_out = out.t + time_offset_s
    idx = np.clip(np.searchsorted(rec.t, t_out), 1, max(n - 1, 1)) if n > 1 else np.zeros(len(out), int)
    if n > 1:
        left = idx - 1
        closer_left = np.abs(t_out - rec.t[left]) <= np.abs(rec.t[idx] - t_out)
        idx = np.where(closer_left, left, idx)
    period = 1.0 / rec.rate_hz if rec.rate_hz > 0 else (np.median(np.diff(rec.t)) if n > 1 else 1.0)
    matched = np.abs(rec.t[idx] - t_out) <= 0.5 * period
    euler = np.full((n, 3), np.nan)
    var = None if out.var is None else np.full((n, 3), np.nan)
    taken = np.zeros(n, bool)
    rows = np.full(n, -1, np.int64)
    duplicates = 0
    for row in np.nonzero(matched)[0]:
        k = idx[row]
        if taken[k]:
            duplicates += 1
            continue
        taken[k] = True
        rows[k] = row
        euler[k] = out.euler[row]
        if var is not None:
            var[k] = out.var[row]
    counts = {"output_rows": len(out), "output_rows_unmatched": int((~matched).sum()),
              "output_rows_duplicate": duplicates}
    if not matched.any():
        raise InputError(f"{out.source}: no output row falls on a sample of {rec.source} "
                         f"(output t {out.t[0]:.6g}..{out.t[-1]:.6g} s, recording "
                         f"{rec.t[0]:.6g}..{rec.t[-1]:.6g} s; see --time-offset)")
    return euler, var, counts, rows


def evaluate_output(rec: Recording, out: EstimatorOutput, six_d: bool = False,
                    time_offset_s: float = 0.0) -> TrialEval:
    """Scores a recorded estimator output against rec's truth."""
    euler, var, counts, rows = _align(rec, out, time_offset_s)
    summary: Dict[str, object] = {}
    if out.status is not None:
        codes, num = np.unique(out.status, return_counts=True)
        summary["status_counts"] = {int(c): int(k) for c, k in zip(codes, num) if c != 0}
    tr = _score(rec, rec.name, f"recorded output {out.source}", euler, var, six_d, counts, summary)
    if out.flags is not None:
        tr.flags = np.where(rows >= 0, out.flags[np.maximum(rows, 0)], 0).astype(np.uint32)
    return tr


def mean_row(trials: List[TrialEval]) -> Dict[str, float]:
    """Mean over trials of each RMSE (trials with truth only), deg."""
    out = {}
    for m in METRICS:
        vals = [t.rmse_deg[m] for t in trials if math.isfinite(t.rmse_deg[m])]
        out[m] = float(np.mean(vals)) if vals else float("nan")
    return out


def _f(v: float, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(v) else f"{v:.{digits}f}"


def format_table(trials: List[TrialEval]) -> str:
    """Plain-text table: one row per trial, then the mean (when there are several trials)."""
    head = ["trial", "samples", "scored", "total", "heading", "incl.", "in 3σ r/p/y %", "NEES/dof", "refused"]
    rows = []
    for tr in trials:
        w = tr.within_3sigma_pct
        within = "/".join("-" if not math.isfinite(w[a]) else f"{w[a]:.0f}" for a in ANGLES)
        rows.append([tr.name, str(tr.counts["samples"]), str(tr.counts.get("scored", 0)),
                     _f(tr.rmse_deg["total"]), _f(tr.rmse_deg["heading"]), _f(tr.rmse_deg["inclination"]),
                     within, _f(tr.nees), str(tr.counts.get("refused", "-"))])
    if len(trials) > 1:
        m = mean_row(trials)
        rows.append([f"mean of {len(trials)}", "", "", _f(m["total"]), _f(m["heading"]),
                     _f(m["inclination"]), "", "", ""])
    widths = [max(len(r[i]) for r in rows + [head]) for i in range(len(head))]
    lines = ["RMSE over the scored (movement) samples, degrees"
             + ("; 6D: mean heading offset removed" if any(t.six_d for t in trials) else "")]
    fmt_row = lambda r: "  ".join(c.ljust(widths[0]) if i == 0 else c.rjust(widths[i])  # noqa: E731
                                  for i, c in enumerate(r))
    lines.append(fmt_row(head))
    lines.append("  ".join("-" * w for w in widths))
    for i, r in enumerate(rows):
        if len(trials) > 1 and i == len(rows) - 1:
            lines.append("  ".join("-" * w for w in widths))
        lines.append(fmt_row(r))
    return "\n".join(lines)
