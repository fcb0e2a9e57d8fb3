"""`attekf bench`: this estimator against VQF, Fusion, Madgwick and Mahony on real recordings
(BROAD), in one run on the same trials, with the BROAD error definitions."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from typing import Dict

from .. import __version__
from . import check_settings, fraction, nonneg_int, parse_pair, positive_float, positive_int
from ..errors import InputError, Interrupted, UsageError
from ..io import read_settings_json

NAME = "bench"
HELP = "benchmark the estimator against VQF, Fusion, Madgwick, Mahony on BROAD (table, JSON, plot)"
DESCRIPTION = """\
Runs, on the same BROAD trials in one run: this estimator through the C binding (9D with the
magnetometer, 6D without), VQF (offline), Fusion (imufusion, with its gyroscope bias
correction in front as its authors run it; fusion-bare-* without), Madgwick (ahrs, beta
0.12) and Mahony (ahrs, Kp 0.74, Ki 0.0012) - the BROAD paper's best common parameters. Every output is
brought to body->ENU and scored like BROAD: e = q_est * inv(q_ref) in the earth frame; total,
heading and inclination angle; RMSE over the 'movement' samples; mean over trials, overall
and per group of trials.json. 6D methods: the mean heading offset is removed before scoring.
Per-sample cost: microseconds per sample on this machine (what is timed: see the cost table).

Outputs: tables on stdout; --json FILE; with --out DIR: DIR/table.txt (all tables, per
trial too), DIR/results.json and DIR/bench_groups.png (bar plot per group); --markdown FILE
writes the tables for docs/accuracy.md. Output paths are checked before the run; files are
written under temporary names and renamed at the end (Ctrl-C leaves none).
Details and the latest numbers: docs/accuracy.md.

Every method is scored on the same trials: 9D is not run on a trial without a usable
magnetometer (no imu_mag, or every row NaN; 6D still is), and a trial a method gives no score
on is left out of every method's mean of that dimension; the table says which and why.

