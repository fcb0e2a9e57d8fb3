#!/usr/bin/env python3
"""Speed of the Python APIs side by side, in one process on one recording: attekf (Filter.update
per sample, attekf.estimate in one call), VQF (VQF.update, updateBatch, offlineVQF) and
imufusion (Ahrs.update per sample; it has no batch call). Prints a Markdown table with the
commit, the versions and the machine (docs/host_tools.md, "Speed beside VQF and imufusion").

    .venv/bin/python scripts/bench_python_api.py [--trial NAME] [--repeat N]

Every variant runs --repeat times (default 7) over the whole recording; the table gives the
best run's rate (samples/s of the process's CPU time, time.process_time: every variant is one
thread, and CPU time leaves out the waits for a core that other load on the machine causes),
and the median run's. The per-sample loops read the quaternion after every sample (what
a user of the API does); the batch calls return every sample's quaternion. attekf's "C step"
row is the CPU time inside its C loop (Result.c_seconds): the filter's own cost, without
Python. The recording is a BROAD trial (ATTEKF_BROAD_DIR or ../shared/data/broad), 9D (with
the magnetometer); not a test: nothing is asserted.
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BROAD = Path(os.environ.get("ATTEKF_BROAD_DIR", ROOT.parent / "shared" / "data" / "broad"))


def load(trial: str):
    import h5py
    matches = sorted(BROAD.glob(f"{trial}*.hdf5"))
    if not matches:
        sys.exit(f"bench_python_api: no BROAD trial {trial}* in {BROAD} (set ATTEKF_BROAD_DIR)")
    with h5py.File(matches[0], "r") as fh:
        arrays = [np.ascontiguousarray(fh[k][:], dtype=np.float64) for k in ("imu_gyr", "imu_acc", "imu_mag")]
        rate = float(fh.attrs["sampling_rate"])
    return matches[0].name, arrays, rate


def variants(gyr, acc, mag, rate):
    """name -> (API, function running the whole recording)."""
    import attekf
    import imufusion
    import vqf

    dt = 1.0 / rate
    c_seconds = []

    def ours_update(scalar):
        def run():
            f = attekf.Filter(scalar=scalar, dt=dt)
            for g, a, m in zip(gyr, acc, mag):
                q = f.update(g, a, m).quaternion   # noqa: F841
        return run

    def ours_batch(scalar):
        def run():
            res = attekf.estimate(gyr, acc, mag, rate_hz=rate, scalar=scalar)
            c_seconds.append((scalar, res.c_seconds))
        return run

    def vqf_update():
        v = vqf.VQF(dt)
        for g, a, m in zip(gyr, acc, mag):
            v.update(g, a, m)
            q = v.getQuat9D()   # noqa: F841

    def fusion_update():
        ahrs = imufusion.Ahrs()
        s = imufusion.AhrsSettings()
        s.convention = imufusion.CONVENTION_ENU
        s.sample_rate = rate
        ahrs.set_settings(s)
        gd, ag = np.degrees(gyr), acc / 9.81
        for g, a, m in zip(gd, ag, mag):
            ahrs.update(g, a, m)
            q = ahrs.get_quaternion()   # noqa: F841

    table = {
        "attekf Filter.update (float)": ("per sample", ours_update("float")),
        "attekf Filter.update (double)": ("per sample", ours_update("double")),
        "VQF VQF.update + getQuat9D": ("per sample", vqf_update),
        "imufusion Ahrs.update + get_quaternion": ("per sample", fusion_update),
        "attekf estimate (float)": ("batch", ours_batch("float")),
        "attekf estimate (double)": ("batch", ours_batch("double")),
        "VQF VQF(Ts).updateBatch": ("batch", lambda: vqf.VQF(dt).updateBatch(gyr, acc, mag)),
        "VQF offlineVQF": ("batch", lambda: vqf.offlineVQF(gyr, acc, mag, dt)),
    }
    return table, c_seconds


def describe() -> str:
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "host_tools", "firmware"],
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit, dirty = "unknown", ""
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").exists() else ""
    versions = ", ".join(f"{p} {metadata.version(p)}" for p in ("numpy", "vqf", "imufusion"))
    return (f"commit {commit}{' (with uncommitted changes)' if dirty else ''}; Python {platform.python_version()}, "
            f"{versions}; {cpu}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trial", default="07", help="BROAD trial name prefix (default 07)")
    ap.add_argument("--repeat", type=int, default=7, help="runs of each variant (default 7)")
    args = ap.parse_args()
    name, (gyr, acc, mag), rate = load(args.trial)
    n = len(gyr)
    header = describe()
    table, c_seconds = variants(gyr, acc, mag, rate)
    rows = []
    for label, (kind, run) in table.items():
        times = []
        for _ in range(args.repeat):
            t0 = time.process_time()
            run()
            times.append(time.process_time() - t0)
        rows.append((label, kind, n / min(times), n / statistics.median(times)))
        print(f"  {label}: {n / min(times) / 1e3:.0f} k samples/s", file=sys.stderr)
    print(f"{name}: {n} samples at {rate:g} Hz, 9D; CPU time, best and median of {args.repeat} runs; "
          f"{header}\n")
    print("| API | call | best, k samples/s | median, k samples/s |")
    print("|---|---|---:|---:|")
    for label, kind, best, med in rows:
        print(f"| {label} | {kind} | {best / 1e3:,.0f} | {med / 1e3:,.0f} |")
    for scalar in ("float", "double"):
        sec = min(s for k, s in c_seconds if k == scalar)
        print(f"| attekf C step alone ({scalar}, CPU time in the C loop) | batch | {n / sec / 1e3:,.0f} | "
              f"{n / statistics.median(s for k, s in c_seconds if k == scalar) / 1e3:,.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
