#!/usr/bin/env python3
"""CAN throughput benchmark of the estimator node (a benchmark that prints numbers, not a test).

For each input frame rate, starts attekf-node on vcan0, sends IMU frames at that rate for
--duration seconds with attekf-can-blast (C, sendmmsg, absolute schedule, 4 frames per sample),
stops the node and reads its counters. A rate is *sustained* when

  * the sender sent every frame on time (no failed send),
  * the node received every frame (rx_frames == frames sent, no kernel drop: rx_overflow 0),
  * it assembled and processed every sample (no discarded, incomplete or missing sample),
  * it kept up: the node-side latency (kernel receive time -> output sent) stayed below
    --max-p99-ms at the 99th percentile, i.e. no backlog built up in the socket buffer.

It runs a ladder of rates, then bisects between the highest sustained and the lowest failed one,
and prints a table and the highest sustained rate. Where the kernel has no CAN the whole run
happens inside one guest of tests/vm/vcan_run.py (user-mode Linux, or QEMU): there the node,
the sender and the kernel share ONE virtual CPU and every system call is expensive (under QEMU
without KVM every instruction is emulated), so the figure is a lower bound for real hardware.

    scripts/can_throughput.py                      # default ladder, 5 s per rate
    scripts/can_throughput.py --rates 10000,20000 --duration 10 --json out.json

Standard library only. Binaries: build/host (override with --node / --blast).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Dict, List, Optional

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_NODE = ROOT / "build" / "host" / "firmware" / "app" / "attekf-node"
DEFAULT_BLAST = ROOT / "build" / "host" / "hal" / "attekf-can-blast"
DEFAULT_RATES = (5000, 10000, 15000, 20000, 25000, 30000, 40000)


def measure(rate: int, duration: float, node: str, blast: str, iface: str, work: Path,
            max_p99_ms: float) -> Dict[str, object]:
    """One run at one rate (inside a machine with the interface)."""
    ready = work / f"ready.{rate}"
    stats = work / f"node.{rate}.json"
    for p in (ready, stats):
        if p.exists():
            p.unlink()
    np = subprocess.Popen([node, "-i", iface, "--ready-file", str(ready), "--stats", str(stats),
                           "-l", "error"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    while not ready.exists():
        if np.poll() is not None or time.monotonic() - t0 > 30:
            np.kill()
            raise RuntimeError(f"attekf-node did not start: {np.stderr.read() if np.stderr else ''}")
        time.sleep(0.01)
    b = subprocess.run([blast, "-i", iface, "--rate", str(rate), "--duration", str(duration)],
                       capture_output=True, text=True)
    # Let the node finish what is queued (its latency tells whether it had fallen behind).
    time.sleep(0.5)
    np.send_signal(signal.SIGTERM)
    _, err = np.communicate(timeout=30)
    if b.returncode != 0 or np.returncode != 0:
        raise RuntimeError(f"rate {rate}: blast rc {b.returncode} {b.stderr.strip()}; node rc {np.returncode} {err.strip()}")
    sent = json.loads(b.stdout)
    st = json.loads(stats.read_text())
    c = st["counters"]
    lat = st["latency_us"]
    problems = []
    if sent["failed"]:
        problems.append(f"{sent['failed']} sends failed")
    if c["rx_frames"] != sent["frames"]:
        problems.append(f"{sent['frames'] - c['rx_frames']} frames lost")
    if c["rx_overflow"]:
        problems.append(f"{c['rx_overflow']} kernel drops")
    bad = {k: c[k] for k in ("discarded", "incomplete", "missing", "gaps", "late", "duplicate") if c[k]}
    if bad:
        problems.append(f"counters {bad}")
    if c["samples"] != sent["samples"]:
        problems.append(f"{sent['samples'] - c['samples']} samples not processed")
    if lat["p99"] > max_p99_ms * 1000:
        problems.append(f"p99 latency {lat['p99'] / 1000:.1f} ms (falling behind)")
    return {"rate": rate, "achieved_fps": sent["frames_per_s"], "frames": sent["frames"],
            "received": c["rx_frames"], "kernel_drops": c["rx_overflow"], "samples": c["samples"],
            "latency_p50_us": lat["p50"], "latency_p99_us": lat["p99"], "latency_max_us": lat["max"],
            "sustained": not problems, "problems": problems}


def inside(args) -> int:
    """The measurement loop, on a machine where the interface exists."""
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    results: List[Dict[str, object]] = []

    def run(rate: int) -> bool:
        r = measure(rate, args.duration, args.node, args.blast, args.iface, work, args.max_p99_ms)
        results.append(r)
        print(json.dumps(r), flush=True)
        return bool(r["sustained"])

    good, bad = None, None
    for rate in args.rates:
        if run(rate):
            good = rate
        else:
            bad = rate
            break
    if good is not None and bad is not None:
        for _ in range(args.bisect):
            mid = int(round((good + bad) / 2 / 500.0)) * 500
            if mid in (good, bad):
                break
            if run(mid):
                good = mid
            else:
                bad = mid
    print(json.dumps({"highest_sustained": good, "lowest_failed": bad}), flush=True)
    return 0


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="can_throughput.py", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rates", default=",".join(str(r) for r in DEFAULT_RATES),
                    help="ladder of input frame rates, frames/s (default %(default)s)")
    ap.add_argument("--duration", type=float, default=5.0, help="seconds per rate (default 5)")
    ap.add_argument("--bisect", type=int, default=3, help="bisection steps after the ladder (default 3)")
    ap.add_argument("--max-p99-ms", type=float, default=50.0,
                    help="node-side p99 latency above which the node is falling behind (default 50)")
    ap.add_argument("--node", default=os.environ.get("ATTEKF_NODE", str(DEFAULT_NODE)))
    ap.add_argument("--blast", default=str(DEFAULT_BLAST))
    ap.add_argument("--iface", default="vcan0")
    ap.add_argument("--mode", choices=("auto", "host", "uml", "qemu", "qemu-kvm", "qemu-tcg"), default="auto",
                    help="where vcan0 comes from (tests/vm/vcan_run.py backends)")
    ap.add_argument("--json", metavar="FILE", help="write every result as JSON")
    ap.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--work", default="", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    try:
        args.rates = [int(r) for r in args.rates.split(",") if r]
    except ValueError:
        ap.error("--rates: comma-separated integers")
    if args.inside:
        return inside(args)
    for b in (args.node, args.blast):
        if not os.access(b, os.X_OK):
            print(f"can_throughput: {b} is not built (cmake --build build/host)", file=sys.stderr)
            return 1
    sys.path.insert(0, str(ROOT / "tests" / "vm"))
    import tempfile
    import vcan_run
    work = tempfile.mkdtemp(prefix="can_throughput.")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--inside", "--work", work,
           "--rates", ",".join(map(str, args.rates)), "--duration", str(args.duration),
           "--bisect", str(args.bisect), "--max-p99-ms", str(args.max_p99_ms),
           "--node", args.node, "--blast", args.blast, "--iface", args.iface]
    try:
        res = vcan_run.run(cmd, ifaces=[args.iface], mode=args.mode, timeout=3600)
    except vcan_run.VcanError as e:
        print(f"can_throughput: {e}", file=sys.stderr)
        return 1
    if res.returncode != 0:
        print(f"can_throughput: measurement failed:\n{res.stderr}", file=sys.stderr)
        return 1
    lines = [json.loads(l) for l in res.stdout.splitlines() if l.startswith("{")]
    rows = [l for l in lines if "rate" in l]
    summary = next(l for l in lines if "highest_sustained" in l)
    print(f"CAN throughput of attekf-node on {args.iface} ({res.mode} mode; {args.duration:g} s per rate, "
          f"4 frames per sample, node output 100 Hz)")
    print(f"{'rate fps':>9} {'achieved':>9} {'received':>9} {'drops':>6} {'p50 us':>8} {'p99 us':>8}  result")
    for r in sorted(rows, key=lambda r: r["rate"]):
        print(f"{r['rate']:>9} {r['achieved_fps']:>9.0f} {r['received']:>9} {r['kernel_drops']:>6} "
              f"{r['latency_p50_us']:>8} {r['latency_p99_us']:>8}  "
              + ("sustained" if r["sustained"] else "FAIL: " + "; ".join(r["problems"])))
    print(f"highest sustained input rate: {summary['highest_sustained']} frames/s"
          + (f" (fails at {summary['lowest_failed']})" if summary["lowest_failed"] else " (no failure in the ladder)"))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({"mode": res.mode, "duration_s": args.duration, "results": rows, **summary}, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
