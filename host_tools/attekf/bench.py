"""Benchmark on real recordings (BROAD): this estimator against VQF, Fusion, Madgwick and Mahony,
on the same trials in one run, scored with the BROAD definitions (metrics.py). Used by
`attekf bench`; docs/accuracy.md holds the latest table and explains the choices below.

Every method returns, per sample, a unit quaternion [w x y z] of the body w.r.t. an ENU earth
frame (the frame of the BROAD truth `opt_quat`), NaN where it has no estimate yet. Ours (the
C estimator through the binding, native.py) is body->ENU already, 9D with the magnetometer, 6D
without, NaN before the filter has aligned. The baselines, their settings, frames and common
start are in baselines.py.

6D scoring: the heading of a magnetometer-free estimate is arbitrary, so the mean heading
offset (circular mean over the scored samples) is removed before scoring
(metrics.orientation_errors(six_d=True)); heading drift still counts.

Cost: wall time of the method's own computation divided by the number of samples, on this
machine. What is timed is stated per method (COST_NOTES): for ours only the C calls, for VQF
its C++ batch call, for Fusion the per-sample Python->C call (so it includes the binding's
per-call overhead), for Madgwick/Mahony ahrs's pure-Python update.

Other rates and dropped samples (RunConfig.transform, transform.py): every method runs on the
same transformed recording. Ours takes the time step of every sample from its timestamps; the
fixed-rate methods get the recording on its nominal grid with missing slots filled
(transform.regular_feed) and are scored on the samples present.

Same trials for every method: a trial a method cannot run (9D without a usable magnetometer:
no imu_mag, or every row NaN) is not run in that dimension, and a trial on which a method gives
no score is left out of every method's mean of that dimension; both are listed in the result
('excluded') and printed under the table.
"""

from __future__ import annotations

import fnmatch
import json
import math
import os
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import consistency as C
from . import metrics as M
from .baselines import (FUSION_BIAS_SETTINGS, FUSION_SETTINGS, GRAVITY, MADGWICK_BETA,  # noqa: F401
                        MAHONY_KI, MAHONY_KP, PACKAGES, Q_NWU_TO_ENU, _run_ahrs, _run_fusion,
                        _run_vqf, enu_to_nwu, initial_quat_enu, nwu_to_enu, quat_from_matrix,
                        start_quat)
from .bench_report import (format_consistency, format_costs, format_markdown, format_summary,  # noqa: F401
                           format_trials, plot_groups)
from .io import Recording, read_recording
from .runinfo import (REPO_ROOT, clean_json, display_path, git_info, machine_info,  # noqa: F401
                      package_versions)
from .transform import Transform, regular_feed
# The BROAD trials: $ATTEKF_BROAD_DIR, else ../shared/data/broad next to this source tree
# (docs/accuracy.md); DEFAULT_DATA_TEXT is how help and docs name it.
DEFAULT_DATA_TEXT = "$ATTEKF_BROAD_DIR, else ../shared/data/broad next to the repository"
DEFAULT_DATA = os.environ.get("ATTEKF_BROAD_DIR") or os.path.normpath(
    os.path.join(REPO_ROOT, "..", "shared", "data", "broad"))
SCHEMA_VERSION = 1
M_KEYS = ("total", "heading", "inclination")

COST_NOTES = {
    "ours": "C calls only (attekf_run over whole blocks, ctypes set-up excluded)",
    "vqf": "one C++ batch call (Cython wrapper) over the recording",
    "fusion": "per-sample Python calls into the C library (Ahrs, and Bias unless fusion-bare; "
              "includes the binding's overhead, ~1 us per call)",
    "madgwick": "pure-Python ahrs update per sample",
    "mahony": "pure-Python ahrs update per sample",
}


