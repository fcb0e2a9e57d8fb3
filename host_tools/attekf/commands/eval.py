"""`attekf eval`: run the C estimator over recordings (or take a recorded output) and score it
against the ground truth with the BROAD definitions."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from typing import Dict, List

from .. import __version__
from . import add_settings_arguments, finite_float, list_settings, parse_settings
from ..errors import InputError, Interrupted, UsageError
from ..extras import require
from ..io import read_output_csv, read_recording

NAME = "eval"
HELP = "evaluate the estimator against ground truth (table, JSON, plots)"
DESCRIPTION = """\
Runs the C estimator (through the binding: the same code as the firmware) over each
recording, or takes a recorded estimator output (--output-csv), and computes the BROAD
orientation errors: error quaternion e = q_est * inv(q_ref) in the earth frame; total,
heading and inclination angle; RMSE over the 'movement' samples, degrees. A directory
evaluates every .csv/.hdf5/.h5 recording in it, with a per-trial and a mean table.

Outputs: the table on stdout; with --out DIR also DIR/table.txt, DIR/results.json and one
plot per trial DIR/<trial>.png (Euler angles vs truth; errors with the filter's 3-sigma
bounds). Without magnetometer (--no-mag, or none in the file) the scoring is 6D: the mean
heading offset is removed first. Output paths are checked before the
work starts; the files are written under temporary names and renamed together at the end,
so an error or Ctrl-C leaves none of them (and earlier files of the same names unchanged).

examples:
  attekf eval out/demo/recordings/undisturbed.csv --out out/eval
  attekf eval ../shared/data/broad --out out/broad --no-plot
  attekf eval trial.csv --output-csv recorded.csv
  attekf eval trial.csv --set accel_noise=0.3 --set mag_gate=0
  attekf eval --list-settings
