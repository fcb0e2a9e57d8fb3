"""Does the filter's reported uncertainty describe its real error? Coverage and NEES against a
recording's ground truth (used by `attekf bench` and `attekf eval`; docs/accuracy.md,
"Consistency").

Error angles. The Euler angles (ZYX roll, pitch, yaw) of the estimate and of the truth, both
from their quaternions (so both in the branch |pitch| <= 90 deg), their differences wrapped
into [-pi, pi): the errors of the angles whose covariance C the filter reports
(att_get_angle_covariance). 6D: the mean heading offset is removed from the estimate first,
exactly as for the RMSE.

    coverage (per angle)  share of the scored samples with |d_angle| <= 3 sqrt(C_angle),
                          in percent (99.7 for a Gaussian error with the reported variance);
                          also within 1 and 2 sqrt(C_angle) (68.3 and 95.4 %, COVERAGE_NOMINAL_PCT):
                          an over-stated variance shows there, where 3 sigma is near 100 % anyway
    mean sigma            mean over the scored samples of sqrt(C_angle), degrees
    NEES / dof            mean over the scored samples of d^T C^-1 d divided by the number of
                          angles d has (1 for a consistent filter); samples within
                          NEES_GIMBAL_MARGIN of +-90 deg pitch are left out (there roll and yaw
                          are nearly the same rotation, C is singular by construction and one
                          sample can dominate the mean)

9D: roll, pitch and yaw (3 degrees of freedom). 6D: the heading is not observable and its
offset is removed before scoring, so yaw is left out: roll and pitch with their 2x2 block of C.
Scored samples: the RMSE's (movement, truth and estimate present), with a finite covariance.
"""

from __future__ import annotations

import math
from typing import Dict, Optional

import numpy as np

from . import metrics as M

ANGLES = ("roll", "pitch", "yaw")
# Share of a Gaussian within k standard deviations, % (erf(k / sqrt 2)), k = 1, 2, 3.
COVERAGE_NOMINAL_PCT = {k: 100.0 * math.erf(k / math.sqrt(2.0)) for k in (1, 2, 3)}
NEES_GIMBAL_MARGIN = np.radians(5.0)
# angle_cov columns: phi phi, theta theta, psi psi, phi theta, phi psi, theta psi
_PACKED = ((0, 3, 4), (3, 1, 5), (4, 5, 2))


def euler_errors(q_est: np.ndarray, q_ref: np.ndarray, six_d: bool = False,
                 mask: Optional[np.ndarray] = None) -> np.ndarray:
    """(N, 3) roll, pitch, yaw errors (rad) of q_est against q_ref (module docstring); 6D: after removing the mean heading offset over mask. NaN where either is NaN."""
    q_est = np.asarray(q_est, dtype=np.float64)
    q_ref = np.asarray(q_ref, dtype=np.float64)
    if six_d:
        off = M.heading_offset(q_est, q_ref, mask)
        if np.isfinite(off):
            q_est = M.quat_mul(M.quat_about_z(-off), q_est)
    ok = np.all(np.isfinite(q_est), axis=-1) & np.all(np.isfinite(q_ref), axis=-1)
    out = np.full(q_est.shape[:-1] + (3,), np.nan)
    out[ok] = M.wrap_pi(M.quat_to_euler(q_est[ok]) - M.quat_to_euler(q_ref[ok]))
    return out


def _cov3(angle_cov: np.ndarray) -> np.ndarray:
    """(N, 6) packed -> (N, 3, 3)."""
    c = np.asarray(angle_cov, dtype=np.float64)
    return np.stack([np.stack([c[:, k] for k in row], axis=-1) for row in _PACKED], axis=-2)