# ---------------------------------------------------------------------------------------------
# Methods
# ---------------------------------------------------------------------------------------------
@dataclass
class RunConfig:
    """Everything a worker needs to rebuild the methods (must pickle)."""

    scalar: str = "float"
    settings: Dict[str, float] = field(default_factory=dict)     # ours, for every 'ours' method
    init_samples: int = 10
    variants: Dict[str, Dict[str, object]] = field(default_factory=dict)  # key -> spec (ablations)
    fusion: Dict[str, float] = field(default_factory=lambda: dict(FUSION_SETTINGS))
    rename: Dict[str, str] = field(default_factory=dict)  # ablation setting -> the build's name
    transform: Transform = field(default_factory=Transform)   # rate change / drops (transform.py)


@dataclass
class Method:
    key: str
    family: str                  # ours, vqf, fusion, madgwick, mahony
    six_d: bool
    label: str
    default: bool = True         # part of the default set
    analysis_only: bool = False  # uses ground-truth knowledge: never a result
    settings: Dict[str, float] = field(default_factory=dict)  # ours: changes w.r.t. the run's settings
    oracle_bias: bool = False
    note: str = ""

    @property
    def dim(self) -> str:
        return "6D" if self.six_d else "9D"


BASE_METHODS: List[Method] = [
    Method("ours-9d", "ours", False, "this EKF, 9D (C binding)"),
    Method("ours-6d", "ours", True, "this EKF, 6D (C binding, no magnetometer)"),
    Method("vqf-9d", "vqf", False, "VQF offline 9D"),
    Method("vqf-6d", "vqf", True, "VQF offline 6D"),
    Method("vqf-online-9d", "vqf", False, "VQF online (causal) 9D", default=False),
    Method("vqf-online-6d", "vqf", True, "VQF online (causal) 6D", default=False),
    Method("fusion-9d", "fusion", False, "Fusion (imufusion) 9D, with its gyroscope bias correction"),
    Method("fusion-6d", "fusion", True, "Fusion (imufusion) 6D, with its gyroscope bias correction"),
    Method("fusion-bare-9d", "fusion", False, "Fusion (imufusion) 9D, AHRS alone (no bias correction)",
           default=False),
    Method("fusion-bare-6d", "fusion", True, "Fusion (imufusion) 6D, AHRS alone (no bias correction)",
           default=False),
    Method("madgwick-9d", "madgwick", False, f"Madgwick (ahrs) beta {MADGWICK_BETA} 9D"),
    Method("madgwick-6d", "madgwick", True, f"Madgwick (ahrs) beta {MADGWICK_BETA} 6D", default=False),
    Method("mahony-9d", "mahony", False, f"Mahony (ahrs) Kp {MAHONY_KP} Ki {MAHONY_KI} 9D"),
    Method("mahony-6d", "mahony", True, f"Mahony (ahrs) Kp {MAHONY_KP} Ki {MAHONY_KI} 6D", default=False),
]

BIG = 1.0e5  # "off" for tolerances and gates: never reached (att_settings_check allows up to 1e6;
#              a gate of 0 = off is refused by some builds)

# Ablations of our filter: what each robustness feature is worth (docs/accuracy.md, "What
# limits the model"). (key suffix, settings changes, dims, description). A variant whose
# settings the C library does not know is skipped with a note.
ABLATIONS: List[Tuple[str, Dict[str, float], Tuple[bool, ...], str]] = [
    ("no-accel-deweight", {"accel_band": 0.0}, (False, True), "accelerometer de-weighting off"),
    ("no-accel-reject", {"accel_reject": BIG}, (False, True), "accelerometer rejection off"),
    ("no-accel-gate", {"accel_gate": BIG}, (False, True), "accelerometer innovation gate off"),
    ("no-accel-adapt", {"accel_adapt_tau": 0.0}, (False, True),
     "adaptive accelerometer noise (running linear-acceleration estimate) off"),
    ("no-mag-disturb", {"mag_norm_tol": BIG, "mag_dip_tol": 3.14}, (False,),
     "magnetic disturbance detection (norm/dip) off"),
    ("no-mag-gate", {"mag_gate": BIG}, (False,), "magnetometer innovation gate off"),
    ("no-rest-bias", {"bias_max": 0.0}, (False, True),
     "gyroscope offset learned at rest off (offset clamped to 0)"),
    ("no-robust", {"accel_band": 0.0, "accel_reject": BIG, "accel_gate": BIG, "accel_adapt_tau": 0.0,
                   "mag_norm_tol": BIG, "mag_dip_tol": 3.14, "mag_gate": BIG},
     (False, True), "all of the above off (the rest bias stays)"),
]


