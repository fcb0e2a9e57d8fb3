"""`attekf sim`: write a synthetic recording with known truth."""

from __future__ import annotations

import argparse
import os
import re

import math

from . import finite_float, fraction, nonneg_float, positive_float, positive_int
from ..errors import UsageError
from ..io import write_recording
from ..outputs import Outputs
from ..progress import bar
from ..scenarios import SCENARIOS, ScenarioConfig, build
from ..sim import MAX_SAMPLES, SimConfig, simulate

NAME = "sim"
HELP = "generate a synthetic IMU recording with known truth (CSV or HDF5)"
DESCRIPTION = """\
Generates a recording: rest, then random rotations (roll/pitch within +-max tilt, any yaw)
separated by static phases; gyro noise and constant bias, accelerometer and magnetometer
noise; optional linear-acceleration and magnetic-disturbance episodes. The truth is exact
(closed form). The output format follows the extension: .csv (docs/host_tools.md) or
.hdf5/.h5 (BROAD layout). Same arguments and --seed give the same file. The disturbance
episodes are printed and stored in the file (CSV: '# episode: KIND START_S STOP_S' lines; HDF5:
attribute 'episodes'), and `attekf eval` shades them in its plots.

Scenarios (--scenario; default random, the motion above): recordings that stress what real
trials rarely hold, at any --rate; their noise options are densities (per sqrt(Hz), the same
sensor at every rate), the per-sample --gyro-noise/--acc-noise/--mag-noise still override:
  flip      360 deg about body y; --approach DEG: closest approach of body x to the vertical
            (the pitch reaches 90 - DEG); --peak-rate DEG_S (default 720); --count; --after
  tumble    three rotations about random axes at --peak-rate (default 720); --count; --after
  rotation  constant --peak-rate (default 180) about --axis (default random) for --spin S
  gap       a rotation at --peak-rate 180 with --gap S (default 0.3) of samples missing
  glitch    at rest, --count glitches of --glitch DEG (default 60) about --axis, --after S apart
  drops     random motion, --drop P (default 0.05) of the samples removed
  offset    random motion without rest, --offset DEG_S (default 2), --offset-drift DEG_S/min
  magnetic  random motion with --mag-disturbance UT (default 50) episodes
  clipping  walk/run: --step-rate HZ (2.8), --impact G (3), accelerometer clipped at --clip G (2)
--drop, --drop-gyro, --offset, --offset-drift and --clip apply to every scenario. Samples
removed by --drop or a gap leave the next sample's gyro as the mean rate since the previous
one (--drop-gyro own: its own reading) and the file has per-sample times (CSV t_s, HDF5 't').
The events (flip, gap, glitch, ...) are stored like the disturbance episodes.

examples:
  attekf sim out/trial.csv --duration 60 --seed 1
  attekf sim out/disturbed.hdf5 --lin-acc 3 --mag-disturbance 30 --seed 2
  attekf sim out/flip.hdf5 --scenario flip --rate 100 --peak-rate 720 --approach 2 --seed 1
  attekf sim out/gap.hdf5 --scenario gap --rate 100 --gap 0.3
  attekf sim out/run.hdf5 --scenario clipping --rate 100 --clip 2
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    d = SimConfig()
    p.add_argument("output", help="file to write (.csv, .hdf5 or .h5)")
    p.add_argument("--duration", type=finite_float, default=d.duration_s, metavar="S",
                   help=f"length, s (default %(default)s; --duration x --rate at most {MAX_SAMPLES:,} samples)")
    p.add_argument("--rate", type=finite_float, default=d.rate_hz, metavar="HZ", help="sampling rate, Hz (default %(default)s)")
    p.add_argument("--seed", type=int, default=d.seed, help="random seed (default %(default)s)")
    p.add_argument("--rest", type=finite_float, default=d.initial_rest_s, metavar="S",
                   help="initial rest, s, not scored (default %(default)s)")
    p.add_argument("--max-tilt", type=finite_float, default=d.max_tilt_deg, metavar="DEG",
                   help="|roll|, |pitch| of rotation targets, deg (default %(default)s)")
    p.add_argument("--pause-probability", type=finite_float, default=d.pause_probability, metavar="P",
                   help="chance of a static phase after each rotation (default %(default)s)")
    p.add_argument("--no-mag", action="store_true", help="no magnetometer columns")
    p.add_argument("--gyro-noise", type=finite_float, default=d.gyro_noise_rad_s, metavar="RAD_S",
                   help="gyro white noise, rad/s 1 sigma (default %(default)s)")
    p.add_argument("--gyro-bias", type=finite_float, default=d.gyro_bias_rad_s, metavar="RAD_S",
                   help="1 sigma of the drawn constant gyro bias per axis, rad/s (default %(default)s)")
    p.add_argument("--acc-noise", type=finite_float, default=d.acc_noise_m_s2, metavar="M_S2",
                   help="accelerometer white noise, m/s^2 (default %(default)s)")
    p.add_argument("--mag-noise", type=finite_float, default=d.mag_noise_uT, metavar="UT",
                   help="magnetometer white noise, uT (default %(default)s)")
    p.add_argument("--field", type=finite_float, default=d.field_uT, metavar="UT", help="Earth field, uT (default %(default)s)")
    p.add_argument("--dip", type=finite_float, default=d.dip_deg, metavar="DEG", help="field dip, deg down (default %(default)s)")
    p.add_argument("--lin-acc", type=finite_float, default=d.lin_acc_m_s2, metavar="M_S2",
                   help="amplitude of linear-acceleration episodes, m/s^2 (default 0: none)")
    p.add_argument("--mag-disturbance", type=finite_float, default=d.mag_disturbance_uT, metavar="UT",
                   help="magnitude of magnetic-disturbance episodes, uT (default 0: none)")
    p.add_argument("--disturbance-every", type=finite_float, default=d.disturbance_every_s, metavar="S",
                   help="about one episode of each kind per this time, s (default %(default)s)")
    p.add_argument("--disturbance-length", type=finite_float, default=d.disturbance_s, metavar="S",
                   help="duration of one episode, s (default %(default)s)")
    g = p.add_argument_group("scenarios (--scenario; defaults per scenario, see above)")
    g.add_argument("--scenario", choices=["random", *SCENARIOS], default="random",
                   help="what to simulate (default random)")
    for flag, field_name, typ, meta, text in SCENARIO_OPTIONS:
        extra = {"choices": ("mean", "own")} if field_name == "drop_gyro" else {"metavar": meta}
        g.add_argument(flag, dest=field_name, type=typ, help=text, **extra)


def _axis(text: str):
    parts = text.split(",")
    if len(parts) != 3:
        raise ValueError(text)
    return tuple(float(v) for v in parts)


_axis.__name__ = "X,Y,Z"

# (option, ScenarioConfig field, type, metavar, help); None = the scenario's default
SCENARIO_OPTIONS = [
    ("--after", "after_s", nonneg_float, "S", "rest after each event, s"),
    ("--count", "count", positive_int, "N", "flips, tumbles or glitches in the recording"),
    ("--peak-rate", "peak_rate_deg_s", positive_float, "DEG_S", "peak (flip, tumble) or constant rate, deg/s"),
    ("--approach", "approach_deg", nonneg_float, "DEG", "flip: closest approach of body x to the vertical, deg"),
    ("--axis", "axis", _axis, "X,Y,Z", "rotation/gap/glitch axis in the body frame (default: random)"),
    ("--spin", "spin_s", positive_float, "S", "rotation/gap: time at the constant rate, s"),
    ("--gap", "gap_s", positive_float, "S", "gap: length of the missing stretch, s"),
    ("--glitch", "glitch_deg", positive_float, "DEG", "glitch: integral of one glitch, deg"),
    ("--step-rate", "step_rate_hz", positive_float, "HZ", "clipping: steps per second"),
    ("--impact", "impact_g", nonneg_float, "G", "clipping: peak vertical acceleration of a step, g"),
    ("--drop", "drop", fraction, "P", "remove a random fraction P of the samples (any scenario)"),
    ("--drop-gyro", "drop_gyro", str, "mean|own", "gyro after removed samples: mean rate since the previous "
     "sample (default) or its own reading"),
    ("--offset", "offset_deg_s", nonneg_float, "DEG_S", "extra gyro offset in a random direction, deg/s"),
    ("--offset-drift", "offset_drift_deg_s_per_min", finite_float, "DEG_S_MIN", "change of that offset, deg/s per min"),
    ("--clip", "clip_g", nonneg_float, "G", "accelerometer range per axis, g (0: none)"),
    ("--gyro-noise-density", "gyro_noise_density", nonneg_float, "RAD_S_RTHZ",
     "gyro white noise density, rad/s/sqrt(Hz) (scenarios; default 1e-4)"),
    ("--acc-noise-density", "acc_noise_density", nonneg_float, "M_S2_RTHZ",
     "accelerometer noise density, m/s^2/sqrt(Hz) (scenarios; default 3e-3)"),
    ("--mag-noise-density", "mag_noise_density", nonneg_float, "UT_RTHZ",
     "magnetometer noise density, uT/sqrt(Hz) (scenarios; default 0.04)"),
]
# options of the random motion that scenarios take too (SimConfig field -> ScenarioConfig field)
SHARED = {"duration": "duration_s", "rate": "rate_hz", "seed": "seed", "gyro_bias": "gyro_bias_rad_s",
          "field": "field_uT", "dip": "dip_deg", "mag_disturbance": "mag_disturbance_uT"}


# which scenarios an option changes (others refuse it rather than ignore it)
EVENTS = ("flip", "tumble", "rotation", "gap", "glitch")
RANDOM_MOTION = ("drops", "offset", "magnetic")
APPLIES = {"after_s": EVENTS + ("clipping",), "count": ("flip", "tumble", "glitch"),
           "peak_rate_deg_s": ("flip", "tumble", "rotation", "gap"), "approach_deg": ("flip",),
           "axis": ("rotation", "gap", "glitch"), "spin_s": ("rotation", "gap"), "gap_s": ("gap",),
           "glitch_deg": ("glitch",), "step_rate_hz": ("clipping",), "impact_g": ("clipping",),
           "duration_s": RANDOM_MOTION + ("clipping",), "mag_disturbance_uT": RANDOM_MOTION}
RANDOM_ONLY = ("max_tilt", "pause_probability", "lin_acc", "disturbance_every", "disturbance_length")
# ScenarioConfig field -> the option that sets it, so that a refused value is named as typed
SCENARIO_FLAGS = dict({f: flag for flag, f, _, _, _ in SCENARIO_OPTIONS},
                      **{f: "--" + opt.replace("_", "-") for opt, f in SHARED.items()}, rest_s="--rest")


def scenario_from_args(args: argparse.Namespace, defaults: argparse.Namespace) -> ScenarioConfig:
    """The ScenarioConfig of --scenario: its preset, changed by every option given (defaults:
    the options' values when not given). UsageError for an option the scenario does not use."""
    def given(name):
        return getattr(args, name) != getattr(defaults, name)

    for opt in RANDOM_ONLY:
        if given(opt):
            raise UsageError(f"--{opt.replace('_', '-')} is an option of the random motion (--scenario random), "
                             f"not of --scenario {args.scenario}")
    changes = {f: getattr(args, f) for _, f, _, _, _ in SCENARIO_OPTIONS if getattr(args, f) is not None}
    changes.update({f: getattr(args, opt) for opt, f in SHARED.items() if given(opt)})
    if given("rest"):
        changes["rest_s"] = args.rest
    for f, scen in APPLIES.items():
        if f in changes and args.scenario not in scen:
            raise UsageError(f"{SCENARIO_FLAGS[f]} does not apply to --scenario {args.scenario} "
                             f"(it applies to: {', '.join(scen)})")
    changes["with_mag"] = not args.no_mag
    rate = changes.get("rate_hz", args.rate)
    for opt, f in (("gyro_noise", "gyro_noise_density"), ("acc_noise", "acc_noise_density"),
                   ("mag_noise", "mag_noise_density")):
        if given(opt) and rate > 0:      # a per-sample sigma: the density that gives it at this rate
            changes[f] = getattr(args, opt) / math.sqrt(rate)
    return ScenarioConfig.preset(args.scenario, **changes)


def config_from_args(args: argparse.Namespace) -> SimConfig:
    return SimConfig(duration_s=args.duration, rate_hz=args.rate, seed=args.seed, initial_rest_s=args.rest,
                     max_tilt_deg=args.max_tilt, pause_probability=args.pause_probability,
                     with_mag=not args.no_mag, gyro_noise_rad_s=args.gyro_noise, gyro_bias_rad_s=args.gyro_bias,
                     acc_noise_m_s2=args.acc_noise, mag_noise_uT=args.mag_noise, field_uT=args.field,
                     dip_deg=args.dip, lin_acc_m_s2=args.lin_acc, mag_disturbance_uT=args.mag_disturbance,
                     disturbance_every_s=args.disturbance_every, disturbance_s=args.disturbance_length)


# SimConfig field -> the option that sets it, so that a refused value is named as typed
OPTIONS = {"seed": "--seed", "duration_s": "--duration", "rate_hz": "--rate", "initial_rest_s": "--rest",
           "max_tilt_deg": "--max-tilt", "pause_probability": "--pause-probability",
           "gyro_noise_rad_s": "--gyro-noise", "gyro_bias_rad_s": "--gyro-bias",
           "acc_noise_m_s2": "--acc-noise", "mag_noise_uT": "--mag-noise", "field_uT": "--field",
           "dip_deg": "--dip", "lin_acc_m_s2": "--lin-acc", "mag_disturbance_uT": "--mag-disturbance",
           "disturbance_every_s": "--disturbance-every", "disturbance_s": "--disturbance-length"}


def _option_names(text: str) -> str:
    return re.sub(r"\b(" + "|".join(OPTIONS) + r")\b", lambda m: OPTIONS[m.group(0)], text)


def _scenario_config(args: argparse.Namespace) -> ScenarioConfig:
    p = argparse.ArgumentParser(add_help=False)
    add_arguments(p)
    return scenario_from_args(args, p.parse_args([args.output]))


def _scenario_message(text: str) -> str:
    return re.sub(r"\b(" + "|".join(SCENARIO_FLAGS) + r")\b", lambda m: SCENARIO_FLAGS[m.group(0)], text)


def run(args: argparse.Namespace) -> int:
    if args.scenario != "random":
        return _run_scenario(args)
    given = [flag for flag, f, _, _, _ in SCENARIO_OPTIONS if getattr(args, f) is not None]
    if given:
        raise UsageError(f"{given[0]} is an option of the scenarios: add --scenario NAME")
    if args.duration > 0 and args.rate > 0 and args.duration * args.rate > MAX_SAMPLES:
        raise UsageError(f"--duration {args.duration:g} s at --rate {args.rate:g} Hz is "
                         f"{args.duration * args.rate:.4g} samples: at most {MAX_SAMPLES:,} in one recording "
                         f"(it is built in memory)")
    cfg = config_from_args(args)
    with Outputs() as out:
        out.file(args.output, "output")
        _check_extension(args.output)
        try:
            rec = simulate(cfg)
        except ValueError as exc:
            raise UsageError(_option_names(str(exc))) from None
        with bar(len(rec), f"writing {args.output}", args.quiet, unit="row") as pb:
            # the temporary name keeps the extension, which selects the format
            write_recording(out.temp(args.output), rec, progress=pb.update)
        out.commit()
    if not args.quiet:
        eps = ", ".join(f"{k.replace('_', ' ')} {a:.1f}-{b:.1f} s" for k, a, b in cfg.episodes) or "no disturbances"
        print(f"wrote {args.output}: {len(rec)} samples, {cfg.duration_s:g} s at {cfg.rate_hz:g} Hz, "
              f"seed {cfg.seed}, {'with' if cfg.with_mag else 'no'} magnetometer; {eps}")
    return 0


def _run_scenario(args: argparse.Namespace) -> int:
    try:
        cfg = _scenario_config(args)
        cfg.validate()
    except ValueError as exc:
        raise UsageError(_scenario_message(str(exc))) from None
    with Outputs() as out:
        out.file(args.output, "output")
        _check_extension(args.output)
        rec = build(cfg)
        with bar(len(rec), f"writing {args.output}", args.quiet, unit="row") as pb:
            write_recording(out.temp(args.output), rec, progress=pb.update)
        out.commit()
    if not args.quiet:
        evs = ", ".join(f"{k.replace('_', ' ')} {a:.2f}-{b:.2f} s" for k, a, b in cfg.events) or "no events"
        print(f"wrote {args.output}: scenario {cfg.scenario}, {len(rec)} samples, {rec.t[-1] - rec.t[0]:g} s at "
              f"{cfg.rate_hz:g} Hz, seed {cfg.seed}, {'with' if cfg.with_mag else 'no'} magnetometer; {evs}")
    return 0


def _check_extension(path: str) -> None:
    ext = path.lower().rsplit(".", 1)[-1] if "." in os.path.basename(path) else ""
    if ext not in ("csv", "hdf5", "h5"):
        raise UsageError(f"{path}: unknown recording format '.{ext}' (expected .csv, .hdf5 or .h5)"
                         if ext else f"{path}: no extension (expected .csv, .hdf5 or .h5)")
