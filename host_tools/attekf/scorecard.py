"""The robustness scorecard (`attekf robustness`): issue 22's targets measured side by side with
VQF in one run, each row with its target and pass/miss. The measures are in robustness.py,
the recordings come from BROAD (transform.py for other rates and drops) and from
scenarios.py; docs/accuracy.md, "How the robustness targets are measured", defines every row.

Parts (PARTS): rates (BROAD at 1/1, 1/2, 1/3, 1/4 of its rate and resampled to 1000 Hz),
flips and tumbles (Monte Carlo at MC_RATES x MC_PEAKS), post-motion (inclination after motion
stops, BROAD at its own rate), glitch, drops (BROAD trial DROP_TRIAL), gap. Every run is one
task of a process pool; every task is a pure function of its arguments (seeds included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from . import bench as B
from . import consistency as C
from . import robustness as R
from . import scenarios as S
from .rest import post_motion_windows
from .transform import Transform

PARTS = ("rates", "flips", "tumbles", "post-motion", "glitch", "drops", "gap")
RATE_TRANSFORMS = (Transform(decimate=1), Transform(decimate=2), Transform(decimate=3), Transform(decimate=4),
                   Transform(resample_hz=1000.0))
SAME_AS_NATIVE = (Transform(decimate=3), 0.3)     # ours at 1/3 of the rate within 0.3 deg of ours native
MC_RATES = (100.0, 200.0, 500.0)
MC_PEAKS = (360.0, 720.0)
MC_APPROACH_MAX_DEG = 5.0
GLITCH_DEG = (20.0, 60.0, 120.0)
GLITCH_RATE_HZ = 100.0
SEEDS = 5                                         # glitch and gap runs (random axes)
GAP = {"rate_hz": 100.0, "peak_rate_deg_s": 180.0, "gap_s": 0.3}
GAP_LATER_S = 20.0
DROP = {"drop": 0.05, "seed": 1}
DROP_TRIAL = "07_undisturbed_fast_rotation_B"
TARGETS = {"heading_p90": 1.0, "heading_max": 3.0, "peak_9d": 5.0, "coverage": 97.0}

OURS = ("ours-9d", "ours-6d")
ONLINE = ("vqf-online-9d", "vqf-online-6d")
OFFLINE = ("vqf-9d", "vqf-6d")


@dataclass
class Plan:
    """What one run of the scorecard does."""

    trials: List[str] = field(default_factory=list)        # BROAD trial paths (rates, post-motion)
    drop_trial: Optional[str] = None                        # path of the drops trial
    parts: Tuple[str, ...] = PARTS
    mc: int = 20                                            # flips / tumbles per cell
    cfg: B.RunConfig = field(default_factory=B.RunConfig)  # our settings, scalar


# ---------------------------------------------------------------------------------------------
# Tasks (top level: pickled into the pool)
# ---------------------------------------------------------------------------------------------
def _estimate(rec, key: str, cfg: B.RunConfig):
    """(quaternions, our reported angle covariance or None) of a method on a recording."""
    m = B.all_methods(cfg)[key]
    if m.family == "ours":
        q, cov, _, _ = B.run_ours_arrays(rec, m, cfg)
        return q, cov
    return B.run_method(rec, m, cfg)[0], None


def broad_task(task) -> Dict[str, object]:
    """A BROAD trial at one transform: BROAD scores per method (and the post-motion
    inclination per window at the native rate)."""
    path, tf, keys, cfg, role = task
    rec = B._recording(path, tf)
    out: Dict[str, object] = {"kind": "broad", "role": role, "trial": rec.name, "transform": tf,
                              "rate_hz": rec.rate_hz, "scores": {}, "post": {}}
    windows = post_motion_windows(rec.t, rec.quat_ref) if tf.identity else []
    for key in keys:
        m = B.all_methods(cfg)[key]
        if not m.six_d and B.mag_usable(rec):
            continue
        q, _ = _estimate(rec, key, cfg)
        out["scores"][key] = B.score(rec, q, m.six_d)
        if windows:
            out["post"][key] = R.window_means(rec.t, R.inclination_error_deg(q, rec.quat_ref), windows)
    return out


def sim_task(task) -> Dict[str, object]:
    """One simulated recording of a part (flips, tumbles, glitch, gap): its measures per method."""
    part, sc, cfg = task
    rec = S.build(sc)
    out: Dict[str, object] = {"kind": part, "rate_hz": sc.rate_hz, "peak": sc.peak_rate_deg_s,
                              "glitch_deg": sc.glitch_deg, "seed": sc.seed, "per": {}}
    t, ref = rec.t, rec.quat_ref
    for key in OURS + ONLINE:
        six = key.endswith("6d")
        q, cov = _estimate(rec, key, cfg)
        err = R.inclination_error_deg(q, ref) if six else R.total_error_deg(q, ref)
        r: Dict[str, object] = {}
        if part in ("flips", "tumbles"):
            _, t0, t1 = S.events(rec, "flip" if part == "flips" else "tumble")[0]
            if six:
                r["heading_change"] = R.heading_change(t, q, ref, t0, t1)
            else:
                r["peak"] = R.peak(t, err, t0)
                r["after_5s"] = float(R.value_at(t, err, t1 + 5.0))
            if cov is not None:
                r["coverage"] = R.coverage_counts(C.consistency(q, ref, angle_cov=cov, movement=rec.movement,
                                                                six_d=six))
        elif part == "glitch":
            _, _, t1 = S.events(rec, "glitch")[0]
            r["recovery_s"] = R.recovery_time(t, err, t1)
        elif part == "gap":
            _, _, after = S.events(rec, "gap")[0]
            r["after"] = float(R.value_at(t, err, after))
            r["later"] = float(R.value_at(t, err, after + GAP_LATER_S))
            if cov is not None:
                r["sigma_deg"] = np.degrees(np.sqrt(R.value_at(t, cov[:, :3], after))).tolist()
        out["per"][key] = r
    return out


def run_task(task) -> Dict[str, object]:
    kind = task[0]
    return broad_task(task[1:]) if kind == "broad" else sim_task(task[1:])


def tasks(plan: Plan) -> List[tuple]:
    """Every task of the plan, the slow ones (long recordings) first."""
    cfg = plan.cfg
    out: List[tuple] = []
    keys = OURS + ONLINE + OFFLINE
    # role "set": the trials of the rate and post-motion rows; "drops": the drops trial alone
    if "rates" in plan.parts:
        for tf in RATE_TRANSFORMS[::-1]:
            out += [("broad", p, tf, keys, cfg, "set") for p in plan.trials]
    elif "post-motion" in plan.parts:
        out += [("broad", p, Transform(), OURS + ONLINE, cfg, "set") for p in plan.trials]
    if "drops" in plan.parts and plan.drop_trial:
        if not (("rates" in plan.parts or "post-motion" in plan.parts) and plan.drop_trial in plan.trials):
            out.append(("broad", plan.drop_trial, Transform(), OURS + ONLINE, cfg, "drops"))
        for gyro in ("mean", "own"):
            out.append(("broad", plan.drop_trial, Transform(drop_gyro=gyro, **DROP), OURS + ONLINE, cfg, "drops"))
    for part, scenario in (("flips", "flip"), ("tumbles", "tumble")):
        if part in plan.parts:
            for rate in MC_RATES:
                for peak in MC_PEAKS:
                    for i in range(plan.mc):
                        extra = {"approach_deg": MC_APPROACH_MAX_DEG * (i + 0.5) / plan.mc} if part == "flips" else {}
                        sc = S.ScenarioConfig.preset(scenario, rate_hz=rate, peak_rate_deg_s=peak, seed=i + 1, **extra)
                        out.append(("sim", part, sc, cfg))
    if "glitch" in plan.parts:
        # about a horizontal body axis (a tilt glitch; the body rests within 20 deg of level),
        # its direction spread evenly over the runs
        out += [("sim", "glitch", S.ScenarioConfig.preset(
            "glitch", rate_hz=GLITCH_RATE_HZ, glitch_deg=g, seed=s + 1,
            axis=(math.cos(2 * math.pi * (s + 0.5) / SEEDS), math.sin(2 * math.pi * (s + 0.5) / SEEDS), 0.0)), cfg)
            for g in GLITCH_DEG for s in range(SEEDS)]
    if "gap" in plan.parts:
        out += [("sim", "gap", S.ScenarioConfig.preset("gap", seed=s + 1, **GAP), cfg) for s in range(SEEDS)]
    return out


def run(plan: Plan, jobs: int = 1, progress=None) -> List[Dict[str, object]]:
    """Results of every task (in task order)."""
    todo = tasks(plan)
    if jobs > 1 and len(todo) > 1:
        import multiprocessing as mp
        out = []
        with mp.get_context("fork").Pool(jobs, initializer=B._worker_init) as pool:
            for r in pool.imap(run_task, todo, chunksize=1):
                out.append(r)
                if progress:
                    progress(1)
        return out
    out = []
    for task in todo:
        out.append(run_task(task))
        if progress:
            progress(1)
    return out
