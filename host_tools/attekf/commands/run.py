"""`attekf run`: the estimator over a recording, its output per sample to a file."""

from __future__ import annotations

import argparse
import math
import os
import sys

from . import add_settings_arguments, list_settings, parse_settings
from ..errors import UsageError

NAME = "run"
HELP = "run the estimator over a recording and write its output per sample (CSV or HDF5)"
DESCRIPTION = """\
Runs the C estimator (the same code as the firmware; --scalar picks the build) over one
recording and writes, per sample, the attitude with its uncertainty and the filter's flags.
The recording is a CSV with a header or an HDF5 file in the BROAD layout:

  CSV columns  t_s (s, strictly increasing), gyr_x_rad_s, gyr_y_rad_s, gyr_z_rad_s (rad/s),
               acc_x_m_s2, acc_y_m_s2, acc_z_m_s2 (m/s^2, +9.81 up at rest), optional
               mag_x_uT, mag_y_uT, mag_z_uT (uT; three empty cells: no sample); other
               columns are ignored. Lines starting with # before the header are comments.
  HDF5         datasets imu_gyr, imu_acc, optional imu_mag (N, 3), attribute
               sampling_rate (Hz) or a dataset t (N,) s.

The output format follows OUT's extension:

  .csv   t_s, quat_w, quat_x, quat_y, quat_z (body -> ENU, or NED with --frame NED),
         roll_rad, pitch_rad, yaw_rad (ZYX), sigma_roll_rad, sigma_pitch_rad, sigma_yaw_rad
         (1-sigma), var_roll_rad2, var_pitch_rad2, var_yaw_rad2, gyro_bias_{x,y,z}_rad_s and
         gyro_bias_sigma_{x,y,z}_rad_s (the gyroscope offset, body frame), flags (bits:
         1 aligned, 2 gimbal lock, 4 accel deweighted, 8 accel rejected, 16 mag disturbed,
         ... as attekf.Flag), status (0 = OK, 11 gated, 12 skipped, others: sample refused).
         Before the filter has aligned (its first 10 samples) the attitude and sigma cells
         are empty. `attekf eval REC --output-csv OUT.csv` scores this file.
  .h5    datasets t, quat, euler, sigma, cov (N, 3, 3), gyro_bias, gyro_bias_sigma, flags,
         status (N, 5); attributes frame, scalar, settings (needs the tools extra)

The output is written under a temporary name and renamed when complete; an error or Ctrl-C
leaves no partial file.

examples:
  attekf run trial.csv -o trial_output.csv
  attekf run trial.hdf5 -o out.h5 --frame NED --settings tuned.toml
  attekf run trial.csv -o out.csv --no-mag --set accel_noise=0.3
"""


def _mounting(text: str):
    """Nine numbers, row-major (sensor -> body rotation)."""
    values = [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
    if len(values) != 9 or not all(math.isfinite(v) for v in values):
        raise ValueError(text)
    return [values[0:3], values[3:6], values[6:9]]


_mounting.__name__ = "rotation matrix (9 numbers)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("recording", nargs="?", help="the recording (.csv, .hdf5 or .h5)")
    p.add_argument("-o", "--out", metavar="OUT", help="the output file (.csv, .h5 or .hdf5)")
    add_settings_arguments(p)
    p.add_argument("--no-mag", action="store_true", help="run without the magnetometer (6D)")
    p.add_argument("--frame", choices=("ENU", "NED"), default="ENU", type=str.upper,
                   help="earth frame of the outputs (default ENU: x east, y north, z up)")
    p.add_argument("--mounting", type=_mounting, metavar="R11,R12,...,R33",
                   help="rotation sensor -> body applied to every input, 9 numbers row-major")
    p.add_argument("--no-unit-check", action="store_true",
                   help="accept data whose magnitudes look like other units (deg/s, g, gauss)")


def run(args: argparse.Namespace) -> int:
    if args.list_settings:
        return list_settings(args.scalar)
    if not args.recording:
        raise UsageError("no recording given (see attekf run --help)")
    if not args.out:
        raise UsageError("-o OUT is needed: the output file, .csv or .h5 (see attekf run --help)")
    ext = os.path.splitext(args.out)[1].lower()
    from ..output_file import EXTS, write_result
    if ext not in EXTS:
        raise UsageError(f"{args.out}: unknown output format '{ext or '(none)'}' (expected .csv, .h5 or .hdf5)")
    if ext != ".csv":
        from ..extras import require
        require("h5py", "HDF5 output")
    settings = parse_settings(args)
    import attekf
    from ..io import read_recording
    from ..outputs import Outputs
    from ..progress import bar
    with Outputs() as out:
        out.inputs([args.recording, args.settings])
        target = out.file(args.out, "-o")
        with bar(None, f"reading {os.path.basename(args.recording)}", args.quiet, unit="row") as pb:
            rec = read_recording(args.recording, check_units=not args.no_unit_check, progress=pb.update)
        try:
            f = attekf.Filter(settings, args.scalar, frame=args.frame, mounting=args.mounting)
        except ValueError as exc:
            if not str(exc).startswith("mounting:"):
                raise
            raise UsageError(f"--{exc}") from None
        with bar(len(rec), rec.name, args.quiet, unit="sample") as pb:
            res = f.run_recording(rec, use_mag=not args.no_mag, progress=pb.update)
        with bar(len(rec), f"writing {os.path.basename(args.out)}", args.quiet, unit="row") as pb:
            write_result(out.temp(target), res, progress=pb.update)
        out.commit()
    if not args.quiet:
        s = res.summary()
        print(f"wrote {args.out}: {len(res)} samples, {s['aligned_samples']} with an estimate, "
              f"{s['samples_refused']} refused by the filter ({args.scalar} build, {args.frame})", file=sys.stderr)
    return 0