Other rates and missing samples (every method, the same recordings; docs/host_tools.md):
--decimate K averages each sensor over K samples (truth and movement at each block's end);
--resample HZ goes to any rate (the integral of every sensor interpolated, so no rotation is
lost; truth by slerp); --drop P removes a random fraction P of the samples (--seed S): our
filter gets each kept sample's time step, the fixed-rate methods the nominal grid with each
missing sample replaced by the next kept one (the same gyroscope integral).

methods (--methods, comma list of keys, or names without -9d/-6d for both dimensions;
default: the ones marked *):
  ours-9d* ours-6d* vqf-9d* vqf-6d* fusion-9d* fusion-6d* madgwick-9d* mahony-9d*
  vqf-online-9d vqf-online-6d fusion-bare-9d fusion-bare-6d madgwick-6d mahony-6d
  (ours = ours-9d,ours-6d; vqf = vqf-9d,vqf-6d (offline); vqf-online; fusion; fusion-bare; ...)
  --ablation adds our filter with robustness features switched off (ours-9d:no-mag-gate ...)
  --oracle-bias adds our filter with the gyro bias taken from the truth (ANALYSIS ONLY)
  --variant NAME:SET=V,SET=V adds our filter with other settings (9D and 6D)

examples:
  attekf bench --jobs 2 --out out/bench
  attekf bench --trials 02,15 --methods ours,vqf
  attekf bench --methods ours --ablation --oracle-bias --jobs 2 --out out/ablation
  attekf bench --methods ours-9d --set accel_noise=0.3 --variant lowq:rate_walk=1.0
  attekf bench --methods ours,vqf-online --decimate 3 --jobs 2        (95.2 Hz)
  attekf bench --methods ours,vqf-online --resample 1000 --drop 0.05 --seed 1
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    from ..bench import DEFAULT_DATA, DEFAULT_DATA_TEXT
    from ..native import SCALARS
    p.add_argument("--data", default=DEFAULT_DATA, metavar="DIR",
                   help=f"directory of BROAD .hdf5 trials with trials.json (default: {DEFAULT_DATA_TEXT})")
    p.add_argument("--trials", metavar="LIST",
                   help="comma list of trial names, name prefixes (e.g. 02,15) or glob patterns")
    p.add_argument("--limit", type=positive_int, metavar="N", help="only the first N trials (after --trials)")
    p.add_argument("--methods", metavar="LIST", default="default",
                   help="comma list of method keys, or names without -9d/-6d for both dimensions (ours, vqf, "
                        "vqf-online, fusion, fusion-bare, madgwick, mahony), 9d, 6d, default, all (default: default)")
    p.add_argument("--list-methods", action="store_true", help="print the methods and exit")
    p.add_argument("--jobs", "-j", type=positive_int, default=os.cpu_count() or 1, metavar="N",
                   help="worker processes over (trial, method) pairs (default: CPU count, %(default)s)")
    p.add_argument("--scalar", choices=sorted(SCALARS), default="float",
                   help="which C build of our filter runs (default float, what ships)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="change one of our filter's settings (repeatable; attekf eval --list-settings)")
    p.add_argument("--settings", nargs="+", default=[], metavar="NAME=VALUE|FILE.json",
                   help="our filter's settings as NAME=VALUE pairs and/or a JSON file {name: value}")
    p.add_argument("--ablation", action="store_true",
                   help="also run our filter with each robustness feature off (docs/accuracy.md)")
    p.add_argument("--oracle-bias", action="store_true",
                   help="also run our filter with the gyro bias removed, taken as the mean gyro over the "
                        "samples at rest by the truth's angular rate (below 2 deg/s for at least 1 s; ANALYSIS "
                        "ONLY: what an exact offset would be worth)")
    p.add_argument("--variant", action="append", default=[], metavar="NAME:SET=V[,SET=V]",
                   help="also run our filter (9D and 6D) with these settings changed; repeatable")
    p.add_argument("--fusion-set", action="append", default=[], metavar="NAME=VALUE",
                   help="change a Fusion setting (gain, gyroscope_range, acceleration_rejection, "
                        "magnetic_rejection, rejection_timeout [s], bias_stationary_threshold "
                        "[deg/s], bias_stationary_period [s]); default: x-io's example values")
    rate = p.add_mutually_exclusive_group()
    rate.add_argument("--decimate", type=positive_int, default=1, metavar="K",
                      help="score at 1/K of the rate: each sensor the mean of K consecutive samples, truth and "
                           "movement mask of each block's last sample (default 1)")
    rate.add_argument("--resample", type=positive_float, metavar="HZ",
                      help="score at HZ (up or down): each sensor's integral interpolated by a cubic through its "
                           "exact values and differenced over the new intervals, truth by slerp")
    p.add_argument("--drop", type=fraction, default=0.0, metavar="P",
                   help="remove a random fraction P (0 <= P < 1) of the samples, after any rate change; ours gets "
                        "each kept sample's time step, the fixed-rate methods the next kept sample in the gap")
    p.add_argument("--drop-gyro", choices=("mean", "own"), default="mean",
                   help="gyroscope of a sample after dropped ones: mean = the mean rate over its whole interval "
                        "(an integrating sensor, the rotation kept; default), own = its own reading (a rate "
                        "sensor whose missed reads are lost)")
    p.add_argument("--seed", type=nonneg_int, default=0, metavar="S",
                   help="random seed of --drop (default %(default)s)")
    p.add_argument("--init-samples", type=positive_int, default=10, metavar="N",
                   help="samples averaged for the common initial attitude of Madgwick, Mahony and "
                        "Fusion (default 10, our filter's align_samples)")
    p.add_argument("--out", metavar="DIR", help="write table.txt, results.json, bench_groups.png")
    p.add_argument("--json", metavar="FILE", help="write the results as JSON here (default DIR/results.json)")
    p.add_argument("--markdown", metavar="FILE", help="write the tables as Markdown (docs/accuracy.md)")
    p.add_argument("--no-plot", action="store_true", help="no plot")
    p.add_argument("--per-trial", action="store_true", help="also print the per-trial total RMSE table")


def transform_from_args(args):
    """The Transform of --decimate / --resample / --drop / --seed."""
    from ..transform import Transform
    return Transform(decimate=args.decimate, resample_hz=args.resample, drop=args.drop, seed=args.seed,
                     drop_gyro=args.drop_gyro)


def _parse_settings(args) -> Dict[str, float]:
    """--settings (NAME=VALUE pairs and JSON files) then --set; each origin checked by the C
    library now, before the pool starts (a refused setting: exit 2, naming its origin)."""
    out: Dict[str, float] = {}
    for item in args.settings:
        if "=" not in item and item.endswith(".json"):
            from_file = read_settings_json(item)
            check_settings(args.scalar, from_file, item)
            out.update(from_file)
        else:
            k, v = parse_pair(item, "--settings")
            out[k] = v
    for item in args.set:
        k, v = parse_pair(item, "--set")
        out[k] = v
    return out


def _parse_variants(items) -> Dict[str, Dict[str, object]]:
    out: Dict[str, Dict[str, object]] = {}
    for item in items:
        name, sep, rest = item.partition(":")
        if not sep or not name.strip() or not rest.strip():
            raise UsageError(f"--variant {item!r}: expected NAME:SETTING=VALUE[,SETTING=VALUE]")
        changes = dict(parse_pair(p, "--variant") for p in rest.split(",") if p.strip())
        for six, d in ((False, "9d"), (True, "6d")):
            out[f"ours-{d}:{name.strip()}"] = {"name": name.strip(), "settings": changes, "six_d": six}
    return out


def _check_ours_settings(methods, cfg) -> list:
    """Refuses unknown/invalid settings before the pool starts; drops ablation variants whose
    settings this build does not have (with a note)."""
    from .. import native
    from ..bench import ABLATIONS
    if not any(m.family == "ours" for m in methods):
        return methods
    native._make_settings(native.load(cfg.scalar), cfg.settings)   # raises SettingsError
    from ..bench import resolve_setting
    known = native.load(cfg.scalar).setting_names
    base = native.default_settings(cfg.scalar)
    base.update(cfg.settings)
    ablations = {a[0] for a in ABLATIONS}
    kept = []
    for m in methods:
        if m.key.split(":")[-1] in ablations:
            names = {k: resolve_setting(k, known) for k in m.settings}
            missing = [k for k, v in names.items() if v is None]
            if missing:
                print(f"note: {m.key} skipped: this build has no setting {', '.join(missing)}",
                      file=sys.stderr)
                continue
            same = all(math.isclose(float(base[names[k]]), float(v), rel_tol=1e-6, abs_tol=1e-12)
                       for k, v in m.settings.items())
            if same:
                print(f"note: {m.key} skipped: {', '.join(f'{names[k]}={v:g}' for k, v in m.settings.items())} "
                      "is already this run's setting (feature off)", file=sys.stderr)
                continue
            cfg.rename.update({k: v for k, v in names.items() if v != k})
        if m.settings:
            merged = dict(cfg.settings)
            merged.update({cfg.rename.get(k, k): v for k, v in m.settings.items()})
            try:
                native._make_settings(native.load(cfg.scalar), merged)
            except native.SettingsError as exc:
                if m.key.split(":")[-1] not in ablations:   # the user's own --variant: an error
                    raise native.SettingsError(f"--variant {m.key.split(':', 1)[-1]}: {exc}") from None
                print(f"note: {m.key} skipped: {exc}", file=sys.stderr)
                continue
        kept.append(m)
    return kept


def run(args: argparse.Namespace) -> int:
    from .. import bench

    cfg = bench.RunConfig(scalar=args.scalar, settings=_parse_settings(args),
                          init_samples=args.init_samples, variants=_parse_variants(args.variant),
                          transform=transform_from_args(args))
    for item in args.fusion_set:
        k, v = parse_pair(item, "--fusion-set")
        if k not in bench.FUSION_SETTINGS:
            raise UsageError(f"--fusion-set {item!r}: unknown Fusion setting (known: "
                             f"{', '.join(bench.FUSION_SETTINGS)})")
        cfg.fusion[k] = v
    if args.list_methods:
        for m in bench.all_methods(cfg).values():
            print(f"  {m.key:32s} {m.dim}  {'default ' if m.default else '        '}{m.label}")
        return 0
    try:
        methods = bench.select_methods(args.methods, args.ablation, args.oracle_bias, cfg)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if cfg.settings and any(m.family == "ours" for m in methods):
        check_settings(cfg.scalar, cfg.settings)
    from ..outputs import Outputs
    with Outputs() as out:
        plan = {"json": args.json or (os.path.join(args.out, "results.json") if args.out else None)}
        if args.out:
            out.directory(args.out, "--out")
            plan["table"] = out.file(os.path.join(args.out, "table.txt"), "--out")
            if not args.no_plot:
                plan["plot"] = out.file(os.path.join(args.out, "bench_groups.png"), "--out")
        out.file(plan["json"], "--json" if args.json else "--out")
        plan["markdown"] = out.file(args.markdown, "--markdown")
        try:
            paths = bench.find_trials(args.data, args.trials, args.limit)
        except FileNotFoundError as exc:
            raise InputError(str(exc)) from None
        except ValueError as exc:     # --trials names no trial
            raise UsageError(str(exc)) from None
        if not paths:
            raise UsageError("no trial selected")
        out.inputs(paths)
        missing = bench.missing_packages(methods)
        if missing:
            raise InputError("; ".join(f"{k} needs the Python package '{p}'" for k, p in missing.items())
                             + " (install host_tools/requirements.lock: scripts/setup.sh, or pip install "
                             "'attekf[bench]'; or leave these out with --methods)")
        methods = _check_ours_settings(methods, cfg)
        for p in paths:   # fail early, with the file named, before the pool starts
            rec = bench.read_recording(p)
            if not rec.has_truth:
                raise InputError(f"{p}: no ground truth (opt_quat): nothing to score")
            try:
                cfg.transform.apply(rec)       # a recording too short for it: said now, not in a worker
            except ValueError as exc:
                raise InputError(str(exc)) from None      # names the file
        return _bench(args, paths, methods, cfg, out, plan)


def _bench(args, paths, methods, cfg, out, plan) -> int:
    from .. import bench
    from ..progress import bar

    n_tasks = len(paths) * len(methods)
    try:
        with bar(n_tasks, f"bench {len(paths)} trials x {len(methods)} methods", args.quiet, unit="run") as pb:
            result = bench.run_benchmark(paths, methods, cfg, jobs=args.jobs, progress=pb.update,
                                         data_dir=args.data)
    except KeyboardInterrupt:
        raise Interrupted(f"{len(paths)} trials x {len(methods)} methods not finished: nothing written "
                          "(outputs are only put in place when complete)") from None
    result["tool"] = f"attekf bench {__version__}"
    result["command"] = "attekf bench " + " ".join(_argv_tail())
    summary = bench.format_summary(result)
    print(summary)
    if args.per_trial:
        print()
        print(bench.format_trials(result))
        print()
        print(bench.format_consistency(result))
    print()
    costs = bench.format_costs(result)
    print(costs)
    git = result["git"]
    print(f"\ncommit {git.get('commit')}{' + uncommitted changes' if git.get('uncommitted_changes') else ''}; "
          f"{result['wall_seconds']:.0f} s wall with --jobs {args.jobs}")
    if any(m.analysis_only for m in methods):
        print("ANALYSIS ONLY rows use ground-truth knowledge (the movement mask): not results.")
    clean = bench.clean_json(result)
    if plan.get("table"):
        with out.open(plan["table"]) as fh:
            fh.write(summary + "\n\n" + bench.format_trials(result) + "\n\n"
                     + bench.format_trials(result, "heading") + "\n\n"
                     + bench.format_trials(result, "inclination") + "\n\n"
                     + bench.format_consistency(result) + "\n\n" + costs + "\n"
                     + f"\ncommand: {result['command']}\ncommit: {git.get('commit')}"
                     + (" + uncommitted changes" if git.get("uncommitted_changes") else "") + "\n")
    if plan.get("plot"):
        bench.plot_groups(result, out.temp(plan["plot"]))
    if plan.get("markdown"):
        with out.open(plan["markdown"]) as fh:
            fh.write(bench.format_markdown(result))
    if plan.get("json"):
        with out.open(plan["json"]) as fh:
            json.dump(clean, fh, indent=1, allow_nan=False)
            fh.write("\n")
    written = out.commit()
    if written and not args.quiet:
        print("wrote " + ", ".join(written), file=sys.stderr)
    return 0


def _argv_tail():
    """The command line after 'bench' (as typed), or a marker when called from Python."""
    argv = sys.argv[1:]
    if NAME not in argv:
        return ["(called from Python; arguments not recorded)"]
    return argv[argv.index(NAME) + 1:]
