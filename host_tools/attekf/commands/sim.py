"""`attekf sim`: write a synthetic recording with known truth."""

from __future__ import annotations

import argparse
import os
import re

from . import finite_float
from ..errors import UsageError
from ..io import write_recording
from ..outputs import Outputs
from ..progress import bar
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

examples:
  attekf sim out/trial.csv --duration 60 --seed 1
  attekf sim out/disturbed.hdf5 --lin-acc 3 --mag-disturbance 30 --seed 2
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


def run(args: argparse.Namespace) -> int:
    if args.duration > 0 and args.rate > 0 and args.duration * args.rate > MAX_SAMPLES:
        raise UsageError(f"--duration {args.duration:g} s at --rate {args.rate:g} Hz is "
                         f"{args.duration * args.rate:.4g} samples: at most {MAX_SAMPLES:,} in one recording "
                         f"(it is built in memory)")
    cfg = config_from_args(args)
    with Outputs() as out:
        out.file(args.output, "output")
        ext = args.output.lower().rsplit(".", 1)[-1] if "." in os.path.basename(args.output) else ""
        if ext not in ("csv", "hdf5", "h5"):
            raise UsageError(f"{args.output}: unknown recording format '.{ext}' (expected .csv, .hdf5 or .h5)"
                             if ext else f"{args.output}: no extension (expected .csv, .hdf5 or .h5)")
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