def resolve_setting(name: str, known: Sequence[str]) -> Optional[str]:
    """The build's name of an ablation setting: the name itself, or the one known name that
    ends with '_' + name or '.' + name (settings of a sub-struct, e.g. rest_bias_max)."""
    if name in known:
        return name
    hits = [k for k in known if k.endswith("_" + name) or k.endswith("." + name)]
    return hits[0] if len(hits) == 1 else None


def ablation_methods() -> List[Method]:
    out = []
    for suffix, changes, dims, text in ABLATIONS:
        for six in dims:
            d = "6d" if six else "9d"
            out.append(Method(f"ours-{d}:{suffix}", "ours", six, f"this EKF {d.upper()}, {text}",
                              default=False, settings=dict(changes), note=text))
    return out


def oracle_methods() -> List[Method]:
    return [Method(f"ours-{d}:oracle-gyro-bias", "ours", six,
                   f"this EKF {d.upper()}, gyro bias removed using the truth's rest periods "
                   "(ANALYSIS ONLY)", default=False, analysis_only=True, oracle_bias=True,
                   note="ANALYSIS ONLY: gyro bias = mean gyro over the samples at rest by the "
                        "truth's angular rate (rest.py), subtracted before filtering; measures "
                        "what an exact offset would be worth, not a result")
            for six, d in ((False, "9d"), (True, "6d"))]


def variant_method(name: str, changes: Dict[str, float], six_d: bool) -> Method:
    d = "6d" if six_d else "9d"
    text = ", ".join(f"{k}={v:g}" for k, v in changes.items())
    return Method(f"ours-{d}:{name}", "ours", six_d, f"this EKF {d.upper()}, {text}", default=False,
                  settings=dict(changes), note=text)


def all_methods(cfg: Optional[RunConfig] = None) -> Dict[str, Method]:
    """Every known method by key (base, ablations, oracle, the run's custom variants)."""
    out = {m.key: m for m in BASE_METHODS + ablation_methods() + oracle_methods()}
    for key, spec in (cfg.variants if cfg else {}).items():
        out[key] = variant_method(str(spec["name"]), dict(spec["settings"]), bool(spec["six_d"]))
    return out


def select_methods(spec: Optional[str], ablation: bool = False, oracle: bool = False,
                   cfg: Optional[RunConfig] = None) -> List[Method]:
    """Methods from a comma list of keys, families ('ours', 'vqf' ...), dims ('9d', '6d'),
    'default' or 'all' (None: default), plus ablation/oracle variants and custom variants."""
    known = all_methods(cfg)
    base = [m for m in known.values() if m.key in {b.key for b in BASE_METHODS}]
    if not spec or spec == "default":
        chosen = [m for m in base if m.default]
    else:
        chosen = []
        for tok in (t.strip().lower() for t in spec.split(",") if t.strip()):
            if tok == "all":
                hit = base
            elif tok == "default":
                hit = [m for m in base if m.default]
            elif tok in known:
                hit = [known[tok]]
            elif tok in ("9d", "6d"):
                hit = [m for m in base if m.default and m.dim.lower() == tok]
            elif any(m.key in (tok + "-9d", tok + "-6d") for m in base):
                # a family or variant name: both dimensions (vqf-online, fusion-bare, ours, vqf)
                hit = [m for m in base if m.key in (tok + "-9d", tok + "-6d")]
            else:
                hit = [m for m in base if fnmatch.fnmatch(m.key, tok)]
            if not hit:
                raise ValueError(f"unknown method '{tok}' (known: {', '.join(known)}; or a name without "
                                 "its dimension for both: ours, vqf, vqf-online, fusion, fusion-bare, madgwick, "
                                 "mahony; 9d, 6d, default, all)")
            chosen += [m for m in hit if m not in chosen]
    extra = (ablation_methods() if ablation else []) + (oracle_methods() if oracle else [])
    extra += [known[k] for k in (cfg.variants if cfg else {})]
    if extra:
        # variants of our filter are compared with its plain run of the same dimension: keep
        # the dimensions selected (both if none of ours is)
        dims = {m.six_d for m in chosen if m.key in ("ours-9d", "ours-6d")}
        if not dims:
            dims = {False, True}
            chosen += [known["ours-9d"], known["ours-6d"]]
        chosen += [m for m in extra if m.six_d in dims and m.key not in {c.key for c in chosen}]
    return chosen


