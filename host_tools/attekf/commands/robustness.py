"""`attekf robustness`: the scorecard of issue 22's targets, ours beside VQF in one run."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from . import positive_int
from .. import __version__
from ..errors import InputError, Interrupted, UsageError

NAME = "robustness"
HELP = "scorecard of the robustness targets (other rates, flips, tumbles, glitches, gaps, drops) beside VQF"
DESCRIPTION = """\
Measures, in one run and side by side with VQF online (and VQF offline on BROAD), each target
of the robustness scorecard with its target and pass/miss (definitions: docs/accuracy.md, "How
the robustness targets are measured"):

  rates        BROAD at its rate, 1/2, 1/3, 1/4 of it (each sensor averaged) and resampled to
               1000 Hz: 9D and 6D total RMSE; ours at 1/3 of the rate against ours native
  flips        360 deg flips about body y (closest approach to the vertical 0-5 deg) at 100,
               200, 500 Hz x 360, 720 deg/s peak rate, --mc runs per cell: 6D heading change
               across the flip, 9D peak total error; coverage of our reported 3 sigma
  tumbles      the same for three rotations about random axes
  post-motion  BROAD: mean inclination error 2-12 s after each motion period that ends in at
               least 12 s of rest (rest from the truth's rate)
  glitch       20/60/120 deg gyro glitches at rest (100 Hz): seconds until the error stays
               below 2 deg
  drops        5 % of BROAD trial --drop-trial's samples dropped (seed 1), the gyro after a
               drop as the mean over its interval and as its own reading: 6D and 9D change
  gap          0.3 s of samples missing in a 180 deg/s rotation (100 Hz): error after, our
               reported sigma there, error 20 s later

Simulated recordings come from `attekf sim --scenario` (scenarios.py), seeds fixed: the same
command gives the same table. The BROAD parts need the data (--data); the others do not.

examples:
  attekf robustness --jobs 2
  attekf robustness --jobs 2 --json out/robustness.json --set accel_noise=0.5
  attekf robustness --parts flips,tumbles --mc 5
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    from ..bench import DEFAULT_DATA, DEFAULT_DATA_TEXT
    from ..native import SCALARS
    from ..scorecard import DROP_TRIAL, PARTS
    p.add_argument("--data", default=DEFAULT_DATA, metavar="DIR",
                   help=f"directory of BROAD .hdf5 trials (default: {DEFAULT_DATA_TEXT})")
    p.add_argument("--trials", metavar="LIST", help="BROAD trials of the rates and post-motion parts: comma "
                   "list of names, prefixes or glob patterns (default: all)")
    p.add_argument("--drop-trial", default=DROP_TRIAL, metavar="NAME",
                   help="BROAD trial of the drops part, a name or prefix (default %(default)s)")
    p.add_argument("--parts", default=",".join(PARTS), metavar="LIST",
                   help=f"comma list of parts to run (default: all: {','.join(PARTS)})")
    p.add_argument("--mc", type=positive_int, default=20, metavar="N",
                   help="flips and tumbles per cell of rate x peak rate (default %(default)s)")
    p.add_argument("--jobs", "-j", type=positive_int, default=os.cpu_count() or 1, metavar="N",
                   help="worker processes (default: CPU count, %(default)s)")
    p.add_argument("--scalar", choices=sorted(SCALARS), default="float", help="C build of our filter (default float)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="change one of our filter's settings (repeatable)")
    p.add_argument("--settings", nargs="+", default=[], metavar="NAME=VALUE|FILE.json",
                   help="our filter's settings as NAME=VALUE pairs and/or a JSON file {name: value}")
    p.add_argument("--json", metavar="FILE", help="write the rows and every run's measures as JSON")


def _parts(text: str):
    from ..scorecard import PARTS
    parts = tuple(t.strip() for t in text.split(",") if t.strip())
    bad = [t for t in parts if t not in PARTS]
    if bad or not parts:
        raise UsageError(f"--parts {text!r}: unknown part {', '.join(bad) or '(none)'} (known: {', '.join(PARTS)})")
    return parts


def run(args: argparse.Namespace) -> int:
    from .. import bench, native, scorecard
    from .bench import _parse_settings
    from ..outputs import Outputs

    parts = _parts(args.parts)
    cfg = bench.RunConfig(scalar=args.scalar, settings=_parse_settings(args))
    native._make_settings(native.load(cfg.scalar), cfg.settings)      # a refused setting: exit 2 now
    missing = bench.missing_packages([bench.all_methods()["vqf-online-9d"]])
    if missing:
        raise InputError("the comparison needs the Python package 'vqf' (scripts/setup.sh, or pip install "
                         "'attekf[bench]')")
    plan = scorecard.Plan(parts=parts, mc=args.mc, cfg=cfg)
    if {"rates", "post-motion", "drops"} & set(parts):
        try:
            if {"rates", "post-motion"} & set(parts):
                plan.trials = bench.find_trials(args.data, args.trials)
            if "drops" in parts:
                plan.drop_trial = bench.find_trials(args.data, args.drop_trial)[0]
        except FileNotFoundError as exc:
            raise InputError(f"{exc} (the parts flips, tumbles, glitch and gap need no data: --parts)") from None
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        for p in plan.trials + ([plan.drop_trial] if plan.drop_trial else []):
            if not bench.read_recording(p).has_truth:
                raise InputError(f"{p}: no ground truth (opt_quat): nothing to score")
    with Outputs() as out:
        out.file(args.json, "--json")
        todo = len(scorecard.tasks(plan))
        from ..progress import bar
        t0 = time.perf_counter()
        try:
            with bar(todo, f"robustness: {todo} runs", args.quiet, unit="run") as pb:
                results = scorecard.run(plan, jobs=args.jobs, progress=pb.update)
        except KeyboardInterrupt:
            raise Interrupted(f"{todo} runs not finished: nothing written") from None
        wall = time.perf_counter() - t0
        return _report(args, plan, results, wall, out)


def _report(args, plan, results, wall, out) -> int:
    from .. import scorecard_report as SR
    from ..bench import clean_json, git_info, REPO_ROOT
    rows = SR.rows(results)
    git = git_info(REPO_ROOT)
    command = "attekf robustness " + " ".join(sys.argv[sys.argv.index(NAME) + 1:]) if NAME in sys.argv else \
        "attekf robustness (called from Python)"
    print(SR.format_table(rows))
    changed = ", ".join(f"{k}={v:g}" for k, v in plan.cfg.settings.items()) or "defaults"
    print(f"\nours: {plan.cfg.scalar} build, settings {changed}; commit {git.get('commit')}"
          f"{' + uncommitted changes' if git.get('uncommitted_changes') else ''}; {wall:.0f} s wall with "
          f"--jobs {args.jobs}")
    if args.json:
        doc = {"tool": f"attekf robustness {__version__}", "command": command, "git": git, "wall_seconds": wall,
               "parts": list(plan.parts), "mc": plan.mc, "scalar": plan.cfg.scalar, "settings": plan.cfg.settings,
               "rows": SR.as_json(rows), "runs": [_run_json(r) for r in results]}
        with out.open(args.json) as fh:
            json.dump(clean_json(doc), fh, indent=1, allow_nan=False)
            fh.write("\n")
    written = out.commit()
    if written and not args.quiet:
        print("wrote " + ", ".join(written), file=sys.stderr)
    return 0


def _run_json(r):
    r = dict(r)
    if "transform" in r:
        r["transform"] = r["transform"].label()
    return r
