#!/usr/bin/env python3
"""Cortex-M benchmark: instructions per estimator stage, flash, RAM and stack.

For each cross build (presets cortex-m4f and cortex-m3 of CMakePresets.json, -Os), this

  1. configures the build if needed and builds the benchmark and footprint images
     (firmware/target/bench.c, footprint.c);
  2. runs the benchmark under QEMU with -icount shift=8, where SysTick advances exactly
     6.4 ticks per executed instruction: instructions of att_predict, att_update_gyro,
     att_update_accel, att_update_mag and of the full att_step (min / mean / max over
     the samples), att_step part by part (the commit's saved copy, the rest detector, the
     gyroscope, prediction, accelerometer and magnetometer stages, the guard, the rest of
     the call), and the deepest stack of att_step (stack painting);
  3. attributes the footprint image's flash and RAM (link map) to the estimator's
     objects and to the library members they pull in (libm, libgcc, libc), following
     undefined symbols through the archives;
  4. lists the largest stack frames of the estimator's functions (-fstack-usage).

With --peers, the same run also measures the peers' filters on the same boards and samples
(scripts/peers.py downloads their pinned sources; firmware/target/peers/): instructions per
full update, flash, RAM and stack of Fusion, VQF and BasicVQF next to att_step's, and on the
host the instructions per sample under callgrind (valgrind), with the ratios.

Prints Markdown tables (the ones recorded in docs/performance.md) with the commit measured.

    scripts/bench_firmware.py [--presets cortex-m4f cortex-m3] [--samples 3000]
                              [--build-type MinSizeRel] [--peers] [--quiet]
"""
import argparse
import collections
import glob
import os
import re
import subprocess
import sys

import bench_peers

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RUNNER = os.path.join(ROOT, "firmware", "target", "qemu_run.sh")
MACHINES = {"cortex-m4f": "mps2-an386", "cortex-m3": "mps2-an385", "cortex-m3-fixed": "mps2-an385"}
# Toolchain file and estimator library of each preset (cortex-m3-fixed: the Q-format build,
# docs/fixed_point.md).
TOOLCHAINS = {"cortex-m4f": "cortex-m4f", "cortex-m3": "cortex-m3", "cortex-m3-fixed": "cortex-m3"}


def core_lib(preset):
    return "attekf_x" if preset.endswith("-fixed") else "attekf_f"

STAGES = ("predict", "update_gyro", "update_accel", "update_mag", "step", "stages_sum")
# att_step part by part, in its order (bench.c)
PARTS = ("part_commit", "part_rest", "part_gyro", "part_predict", "part_accel", "part_mag", "part_guard",
         "step_other")
TARGET_INSNS = 9000       # full step on M4F, mean: the budget with the exact propagation (issue 22)
TARGET_STATE_BYTES = 512  # x and P in float
TARGET_FLASH = 16 * 1024  # estimator library at -Os
TARGET_STACK = 1024


class BenchError(Exception):
    pass


def log(args, msg):
    if not args.quiet:
        print(f"[bench] {msg}", file=sys.stderr, flush=True)


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        raise BenchError(f"{' '.join(cmd)} failed (exit {r.returncode}):\n{r.stdout[-3000:]}{r.stderr[-3000:]}")
    return r.stdout


def build_dir(preset, build_type, build_root=None):
    if build_root is not None:
        return os.path.join(build_root, f"{preset}-{build_type}")
    if build_type == "MinSizeRel":
        return os.path.join(ROOT, "build", preset)
    return os.path.join(ROOT, "build", f"bench-{preset}-{build_type}")


def ensure_built(args, preset):
    bdir = build_dir(preset, args.build_type, args.build_root)
    if not os.path.isfile(os.path.join(bdir, "build.ninja")):
        log(args, f"configuring {os.path.relpath(bdir, ROOT)}")
        if args.build_type == "MinSizeRel" and args.build_root is None:
            run(["cmake", "--preset", preset], cwd=ROOT)
        else:
            run(["cmake", "-S", ROOT, "-B", bdir, "-G", "Ninja",
                 "--toolchain", os.path.join(ROOT, "cmake", "toolchains", f"{TOOLCHAINS[preset]}.cmake"),
                 f"-DCMAKE_BUILD_TYPE={args.build_type}",
                 f"-DATTEKF_FIRMWARE_SCALAR={'FIXED' if preset.endswith('-fixed') else 'FLOAT'}",
                 f"-DPython3_EXECUTABLE={os.path.join(ROOT, '.venv', 'bin', 'python')}"], cwd=ROOT)
    log(args, f"building the benchmark images in {os.path.relpath(bdir, ROOT)}")
    run(["cmake", "--build", bdir, "--target", "attekf_bench", "attekf_footprint"], cwd=ROOT)
    return bdir


