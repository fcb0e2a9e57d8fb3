#!/usr/bin/env python3
"""Where the instructions of one estimator step go, on the emulated Cortex-M.

Runs the benchmark image (firmware/target/bench.c) for a few samples under QEMU with a
per-instruction trace (-singlestep -d exec,nochain), rebuilds the call stack from the
trace and the image's disassembly, and prints, for everything executed inside att_step,
the instructions per step of each function: inclusive (with its callees) and self.

    scripts/profile_firmware.py [--build build/cortex-m4f] [--samples 20] [--top 30]
    scripts/profile_firmware.py --build build/peers-cortex-m4f \
        --image build/peers-cortex-m4f/firmware/target/peers/attekf_peers_bench.elf \
        --args VQF --root _ZN3VQF6updateEPKfS1_S1_ --require _ZN3VQF9updateAccEPKf

Needs a configured and built cross build (cmake --preset cortex-m4f && cmake --build
--preset cortex-m4f). The trace of 20 samples is about 300 MB in a temporary directory.
"""
import argparse
import bisect
import collections
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CALL = re.compile(r"^\s*([0-9a-f]+):\s+(?:[0-9a-f]{4}\s?){1,2}\s+(bl|blx)\b")


def machine_of(build):
    cache = os.path.join(build, "CMakeCache.txt")
    with open(cache, encoding="utf-8") as f:
        for line in f:
            if "cortex-m3.cmake" in line:
                return "mps2-an385"
    return "mps2-an386"


def functions(elf):
    """Sorted (entry address, name) of every function symbol, and the set of call sites."""
    nm = subprocess.run(["arm-none-eabi-nm", "-n", elf], check=True, capture_output=True, text=True).stdout
    entries = []
    for line in nm.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[1] in "Tt" and not parts[2].startswith("$"):
            entries.append((int(parts[0], 16) & ~1, parts[2]))
    entries.sort()
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", elf], check=True, capture_output=True, text=True).stdout
    calls = set()
    for line in dis.splitlines():
        m = CALL.match(line)
        if m:
            calls.add(int(m.group(1), 16))
    return entries, calls


def profile(trace, entries, calls, root, require):
    """Per-function counters summed over the calls of root that called require."""
    addrs = [a for a, _ in entries]
    names = [n for _, n in entries]
    total = {"incl": collections.Counter(), "self": collections.Counter(), "calls": collections.Counter()}
    cur = None  # counters of the root call in progress
    kept = 0
    stack = []
    prev = None
    with open(trace, encoding="utf-8", errors="replace") as f:
        for line in f:
            lb = line.find("[")
            if not line.startswith("Trace") or lb < 0:
                continue
            pc = int(line[lb + 10:lb + 18], 16)
            i = bisect.bisect_right(addrs, pc) - 1
            prev_pc, prev = prev, pc
            if i < 0:
                continue
            fn = names[i]
            at_entry = pc == addrs[i]
            if at_entry and prev_pc in calls:
                stack.append(fn)
                if fn == root:
                    cur = {"incl": collections.Counter(), "self": collections.Counter(),
                           "calls": collections.Counter()}
                if cur is not None:
                    cur["calls"][fn] += 1
            elif stack and stack[-1] != fn:
                if fn in stack:
                    while stack[-1] != fn:
                        stack.pop()
                elif at_entry:  # tail call (b <fn>): the callee replaces the caller
                    stack[-1] = fn
                    if fn == root and cur is None:  # root entered by a tail call
                        cur = {"incl": collections.Counter(), "self": collections.Counter(),
                               "calls": collections.Counter()}
                    if cur is not None:
                        cur["calls"][fn] += 1
                else:
                    stack.append(fn)
            elif not stack:
                stack.append(fn)
            if cur is not None and root not in stack:  # the root call returned
                if cur["calls"][require] > 0:
                    kept += 1
                    for k in total:
                        total[k].update(cur[k])
                cur = None
            if cur is not None:
                for g in set(stack[stack.index(root):]):
                    cur["incl"][g] += 1
                cur["self"][fn] += 1
    return total, kept


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build", "cortex-m4f"),
                    help="configured and built cross build directory (default build/cortex-m4f)")
    ap.add_argument("--samples", type=int, default=20,
                    help="benchmark samples (the first 10 align the filter; default 20)")
    ap.add_argument("--root", default="att_step_traced", help="function whose call tree is profiled (att_step is a tail call to it)")
    ap.add_argument("--require", default="att_stage_predict",
                    help="count only root calls that called this function (default: the "
                         "steps after the alignment, which run the prediction)")
    ap.add_argument("--top", type=int, default=30, help="functions listed (default 30)")
    ap.add_argument("--image", default=None,
                    help="image to trace instead of the build's attekf_bench.elf, e.g. the peers' "
                         "firmware/target/peers/attekf_peers_bench.elf (with --root, --require, --args)")
    ap.add_argument("--args", nargs="*", default=None,
                    help="arguments of the image after the sample count (e.g. VQF for the peers' image)")
    ap.add_argument("--quiet", action="store_true", help="print only the table")
    args = ap.parse_args()

    elf = args.image or os.path.join(args.build, "firmware", "target", "attekf_bench.elf")
    if not os.path.isfile(elf):
        sys.exit(f"profile_firmware: no benchmark image {elf}: configure and build the cross build first")
    if args.samples < 20:
        sys.exit("profile_firmware: --samples must be at least 20")
    entries, calls = functions(elf)
    runner = os.path.join(ROOT, "firmware", "target", "qemu_run.sh")
    with tempfile.TemporaryDirectory() as tmp:
        trace = os.path.join(tmp, "trace.log")
        if not args.quiet:
            print(f"profile_firmware: tracing {args.samples} samples of {os.path.relpath(elf, ROOT)}", file=sys.stderr)
        run = subprocess.run([runner, "--machine", machine_of(args.build), "--icount", "8", "--trace", trace,
                              elf, str(args.samples)] + (args.args or []), capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit(f"profile_firmware: benchmark failed (exit {run.returncode}):\n{run.stdout}{run.stderr}")
        total, steps = profile(trace, entries, calls, args.root, args.require)
    if steps == 0:
        sys.exit(f"profile_firmware: no call of {args.root} that called {args.require}")
    incl, self_, ncalls = total["incl"], total["self"], total["calls"]
    print(f"{args.root}: {steps} calls that ran {args.require}, {incl[args.root] / steps:.0f} instructions per call")
    print(f"{'function':32s} {'calls/step':>10s} {'incl/step':>10s} {'self/step':>10s} {'incl/call':>10s}")
    for fn, n in incl.most_common(args.top):
        c = ncalls[fn] / steps
        per_call = n / ncalls[fn] if ncalls[fn] else float("nan")
        print(f"{fn:32s} {c:10.2f} {n / steps:10.0f} {self_[fn] / steps:10.0f} {per_call:10.0f}")


if __name__ == "__main__":
    main()