# ---------------------------------------------------------------------------------------------
# Running one method on one recording
# ---------------------------------------------------------------------------------------------
def oracle_gyro_bias(rec: Recording) -> np.ndarray:
    """ANALYSIS ONLY: mean gyro over the samples the truth shows at rest (rest.py: the truth's
    rate below 2 deg/s for at least 1 s), rad/s; zero without such samples."""
    from .rest import rest_mask
    rest = rest_mask(rec.t, rec.quat_ref) if rec.quat_ref is not None else np.zeros(len(rec), bool)
    if not rest.any():
        return np.zeros(3)
    return rec.gyr[rest].mean(axis=0)


def run_ours_arrays(rec: Recording, m: Method, cfg: RunConfig):
    """Our filter on a recording: (quaternions with NaN before alignment, the reported angle
    covariance (N, 6) likewise NaN, the binding's Result, extra info)."""
    from . import native
    settings = dict(cfg.settings)
    settings.update({cfg.rename.get(k, k): v for k, v in m.settings.items()})
    gyr = rec.gyr
    extra: Dict[str, object] = {}
    if m.oracle_bias:
        bias = oracle_gyro_bias(rec)
        gyr = rec.gyr - bias
        extra["oracle_gyro_bias_rad_s"] = bias.tolist()
    res = native.run_arrays(rec.t, gyr, rec.acc, None if m.six_d else rec.mag, settings, cfg.scalar)
    q = res.quat.copy()
    q[~res.aligned] = np.nan
    cov = res.angle_cov.copy()
    cov[~res.aligned] = np.nan
    return q, cov, res, extra


def _run_ours(rec: Recording, m: Method, cfg: RunConfig) -> Tuple[np.ndarray, float, Dict[str, object]]:
    q, cov, res, extra = run_ours_arrays(rec, m, cfg)
    if rec.quat_ref is not None:   # does the reported covariance cover the error (consistency.py)
        extra.update(C.flat(C.consistency(q, rec.quat_ref, angle_cov=cov,
                                          movement=rec.movement, six_d=m.six_d)))
    summary = res.summary()
    extra["samples_refused"] = summary["samples_refused"]
    extra["not_aligned"] = int((~res.aligned).sum())
    return q, res.c_seconds, extra


def missing_packages(methods: Sequence[Method]) -> Dict[str, str]:
    """method key -> Python package it needs that is not installed."""
    from importlib.util import find_spec
    out = {}
    for m in methods:
        pkg = PACKAGES.get(m.family)
        if pkg and find_spec(pkg) is None:
            out[m.key] = pkg
    return out


RUNNERS: Dict[str, Callable] = {"ours": _run_ours, "vqf": _run_vqf, "fusion": _run_fusion,
                                "madgwick": _run_ahrs, "mahony": _run_ahrs}


def mag_usable(rec: Recording) -> Optional[str]:
    """None if the recording has a magnetometer sample to run 9D on, else why not."""
    if rec.mag is None:
        return "no magnetometer (imu_mag absent)"
    if not np.isfinite(rec.mag).all(axis=1).any():
        return "no magnetometer sample (imu_mag all NaN)"
    return None


