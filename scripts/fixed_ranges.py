#!/usr/bin/env python3
"""Measured ranges behind the fixed-point formats (docs/fixed_point.md, "Measured ranges").

Builds the estimator in double precision with every scalar operation, every att_step and
every covariance operation recorded (tests/ranges/instr_scalar.h, instr.c; the estimator's
sources compiled unchanged), with the fixed-point build's default settings where they differ
from double's, and runs it on

  broad      the BROAD trials through the Python binding (attekf bench, 9D and 6D),
  stress     tests/c/test_att_stress.c (10^6 random steps, valid and invalid input),
  envelope   tests/c/test_fixed_envelope.c (10^6 random steps inside the envelope).

Prints, per run, the range of every quantity (smallest non-zero and largest magnitude and
the 0.1 % / 99.9 % quantiles of the magnitude) as Markdown tables, with the commit.

    scripts/fixed_ranges.py [--runs broad stress envelope] [--trials LIST] [--quiet]

Needs build/host (scripts/setup.sh: Unity's sources are taken from its _deps) and, for
broad, the BROAD data (../shared/data/broad or $ATTEKF_BROAD_DIR).
"""
import argparse
import glob
import math
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "build", "ranges")
BIN_LO, BINS = -120, 160


class RangesError(Exception):
    pass


def log(args, msg):
    if not args.quiet:
        print(f"[ranges] {msg}", file=sys.stderr, flush=True)