# ---- instruction counts -------------------------------------------------------------------
def run_bench(args, preset, bdir):
    elf = os.path.join(bdir, "firmware", "target", "attekf_bench.elf")
    log(args, f"{preset}: running the benchmark under QEMU (-icount shift=8, {args.samples} samples)")
    out = run([RUNNER, "--machine", MACHINES[preset], "--icount", "8", elf, str(args.samples)])
    res = {"insns": {}, "raw": out}
    for line in out.splitlines():
        f = line.split()
        if f[:1] == ["insns"]:
            kv = dict(zip(f[2::2], f[3::2]))
            res["insns"][f[1]] = {k: int(kv[k]) for k in ("min", "mean", "max", "n")}
        elif f[:2] == ["stack", "step_max"]:
            res["stack_step"] = int(f[2])
        elif f[:1] == ["memory"]:
            kv = dict(zip(f[1::2], f[2::2]))
            res["state_bytes"] = int(kv["state_x_P"])
            res["filter_bytes"] = int(kv["filter_struct"])
        elif f[:1] == ["calibration"]:
            res["calibration"] = line
        elif f[:1] == ["fused"]:
            res["fused"] = line
        elif line.startswith("final attitude error"):
            res["final_error"] = line
    missing = [s for s in STAGES + PARTS if s not in res["insns"]]
    if missing or "stack_step" not in res:
        raise BenchError(f"{preset}: unexpected benchmark output (missing {missing}):\n{out}")
    return res


# ---- footprint ------------------------------------------------------------------------------
MEMBER = re.compile(r"^(\S+\.a)\((\S+)\)$")
INPUT = re.compile(r"^ (\S+)?\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+)$")


def parse_map(path):
    """Bytes per (file, kind) kept in the image; kind: text (code + read-only), data, bss."""
    sizes = collections.defaultdict(lambda: collections.Counter())
    with open(path, encoding="utf-8") as f:
        lines = f.read().splitlines()
    try:
        start = lines.index("Linker script and memory map")
    except ValueError:
        raise BenchError(f"{path}: not a GNU ld map file")
    out_sec = None
    pending = None
    for line in lines[start + 1:]:
        if line and not line[0].isspace():
            out_sec = line.split()[0]
            pending = None
            continue
        if re.match(r"^ \S+$", line):  # long input section name, values on the next line
            pending = line.strip()
            continue
        m = INPUT.match(line)
        if not m or out_sec is None:
            pending = None
            continue
        size = int(m.group(3), 16)
        src = m.group(4)
        pending = None
        if size == 0 or out_sec.startswith(".debug") or out_sec in (".comment", ".ARM.attributes"):
            continue
        kind = "bss" if out_sec == ".bss" else "data" if out_sec == ".data" else "text"
        sizes[src][kind] += size
    return sizes


def archive_symbols(archive, cwd):
    """{member: (defined symbols, undefined symbols)} of a static library."""
    out = run(["arm-none-eabi-nm", "-A", archive], cwd=cwd)
    members = collections.defaultdict(lambda: (set(), set()))
    for line in out.splitlines():
        # "<archive>:<member>:<addr> <type> <sym>" or "<archive>:<member>:         U <sym>"
        head, _, rest = line.rpartition(":")
        member = head.split(":")[-1]
        parts = rest.split()
        if len(parts) < 2:
            continue
        typ, sym = parts[-2], parts[-1]
        if typ == "U":
            members[member][1].add(sym)
        elif typ.isupper() or typ in "tdbr":
            members[member][0].add(sym)
    return members


def footprint(args, preset, bdir):
    return footprint_of(os.path.join(bdir, "firmware", "target", "attekf_footprint.elf"), f"lib{core_lib(preset)}.a",
                        bdir)