def consistency(q_est: np.ndarray, q_ref: np.ndarray, var: Optional[np.ndarray] = None,
                angle_cov: Optional[np.ndarray] = None, movement: Optional[np.ndarray] = None,
                six_d: bool = False) -> Dict[str, object]:
    """Coverage, mean sigma and NEES (module docstring) of one trial. var: (N, 3) reported
    roll/pitch/yaw variances (rad^2), or angle_cov: (N, 6) the packed covariance (gives the NEES
    too; its diagonal is used when var is None). Returns {'coverage_pct': {angle: %} (within
    3 sigma), 'coverage_k_pct': {k: {angle: %}} (within k sigma, k = 1, 2, 3), 'sigma_deg':
    {angle: deg}, 'nees': float (NaN without angle_cov), 'dof', 'samples'}; yaw is NaN in 6D."""
    n = np.asarray(q_est).shape[0]
    if var is None and angle_cov is None:
        raise ValueError("consistency needs var or angle_cov")
    if var is None:
        var = np.asarray(angle_cov, dtype=np.float64)[:, :3]
    var = np.asarray(var, dtype=np.float64)
    scored = np.ones(n, bool) if movement is None else np.asarray(movement, bool).copy()
    scored &= np.all(np.isfinite(q_est), axis=1) & np.all(np.isfinite(q_ref), axis=1)
    d = euler_errors(q_est, q_ref, six_d, scored)
    pitch = M.quat_to_euler(np.where(np.isfinite(q_est), q_est, 1.0))[:, 1]
    k = 2 if six_d else 3
    scored &= np.all(np.isfinite(var[:, :k]), axis=1) & np.all(var[:, :k] > 0, axis=1)
    cov_k: Dict[int, Dict[str, float]] = {m: {} for m in COVERAGE_NOMINAL_PCT}
    out: Dict[str, object] = {"coverage_pct": cov_k[3], "coverage_k_pct": cov_k, "sigma_deg": {},
                              "nees": float("nan"), "dof": k, "samples": int(scored.sum()), "nees_samples": 0}
    for i, name in enumerate(ANGLES):
        if i >= k or not scored.any():
            for m in cov_k:
                cov_k[m][name] = float("nan")
            out["sigma_deg"][name] = float("nan")
            continue
        sig = np.sqrt(var[scored, i])
        for m in cov_k:
            cov_k[m][name] = float(100.0 * np.mean(np.abs(d[scored, i]) <= m * sig))
        out["sigma_deg"][name] = float(np.degrees(np.mean(sig)))
    use = scored & (np.abs(pitch) < np.pi / 2 - NEES_GIMBAL_MARGIN)
    out["nees_samples"] = int(use.sum())
    if angle_cov is not None and use.any():
        c = _cov3(np.asarray(angle_cov)[use])[:, :k, :k]
        dd = d[use, :k]
        try:
            sol = np.linalg.solve(c, dd[..., None])[..., 0]
            eps = np.einsum("ni,ni->n", dd, sol)
            eps = eps[np.isfinite(eps)]
            out["nees"] = float(np.mean(eps) / k) if eps.size else float("nan")
        except np.linalg.LinAlgError:
            out["nees"] = float("nan")
    return out


def flat(c: Dict[str, object]) -> Dict[str, float]:
    """The per-trial numbers as flat keys (cov_roll, sigma_roll_deg, ..., nees; cov1_roll and
    cov2_roll: within 1 and 2 sigma) for result rows."""
    out = {f"cov_{a}": c["coverage_pct"][a] for a in ANGLES}
    out.update({f"cov{m}_{a}": c["coverage_k_pct"][m][a] for m in (1, 2) for a in ANGLES})
    out.update({f"sigma_{a}_deg": c["sigma_deg"][a] for a in ANGLES})
    out["nees"] = c["nees"]
    return out


def _fin(v) -> bool:
    return v is not None and isinstance(v, (int, float)) and math.isfinite(v)


def aggregate(trials: Dict[str, Dict[str, object]]) -> Dict[str, float]:
    """Over the trial rows of one method: the smallest coverage per angle (the target is
    >= 97 on every trial), the number of trials below 97 % on any angle, mean sigma and mean
    NEES / dof. Empty dict when no row has coverage."""
    rows = [r for r in trials.values() if _fin(r.get("cov_roll"))]
    if not rows:
        return {}
    out: Dict[str, float] = {}
    for a in ANGLES:
        cov = [r[f"cov_{a}"] for r in rows if _fin(r.get(f"cov_{a}"))]
        sig = [r[f"sigma_{a}_deg"] for r in rows if _fin(r.get(f"sigma_{a}_deg"))]
        out[f"cov_min_{a}"] = float(min(cov)) if cov else float("nan")
        out[f"sigma_{a}_deg"] = float(np.mean(sig)) if sig else float("nan")
    out["trials_below_97"] = sum(any(_fin(r.get(f"cov_{a}")) and r[f"cov_{a}"] < 97.0 for a in ANGLES)
                                 for r in rows)
    nees = [r["nees"] for r in rows if _fin(r.get("nees"))]
    out["nees"] = float(np.mean(nees)) if nees else float("nan")
    return out


def _f(v, digits=1) -> str:
    return "-" if not _fin(v) else f"{v:.{digits}f}"


def summary_cells(agg: Dict[str, float]) -> Dict[str, str]:
    """Table cells: 'min cov r/p/y %', 'sigma r/p/y deg', 'NEES/dof'."""
    if not agg:
        return {"cov": "", "sigma": "", "nees": ""}
    return {"cov": "/".join(_f(agg[f"cov_min_{a}"], 0) for a in ANGLES),
            "sigma": "/".join(_f(agg[f"sigma_{a}_deg"], 2) for a in ANGLES),
            "nees": _f(agg["nees"], 2)}


def trial_cells(row: Dict[str, object]) -> str:
    """'cov r/p/y % (sigma r/p/y deg) NEES' of one trial row, '' without coverage."""
    if not _fin(row.get("cov_roll")):
        return ""
    return ("/".join(_f(row.get(f"cov_{a}"), 0) for a in ANGLES) + " ("
            + "/".join(_f(row.get(f"sigma_{a}_deg"), 2) for a in ANGLES) + ") " + _f(row.get("nees"), 2))