def run_method(rec: Recording, m: Method, cfg: RunConfig) -> Tuple[np.ndarray, float, Dict[str, object]]:
    """(quaternions body->ENU (N, 4), seconds of measured computation, extra info). A
    fixed-rate method on a recording with missing samples runs on its regular feed
    (transform.regular_feed) and gives the estimates at the samples present."""
    why = None if m.six_d else mag_usable(rec)
    if why:
        raise ValueError(f"{rec.source}: {m.key} needs a magnetometer: {why}")
    if m.family == "ours":
        return _run_ours(rec, m, cfg)
    feed, slots = regular_feed(rec)
    q, sec, extra = RUNNERS[m.family](feed, m, cfg)
    return (q if slots is None else q[slots]), sec, extra


def score(rec: Recording, q: np.ndarray, six_d: bool) -> Dict[str, object]:
    """BROAD RMSE (deg) of q against the recording's truth over the movement samples."""
    errs = M.orientation_errors(q, rec.quat_ref, rec.movement, six_d=six_d)
    out: Dict[str, object] = dict(errs.rmse_deg())
    out["scored"] = int(errs.scored.sum())
    out["heading_offset_removed_deg"] = float(np.degrees(errs.heading_offset_rad)) if six_d else 0.0
    return out


# ---------------------------------------------------------------------------------------------
# A whole benchmark
# ---------------------------------------------------------------------------------------------
_REC_CACHE: "OrderedDict[tuple, Recording]" = OrderedDict()
_REC_CACHE_SIZE = 4      # recordings kept per worker (a trial at a few rates)


def _recording(path: str, transform: Optional[Transform] = None) -> Recording:
    """The recording of path, transformed; the last few are kept (per worker process)."""
    transform = transform or Transform()
    key = (path, transform)
    if key not in _REC_CACHE:
        rec = read_recording(path)
        _REC_CACHE[key] = rec if transform.identity else transform.apply(rec)
        while len(_REC_CACHE) > _REC_CACHE_SIZE:
            _REC_CACHE.popitem(last=False)
    _REC_CACHE.move_to_end(key)
    return _REC_CACHE[key]


def run_task(task: Tuple[str, str, RunConfig]) -> Dict[str, object]:
    """One (trial path, method key) pair; the unit of work of the pool (picklable)."""
    path, key, cfg = task
    rec = _recording(path, cfg.transform)
    m = all_methods(cfg)[key]
    q, sec, extra = run_method(rec, m, cfg)
    row = score(rec, q, m.six_d)
    row.update(trial=rec.name, method=key, samples=len(rec), seconds=sec, **extra)
    return row


def find_trials(data_dir: str, select: Optional[str] = None, limit: Optional[int] = None) -> List[str]:
    """HDF5 trial files of data_dir, sorted; select: comma list of names, name prefixes (e.g.
    '02,15') or glob patterns; limit: keep the first N."""
    if not os.path.isdir(data_dir):
        raise FileNotFoundError(f"{data_dir}: no such directory (BROAD data; see --data)")
    files = sorted(f for f in os.listdir(data_dir) if f.lower().endswith((".hdf5", ".h5")))
    if not files:
        raise FileNotFoundError(f"{data_dir}: no .hdf5 trials in this directory")
    if select:
        chosen = []
        for tok in (t.strip() for t in select.split(",") if t.strip()):
            hit = [f for f in files if f.startswith(tok) or os.path.splitext(f)[0] == tok
                   or fnmatch.fnmatch(f, tok) or fnmatch.fnmatch(os.path.splitext(f)[0], tok)]
            if not hit:
                raise ValueError(f"--trials {tok}: no trial of {data_dir} matches")
            chosen += [f for f in hit if f not in chosen]
        files = [f for f in files if f in chosen]
    if limit is not None:
        files = files[:max(0, int(limit))]
    return [os.path.join(data_dir, f) for f in files]


