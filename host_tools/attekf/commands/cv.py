"""`attekf cv`: leave-one-group-out cross-validation of the estimator's settings on BROAD."""

from __future__ import annotations

import argparse
import os
import sys

from ..errors import InputError, UsageError

NAME = "cv"
HELP = "cross-validate the estimator's settings over groups of BROAD trials (leave one group out)"
DESCRIPTION = """\
Chooses the estimator's settings by leave-one-group-out cross-validation over the BROAD
trials (host_tools/attekf/cv.py; docs/accuracy.md, "Tuning protocol"): every trial belongs to
one fold (rotation, translation, tapping, vibration, stationary_magnet, attached_magnet, ... of
trials.json); for each fold the accuracy settings are chosen on the other folds' trials (a
small grid, plateau-smoothed objective: mean of the 9D and 6D total RMSE) and the fold is
scored with them; the reported-covariance settings likewise (the cheapest that covers 97 % on
every training trial). Prints the cross-validated and the in-sample figures, VQF beside, the
coverage per trial and the sensitivity of each tuned setting.

--decimate K1,K2,... and --resample HZ1,... cross-validate over rates as well: every run is
made at each rate (transform.py: each sensor averaged over K samples / resampled to HZ) and a
trial's score is the mean over the rates, so that the settings chosen serve all of them.

examples:
  attekf cv --jobs 2 --out out/cv
  attekf cv --jobs 2 --decimate 1,3 --resample 1000
  attekf cv --grid accel_noise=0.3,0.5 --grid accel_lpf_tau=0.7,1.0 --grid mag_heading_noise=0.5 --trials 02,16,30
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    from ..bench import DEFAULT_DATA, DEFAULT_DATA_TEXT
    from ..native import SCALARS
    p.add_argument("--data", default=DEFAULT_DATA, metavar="DIR",
                   help=f"directory of BROAD .hdf5 trials with trials.json (default: {DEFAULT_DATA_TEXT})")
    p.add_argument("--trials", metavar="LIST", help="comma list of trial names or prefixes (default: all)")
    p.add_argument("--jobs", "-j", type=int, default=os.cpu_count() or 1, metavar="N", help="worker processes")
    p.add_argument("--scalar", choices=sorted(SCALARS), default="float", help="C build (default float)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a setting held fixed for every run (repeatable)")
    p.add_argument("--grid", action="append", default=[], metavar="NAME=V1,V2,...",
                   help="a tuned setting and its grid values (repeatable; replaces the default grid: "
                        "accel_noise, accel_lpf_tau, mag_heading_noise, bias.walk)")
    p.add_argument("--decimate", metavar="K1,K2,...",
                   help="score every run at each of these decimations (1 = the native rate) and average")
    p.add_argument("--resample", metavar="HZ1,HZ2,...",
                   help="score every run at each of these rates too (resampled) and average")
    p.add_argument("--tune-covariance", action="store_true",
                   help="choose the reported-covariance settings (angle_walk_rate, accel_ref_sigma, "
                        "mag_ref_sigma) per fold as well, the cheapest covering every training trial; by "
                        "default they stay at the shipped (or --set) values: they describe the device and "
                        "the place, which a left-out trial need not share")
    p.add_argument("--no-vqf", action="store_true", help="do not run VQF for the comparison columns")
    p.add_argument("--out", metavar="DIR", help="write cv.txt and cv.json into DIR")


def _pairs(items, what):
    out = []
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise InputError(f"{what} {item!r}: expected NAME=VALUE")
        try:
            vals = [float(v) for v in value.split(",") if v.strip()]
        except ValueError:
            raise InputError(f"{what} {item!r}: '{value}' is not a number list") from None
        if not vals:
            raise InputError(f"{what} {item!r}: no value")
        out.append((name.strip(), vals))
    return out


def transforms_from_args(args):
    """The rates of --decimate and --resample (the native rate when neither is given)."""
    from ..transform import Transform

    def numbers(text, what, convert):
        try:
            vals = [convert(v) for v in text.split(",") if v.strip()]
            if not vals:
                raise ValueError
            return vals
        except ValueError:
            raise UsageError(f"{what} {text!r}: expected a comma list of numbers") from None

    out = []
    try:
        for k in numbers(args.decimate, "--decimate", int) if args.decimate else []:
            out.append(Transform(decimate=k))
        for hz in numbers(args.resample, "--resample", float) if args.resample else []:
            out.append(Transform(resample_hz=hz))
    except ValueError as exc:
        raise UsageError(f"--decimate/--resample: {exc}") from None
    if len(set(out)) != len(out):
        raise UsageError("--decimate/--resample: a rate is given twice")
    return out or [Transform()]


def run(args: argparse.Namespace) -> int:
    from .. import bench, cv, native
    from ..progress import bar
    if args.jobs < 1:
        raise UsageError("--jobs must be >= 1")
    tfs = transforms_from_args(args)
    base = {k: v[0] for k, v in _pairs(args.set, "--set")}
    grid = _pairs(args.grid, "--grid") or cv.DEFAULT_GRID
    lib = native.load(args.scalar)
    for name, vals in grid:     # refuse unknown names and out-of-range values before any run
        for v in vals:
            native._make_settings(lib, dict(base, **{name: v}))
    try:
        shipped = cv.shipped_covariance(native.default_settings(args.scalar), base)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    try:
        paths = bench.find_trials(args.data, args.trials)
    except FileNotFoundError as exc:
        raise InputError(str(exc)) from None
    try:
        cv.folds([os.path.splitext(os.path.basename(p))[0] for p in paths], bench.load_groups(args.data)[1])
    except ValueError as exc:
        raise InputError(str(exc)) from None
    if tfs != [bench.Transform()]:
        for p in paths:      # a trial too short for a rate: said now, not in a worker
            rec = bench.read_recording(p)
            for tf in tfs:
                try:
                    tf.apply(rec)
                except ValueError as exc:
                    raise InputError(str(exc)) from None      # names the file
    log = (lambda m: None) if args.quiet else (lambda m: print(m, file=sys.stderr))
    with bar(None, "cv runs", args.quiet, unit="run") as pb:
        result = cv.run_cv(paths, args.data, grid, base, args.scalar, args.jobs, pb.update, log, tfs,
                           args.tune_covariance, shipped)
        vqf = None if args.no_vqf else cv.vqf_scores(paths, args.jobs, pb.update, tfs)
    result["vqf"] = vqf
    git = bench.git_info(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    result["git"] = git
    result["command"] = "attekf cv " + " ".join(sys.argv[sys.argv.index(NAME) + 1:]) if NAME in sys.argv else "attekf cv"
    text = cv.format_report(result, vqf)
    text += (f"\n\ncommit {git.get('commit')}{' + uncommitted changes' if git.get('uncommitted_changes') else ''}; "
             f"command: {result['command']}")
    print(text)
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "cv.txt"), "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
        cv.save(os.path.join(args.out, "cv.json"), result)
    return 0
