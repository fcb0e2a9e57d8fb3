"""Leave-one-group-out cross-validation of the estimator's settings on BROAD (`attekf cv`;
docs/accuracy.md, "Tuning protocol").

Folds. Every trial of trials.json belongs to exactly one of FOLD_ORDER (its kind of motion when
undisturbed, its kind of disturbance otherwise): the folds partition the trials, so every
trial is left out exactly once. On the 22 trials at hand: rotation (5), translation (7),
tapping (2), vibration (1), stationary_magnet (2), attached_magnet (5).

Accuracy settings. A small grid over the settings that set the filter's time constants
(DEFAULT_GRID). Every grid point runs once on every trial, 9D and 6D (6D runs are shared by
points that differ only in magnetometer settings). For each fold the point with the lowest
training objective is chosen: the mean over the other folds' trials of (9D total RMSE + 6D
total RMSE) / 2, averaged over the point and its neighbours along each axis (a point on a plateau beats
a sharp optimum of the same depth). The left-out trials are scored with that point: the
cross-validated figure of each trial comes from settings chosen without it.

Reported-covariance settings. They change no estimate, only the reported covariance
(att_consider.h and the reference terms), and they describe the device and the place, not the
motion: the gyroscope's scale and misalignment errors (angle_walk_rate), the accelerometer's
alignment (accel_ref_sigma), the local field's direction error (mag_ref_sigma). A trial left
out can differ from every training trial in exactly these (BROAD trial 27's field points
4.5 deg away from the optical reference's north, the other trials' within about 1 deg), so they
are not chosen from the data: the left-out trials' coverage is reported at the shipped values
(or --set ones). With tune_covariance (`--tune-covariance`) each fold instead takes the cheapest
combination of CONSIDER_GRID (smallest mean reported sigma) that gives >= 97 % coverage on every
angle of every training trial, 9D and 6D; that shows what tuning them would cost. The reported
covariance is P + V Pb V^T + colored term + k^2 R1 + reference terms, exactly linear in
k^2 = angle_walk_rate^2: two runs per trial (k = 0 and k = K0) give every combination.

The settings that ship are the choice on all trials (the in-sample figure, printed beside).

Rates. With several transforms (`--decimate 1,3`, `--resample 1000`; transform.py) every run is
made at each of them and a trial's score is the mean of its scores over them (its coverage the
lowest over them), so that the chosen settings serve every rate; the folds are unchanged.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import bench as B
from . import bench_report as R
from . import consistency as C
from .transform import Transform

FOLD_ORDER = ("rotation", "translation", "combined", "tapping", "vibration", "stationary_magnet",
              "attached_magnet", "office_environment", "mixed")

# name, grid values. accel_noise: weight of the accelerometer (the tilt correction's time
# constant; a density, m/s^2 sqrt(s)); accel_lpf_tau: the low-pass's time constant
# (linear-acceleration averaging against the lag of the rate compensation); mag_heading_noise:
# weight of the magnetometer (the heading correction's time constant against averaging of
# field errors; rad sqrt(s)); bias.walk: how fast the offset learned in motion may change
# (att_bias.h).
DEFAULT_GRID: List[Tuple[str, List[float]]] = [
    ("accel_noise", [0.03, 0.0414, 0.055]),
    ("accel_lpf_tau", [0.7, 1.0, 1.4]),
    ("mag_heading_noise", [0.01, 0.015, 0.022]),
    ("bias.walk", [3e-5, 6.7e-5, 1.5e-4]),
]
MAG_ONLY = ("mag_heading_noise", "mag_gate", "mag_norm_tol", "mag_dip_tol", "mag_reset_time")

K0 = 0.002  # angle_walk_rate of the second consider run, sqrt(s)
CONSIDER_GRID: Dict[str, List[float]] = {
    "angle_walk_rate": [0.0, 0.001, 0.0015, 0.002, 0.003],
    "accel_ref_sigma": [0.0, 0.0025, 0.005, 0.0075],
    "mag_ref_sigma": [0.0, 0.02, 0.03, 0.04, 0.05, 0.06],
}
COVERAGE_TARGET = 97.0
HEADING_LIMITED = 1 << 10  # ATT_FLAG_HEADING_LIMITED (att.h): no magnetic heading reference


def folds(trials: Sequence[str], trial_groups: Dict[str, List[str]]) -> Dict[str, List[str]]:
    """fold name -> its trials (FOLD_ORDER order). ValueError naming a trial in no fold."""
    out: Dict[str, List[str]] = {}
    for t in trials:
        hit = [g for g in FOLD_ORDER if g in trial_groups.get(t, [])]
        if not hit:
            raise ValueError(f"trials.json: trial {t} is in none of the fold groups ({', '.join(FOLD_ORDER)})")
        out.setdefault(hit[0], []).append(t)
    return {g: out[g] for g in FOLD_ORDER if g in out}


# ---------------------------------------------------------------------------------------------
# Workers (top level: they are pickled into the pool)
# ---------------------------------------------------------------------------------------------
def _accuracy_task(task):
    path, settings, six_d, scalar, tf = task
    from . import native
    rec = B._recording(path, tf)
    res = native.run_arrays(rec.t, rec.gyr, rec.acc, None if six_d else rec.mag, settings, scalar)
    q = res.quat.copy()
    q[~res.aligned] = np.nan
    row = B.score(rec, q, six_d)
    return rec.name, {k: row[k] for k in B.M_KEYS}


def _consider_task(task):
    """Coverage and mean sigma of every CONSIDER_GRID combination on one trial and dimension."""
    path, settings, six_d, scalar, tf = task
    from . import native
    rec = B._recording(path, tf)
    runs = []
    for k in (0.0, K0):
        s = dict(settings, angle_walk_rate=k, accel_ref_sigma=0.0, mag_ref_sigma=0.0)
        runs.append(native.run_arrays(rec.t, rec.gyr, rec.acc, None if six_d else rec.mag, s, scalar))
    q = runs[0].quat.copy()
    q[~runs[0].aligned] = np.nan
    mag_ref = ((runs[0].flags & HEADING_LIMITED) == 0).astype(float)
    scored = rec.movement.astype(bool) & np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(rec.quat_ref), axis=1)
    d = C.euler_errors(q, rec.quat_ref, six_d, scored)
    dof = 2 if six_d else 3
    # (before the alignment the covariances are NaN: only the scored samples are compared)
    base = runs[0].angle_cov[scored]
    r1 = (runs[1].angle_cov[scored] - base) / K0 ** 2
    d, mag_ref = d[scored, :dof], mag_ref[scored]
    table = {}
    for k, sa, sm in itertools.product(*CONSIDER_GRID.values()):
        var = base[:, :3] + k * k * r1[:, :3]
        var[:, 0] += sa * sa
        var[:, 1] += sa * sa
        var[:, 2] += sm * sm * mag_ref
        sig = np.sqrt(np.maximum(var[:, :dof], 1e-30))
        table[(k, sa, sm)] = ([float(100.0 * np.mean(np.abs(d[:, i]) <= 3 * sig[:, i])) for i in range(dof)],
                              [float(np.degrees(np.mean(sig[:, i]))) for i in range(dof)])
    return rec.name, table


def _pool_map(fn, tasks, jobs, progress):
    out = []
    if jobs > 1 and len(tasks) > 1:
        import multiprocessing as mp
        with mp.get_context("fork").Pool(jobs, initializer=B._worker_init) as pool:
            for r in pool.imap(fn, tasks, chunksize=1):
                out.append(r)
                if progress:
                    progress(1)
    else:
        for t in tasks:
            out.append(fn(t))
            if progress:
                progress(1)
    return out


# ---------------------------------------------------------------------------------------------
# Selection
# ---------------------------------------------------------------------------------------------
def objective(scores9: Dict[str, Dict[str, float]], scores6: Dict[str, Dict[str, float]],
              trials: Sequence[str]) -> float:
    """Mean over trials of (9D total + 6D total) / 2, deg."""
    return float(np.mean([(scores9[t]["total"] + scores6[t]["total"]) / 2.0 for t in trials]))


def smoothed(values: Dict[Tuple[int, ...], float], shape: Tuple[int, ...]) -> Dict[Tuple[int, ...], float]:
    """Each grid point's value averaged with its neighbours along each axis (index +-1 on one
    axis at a time, the points that exist). Not the whole box of +-1 on every axis: in four
    dimensions that averages up to 81 points, and a corner (16 of them, all inward) is then
    favoured over any interior point."""
    out = {}
    for idx in values:
        nb = [idx]
        for a in range(len(shape)):
            for o in (-1, 1):
                n = tuple(i + (o if b == a else 0) for b, i in enumerate(idx))
                if 0 <= n[a] < shape[a]:
                    nb.append(n)
        out[idx] = float(np.mean([values[n] for n in nb]))
    return out


def shipped_covariance(defaults: Dict[str, float], base: Dict[str, float]) -> tuple:
    """The reported-covariance settings as CONSIDER_GRID values (in its order): the build's
    defaults, or base's (--set) ones; each must be one of the grid's values (to a float's
    rounding), else ValueError naming it."""
    out = []
    for name, values in CONSIDER_GRID.items():
        v = float(base[name] if name in base else defaults[name])
        near = [g for g in values if abs(g - v) <= 1e-6 * max(abs(g), 1e-9)]
        if not near:
            raise ValueError(f"{name} = {v:g}: not one of the reported-covariance grid's values "
                             f"{', '.join(f'{g:g}' for g in values)} (host_tools/attekf/cv.py, CONSIDER_GRID)")
        out.append(near[0])
    return tuple(out)


def choose_consider(tables: Dict[Tuple[str, bool], Dict[tuple, tuple]], trials: Sequence[str]) -> tuple:
    """The combination with the smallest mean sigma (over the trials' angles) among those with
    every trial's coverage >= COVERAGE_TARGET on every angle; if none reaches it, the one with
    the largest worst coverage."""
    combos = list(next(iter(tables.values())).keys())
    best, best_key = None, None
    for cb in combos:
        covs = [c for t in trials for six in (False, True) for c in tables[(t, six)][cb][0]]
        sigs = [s for t in trials for six in (False, True) for s in tables[(t, six)][cb][1]]
        ok = min(covs) >= COVERAGE_TARGET
        key = (0 if ok else 1, float(np.mean(sigs)) if ok else -min(covs))
        if best_key is None or key < best_key:
            best, best_key = cb, key
    return best


# ---------------------------------------------------------------------------------------------
# The whole protocol
# ---------------------------------------------------------------------------------------------
def _per_trial_mean(rows: List[Tuple[str, Dict[str, float]]]) -> Dict[str, Dict[str, float]]:
    """(trial, scores) rows, a trial once per transform -> trial: scores averaged over them."""
    by: Dict[str, List[Dict[str, float]]] = {}
    for name, sc in rows:
        by.setdefault(name, []).append(sc)
    return {t: {k: float(np.mean([sc[k] for sc in v])) for k in v[0]} for t, v in by.items()}


def _merge_tables(tables: List[Dict[tuple, tuple]]) -> Dict[tuple, tuple]:
    """Coverage tables of one trial at several transforms -> the lowest coverage and the mean
    sigma per angle, per combination."""
    out = {}
    for cb in tables[0]:
        covs = [tb[cb][0] for tb in tables]
        sigs = [tb[cb][1] for tb in tables]
        out[cb] = ([min(c[i] for c in covs) for i in range(len(covs[0]))],
                   [float(np.mean([s[i] for s in sigs])) for i in range(len(sigs[0]))])
    return out


def run_cv(paths: List[str], data_dir: str, grid: List[Tuple[str, List[float]]], base: Dict[str, float],
           scalar: str = "float", jobs: int = 1, progress=None, log=None,
           transforms: Sequence[Transform] = (Transform(),), tune_covariance: bool = False,
           covariance_values: Optional[tuple] = None) -> Dict[str, object]:
    """Runs the protocol of the module docstring at each of `transforms` (a trial's score: the
    mean over them); returns the result dictionary (JSON-able after clean_json).
    covariance_values: the CONSIDER_GRID settings' values when they are not tuned (in
    CONSIDER_GRID's order; each must be one of its grid values)."""
    log = log or (lambda msg: None)
    tfs = list(transforms)
    group_names, trial_groups = B.load_groups(data_dir)
    trials = [os.path.splitext(os.path.basename(p))[0] for p in paths]
    by_name = dict(zip(trials, paths))
    fold_of = folds(trials, trial_groups)
    names = [g[0] for g in grid]
    shape = tuple(len(g[1]) for g in grid)
    points = list(itertools.product(*[range(n) for n in shape]))

    def settings_of(idx, six_d):
        s = dict(base)
        s.update({names[a]: grid[a][1][i] for a, i in enumerate(idx) if not (six_d and names[a] in MAG_ONLY)})
        return s

    # 1. every grid point on every trial (6D runs shared across magnetometer-only settings)
    keys9 = {idx: idx for idx in points}
    keys6 = {idx: tuple(i if names[a] not in MAG_ONLY else 0 for a, i in enumerate(idx)) for idx in points}
    jobs_list = [(k, False) for k in sorted(set(keys9.values()))] + [(k, True) for k in sorted(set(keys6.values()))]
    tasks = [(by_name[t], settings_of(k, six), six, scalar, tf) for k, six in jobs_list for t in trials
             for tf in tfs]
    log(f"accuracy grid: {len(points)} points, {len(tasks)} runs")
    res = _pool_map(_accuracy_task, tasks, jobs, progress)
    runs: Dict[Tuple[tuple, bool], Dict[str, Dict[str, float]]] = {}
    size = len(trials) * len(tfs)
    for (k, six), chunk in zip(jobs_list, [res[i:i + size] for i in range(0, len(res), size)]):
        runs[(k, six)] = _per_trial_mean(chunk)
    s9 = {idx: runs[(keys9[idx], False)] for idx in points}
    s6 = {idx: runs[(keys6[idx], True)] for idx in points}

    def pick(train):
        j = {idx: objective(s9[idx], s6[idx], train) for idx in points}
        sm = smoothed(j, shape)
        return min(points, key=lambda idx: (sm[idx], j[idx])), j, sm

    # 2. per fold: choose on the others, score the left-out trials
    chosen: Dict[str, tuple] = {}
    cv9: Dict[str, Dict[str, float]] = {}
    cv6: Dict[str, Dict[str, float]] = {}
    for fold, members in fold_of.items():
        train = [t for t in trials if t not in members]
        idx, _, _ = pick(train)
        chosen[fold] = idx
        for t in members:
            cv9[t] = s9[idx][t]
            cv6[t] = s6[idx][t]
    full, j_all, sm_all = pick(trials)

    # 3. the reported-covariance settings, at every accuracy point any fold chose
    consider_points = sorted(set(chosen.values()) | {full})
    ctasks = [(by_name[t], settings_of(idx, six), six, scalar, tf) for idx in consider_points for six in (False, True)
              for t in trials for tf in tfs]
    log(f"reported covariance: {len(consider_points)} accuracy point(s), {len(ctasks)} runs")
    cres = _pool_map(_consider_task, ctasks, jobs, progress)
    ctab: Dict[tuple, Dict[Tuple[str, bool], dict]] = {}
    i = 0
    for idx in consider_points:
        for six in (False, True):
            for t in trials:
                chunk = cres[i:i + len(tfs)]
                ctab.setdefault(idx, {})[(chunk[0][0], six)] = _merge_tables([tb for _, tb in chunk])
                i += len(tfs)
    cons_chosen: Dict[str, tuple] = {}
    cv_cov: Dict[Tuple[str, bool], tuple] = {}
    if not tune_covariance and covariance_values is None:
        from .native import default_settings
        covariance_values = shipped_covariance(default_settings(scalar), base)
    for fold, members in fold_of.items():
        train = [t for t in trials if t not in members]
        cb = choose_consider(ctab[chosen[fold]], train) if tune_covariance else covariance_values
        cons_chosen[fold] = cb
        for t in members:
            for six in (False, True):
                cv_cov[(t, six)] = ctab[chosen[fold]][(t, six)][cb]
    cons_full = choose_consider(ctab[full], trials) if tune_covariance else covariance_values
    in_cov = {(t, six): ctab[full][(t, six)][cons_full] for t in trials for six in (False, True)}

    # 4. sensitivity around the in-sample choice: the all-trials objective along each axis
    sens = {}
    for a, name in enumerate(names):
        prof = []
        for i, v in enumerate(grid[a][1]):
            idx = tuple(i if b == a else full[b] for b in range(len(names)))
            prof.append({"value": v, "objective": j_all[idx], "smoothed": sm_all[idx],
                         "total_9d": float(np.mean([s9[idx][t]["total"] for t in trials])),
                         "total_6d": float(np.mean([s6[idx][t]["total"] for t in trials]))})
        sens[name] = prof

    def point_settings(idx):
        return {names[a]: grid[a][1][i] for a, i in enumerate(idx)}

    def cons_settings(cb):
        return dict(zip(CONSIDER_GRID.keys(), cb))

    return {
        "trials": trials, "group_names": group_names, "trial_groups": {t: trial_groups.get(t, []) for t in trials},
        "folds": fold_of, "grid": {n: v for n, v in grid}, "base_settings": base, "scalar": scalar,
        "rates": [tf.label() for tf in tfs],
        "consider_grid": CONSIDER_GRID, "covariance_tuned": tune_covariance,
        "chosen": {f: {"accuracy": point_settings(idx), "reported_covariance": cons_settings(cons_chosen[f])}
                   for f, idx in chosen.items()},
        "in_sample": {"accuracy": point_settings(full), "reported_covariance": cons_settings(cons_full)},
        "cv": {"9d": cv9, "6d": cv6}, "in": {"9d": s9[full], "6d": s6[full]},
        "coverage_cv": {f"{t}|{'6d' if six else '9d'}": v for (t, six), v in cv_cov.items()},
        "coverage_in": {f"{t}|{'6d' if six else '9d'}": v for (t, six), v in in_cov.items()},
        "sensitivity": sens,
        "points": [{"settings": point_settings(idx), "objective_all": j_all[idx], "smoothed_all": sm_all[idx],
                    "total_9d": {t: s9[idx][t]["total"] for t in trials},
                    "total_6d": {t: s6[idx][t]["total"] for t in trials}} for idx in points],
    }


# ---------------------------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------------------------
def _mean(vals):
    vals = [v for v in vals if v is not None and math.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")


def _f(v, d=2):
    return "n/a" if v is None or not math.isfinite(v) else f"{v:.{d}f}"


def format_report(r: Dict[str, object], vqf: Optional[Dict[str, Dict[str, Dict[str, float]]]] = None) -> str:
    """Text tables: choices per fold, overall and per group (CV and in-sample, VQF beside when
    given), coverage per trial, sensitivity."""
    trials = r["trials"]
    lines = ["Leave-one-group-out cross-validation (folds: " + ", ".join(f"{f} ({len(m)})" for f, m in r["folds"].items())
             + ")"]
    if r.get("rates", ["native"]) != ["native"]:
        lines.append("at the rates: " + ", ".join(r["rates"]) + " (each trial's score: the mean over them; its "
                     "coverage: the lowest)")
    lines += ["", "chosen on the other folds:"]
    for f, ch in r["chosen"].items():
        lines.append(f"  without {f:18s} " + ", ".join(f"{k}={v:g}" for k, v in ch["accuracy"].items()) + "; "
                     + ", ".join(f"{k}={v:g}" for k, v in ch["reported_covariance"].items()))
    ins = r["in_sample"]
    lines.append(f"  all trials (in-sample)     " + ", ".join(f"{k}={v:g}" for k, v in ins["accuracy"].items()) + "; "
                 + ", ".join(f"{k}={v:g}" for k, v in ins["reported_covariance"].items()))
    if not r.get("covariance_tuned", True):
        lines.append("  (reported-covariance settings not tuned: the shipped or --set values in every fold; "
                     "--tune-covariance chooses them)")
    lines.append("")
    head = ["", "total", "heading", "incl.", "trials worse than VQF (total)"]
    rows = []
    for dim in ("9d", "6d"):
        for label, src in (("CV", r["cv"][dim]), ("in-sample", r["in"][dim])):
            worse = "" if vqf is None else str(sum(src[t]["total"] > vqf[dim][t]["total"] for t in trials))
            rows.append([f"ours-{dim} {label}"] + [_f(_mean([src[t][k] for t in trials])) for k in B.M_KEYS] + [worse])
        if vqf is not None:
            rows.append([f"vqf-{dim} (offline)"] + [_f(_mean([vqf[dim][t][k] for t in trials])) for k in B.M_KEYS] + [""])
    lines += ["mean RMSE over the trials, deg:"] + R._table(head, rows)
    groups = [g for g in r["group_names"] if any(g == "all_trials" or g in r["trial_groups"][t] for t in trials)]
    lines += ["", "total RMSE per group (deg): CV / in-sample" + (" / VQF offline" if vqf else "")]
    ghead = ["group (n)", "9D", "6D"]
    grows = []
    for g in groups:
        mem = [t for t in trials if g == "all_trials" or g in r["trial_groups"][t]]
        cells = [f"{g} ({len(mem)})"]
        for dim in ("9d", "6d"):
            vals = [_mean([r["cv"][dim][t]["total"] for t in mem]), _mean([r["in"][dim][t]["total"] for t in mem])]
            if vqf is not None:
                vals.append(_mean([vqf[dim][t]["total"] for t in mem]))
            cells.append(" / ".join(_f(v) for v in vals))
        grows.append(cells)
    lines += R._table(ghead, grows)
    lines += ["", "coverage within 3 sigma, roll/pitch/yaw % (mean sigma deg), CV | in-sample:"]
    chead = ["trial", "9D CV", "9D in-sample", "6D CV", "6D in-sample"]
    crows = []
    for t in trials:
        cells = [t]
        for dim in ("9d", "6d"):
            for src in ("coverage_cv", "coverage_in"):
                cov, sig = r[src][f"{t}|{dim}"]
                cells.append("/".join(f"{c:.1f}" for c in cov) + " (" + "/".join(f"{s:.2f}" for s in sig) + ")")
        crows.append(cells)
    lines += R._table(chead, crows)
    for src, label in (("coverage_cv", "CV"), ("coverage_in", "in-sample")):
        for dim in ("9d", "6d"):
            vals = [r[src][f"{t}|{dim}"] for t in trials]
            lo = [min(c[i] for c, _ in vals) for i in range(len(vals[0][0]))]
            ms = [_mean([s[i] for _, s in vals]) for i in range(len(vals[0][1]))]
            below = sum(min(c) < COVERAGE_TARGET for c, _ in vals)
            lines.append(f"  {label:9s} {dim}: worst coverage " + "/".join(f"{x:.1f}" for x in lo) + " %, mean sigma "
                         + "/".join(f"{x:.2f}" for x in ms) + f" deg, trials below {COVERAGE_TARGET:g} %: {below}")
    lines += ["", "sensitivity (all trials, the other settings at the all-trials choice): objective = mean (9D + 6D) / 2"]
    for name, prof in r["sensitivity"].items():
        lines.append(f"  {name}: " + "  ".join(f"{p['value']:g}: {p['objective']:.3f} ({p['total_9d']:.2f}/{p['total_6d']:.2f})"
                                             for p in prof))
    return "\n".join(lines)


def vqf_scores(paths: List[str], jobs: int = 1, progress=None,
               transforms: Sequence[Transform] = (Transform(),)) -> Dict[str, Dict[str, Dict[str, float]]]:
    """VQF offline 9D / 6D per trial (the same runs as `attekf bench`), the mean over the
    transforms."""
    tasks = [(p, key, B.RunConfig(transform=tf)) for key in ("vqf-9d", "vqf-6d") for p in paths for tf in transforms]
    rows = _pool_map(B.run_task, tasks, jobs, progress)
    out: Dict[str, Dict[str, Dict[str, float]]] = {}
    for dim in ("9d", "6d"):
        out[dim] = _per_trial_mean([(r["trial"], {k: r[k] for k in B.M_KEYS}) for r in rows
                                    if r["method"].endswith(dim)])
    return out


def save(path: str, r: Dict[str, object]) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(B.clean_json(r), fh, indent=1, allow_nan=False)
        fh.write("\n")