def footprint_of(elf, libname, bdir):
    """Flash/RAM of the objects of static library libname in image elf and of every library
    member they pull in (followed through undefined symbols), grouped; and the image's size."""
    sizes = parse_map(elf + ".map")
    # archives the image took members from, and the symbols of every member
    archives = sorted({MEMBER.match(s).group(1) for s in sizes if MEMBER.match(s)})
    defs = {}   # symbol -> "archive(member)"
    undef = {}  # "archive(member)" -> undefined symbols
    for a in archives:
        for member, (d, u) in archive_symbols(a, bdir).items():
            key = f"{a}({member})"
            undef[key] = u
            for s in d:
                defs.setdefault(s, key)
    # closure from the library's objects through undefined symbols
    lib = [s for s in sizes if MEMBER.match(s) and os.path.basename(MEMBER.match(s).group(1)) == libname]
    seen = set(lib)
    todo = list(lib)
    while todo:
        key = todo.pop()
        for sym in undef.get(key, ()):
            dep = defs.get(sym)
            if dep is not None and dep in sizes and dep not in seen:
                seen.add(dep)
                todo.append(dep)
    groups = collections.OrderedDict()
    for key in sorted(seen):
        m = MEMBER.match(key)
        name = os.path.basename(m.group(1))
        group = f"estimator: {re.sub(r'[.]obj$', '', m.group(2))}" if name == libname else name
        groups.setdefault(group, collections.Counter()).update(sizes[key])
    size_out = run(["arm-none-eabi-size", elf]).splitlines()[1].split()
    return {"groups": groups, "image": {"text": int(size_out[0]), "data": int(size_out[1]), "bss": int(size_out[2])},
            "elf": elf}


def stack_frames(bdir, top=6, lib="attekf_f"):
    rows = []
    for su in glob.glob(os.path.join(bdir, "firmware", "CMakeFiles", f"{lib}.dir", "**", "*.su"), recursive=True):
        with open(su, encoding="utf-8") as f:
            for line in f:
                parts = line.rstrip("\n").split("\t")
                if len(parts) == 3:
                    rows.append((int(parts[1]), parts[0].split(":")[-1], parts[2]))
    rows.sort(reverse=True)
    return rows[:top]


# ---- report ---------------------------------------------------------------------------------
def commit():
    try:
        head = run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT).strip()
        dirty = run(["git", "status", "--porcelain"], cwd=ROOT).strip()
    except BenchError:
        return "unknown commit"
    return head + (" with uncommitted changes" if dirty else "")


def verdict(value, limit):
    return "met" if value <= limit else "**missed**"


