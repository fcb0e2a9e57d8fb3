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
"""

from __future__ import annotations

import fnmatch
import json
import math
import os
import platform
import subprocess
import time
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

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
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
                   f"this EKF {d.upper()}, gyro bias removed using the truth's rest phases "
                   "(ANALYSIS ONLY)", default=False, analysis_only=True, oracle_bias=True,
                   note="ANALYSIS ONLY: gyro bias = mean gyro over the non-movement samples "
                        "(the truth's movement mask), subtracted before filtering; measures "
                        "what the missing gyro-bias state costs, not a result")
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
            else:
                hit = [m for m in base if (m.family == tok and m.default) or fnmatch.fnmatch(m.key, tok)]
            if not hit:
                raise ValueError(f"unknown method '{tok}' (known: {', '.join(known)}; or a family "
                                 "ours/vqf/fusion/madgwick/mahony, 9d, 6d, default, all)")
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
    """ANALYSIS ONLY: mean gyro over the samples the truth marks as not moving (rad/s)."""
    rest = np.ones(len(rec), bool) if rec.movement is None else ~rec.movement.astype(bool)
    if not rest.any():
        return np.zeros(3)
    return rec.gyr[rest].mean(axis=0)


def _run_ours(rec: Recording, m: Method, cfg: RunConfig) -> Tuple[np.ndarray, float, Dict[str, object]]:
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
    if rec.quat_ref is not None:   # does the reported covariance cover the error (consistency.py)
        cov = res.angle_cov.copy()
        cov[~res.aligned] = np.nan
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


def run_method(rec: Recording, m: Method, cfg: RunConfig) -> Tuple[np.ndarray, float, Dict[str, object]]:
    """(quaternions body->ENU (N, 4), seconds of measured computation, extra info)."""
    if m.six_d is False and rec.mag is None:
        raise ValueError(f"{rec.source}: {m.key} needs a magnetometer, the recording has none")
    return RUNNERS[m.family](rec, m, cfg)


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
_REC_CACHE: Dict[str, Recording] = {}


def _recording(path: str) -> Recording:
    if path not in _REC_CACHE:
        _REC_CACHE.clear()          # one trial at a time per worker is enough
        _REC_CACHE[path] = read_recording(path)
    return _REC_CACHE[path]


def run_task(task: Tuple[str, str, RunConfig]) -> Dict[str, object]:
    """One (trial path, method key) pair; the unit of work of the pool (picklable)."""
    path, key, cfg = task
    rec = _recording(path)
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


def aggregate(rows: List[Dict[str, object]], methods: List[Method], trials: List[str],
              group_names: List[str], trial_groups: Dict[str, List[str]]) -> Dict[str, object]:
    """Per method: per-trial rows, mean per group (trials.json) and overall, cost."""
    by = {(r["method"], r["trial"]): r for r in rows}
    out: Dict[str, object] = {}
    for m in methods:
        per = {t: by[(m.key, t)] for t in trials if (m.key, t) in by}
        groups = {}
        for g in group_names:
            members = [t for t in trials if g == "all_trials" or g in trial_groups.get(t, [])]
            if not members:
                continue
            groups[g] = {"n": len(members)}
            for k in M_KEYS:
                groups[g][k] = _mean([per[t][k] for t in members if t in per])
        samples = sum(int(r["samples"]) for r in per.values())
        seconds = sum(float(r["seconds"]) for r in per.values())
        out[m.key] = {
            "trials": per,
            "groups": groups,
            "overall": {k: _mean([r[k] for r in per.values()]) for k in M_KEYS},
            "us_per_sample": 1e6 * seconds / samples if samples else float("nan"),
            "seconds": seconds,
            "samples": samples,
            "consistency": C.aggregate(per),
        }
    return out



def git_info(repo: str) -> Dict[str, object]:
    """Commit and whether the tree has uncommitted changes (read-only git calls)."""
    def git(*args):
        return subprocess.run(["git", "-C", repo, *args], capture_output=True, text=True, timeout=10)
    try:
        head = git("rev-parse", "--short=12", "HEAD")
        status = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "uncommitted_changes": None}
    if head.returncode != 0:
        return {"commit": None, "uncommitted_changes": None}
    changed = [ln[3:] for ln in status.stdout.splitlines() if ln.strip()]
    out = {"commit": head.stdout.strip(), "uncommitted_changes": bool(changed), "changed_files": changed}
    if changed:   # identifies the working tree's state (tracked files) for a later comparison
        import hashlib
        diff = subprocess.run(["git", "-C", repo, "diff", "HEAD"], capture_output=True, timeout=30)
        out["diff_sha256"] = hashlib.sha256(diff.stdout).hexdigest()[:16]
    return out


def machine_info() -> Dict[str, object]:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {"cpu": cpu, "cpus": os.cpu_count(), "python": platform.python_version(),
            "system": platform.platform()}


def package_versions() -> Dict[str, Optional[str]]:
    from importlib import metadata
    out = {}
    for name in ("vqf", "imufusion", "AHRS", "numpy"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


# ---------------------------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------------------------
def clean_json(obj):
    """NaN/inf -> None, numpy scalars -> Python (strict JSON)."""
    if isinstance(obj, dict):
        return {k: clean_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean_json(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def _worker_init() -> None:
    """Pool workers leave Ctrl-C to the parent (which stops the pool and reports once) and
    end quietly on the pool's SIGTERM."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def display_path(path: str) -> str:
    """A path as results name it: relative to the repository when inside it or next to it
    (build/host/..., ../shared/data/broad), so that no machine's directory ends up in docs."""
    full = os.path.abspath(path)
    parent = os.path.dirname(REPO_ROOT)
    if full == REPO_ROOT or full.startswith(REPO_ROOT + os.sep):
        return os.path.relpath(full, REPO_ROOT)
    if full.startswith(parent + os.sep):
        return os.path.relpath(full, REPO_ROOT)
    return path


def run_benchmark(trial_paths: List[str], methods: List[Method], cfg: RunConfig, jobs: int = 1,
                  progress=None, data_dir: Optional[str] = None) -> Dict[str, object]:
    """Runs every method on every trial (a pool of `jobs` processes over (trial, method) pairs)
    and returns the result dictionary (see docs/accuracy.md for its schema)."""
    from . import native
    group_names, trial_groups = load_groups(data_dir or os.path.dirname(trial_paths[0]))
    trials = [os.path.splitext(os.path.basename(p))[0] for p in trial_paths]
    # slow methods first so that the pool does not end on one long task
    order = {"madgwick": 0, "mahony": 0, "fusion": 1, "ours": 2, "vqf": 3}
    tasks = [(p, m.key, cfg) for m in sorted(methods, key=lambda m: order[m.family]) for p in trial_paths]
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
        "results": aggregate(rows, methods, trials, group_names, trial_groups),
    }
    return result