"""

RECORDING_EXTS = (".csv", ".hdf5", ".h5")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("inputs", nargs="*", metavar="RECORDING",
                   help="recording files (.csv, .hdf5, .h5) or directories of them")
    p.add_argument("--output-csv", metavar="FILE",
                   help="score this recorded estimator output instead of running the estimator "
                        "(one recording only; the format `attekf run` writes, see attekf run --help)")
    p.add_argument("--time-offset", type=finite_float, default=0.0, metavar="S",
                   help="added to the output file's t_s before matching it to samples (default 0)")
    add_settings_arguments(p)
    p.add_argument("--no-mag", action="store_true",
                   help="run without the magnetometer and score 6D (mean heading offset removed)")
    p.add_argument("--out", metavar="DIR", help="write table.txt, results.json and plots into DIR")
    p.add_argument("--json", metavar="FILE", help="write the results as JSON here (default DIR/results.json)")
    p.add_argument("--no-plot", action="store_true", help="no plots")
    p.add_argument("--save-output", action="store_true",
                   help="also write each run's estimator output as DIR/<trial>_output.csv")
    p.add_argument("--no-unit-check", action="store_true",
                   help="accept data whose magnitudes look like other units (deg/s, g, gauss)")


def _collect(inputs: List[str]) -> List[str]:
    files: List[str] = []
    for path in inputs:
        if os.path.isdir(path):
            try:
                names = os.listdir(path)
            except OSError as exc:
                raise InputError(f"{path}: cannot read the directory: {exc.strerror or exc}") from None
            found = sorted(os.path.join(path, f) for f in names
                           if f.lower().endswith(RECORDING_EXTS) and not f.endswith("_output.csv")
                           and not f.startswith(".") and os.path.isfile(os.path.join(path, f)))
            if not found:
                raise InputError(f"{path}: no recordings (.csv, .hdf5, .h5) in this directory")
            files += found
        else:
            files.append(path)
    return files


def run(args: argparse.Namespace) -> int:
    if args.list_settings:
        return list_settings(args.scalar)
    if not args.inputs:
        raise UsageError("no recording given (see --help)")
    if args.save_output and not args.out:
        raise UsageError("--save-output needs --out DIR")
    settings = parse_settings(args)
    files = _collect(args.inputs)
    if args.output_csv and len(files) != 1:
        raise UsageError(f"--output-csv scores one recording, {len(files)} given")
    if args.out and not args.no_plot:
        require("matplotlib", "the plots of attekf eval (or --no-plot)", "plots")
    from ..outputs import Outputs
    with Outputs() as out:
        out.inputs(files + [args.output_csv, args.settings])
        plan = _plan_outputs(args, files, out)
        _evaluate(args, files, settings, out, plan)
    return 0


def _trial_names(files: List[str]) -> List[str]:
    """A table name per file: the file name without extension, made unique by its directory
    (same stem in two directories) and, failing that, by the extension."""
    stems = [os.path.splitext(os.path.basename(p))[0] for p in files]
    names = []
    for p, stem in zip(files, stems):
        name = stem
        if stems.count(stem) > 1:
            name = f"{stem}@{os.path.basename(os.path.dirname(os.path.abspath(p)))}"
        if name in names:
            name = f"{name}.{os.path.splitext(p)[1].lstrip('.').lower()}"
        k = 2
        base = name
        while name in names:
            name = f"{base}#{k}"
            k += 1
        names.append(name)
    return names


def _plan_outputs(args, files: List[str], out) -> Dict[str, object]:
    """Declares (and so checks, before any work) every file this run will write."""
    names = _trial_names(files)
    plan: Dict[str, object] = {"names": names, "plots": {}, "saved": {}}
    if args.out:
        out.directory(args.out, "--out")
        plan["table"] = out.file(os.path.join(args.out, "table.txt"), "--out")
        if not args.no_plot:
            plan["plots"] = {n: out.file(os.path.join(args.out, f"{n}.png"), "--out") for n in names}
        if args.save_output:
            plan["saved"] = {n: out.file(os.path.join(args.out, f"{n}_output.csv"), "--save-output")
                             for n in names}
    json_path = args.json or (os.path.join(args.out, "results.json") if args.out else None)
    plan["json"] = out.file(json_path, "--json" if args.json else "--out")
    return plan


def _evaluate(args, files: List[str], settings: Dict[str, float], out, plan) -> None:
    from ..evaluate import evaluate_output, evaluate_run, format_table, mean_row
    from ..progress import bar

    trials = []
    try:
        for path, name in zip(files, plan["names"]):
            with bar(None, f"reading {os.path.basename(path)}", args.quiet, unit="row") as pb:
                rec = read_recording(path, check_units=not args.no_unit_check, progress=pb.update)
            if args.output_csv:
                tr = evaluate_output(rec, read_output_csv(args.output_csv), six_d=args.no_mag or rec.mag is None,
                                     time_offset_s=args.time_offset)
            else:
                with bar(len(rec), f"{name}", args.quiet, unit="sample") as pb:
                    tr, res = evaluate_run(rec, settings, scalar=args.scalar, use_mag=not args.no_mag,
                                           progress=pb.update)
                if args.save_output:
                    from ..output_file import write_result_csv
                    with bar(len(rec), f"writing {name}_output.csv", args.quiet, unit="row") as pb:
                        write_result_csv(out.temp(plan["saved"][name]), res, progress=pb.update)
            tr.name = name
            trials.append(tr)
            if name in plan["plots"]:
                from ..plots import PLOT_STEPS, plot_trial
                with bar(PLOT_STEPS, f"plotting {name}", args.quiet, unit="step") as pb:
                    plot_trial(tr, out.temp(plan["plots"][name]), progress=pb.update)
    except KeyboardInterrupt:
        raise Interrupted(f"after {len(trials)} of {len(files)} recording(s): nothing written "
                          "(outputs are only put in place when complete)") from None

    table = format_table(trials)
    print(table)
    notes = _notes(trials)
    for line in notes:
        print(line)
    result = {
        "tool": f"attekf eval {__version__}",
        "estimator": "recorded output" if args.output_csv else f"C estimator ({args.scalar})",
        "settings_changed": settings,
        "settings": None,
        "trials": [t.to_json() for t in trials],
        "mean_rmse_deg": {k: (v if math.isfinite(v) else None) for k, v in mean_row(trials).items()},
    }
    if not args.output_csv:
        from ..native import default_settings
        used = default_settings(args.scalar)
        used.update(settings)
        result["settings"] = used
    if plan.get("table"):
        with out.open(plan["table"]) as fh:
            fh.write(table + "\n" + "".join(n + "\n" for n in notes))
    if plan["json"]:
        with out.open(plan["json"]) as fh:
            json.dump(result, fh, indent=2)
            fh.write("\n")
    written = out.commit()
    if written and not args.quiet:
        plots = len(plan["plots"])
        print("wrote " + ", ".join(p for p in written if not p.endswith((".png", "_output.csv")))
              + (f", {plots} plot(s)" if plots else "")
              + (f", {len(plan['saved'])} output CSV(s)" if plan["saved"] else "")
              + (f" in {args.out}" if args.out else ""), file=sys.stderr)


def _notes(trials) -> List[str]:
    """Lines for everything that was not scored or was refused, so that nothing goes unseen."""
    out = []
    for tr in trials:
        c = tr.counts
        parts = []
        if not tr.has_truth:
            parts.append("no ground truth: nothing scored (attekf run writes the estimator's output)")
        for key, label in (("movement_without_truth", "movement samples without truth"),
                           ("movement_without_estimate", "movement samples without estimate"),
                           ("refused", "samples refused by the estimator"),
                           ("output_rows_unmatched", "output rows matching no sample"),
                           ("output_rows_duplicate", "output rows for an already-matched sample")):
            if c.get(key):
                parts.append(f"{c[key]} {label}")
        sc = tr.estimator_summary.get("status_counts") if tr.estimator_summary else None
        if c.get("refused") and sc:
            parts.append("status: " + "; ".join(f"{col} " + ", ".join(f"{k} x{v}" for k, v in d.items())
                                                for col, d in sc.items()))
        if parts:
            out.append(f"note: {tr.name}: " + ", ".join(parts))
    return out