def report(args, results):
    print(f"Measured at {commit()}, `scripts/bench_firmware.py --samples {args.samples}"
          f"{' --peers' if args.peers else ''}` "
          f"(build type {args.build_type}, arm-none-eabi-gcc, QEMU -icount shift=8).\n")
    print("### Instructions per call\n")
    print("Executed instructions (not cycles) over the benchmark's samples after the alignment "
          "(min / mean / max). `step` is one `att_step` with gyroscope, accelerometer and "
          "magnetometer; `sum of stages` is the same work timed stage by stage.\n")
    presets = list(results)
    print("| stage | " + " | ".join(presets) + " |")
    print("|---|" + "---|" * len(presets))
    names = {"predict": "att_predict", "update_gyro": "att_update_gyro (3 scalar updates)",
             "update_accel": "att_update_accel (2 scalar updates)", "update_mag": "att_update_mag (1 scalar update)",
             "step": "**full step** (att_step)", "stages_sum": "sum of stages"}
    for s in STAGES:
        cells = []
        for p in presets:
            v = results[p]["bench"]["insns"][s]
            cells.append(f"{v['min']:,} / {v['mean']:,} / {v['max']:,}")
        print(f"| {names[s]} | " + " | ".join(cells) + " |")
    print("\n`att_step` part by part, in its order (the same samples, on a copy of the filter; the parts "
          "add up to the full step):\n")
    print("| part of att_step | " + " | ".join(presets) + " |")
    print("|---|" + "---|" * len(presets))
    part_names = {"part_commit": "commit: the saved copy of the variables", "part_rest": "rest detector",
                  "part_gyro": "gyroscope stage (3 scalar updates)", "part_predict": "prediction stage",
                  "part_accel": "accelerometer stage (2 scalar updates)",
                  "part_mag": "magnetometer stage (1 scalar update)",
                  "part_guard": "guard (floor, LDL^T) and finiteness check",
                  "step_other": "validation, report, calls (the step less its parts)"}
    for s in PARTS:
        cells = []
        for p in presets:
            v = results[p]["bench"]["insns"][s]
            cells.append(f"{v['min']:,} / {v['mean']:,} / {v['max']:,}")
        print(f"| {part_names[s]} | " + " | ".join(cells) + " |")
    if "cortex-m4f" in results:
        step = results["cortex-m4f"]["bench"]["insns"]["step"]["mean"]
        print(f"\nTarget <= {TARGET_INSNS:,} instructions per full step on M4F (mean): {verdict(step, TARGET_INSNS)} "
              f"(mean {step:,}, {'missed by ' + format(step - TARGET_INSNS, ',') if step > TARGET_INSNS else 'headroom ' + format(TARGET_INSNS - step, ',')}).")
    for p in presets:
        b = results[p]["bench"]
        print(f"\n{p}: {b.get('calibration', '')}; {b.get('fused', '')}; {b.get('final_error', '')}")

    print("\n### Memory\n")
    print("| | " + " | ".join(presets) + " |")
    print("|---|" + "---|" * len(presets))
    first = results[presets[0]]
    print("| filter state x + P (bytes) | " + " | ".join(str(results[p]["bench"]["state_bytes"]) for p in presets) + " |")
    print("| whole att_ekf_t (bytes) | " + " | ".join(str(results[p]["bench"]["filter_bytes"]) for p in presets) + " |")
    print("| deepest att_step stack, painted (bytes) | " +
          " | ".join(str(results[p]["bench"]["stack_step"]) for p in presets) + " |")
    all_groups = []
    for p in presets:
        for g in results[p]["fp"]["groups"]:
            if g not in all_groups:
                all_groups.append(g)
    for g in all_groups:
        cells = []
        for p in presets:
            c = results[p]["fp"]["groups"].get(g)
            cells.append(f"{c['text'] + c['data']:,} flash, {c['data'] + c['bss']:,} RAM" if c else "-")
        print(f"| {g} | " + " | ".join(cells) + " |")
    for p in presets:
        gr = results[p]["fp"]["groups"]
        est = sum(c["text"] + c["data"] for g, c in gr.items() if g.startswith("estimator"))
        dep = sum(c["text"] + c["data"] for g, c in gr.items() if not g.startswith("estimator"))
        results[p]["flash_est"], results[p]["flash_all"] = est, est + dep
    print("| **estimator objects, flash** | " + " | ".join(f"{results[p]['flash_est']:,}" for p in presets) + " |")
    print("| **estimator + what it pulls in (libm, libgcc, libc), flash** | " +
          " | ".join(f"{results[p]['flash_all']:,}" for p in presets) + " |")
    print("| footprint image (text / data / bss) | " + " | ".join(
        "{text:,} / {data:,} / {bss:,}".format(**results[p]["fp"]["image"]) for p in presets) + " |")
    p0 = presets[0]
    print(f"\nTargets ({p0}): state <= {TARGET_STATE_BYTES} B: "
          f"{verdict(first['bench']['state_bytes'], TARGET_STATE_BYTES)}; library <= 16 KiB flash: "
          f"{verdict(first['flash_all'], TARGET_FLASH)} ({first['flash_all']:,} B with its dependencies, "
          f"{'over by ' + format(first['flash_all'] - TARGET_FLASH, ',') if first['flash_all'] > TARGET_FLASH else 'headroom ' + format(TARGET_FLASH - first['flash_all'], ',')} B); "
          f"stack <= 1 KiB: {verdict(first['bench']['stack_step'], TARGET_STACK)}.")
    print("\nLargest stack frames of the estimator (-fstack-usage, " + p0 + "):\n")
    for size, fn, kind in first["frames"]:
        print(f"- {fn}: {size} bytes ({kind})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--presets", nargs="+", default=["cortex-m4f", "cortex-m3"], choices=sorted(MACHINES),
                    help="cross builds to measure (default: both)")
    ap.add_argument("--samples", type=int, default=3000, help="benchmark samples, 20..1000000 (default 3000)")
    ap.add_argument("--build-type", default="MinSizeRel", choices=["MinSizeRel", "Release", "RelWithDebInfo"],
                    help="CMake build type; other than MinSizeRel (-Os) uses build/bench-<preset>-<type>")
    ap.add_argument("--build-root", default=None,
                    help="build in DIR/<preset>-<build type> instead of the presets' build/<preset> "
                         "(a private tree while others use build/)")
    ap.add_argument("--peers", action="store_true",
                    help="also measure Fusion, VQF and BasicVQF (downloaded, pinned) on the same boards and "
                         "on the host (callgrind), side by side with the ratios")
    ap.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    args = ap.parse_args()
    if not 20 <= args.samples <= 1000000:
        ap.error("--samples must be in 20..1000000")
    results = collections.OrderedDict()
    try:
        for preset in args.presets:
            bdir = ensure_built(args, preset)
            results[preset] = {"bench": run_bench(args, preset, bdir), "fp": footprint(args, preset, bdir),
                               "frames": stack_frames(bdir, lib=core_lib(preset))}
        if args.peers:
            peer_results = bench_peers.measure(args, results, sys.modules[__name__])
    except (BenchError, bench_peers.PeerError) as e:
        print(f"bench_firmware: {e}", file=sys.stderr)
        return 1
    except FileNotFoundError as e:
        print(f"bench_firmware: {e.filename}: not found (cross toolchain and QEMU installed? scripts/setup.sh)",
              file=sys.stderr)
        return 1
    report(args, results)
    if args.peers:
        bench_peers.report(args, results, peer_results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