def load_groups(data_dir: str) -> Tuple[List[str], Dict[str, List[str]]]:
    """(group names in trials.json order, trial name -> its groups); without trials.json only
    'all_trials'."""
    path = os.path.join(data_dir, "trials.json")
    if not os.path.exists(path):
        return ["all_trials"], {}
    with open(path, encoding="utf-8") as fh:
        info = json.load(fh)
    names = [g["name"] for g in info.get("groups", [])]
    return names, {t: list(v.get("groups", [])) for t, v in info.get("trials", {}).items()}


def _mean(vals: Sequence[float]) -> float:
    vals = [v for v in vals if v is not None and math.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")


def common_trials(rows: List[Dict[str, object]], methods: List[Method], trials: List[str],
                  not_run: Optional[Dict[Tuple[str, str], str]] = None
                  ) -> Tuple[Dict[str, List[str]], List[Dict[str, str]]]:
    """({dim: the trials every method of that dimension has a finite score on}, [{trial, dim,
    reason} for each trial left out of a dimension's means]). not_run: (trial, dim) -> why the
    dimension was not run on the trial."""
    by = {(r["method"], r["trial"]): r for r in rows}
    not_run = not_run or {}
    used: Dict[str, List[str]] = {}
    excluded: List[Dict[str, str]] = []
    for dim in ("9D", "6D"):
        keys = [m.key for m in methods if m.dim == dim]
        if not keys:
            continue
        used[dim] = []
        for t in trials:
            bad = [k for k in keys if not (k, t) in by or not _finite(by[(k, t)].get("total"))]
            if not bad:
                used[dim].append(t)
            elif (t, dim) in not_run:
                excluded.append({"trial": t, "dim": dim, "reason": f"not run: {not_run[(t, dim)]}"})
            else:
                excluded.append({"trial": t, "dim": dim, "reason": f"no score from {', '.join(bad)}"})
    return used, excluded


def _finite(v) -> bool:
    return isinstance(v, (int, float, np.floating)) and math.isfinite(v)


def aggregate(rows: List[Dict[str, object]], methods: List[Method], trials: List[str],
              group_names: List[str], trial_groups: Dict[str, List[str]]) -> Dict[str, object]:
    """Per method: per-trial rows, mean per group (trials.json) and overall over the trials
    every method of its dimension has scored (common_trials), cost."""
    by = {(r["method"], r["trial"]): r for r in rows}
    used, _ = common_trials(rows, methods, trials)
    out: Dict[str, object] = {}
    for m in methods:
        per = {t: by[(m.key, t)] for t in trials if (m.key, t) in by}
        common = used.get(m.dim, [])
        groups = {}
        for g in group_names:
            members = [t for t in common if g == "all_trials" or g in trial_groups.get(t, [])]
            if not members:
                continue
            groups[g] = {"n": len(members)}
            for k in M_KEYS:
                groups[g][k] = _mean([per[t][k] for t in members])
        samples = sum(int(r["samples"]) for r in per.values())
        seconds = sum(float(r["seconds"]) for r in per.values())
        out[m.key] = {
            "trials": per,
            "groups": groups,
            "overall": {k: _mean([per[t][k] for t in common]) for k in M_KEYS},
            "n_trials": len(common),
            "us_per_sample": 1e6 * seconds / samples if samples else float("nan"),
            "seconds": seconds,
            "samples": samples,
            "consistency": C.aggregate({t: per[t] for t in common}),
        }
    return out


def _worker_init() -> None:
    """Pool workers leave Ctrl-C to the parent (which stops the pool and reports once) and
    end quietly on the pool's SIGTERM."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def run_benchmark(trial_paths: List[str], methods: List[Method], cfg: RunConfig, jobs: int = 1,
                  progress=None, data_dir: Optional[str] = None) -> Dict[str, object]:
    """Runs every method on every trial (a pool of `jobs` processes over (trial, method) pairs)
    and returns the result dictionary (see docs/accuracy.md for its schema)."""
    from . import native
    group_names, trial_groups = load_groups(data_dir or os.path.dirname(trial_paths[0]))
    trials = [os.path.splitext(os.path.basename(p))[0] for p in trial_paths]
    # 9D is not run on a trial without a usable magnetometer (listed, left out of the 9D means)
    not_run: Dict[Tuple[str, str], str] = {}
    for p, t in zip(trial_paths, trials):
        why = mag_usable(read_recording(p))
        if why and any(not m.six_d for m in methods):
            not_run[(t, "9D")] = why
    # slow methods first so that the pool does not end on one long task
    order = {"madgwick": 0, "mahony": 0, "fusion": 1, "ours": 2, "vqf": 3}
    tasks = [(p, m.key, cfg) for m in sorted(methods, key=lambda m: order[m.family])
             for p, t in zip(trial_paths, trials) if (t, m.dim) not in not_run]
    tasks.sort(key=lambda t: (order[all_methods(cfg)[t[1]].family], t[0]))
    rows: List[Dict[str, object]] = []
    t_wall = time.perf_counter()
    if jobs > 1 and len(tasks) > 1:
        import multiprocessing as mp
        with mp.get_context("fork").Pool(jobs, initializer=_worker_init) as pool:
            for row in pool.imap_unordered(run_task, tasks, chunksize=1):
                rows.append(row)
                if progress:
                    progress(1)
    else:
        for task in tasks:
            rows.append(run_task(task))
            if progress:
                progress(1)
    wall = time.perf_counter() - t_wall
    ours_settings = None
    if any(m.family == "ours" for m in methods):
        ours_settings = native.default_settings(cfg.scalar)
        ours_settings.update(cfg.settings)
    result = {
        "schema": SCHEMA_VERSION,
        "git": git_info(REPO_ROOT),
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "data_dir": display_path(data_dir or os.path.dirname(trial_paths[0])),
        "trials": trials,
        "group_names": group_names,
        "scoring": {"error": "e = q_est * inv(q_ref) (earth frame)", "total": "2 acos|e_w|",
                    "heading": "2 atan|e_z/e_w|", "inclination": "2 acos sqrt(e_w^2 + e_z^2)",
                    "rmse_over": "movement samples with truth and estimate", "unit": "deg",
                    "aggregate": "mean over the trials of a group",
                    "six_d": "mean heading offset (circular mean over scored samples) removed first"},
        "methods": {m.key: {"label": m.label, "family": m.family, "dim": m.dim,
                            "heading_offset_removed": m.six_d, "analysis_only": m.analysis_only,
                            "settings_changed": {cfg.rename.get(k, k): v for k, v in m.settings.items()}
                            or None, "note": m.note or None,
                            "cost_measured": COST_NOTES[m.family]} for m in methods},
        "ours": {"scalar": cfg.scalar, "settings": ours_settings, "settings_changed": dict(cfg.settings)},
        "baselines": {"madgwick": {"beta": MADGWICK_BETA, "frame": "NWU -> ENU by qz(90 deg)"},
                      "mahony": {"kp": MAHONY_KP, "ki": MAHONY_KI, "frame": "ENU"},
                      "fusion": dict(cfg.fusion, convention="ENU",
                                     bias="imufusion.Bias in front of the AHRS (fusion-bare-*: none)"),
                      "vqf": {"params": "defaults", "offline": True},
                      "init": f"mean acc/mag of the first {cfg.init_samples} samples "
                              "(Madgwick, Mahony, Fusion); VQF and ours initialise themselves"},
        "library": (display_path(str(native.load(cfg.scalar).path)) if any(m.family == "ours" for m in methods)
                    else None),
        "packages": package_versions(),
        "machine": dict(machine_info(), jobs=jobs),
        "wall_seconds": wall,
        "transform": {"decimate": cfg.transform.decimate, "resample_hz": cfg.transform.resample_hz,
                      "drop": cfg.transform.drop, "seed": cfg.transform.seed,
                      "drop_gyro": cfg.transform.drop_gyro,
                      "label": cfg.transform.label()},
        "excluded": common_trials(rows, methods, trials, not_run)[1],
        "results": aggregate(rows, methods, trials, group_names, trial_groups),
    }
    return result