def run(cmd, env=None, cwd=ROOT):
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    if r.returncode != 0:
        raise RangesError(f"{' '.join(cmd[:3])} ... failed (exit {r.returncode}):\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
    return r.stdout


def fixed_setting_overrides():
    """Settings whose default differs between the fixed-point and the double build."""
    sys.path.insert(0, os.path.join(ROOT, "host_tools"))
    from attekf import native  # noqa: E402 (the package of this tree)
    fx, db = native.default_settings("fixed"), native.default_settings("double")
    return {k: v for k, v in fx.items() if k in db and v != db[k]}


def build(args):
    """The instrumented library (for the binding) and the two drivers."""
    os.makedirs(os.path.join(OUT, "obj"), exist_ok=True)
    os.makedirs(os.path.join(OUT, "lib"), exist_ok=True)
    unity = os.path.join(ROOT, "build", "host", "_deps", "unity-2.6.1")
    if not os.path.isfile(os.path.join(unity, "unity.c")):
        raise RangesError(f"{os.path.relpath(unity, ROOT)}/unity.c not found: build build/host first (scripts/setup.sh)")
    inc = ["-I", os.path.join(ROOT, "firmware", "ekf"), "-I", os.path.join(ROOT, "firmware", "att")]
    base = ["gcc", "-std=c99", "-O2", "-fPIC", "-DEKF_SCALAR_DOUBLE=1", "-D_POSIX_C_SOURCE=200809L"] + inc
    forced = ["-include", os.path.join(ROOT, "tests", "ranges", "instr_scalar.h")]
    sources = [os.path.join(ROOT, "firmware", "ekf", "ekf.c"), os.path.join(ROOT, "firmware", "ekf", "ekf_math.c")]
    sources += sorted(glob.glob(os.path.join(ROOT, "firmware", "att", "*.c")))
    objs = []
    log(args, f"compiling {len(sources)} estimator sources, instrumented")
    for src in sources:
        name = os.path.basename(src)
        extra = ["-DINSTR_NO_API"] if name == "att.c" else ["-DINSTR_NO_COV"] if name.startswith("att_cov_") else []
        obj = os.path.join(OUT, "obj", name + ".o")
        run(base + forced + extra + ["-c", src, "-o", obj])
        objs.append(obj)
    instr = os.path.join(OUT, "obj", "instr.o")
    run(base + ["-c", os.path.join(ROOT, "tests", "ranges", "instr.c"), "-o", instr])
    objs.append(instr)
    # the Python extension module of the double build (host_tools/native), linked with them
    native = os.path.join(ROOT, "host_tools", "native")
    py = os.path.join(ROOT, ".venv", "bin", "python")
    inc_py, inc_np, suffix = run([py, "-c", "import sysconfig, numpy; print(sysconfig.get_paths()['include']); "
                                  "print(numpy.get_include()); print(sysconfig.get_config_var('EXT_SUFFIX'))"]).split()
    lib = os.path.join(OUT, "lib", "_core_d" + suffix)
    core = [os.path.join(native, f) for f in ("core_module.c", "core_filter.c", "core_io.c")]
    run(base + forced + ["-I", native, "-isystem", inc_py, "-isystem", inc_np, "-DCORE_MODULE=_core_d",
                         '-DCORE_LAYOUT="instrumented"', "-shared"] + core + objs + ["-o", lib, "-lm"])
    drivers = {}
    support = os.path.join(ROOT, "tests", "c", "support")
    for name, test in (("stress", "test_att_stress.c"), ("envelope", "test_fixed_envelope.c")):
        exe = os.path.join(OUT, f"ranges_{name}")
        run(base + ["-I", support, "-I", unity, "-Datt_default_settings=instr_default_settings",
                    "-Datt_step=instr_att_step", os.path.join(ROOT, "tests", "c", test),
                    os.path.join(support, "testsim.c"), os.path.join(unity, "unity.c")] + objs + ["-o", exe, "-lm"])
        drivers[name] = exe
    return lib, drivers


def read_stats(directory):
    merged = {}
    for path in glob.glob(os.path.join(directory, "ranges_*.txt")):
        with open(path, encoding="utf-8") as f:
            for line in f:
                p = line.split()
                name, n, zeros, mn, mx = p[0], int(p[1]), int(p[2]), float(p[3]), float(p[4])
                hist = [int(v) for v in p[5:5 + BINS]]
                m = merged.setdefault(name, {"n": 0, "zeros": 0, "min": math.inf, "max": 0.0, "hist": [0] * BINS})
                m["n"] += n
                m["zeros"] += zeros
                if n > zeros:
                    m["min"] = min(m["min"], mn)
                m["max"] = max(m["max"], mx)
                m["hist"] = [a + b for a, b in zip(m["hist"], hist)]
    if not merged:
        raise RangesError(f"no statistics written to {os.path.relpath(directory, ROOT)}")
    return merged


def quantile(m, q):
    """Quantile q of the non-zero magnitudes: log-linear within its log2 bin, within the
    smallest and largest value seen."""
    hist = m["hist"]
    total = sum(hist)
    if total == 0:
        return None
    acc = 0
    for b, c in enumerate(hist):
        if c > 0 and acc + c >= q * total:
            frac = (q * total - acc) / c
            return min(max(2.0 ** (b + BIN_LO + frac), m["min"]), m["max"])
        acc += c
    return m["max"]


def fmt(v):
    if v is None or (isinstance(v, float) and (math.isinf(v) or v == 0.0)):
        return "-"
    return f"{v:.2g}"


def report(name, stats, cmd):
    print(f"\n### {name}\n\n`{cmd}`\n")
    print("| quantity | count | zeros | smallest | 0.1 % | 99.9 % | largest |")
    print("|---|---|---|---|---|---|---|")
    for q, m in stats.items():
        if m["n"] == 0:
            continue
        print(f"| {q} | {m['n']:,} | {m['zeros']:,} | {fmt(m['min'])} | {fmt(quantile(m, 0.001))} | "
              f"{fmt(quantile(m, 0.999))} | {fmt(m['max'])} |")


def commit():
    try:
        head = run(["git", "rev-parse", "--short", "HEAD"]).strip()
        dirty = run(["git", "status", "--porcelain", "--", "firmware", "tests", "scripts"]).strip()
    except RangesError:
        return "unknown commit"
    return head + (" with uncommitted changes" if dirty else "")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--runs", nargs="+", default=["broad", "stress", "envelope"], choices=["broad", "stress", "envelope"])
    ap.add_argument("--trials", default=None, help="BROAD trials (attekf bench --trials), default all")
    ap.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    args = ap.parse_args()
    try:
        overrides = fixed_setting_overrides()
        lib, drivers = build(args)
        env = dict(os.environ)
        if "gimbal_limit" in overrides:
            env["INSTR_GIMBAL_LIMIT"] = repr(overrides["gimbal_limit"])
        if "var_floor" in overrides:
            env["INSTR_VAR_FLOOR"] = repr(overrides["var_floor"])
        print(f"Measured at {commit()}: the double build, instrumented, with the fixed-point defaults "
              f"{', '.join(f'{k} = {v:g}' for k, v in sorted(overrides.items())) or '(none differ)'}.")
        for r in args.runs:
            out = os.path.join(OUT, "out", r)
            os.makedirs(out, exist_ok=True)
            for old in glob.glob(os.path.join(out, "ranges_*.txt")):
                os.remove(old)
            env["INSTR_OUT"] = out
            if r == "broad":
                cmd = [os.path.join(ROOT, ".venv", "bin", "attekf"), "bench", "--scalar", "double",
                       "--methods", "ours-9d,ours-6d", "--jobs", "1", "-q", "--no-plot"]
                cmd += [a for k, v in sorted(overrides.items()) for a in ("--set", f"{k}={v!r}")]
                if args.trials:
                    cmd += ["--trials", args.trials]
                log(args, "BROAD through the binding (one process: the recorders write at exit)")
                run(cmd, env=dict(env, ATTEKF_LIB=os.path.dirname(lib)))
                shown = "attekf bench --scalar double --methods ours-9d,ours-6d (instrumented library)"
            else:
                log(args, f"{r}: 10^6 steps")
                run([drivers[r]], env=env)
                shown = f"tests/c/{'test_att_stress.c' if r == 'stress' else 'test_fixed_envelope.c'} (instrumented)"
            report(r, read_stats(out), shown)
    except RangesError as e:
        print(f"fixed_ranges: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
