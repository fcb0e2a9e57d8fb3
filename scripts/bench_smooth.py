#!/usr/bin/env python3
"""Throughput and memory of the smoother (attekf.smooth: the filter forward, its Rauch-Tung-
Striebel pass backward; docs/host_tools.md, "Smoothing"), printed as a Markdown table with the
commit and the machine. Not a test: nothing is asserted.

    .venv/bin/python scripts/bench_smooth.py [--trials 02,07] [--repeat 5] [--hours 1] [--rate 1000]
                                             [--segment N]

1. BROAD (ATTEKF_BROAD_DIR or ../shared/data/broad; skipped with a note when absent): every
   trial (or --trials), 9D, --repeat runs each of attekf.smooth and attekf.estimate; the rate is
   samples per second of CPU time inside the C call (Result.c_seconds: the process's CPU time,
   which leaves out the waits for a core that other load causes), the best run and the median
   run of the sum over the trials, and the wall time of the whole smooth() call.
2. A long recording: --hours of the simulator's random motion (attekf.sim) at --rate Hz, one
   run of attekf.smooth with a progress bar; its rate, the smoother's segments and the process's
   peak resident memory before and during the call. --segment N sets the samples per segment
   of that run (default: 64 MiB of traces; the whole recording in one segment runs the filter
   once instead of twice, with its traces all in memory).
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BROAD = Path(os.environ.get("ATTEKF_BROAD_DIR", ROOT.parent / "shared" / "data" / "broad"))


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def broad_rows(trials, repeat: int, scalar: str):
    import attekf
    from attekf.io import read_recording
    paths = sorted(BROAD.glob("*.hdf5"))
    if trials:
        paths = [p for p in paths if any(p.name.startswith(t) for t in trials.split(","))]
    if not paths:
        print(f"note: no BROAD trials in {BROAD}: part 1 skipped", file=sys.stderr)
        return None
    recs = [read_recording(str(p)) for p in paths]
    n = sum(len(r.t) for r in recs)
    runs = {"smooth": [], "estimate": [], "wall": []}
    for _ in range(repeat):
        cs = ce = wall = 0.0
        for r in recs:
            t0 = time.perf_counter()
            res = attekf.smooth(r.gyr, r.acc, r.mag, t=r.t, scalar=scalar)
            wall += time.perf_counter() - t0
            cs += res.c_seconds
            ce += attekf.estimate(r.gyr, r.acc, r.mag, t=r.t, scalar=scalar).c_seconds
        runs["smooth"].append(n / cs)
        runs["estimate"].append(n / ce)
        runs["wall"].append(n / wall)
    return len(recs), n, runs


def long_row(hours: float, rate: float, scalar: str, segment):
    import attekf
    from attekf.progress import bar
    from attekf.sim import SimConfig, simulate
    rec = simulate(SimConfig(duration_s=3600.0 * hours, rate_hz=rate, seed=1))
    before = peak_rss_mib()
    t0 = time.perf_counter()
    with bar(2 * len(rec.t), f"smoothing {hours:g} h at {rate:g} Hz", False, unit="step") as pb:
        res = attekf.smooth(rec.gyr, rec.acc, rec.mag, t=rec.t, scalar=scalar, progress=pb.update,
                            segment=segment)
    wall = time.perf_counter() - t0
    return len(rec.t), res, wall, before, peak_rss_mib()


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=True).stdout.strip()
        return out + (" + uncommitted changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", help="BROAD trials (comma list of name prefixes; default all)")
    ap.add_argument("--repeat", type=int, default=5, help="runs over the BROAD trials (default 5)")
    ap.add_argument("--hours", type=float, default=1.0, help="length of the long recording, h (0: none; default 1)")
    ap.add_argument("--rate", type=float, default=1000.0, help="its sample rate, Hz (default 1000)")
    ap.add_argument("--segment", type=int, help="samples per segment of the long run (default: the API's)")
    ap.add_argument("--scalar", default="float", choices=("float", "double", "fixed"),
                    help="the filter's build (default float)")
    args = ap.parse_args()
    if args.repeat < 1 or args.hours < 0 or args.rate <= 0 or (args.segment is not None and args.segment < 1):
        ap.error("--repeat must be >= 1, --hours >= 0, --rate > 0, --segment >= 1")
    print(f"commit {git_commit()}, {cpu_name()}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.1f}, Python {platform.python_version()}, numpy {np.__version__}, "
          f"{args.scalar} filter\n")
    print("| what | samples | k samples/s (best) | k samples/s (median) |")
    print("|---|---:|---:|---:|")
    broad = broad_rows(args.trials, args.repeat, args.scalar)
    if broad:
        trials, n, runs = broad
        for key, label in (("smooth", "attekf.smooth, C call (CPU time)"),
                           ("wall", "attekf.smooth, whole call (wall time)"),
                           ("estimate", "attekf.estimate, C call (CPU time)")):
            print(f"| BROAD, {trials} trials, 9D: {label} | {n:,} | {max(runs[key]) / 1e3:,.0f} | "
                  f"{statistics.median(runs[key]) / 1e3:,.0f} |")
    if args.hours > 0:
        n, res, wall, before, during = long_row(args.hours, args.rate, args.scalar, args.segment)
        sm = res.smoother
        print(f"| {args.hours:g} h at {args.rate:g} Hz (simulated), 9D: attekf.smooth, C call (CPU time) | "
              f"{n:,} | {n / res.c_seconds / 1e3:,.0f} | |")
        print(f"| the same, whole call (wall time) | {n:,} | {n / wall / 1e3:,.0f} | |")
        print(f"\nlong recording: {sm['segment']:,} samples per segment, {sm['recomputed']:,} samples "
              f"recomputed, peak resident memory {before:,.0f} MiB before the call (the recording), "
              f"{during:,.0f} MiB during it (with the {n:,} rows of the result)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
